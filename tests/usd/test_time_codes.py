"""The output keeps the input's time codes: frame f is the input's startTimeCode + f."""

import numpy as np
from pxr import Gf, Usd, UsdGeom

from warpshade.pipeline import Pipeline
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
