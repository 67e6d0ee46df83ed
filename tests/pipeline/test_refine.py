"""Receiver refinement: a coarse static ground gets vertices for the contact shadows to fall on."""

import numpy as np
import pytest
from pxr import Usd, UsdGeom, UsdLux

from warpshade.pipeline import Pipeline
from warpshade.pipeline.refine import EDGE_FRACTION, refine_receivers, refinement_edge
from warpshade.scene import SceneError
from warpshade.usd import AnimationWriter, read_scene


def _box_on_ground(path):
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(stage.GetPrimAtPath("/World"))
    cube = UsdGeom.Cube.Define(stage, "/World/Box")
    UsdGeom.XformCommonAPI(cube).SetTranslate((0, 1, 0))  # size 2: sits on the ground
    g = UsdGeom.Mesh.Define(stage, "/World/Ground")
    g.CreatePointsAttr([(-4, 0, -4), (4, 0, -4), (4, 0, 4), (-4, 0, 4)])
    g.CreateFaceVertexCountsAttr([3, 3])
    g.CreateFaceVertexIndicesAttr([0, 2, 1, 0, 3, 2])
    UsdLux.DomeLight.Define(stage, "/World/Sky")
    stage.GetRootLayer().Save()
    return str(path)


def test_auto_edge_refines_only_the_coarse_mesh(tmp_path):
    scene = read_scene(_box_on_ground(tmp_path / "s.usda"))
    box_before = scene.object("/World/Box").mesh.num_vertices
    edge = refinement_edge(scene, "auto")
    diag = np.linalg.norm([8, 2, 8])
    assert edge == pytest.approx(diag * EDGE_FRACTION)
    refined = refine_receivers(scene)
    assert [r.name for r in refined] == ["/World/Ground"]
    ground = scene.object("/World/Ground").mesh
    tri = ground.points[ground.faces]
    assert np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max() <= edge
    assert np.allclose(ground.points[:, 1], 0) and np.ptp(ground.points[:, 0]) == 8  # same plane, same extent
    assert scene.object("/World/Box").mesh.num_vertices == box_before
    assert refine_receivers(scene) == []  # idempotent


def test_off_and_bad_values(tmp_path):
    scene = read_scene(_box_on_ground(tmp_path / "s.usda"))
    assert refine_receivers(scene, "off") == [] and scene.object("/World/Ground").mesh.num_vertices == 4
    with pytest.raises(SceneError, match="refinement edge"):
        refine_receivers(scene, "-1")


def test_refined_ground_shows_the_contact_shadow(tmp_path):
    """Under a dome, ground next to the box sees less sky than ground far away: with the 4 corner
    vertices alone there is nothing to show it; refined, the ring around the base is darker
    (ambient occlusion of a 2x2x2 box: well over 10 % at 0.1-0.3 from its faces; 0.9 is a loose bound)."""
    scene = read_scene(_box_on_ground(tmp_path / "s.usda"))
    out = tmp_path / "o.usda"
    Pipeline(scene, frames=1, workers=1).run(AnimationWriter(str(out), fps=scene.fps), progress=False)
    stage = Usd.Stage.Open(str(out))
    prim = stage.GetPrimAtPath("/World/Ground")
    pts = np.asarray(UsdGeom.Mesh(prim).GetPointsAttr().Get(0))
    col = np.asarray(UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayColor").Get(0)).mean(axis=1)
    gap = np.maximum(np.abs(pts[:, 0]), np.abs(pts[:, 2])) - 1.0  # distance outside the box's footprint
    near, far = col[(gap > 0.05) & (gap < 0.6)], col[gap > 2.5]
    assert len(pts) > 100 and len(near) and len(far)
    assert near.mean() < 0.9 * far.mean(), (near.mean(), far.mean())
