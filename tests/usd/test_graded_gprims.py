"""The USD reader grades shaded Cube and Plane gprims by default (warpshade.geometry.shapes.Grading):
fine near the other objects' regions (a cloth's swept down to the floor, a moving object's over its
frames), coarse away; ``warpshade:graded`` on the default prim or a gprim switches it, a bad value is
an error naming the prim and the attribute. Counts and rows are worked out by hand in each test."""

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom

from warpshade.geometry.shapes import GRADE_LEVELS, box_shape
from warpshade.scene import SceneError
from warpshade.usd.scene_io import scene_from_stage


def _stage(graded=None, frames=1):
    st = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(st, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(st, 1.0)
    st.SetStartTimeCode(1)
    st.SetEndTimeCode(frames)
    root = UsdGeom.Xform.Define(st, "/World").GetPrim()
    st.SetDefaultPrim(root)
    if graded is not None:
        root.CreateAttribute("warpshade:graded", Sdf.ValueTypeNames.Bool).Set(graded)
    return st


def _floor(st, graded=None):
    """A 3 x 3 x 0.05 m slab (a unit Cube scaled), its top at z = 0; at a 2.5 cm edge: 120 x 120 x 2."""
    c = UsdGeom.Cube.Define(st, "/World/Floor")
    c.CreateSizeAttr(1.0)
    c.AddTranslateOp().Set(Gf.Vec3d(0, 0, -0.025))
    c.AddScaleOp().Set(Gf.Vec3f(3, 3, 0.05))
    if graded is not None:
        c.GetPrim().CreateAttribute("warpshade:graded", Sdf.ValueTypeNames.Bool).Set(graded)
    return c


def _cloth(st, n=20, size=0.5, height=0.75):
    """An n x n quad sheet centred over the origin at ``height``, edge size / n (2.5 cm)."""
    m = UsdGeom.Mesh.Define(st, "/World/Cloth")
    m.CreatePointsAttr([Gf.Vec3f(-size / 2 + i * size / n, -size / 2 + j * size / n, height)
                        for j in range(n + 1) for i in range(n + 1)])
    m.CreateFaceVertexCountsAttr([4] * (n * n))
    m.CreateFaceVertexIndicesAttr([v for j in range(n) for i in range(n) for v in
                                   (j * (n + 1) + i, j * (n + 1) + i + 1, (j + 1) * (n + 1) + i + 1, (j + 1) * (n + 1) + i)])
    m.GetPrim().CreateAttribute("warpshade:kind", Sdf.ValueTypeNames.Token).Set("cloth")


def _floor_points(st):
    return {o.name: o for o in scene_from_stage(st, source="t.usda").objects}["/World/Floor"].mesh.points


def _top_rows(points, axis):
    top = points[np.isclose(points[:, 2], 0.0, atol=1e-6)]
    return np.unique(np.round(top[:, axis], 5))


UNIFORM = 2 * (121 * 121 + 2 * 121 * 3)  # 120 x 120 squares on top and bottom, 120 x 2 on the sides


def test_the_floor_under_a_cloth_is_fine_there_and_coarse_elsewhere():
    """The cloth hangs 0.75 m up; its region sweeps down to the floor, so the top face's rows under its
    footprint (0.5 m, widened by 10 % of its diagonal: +-0.32 m) are 2.5 cm apart; towards the slab's
    sides they widen to 2**GRADE_LEVELS x 2.5 cm; the bottom is coarse everywhere."""
    st = _stage()
    _floor(st)
    _cloth(st)
    pts = _floor_points(st)
    assert len(pts) < UNIFORM / 3
    for axis in (0, 1):
        rows = _top_rows(pts, axis)
        under = rows[np.abs(rows) <= 0.3]
        assert np.allclose(np.diff(under), 0.025, atol=1e-5) and len(under) == 25
        assert np.diff(rows).max() == pytest.approx(2 ** GRADE_LEVELS * 0.025, abs=1e-5)
        bottom = np.unique(np.round(pts[np.isclose(pts[:, 2], -0.05, atol=1e-6)][:, axis], 5))
        assert np.diff(bottom)[:-1] == pytest.approx(2 ** GRADE_LEVELS * 0.025, abs=1e-5)


def test_graded_false_on_the_default_prim_gives_the_uniform_mesh_exactly():
    st = _stage(graded=False)
    _floor(st)
    _cloth(st)
    pts = _floor_points(st)
    v, _ = box_shape([1.0] * 3, (120, 120, 2))
    assert len(pts) == UNIFORM
    scale = np.array([3, 3, np.float32(0.05)], dtype=np.float64)  # the scale op is a float3
    assert np.array_equal(pts, (v * scale + [0, 0, -0.025]).astype(np.float32))


@pytest.mark.parametrize("scene, prim, graded", [(None, False, False), (False, True, True), (True, None, True),
                                                 (False, None, False)])
def test_a_gprims_own_graded_overrides_the_scenes(scene, prim, graded):
    st = _stage(graded=scene)
    _floor(st, graded=prim)
    _cloth(st)
    assert (len(_floor_points(st)) < UNIFORM) == graded


def test_a_moving_object_makes_the_floor_fine_along_its_path():
    """A ball keyed from x = -1 to x = +1 over 25 frames: the floor is fine under both ends of its path
    (its bounds at the sampled frames), not only where it starts."""
    st = _stage(frames=25)
    _floor(st)
    _cloth(st)  # sets the 2.5 cm edge
    ball = UsdGeom.Sphere.Define(st, "/World/Ball")
    ball.CreateRadiusAttr(0.1)
    op = ball.AddTranslateOp()
    op.Set(Gf.Vec3d(-1, 0, 0.1), 1)
    op.Set(Gf.Vec3d(1, 0, 0.1), 25)
    rows = _top_rows(_floor_points(st), 0)
    for x in (-1.0, 1.0):
        there = rows[np.abs(rows - x) <= 0.1 + 1e-4]
        assert np.allclose(np.diff(there), 0.025, atol=1e-5) and len(there) == 9


@pytest.mark.parametrize("value, type_name", [("yes", "String"), (1, "Int"), (0.0, "Float")])
def test_a_bad_graded_value_names_the_prim_and_the_attribute(value, type_name):
    st = _stage()
    c = _floor(st)
    c.GetPrim().CreateAttribute("warpshade:graded", getattr(Sdf.ValueTypeNames, type_name)).Set(value)
    with pytest.raises(SceneError, match=r"t.usda:/World/Floor: warpshade:graded must be a bool"):
        scene_from_stage(st, source="t.usda")
    st = _stage()
    st.GetDefaultPrim().CreateAttribute("warpshade:graded", getattr(Sdf.ValueTypeNames, type_name)).Set(value)
    _floor(st)
    with pytest.raises(SceneError, match=r"t.usda:/World: warpshade:graded must be a bool"):
        scene_from_stage(st, source="t.usda")
