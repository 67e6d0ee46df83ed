"""The output keeps the input's prim paths, hierarchy, transforms and default prim (issue 15, item 3),
so it can be layered over the source asset; ``--resume`` and ``warpshade export`` work on it."""

from __future__ import annotations

import os

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom

from helpers import InterruptingWriter
from warpshade.cli import main
from warpshade.pipeline import Pipeline
from warpshade.usd import AnimationWriter, read_scene
from warpshade.usd.writer import BACK_SIDE_OFFSET
from warpshade.usd.validate import validation_errors

QUICK = dict(method="reference", knobs={"rays": 4}, order=2, refine_receivers="off")
CLI_QUICK = ["--method", "reference", "--rays", "4", "--order", "2", "--refine-receivers", "off", "--no-progress"]
MESHES = {"/Asset/Body/Geo/Box", "/Asset/Body/Geo/Sheet"}


def make_asset(path):
    """A Z-up, centimetre asset: /Asset (rotated, moved) > Body (scaled) > Geo (typeless) > a Cube
    gprim and a moving Mesh, a guide-purpose collision twin of the Cube and an invisible Sphere."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, 0.01)
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(3)
    asset = UsdGeom.Xform.Define(stage, "/Asset")
    asset.AddTranslateOp().Set(Gf.Vec3d(10.0, -5.0, 2.0))
    asset.AddRotateZOp().Set(30.0)
    stage.SetDefaultPrim(asset.GetPrim())
    body = UsdGeom.Xform.Define(stage, "/Asset/Body")
    body.AddScaleOp().Set(Gf.Vec3f(2.0, 2.0, 2.0))
    stage.DefinePrim("/Asset/Body/Geo")  # typeless, as Newton's "visuals" scopes
    cube = UsdGeom.Cube.Define(stage, "/Asset/Body/Geo/Box")
    cube.CreateSizeAttr(4.0)
    cube.AddTranslateOp().Set(Gf.Vec3d(0.0, 0.0, 2.0))
    guide = UsdGeom.Cube.Define(stage, "/Asset/Body/Collision/Box")
    guide.CreatePurposeAttr(UsdGeom.Tokens.guide)
    hidden = UsdGeom.Sphere.Define(stage, "/Asset/Body/Geo/Hidden")
    hidden.CreateVisibilityAttr(UsdGeom.Tokens.invisible)
    sheet = UsdGeom.Mesh.Define(stage, "/Asset/Body/Geo/Sheet")
    n = 6
    u = np.linspace(-5.0, 5.0, n)
    grid = np.array([(x, y, 0.0) for y in u for x in u])
    quads = [(j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i) for j in range(n - 1) for i in range(n - 1)]
    sheet.CreateFaceVertexCountsAttr([4] * len(quads))
    sheet.CreateFaceVertexIndicesAttr(np.ravel(quads).tolist())
    for t in (1, 2, 3):  # time-sampled points: an "animated" mesh
        sheet.GetPointsAttr().Set([Gf.Vec3f(*p) for p in grid + (0.0, 0.0, 0.5 * t)], t)
    sheet.AddTranslateOp().Set(Gf.Vec3d(0.0, 0.0, 6.0))
    stage.GetRootLayer().Save()
    return stage


def world_points(stage, path, t):
    prim = stage.GetPrimAtPath(path)
    pts = np.asarray(UsdGeom.Mesh(prim).GetPointsAttr().Get(t), dtype=np.float64)
    xf = np.asarray(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(t), dtype=np.float64)
    return pts @ xf[:3, :3] + xf[3, :3]


@pytest.fixture(scope="module")
def shaded(tmp_path_factory):
    d = tmp_path_factory.mktemp("hier")
    src = d / "asset.usda"
    make_asset(src)
    out = d / "out.usda"
    assert main(["run", str(src), "--out", str(out)] + CLI_QUICK) == 0
    return src, out


def test_meshes_keep_their_input_paths_and_default_prim(shaded):
    src, out = shaded
    stage = Usd.Stage.Open(str(out))
    meshes = {str(p.GetPath()) for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)}
    assert meshes == MESHES  # no guide twin, no invisible sphere, nothing flattened to /World/<leaf>
    assert str(stage.GetDefaultPrim().GetPath()) == "/Asset"
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z and UsdGeom.GetStageMetersPerUnit(stage) == 0.01
    assert stage.GetPrimAtPath("/Asset/Body").GetTypeName() == "Xform"
    assert stage.GetPrimAtPath("/Asset/Body/Geo").GetTypeName() == ""  # typeless stays typeless
    assert not stage.GetPrimAtPath("/World")  # nothing was built in Python: no /World
    assert stage.GetPrimAtPath("/Asset/Looks") and stage.GetPrimAtPath("/Asset/Lights")
    assert validation_errors(out) == []


def test_output_world_positions_match_the_input(shaded):
    src, out = shaded
    a, b = Usd.Stage.Open(str(src)), Usd.Stage.Open(str(out))
    for t in (1, 2, 3):
        # float32 points through a float64 transform chain of scale ~2 and offsets ~10: 1e-5 [cm]
        np.testing.assert_allclose(world_points(b, "/Asset/Body/Geo/Sheet", t),
                                   world_points(a, "/Asset/Body/Geo/Sheet", t), atol=1e-5)
    box_in = UsdGeom.Imageable(a.GetPrimAtPath("/Asset/Body/Geo/Box")).ComputeWorldBound(1, "default").ComputeAlignedRange()
    box_out = UsdGeom.Imageable(b.GetPrimAtPath("/Asset/Body/Geo/Box")).ComputeWorldBound(1, "default").ComputeAlignedRange()
    np.testing.assert_allclose(box_out.GetMin(), box_in.GetMin(), atol=1e-5)
    np.testing.assert_allclose(box_out.GetMax(), box_in.GetMax(), atol=1e-5)
    # the ancestors' transforms are the input's (the mesh's own one is baked into its points)
    for path in ("/Asset", "/Asset/Body"):
        np.testing.assert_allclose(
            np.asarray(UsdGeom.Xformable(b.GetPrimAtPath(path)).GetLocalTransformation(1)),
            np.asarray(UsdGeom.Xformable(a.GetPrimAtPath(path)).GetLocalTransformation(1)), atol=1e-12)


def test_output_layered_over_the_source_shows_the_output(shaded, tmp_path):
    """Layered over the source (stronger), each mesh is where the output alone puts it, with the
    output's colours; the source's own prims (the guide twin) are still there."""
    src, out = shaded
    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.subLayerPaths = [str(out), str(src)]
    both, alone = Usd.Stage.Open(layer), Usd.Stage.Open(str(out))
    for path in MESHES:
        for t in (1, 3):
            np.testing.assert_allclose(world_points(both, path, t), world_points(alone, path, t), atol=1e-6)
        colors = UsdGeom.PrimvarsAPI(both.GetPrimAtPath(path)).GetPrimvar("displayColor").Get(2)
        assert colors is not None and np.asarray(colors).max() > 0, path
    assert both.GetPrimAtPath("/Asset/Body/Collision/Box").GetTypeName() == "Cube"


def test_python_objects_keep_world_paths_beside_input_hierarchy(tmp_path):
    src = tmp_path / "asset.usda"
    make_asset(src)
    scene = read_scene(str(src))
    extra = read_scene(str(src)).object("/Asset/Body/Geo/Box")
    extra.name, extra.prim_path, extra.prim_xforms = "Extra", None, ()  # as if built in Python
    extra.mesh.points[:] += (0.0, 0.0, 50.0)
    scene.objects.append(extra)
    out = tmp_path / "o.usda"
    Pipeline(scene, frames=1, **QUICK).run(AnimationWriter(str(out), fps=scene.fps, up_axis="Z"), progress=False)
    stage = Usd.Stage.Open(str(out))
    assert {str(p.GetPath()) for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)} == MESHES | {"/World/Extra"}
    assert str(stage.GetDefaultPrim().GetPath()) == "/Asset"


def test_resume_and_export_keep_the_hierarchy(shaded, tmp_path):
    src, full = shaded
    out = tmp_path / "o.usda"
    scene = read_scene(str(src))
    with pytest.raises(KeyboardInterrupt):
        Pipeline(scene, **QUICK).run(InterruptingWriter(str(out), chunk=1, at=3, fps=scene.fps, up_axis="Z",
                                                         meters_per_unit=0.01,
                                                         metadata={"scene": os.path.abspath(src), "order": 2}),
                                     progress=False)
    assert Usd.Stage.Open(str(out)).GetEndTimeCode() == 2
    assert main(["run", str(src), "--out", str(out), "--resume"] + CLI_QUICK) == 0
    a, b = Usd.Stage.Open(str(full)), Usd.Stage.Open(str(out))
    assert b.GetEndTimeCode() == 3
    for t in (1, 2, 3):  # same deterministic run: the same points (reference rays are seeded)
        np.testing.assert_array_equal(world_points(b, "/Asset/Body/Geo/Sheet", t), world_points(a, "/Asset/Body/Geo/Sheet", t))
    flat = tmp_path / "flat.usdc"
    assert main(["export", str(out), "-o", str(flat)]) == 0
    f = Usd.Stage.Open(str(flat))
    assert {str(p.GetPath()) for p in f.Traverse() if p.IsA(UsdGeom.Mesh)} == MESHES
    np.testing.assert_allclose(world_points(f, "/Asset/Body/Geo/Sheet", 3), world_points(a, "/Asset/Body/Geo/Sheet", 3),
                               atol=1e-6)


def test_two_sided_cloth_under_a_transformed_parent(tmp_path):
    """A cloth under a moved, scaled parent: front at its input path, back beside it, both in the
    parent's space, on the same world points."""
    src = tmp_path / "rig.usda"
    stage = Usd.Stage.CreateNew(str(src))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)  # in metres (unauthored is centimetres and warns)
    rig = UsdGeom.Xform.Define(stage, "/Rig")
    rig.AddTranslateOp().Set(Gf.Vec3d(0.5, 1.0, 0.0))
    rig.AddScaleOp().Set(Gf.Vec3f(2.0, 2.0, 2.0))
    stage.SetDefaultPrim(rig.GetPrim())
    drape = UsdGeom.Mesh.Define(stage, "/Rig/Drape")
    n = 5
    u = np.linspace(-0.25, 0.25, n)
    drape.CreatePointsAttr([Gf.Vec3f(float(x), 0.0, float(z)) for z in u for x in u])
    quads = [(j * n + i, (j + 1) * n + i, (j + 1) * n + i + 1, j * n + i + 1) for j in range(n - 1) for i in range(n - 1)]
    drape.CreateFaceVertexCountsAttr([4] * len(quads))
    drape.CreateFaceVertexIndicesAttr(np.ravel(quads).tolist())
    prim = drape.GetPrim()
    prim.CreateAttribute("warpshade:kind", Sdf.ValueTypeNames.String, custom=True).Set("cloth")
    prim.CreateAttribute("warpshade:pinned", Sdf.ValueTypeNames.IntArray, custom=True).Set([0, n - 1])
    stage.GetRootLayer().Save()
    out = tmp_path / "o.usda"
    assert main(["run", str(src), "--out", str(out), "--frames", "3"] + CLI_QUICK) == 0
    res = Usd.Stage.Open(str(out))
    assert {str(p.GetPath()) for p in res.Traverse() if p.IsA(UsdGeom.Mesh)} == {"/Rig/Drape", "/Rig/Drape_back"}
    diag = float(np.linalg.norm(np.ptp(world_points(res, "/Rig/Drape", 0), axis=0)))
    for t in (0, 2):
        # the back lies BACK_SIDE_OFFSET of the size behind the front (in world space, through the parent's scale)
        gap = np.linalg.norm(world_points(res, "/Rig/Drape_back", t) - world_points(res, "/Rig/Drape", t), axis=1)
        np.testing.assert_allclose(gap, BACK_SIDE_OFFSET * diag, rtol=1e-2)  # 1 %: float32 points of size ~1
    # pinned corners stay where the input puts them in world space: (0.5, 1, 0) + 2 * (+-0.25, 0, -0.25)
    np.testing.assert_allclose(world_points(res, "/Rig/Drape", 2)[[0, n - 1]], [[0.0, 1.0, -0.5], [1.0, 1.0, -0.5]],
                               atol=1e-5)


def _lit_asset(path):
    """make_asset plus a DistantLight under a moved, rotated rig of the asset (with its own
    rotation) and a DomeLight under a second root prim."""
    stage = make_asset(path)
    rig = UsdGeom.Xform.Define(stage, "/Asset/Rig")
    rig.AddTranslateOp().Set(Gf.Vec3d(0.0, 3.0, 40.0))
    rig.AddRotateXOp().Set(-20.0)
    from pxr import UsdLux

    sun = UsdLux.DistantLight.Define(stage, "/Asset/Rig/Sun")
    sun.AddRotateYOp().Set(35.0)
    sun.CreateIntensityAttr(2.5)
    sun.CreateAngleAttr(3.0)
    env = UsdGeom.Xform.Define(stage, "/Env")
    env.AddRotateZOp().Set(90.0)
    UsdLux.DomeLight.Define(stage, "/Env/Sky").CreateIntensityAttr(0.4)
    stage.GetRootLayer().Save()
    return stage


def test_lights_keep_their_input_paths_and_world_transforms(tmp_path):
    """Lights read from a USD scene are written at their input prim paths under their input
    ancestors (issue 15, item 3), with the input's world transforms, alone and layered over the source."""
    from pxr import UsdLux

    src = tmp_path / "lit.usda"
    _lit_asset(src)
    out = tmp_path / "o.usda"
    assert main(["run", str(src), "--out", str(out)] + CLI_QUICK) == 0
    a, b = Usd.Stage.Open(str(src)), Usd.Stage.Open(str(out))
    lights = {str(p.GetPath()): p.GetTypeName() for p in b.Traverse() if p.HasAPI(UsdLux.LightAPI)}
    assert lights == {"/Asset/Rig/Sun": "DistantLight", "/Env/Sky": "DomeLight"}
    assert not b.GetPrimAtPath("/Asset/Lights") and not b.GetPrimAtPath("/World")
    assert b.GetPrimAtPath("/Asset/Rig").GetTypeName() == "Xform" and b.GetPrimAtPath("/Env").GetTypeName() == "Xform"
    layer = Sdf.Layer.CreateAnonymous(".usda")
    layer.subLayerPaths = [str(out), str(src)]
    both = Usd.Stage.Open(layer)
    for path in lights:
        want = np.asarray(UsdGeom.Xformable(a.GetPrimAtPath(path)).ComputeLocalToWorldTransform(0))
        for stage in (b, both):
            # float64 transform chain of translations ~40 and rotations: 1e-9 relative is float64 round-off
            np.testing.assert_allclose(
                np.asarray(UsdGeom.Xformable(stage.GetPrimAtPath(path)).ComputeLocalToWorldTransform(0)), want,
                atol=1e-9)
    assert UsdLux.DistantLight(b.GetPrimAtPath("/Asset/Rig/Sun")).GetIntensityAttr().Get() == 2.5
    assert UsdLux.DistantLight(b.GetPrimAtPath("/Asset/Rig/Sun")).GetAngleAttr().Get() == 3.0
    # the parents' own transforms are the input's
    for path in ("/Asset/Rig", "/Env"):
        np.testing.assert_allclose(np.asarray(UsdGeom.Xformable(b.GetPrimAtPath(path)).GetLocalTransformation(0)),
                                   np.asarray(UsdGeom.Xformable(a.GetPrimAtPath(path)).GetLocalTransformation(0)),
                                   atol=1e-12)
    assert validation_errors(out) == []


def test_python_lights_go_under_the_default_prims_lights(tmp_path):
    """A light built in Python (no input prim) is written under Lights of the default prim, beside
    the input's lights at their own paths."""
    from pxr import UsdLux

    from warpshade.scene import LightSpec

    src = tmp_path / "lit.usda"
    _lit_asset(src)
    scene = read_scene(str(src))
    scene.lights.append(LightSpec("sphere", "Bulb", intensity=0.5, radius=2.0,
                                  transform=np.array([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 30.0], [0, 0, 0, 1]])))
    out = tmp_path / "o.usda"
    Pipeline(scene, frames=1, **QUICK).run(AnimationWriter(str(out), fps=scene.fps, up_axis="Z"), progress=False)
    stage = Usd.Stage.Open(str(out))
    lights = {str(p.GetPath()) for p in stage.Traverse() if p.HasAPI(UsdLux.LightAPI)}
    assert lights == {"/Asset/Rig/Sun", "/Env/Sky", "/Asset/Lights/Bulb"}
    bulb = np.asarray(UsdGeom.Xformable(stage.GetPrimAtPath("/Asset/Lights/Bulb")).ComputeLocalToWorldTransform(0))
    # at its world position although /Asset (the default prim) is moved and rotated in the output
    np.testing.assert_allclose(bulb[3, :3], [0.0, 0.0, 30.0], atol=1e-9)
    assert UsdLux.SphereLight(stage.GetPrimAtPath("/Asset/Lights/Bulb")).GetRadiusAttr().Get() == 2.0


def test_default_sky_is_not_turned_by_a_moved_default_prim(shaded):
    """The default sky (no scene light) goes under Lights of the input's default prim, which the
    output moves and rotates as the input does: the dome keeps the world orientation it is shaded with."""
    from pxr import UsdLux

    _, out = shaded
    stage = Usd.Stage.Open(str(out))
    domes = [p for p in stage.Traverse() if p.IsA(UsdLux.DomeLight)]
    assert [str(p.GetPath()) for p in domes] == ["/Asset/Lights/DefaultSky"]
    world = np.asarray(UsdGeom.Xformable(domes[0]).ComputeLocalToWorldTransform(0))
    assert not np.allclose(np.asarray(UsdGeom.Xformable(stage.GetPrimAtPath("/Asset")).GetLocalTransformation(0)),
                           np.eye(4))  # the parent really is moved
    # a Z-up scene's sky: the dome's +Y (its lat-long top; row 1 of USD's row-vector matrix) is world +Z
    np.testing.assert_allclose(world[1, :3], [0.0, 0.0, 1.0], atol=1e-9)
    np.testing.assert_allclose(world[3, :3], 0.0, atol=1e-9)
