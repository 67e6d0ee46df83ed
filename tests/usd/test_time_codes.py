"""The output keeps the input's time codes: frame f is the input's startTimeCode + f."""

import numpy as np
import pytest
from pxr import Gf, Usd, UsdGeom

from warpshade.pipeline import Pipeline
from warpshade.scene import SceneError
from warpshade.usd import AnimationWriter, read_scene


def _moving_scene(path, start=1, end=6):
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    stage.SetStartTimeCode(start)
    stage.SetEndTimeCode(end)
    stage.SetTimeCodesPerSecond(24)
    UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(stage.GetPrimAtPath("/World"))
    tri = UsdGeom.Mesh.Define(stage, "/World/Tri")
    tri.CreateFaceVertexCountsAttr([3])
    tri.CreateFaceVertexIndicesAttr([0, 1, 2])
    pts = tri.CreatePointsAttr()
    for t in range(start, end + 1):  # x = time code, so a frame read at the wrong time shows
        pts.Set([Gf.Vec3f(t, 0, 0), Gf.Vec3f(t + 1, 0, 0), Gf.Vec3f(t, 0, -1)], t)
    stage.GetRootLayer().Save()


def test_output_keeps_start_end_and_rate(tmp_path):
    src = tmp_path / "in.usda"
    _moving_scene(src)
    scene = read_scene(str(src))
    assert (scene.start_time, scene.frames, scene.fps) == (1, 6, 24)
    out = tmp_path / "out.usda"
    Pipeline(scene, workers=1).run(AnimationWriter(str(out), fps=scene.fps), progress=False)
    stage = Usd.Stage.Open(str(out))
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode(), stage.GetTimeCodesPerSecond()) == (1, 6, 24)
    pts = UsdGeom.Mesh(stage.GetPrimAtPath("/World/Tri")).GetPointsAttr()
    for t in range(1, 7):
        assert np.asarray(pts.Get(t))[0, 0] == t  # sampled at the same time code as the input


def _sampled_topology(path, quad_from=None):
    """A triangle whose faces, like its points, are time-sampled beside empty defaults, as Blender 5 writes a mesh
    whose modifiers change it (`faceVertexCounts = []` and `faceVertexCounts.timeSamples`); from time code
    ``quad_from`` on it is a quad (a Build or Remesh modifier changed it)."""
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(4)
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/World").GetPrim())
    mesh = UsdGeom.Mesh.Define(stage, "/World/Sheet")
    counts, idx, pts = mesh.CreateFaceVertexCountsAttr([]), mesh.CreateFaceVertexIndicesAttr([]), mesh.CreatePointsAttr([])
    for t in range(1, 5):
        quad = quad_from is not None and t >= quad_from
        counts.Set([4] if quad else [3], t)
        idx.Set([0, 1, 2, 3] if quad else [0, 1, 2], t)
        pts.Set([Gf.Vec3f(0, 0.1 * t, 0), Gf.Vec3f(1, 0.1 * t, 0), Gf.Vec3f(1, 0.1 * t, -1)]
                + ([Gf.Vec3f(0, 0.1 * t, -1)] if quad else []), t)
    stage.GetRootLayer().Save()


def test_time_sampled_faces_that_stay_alike_are_read(tmp_path):
    """Before: 'empty mesh (0 vertices, 0 triangles)' (the empty defaults were read)."""
    _sampled_topology(tmp_path / "in.usda")
    scene = read_scene(str(tmp_path / "in.usda"))
    sheet = scene.object("/World/Sheet")
    assert sheet.kind == "animated" and sheet.mesh.faces.tolist() == [[0, 1, 2]]
    frames = [geo["/World/Sheet"][0, 1] for _, geo in Pipeline(scene, workers=0).simulate()]
    np.testing.assert_allclose(frames, [0.1, 0.2, 0.3, 0.4], rtol=1e-6)  # time codes 1..4 (float32 points)


def test_time_sampled_faces_that_change_are_an_error_naming_when(tmp_path):
    """Before: 'empty mesh (0 vertices, 0 triangles)', which says nothing of the cause."""
    _sampled_topology(tmp_path / "in.usda", quad_from=3)
    with pytest.raises(SceneError, match="in.usda:/World/Sheet: its faces change over time .*1 faces of 3 corners at "
                                         "time 1, 1 of 4 at 3.*apply the modifiers that change them"):
        read_scene(str(tmp_path / "in.usda"))
