"""Scenes no one here wrote (issue 15): Newton's ``humanoid.usda`` (Z-up, Capsule and Sphere gprims,
each with a ``purpose = "guide"`` collision twin) and ``unisex_shirt.usd`` (Y-up, centimetres, no
default prim). Copies in tests/data/newton/ (Apache-2.0, see its NOTICE)."""

from __future__ import annotations

import os
import warnings

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom

from helpers import DATA
from warpshade.pipeline import Pipeline
from warpshade.scene import SceneWarning
from warpshade.usd import AnimationWriter, read_scene
from warpshade.usd.scene_io import scene_from_stage

NEWTON = os.path.join(DATA, "newton")
HUMANOID = os.path.join(NEWTON, "humanoid.usda")
SHIRT = os.path.join(NEWTON, "unisex_shirt.usd")
QUICK = dict(method="reference", knobs={"rays": 16}, order=4, refine_receivers="off")


def _source_prims():
    """(visible shapes, guide shapes) of the humanoid, read with pxr alone."""
    stage = Usd.Stage.Open(HUMANOID)
    shapes = [p for p in stage.Traverse() if p.GetTypeName() in ("Capsule", "Sphere")]
    guides = {str(p.GetPath()) for p in shapes if UsdGeom.Imageable(p).ComputePurpose() == UsdGeom.Tokens.guide}
    visible = {str(p.GetPath()) for p in shapes} - guides
    return stage, visible, guides


def test_humanoid_reads_every_visible_capsule_and_sphere_and_no_guide():
    stage, visible, guides = _source_prims()
    kinds = {str(p.GetPath()): p.GetTypeName() for p in stage.Traverse()}
    assert len(visible) == 19 and len(guides) == 19  # 16 capsules + 3 spheres, each with a guide twin
    assert sum(kinds[p] == "Capsule" for p in visible) == 16
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = read_scene(HUMANOID)
    # its physics prims (PhysicsScene, joints, collision groups) draw nothing and are skipped quietly
    assert [str(w.message) for w in caught if issubclass(w.category, SceneWarning)] == []
    names = {o.prim_path for o in scene.objects}
    assert names == visible
    assert not names & guides
    assert scene.up_axis == "Z" and scene.default_prim == "/nv_humanoid"


def test_invisible_prims_of_a_real_asset_are_not_read():
    """An ``over`` setting the head invisible, layered over the asset: the head is gone, the rest stays."""
    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.subLayerPaths = [HUMANOID]
    stage = Usd.Stage.Open(layer)
    stage.OverridePrim("/nv_humanoid/head").CreateAttribute("visibility", Sdf.ValueTypeNames.Token).Set("invisible")
    _, visible, _ = _source_prims()
    names = {o.prim_path for o in scene_from_stage(stage, "over.usda").objects}
    assert names == visible - {"/nv_humanoid/head/visuals/head"}


@pytest.fixture(scope="module")
def humanoid_out(tmp_path_factory):
    out = tmp_path_factory.mktemp("humanoid") / "h.usda"
    scene = read_scene(HUMANOID)
    Pipeline(scene, frames=1, **QUICK).run(
        AnimationWriter(str(out), fps=scene.fps, up_axis=scene.up_axis, meters_per_unit=scene.meters_per_unit),
        progress=False)
    return Usd.Stage.Open(str(out))


def test_humanoid_output_keeps_paths_and_shades_each_visual(humanoid_out):
    _, visible, guides = _source_prims()
    stage = humanoid_out
    meshes = {str(p.GetPath()): p for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)}
    assert set(meshes) == visible
    assert str(stage.GetDefaultPrim().GetPath()) == "/nv_humanoid"
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z
    for path, prim in meshes.items():
        colors = np.asarray(UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayColor").Get(0))
        # lit by the default sky: mean radiance measured 0.044 (left lower arm, mostly in the body's
        # shadow, its caps inside its neighbours) to 0.39 (head); an unshaded or black mesh has 0
        assert colors.mean() > 0.02, path


def test_humanoid_is_lit_from_its_up_axis(humanoid_out):
    """Z-up honoured: under the default sky the top of the head (+Z normals) is brighter than its
    underside (-Z normals); with the sky on +Y the two would be alike (both horizontal)."""
    prim = humanoid_out.GetPrimAtPath("/nv_humanoid/head/visuals/head")
    n = np.asarray(UsdGeom.Mesh(prim).GetNormalsAttr().Get(0))
    c = np.asarray(UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayColor").Get(0)).mean(axis=1)
    top, bottom = c[n[:, 2] > 0.7].mean(), c[n[:, 2] < -0.7].mean()
    assert top > 2.0 * bottom, (top, bottom)


def test_shirt_loads_and_shades_in_its_units(tmp_path):
    scene = read_scene(SHIRT)
    assert [o.prim_path for o in scene.objects] == ["/root/shirt"]
    assert scene.meters_per_unit == pytest.approx(0.01) and scene.up_axis == "Y"
    out = tmp_path / "s.usda"
    Pipeline(scene, frames=1, **QUICK).run(
        AnimationWriter(str(out), fps=scene.fps, up_axis=scene.up_axis, meters_per_unit=scene.meters_per_unit),
        progress=False)
    stage = Usd.Stage.Open(str(out))
    assert UsdGeom.GetStageMetersPerUnit(stage) == pytest.approx(0.01)
    prim = stage.GetPrimAtPath("/root/shirt")
    assert prim.IsA(UsdGeom.Mesh)
    colors = np.asarray(UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayColor").Get(0))
    assert len(colors) == len(scene.objects[0].mesh.points) and np.mean(colors.max(axis=1) > 0) > 0.9
