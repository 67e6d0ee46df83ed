"""Gprims are tessellated for one target edge length in world units, whatever their size and scale:
the finest cloth's edge or 1/100 of the scene's diagonal, a USD attribute to choose it, clamps and a
vertex budget (warpshade.geometry.shapes). Expected counts are worked out by hand in each test."""

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom

from warpshade.scene import SceneError, SceneWarning
from warpshade.usd.scene_io import scene_from_stage


def _stage(edge=None, graded=False):
    """A Z-up metre stage; uniform tessellation (``warpshade:graded = false``) unless ``graded``: these
    tests are of the uniform rule (tests/usd/test_graded_gprims.py: the graded one)."""
    st = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(st, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(st, 1.0)
    root = UsdGeom.Xform.Define(st, "/World").GetPrim()
    st.SetDefaultPrim(root)
    if not graded:
        root.CreateAttribute("warpshade:graded", Sdf.ValueTypeNames.Bool).Set(False)
    if edge is not None:
        root.CreateAttribute("warpshade:edgeLength", Sdf.ValueTypeNames.Float).Set(edge)
    return st


def _cube(st, path, size=1.0, scale=(1, 1, 1), translate=(0, 0, 0), edge=None):
    c = UsdGeom.Cube.Define(st, path)
    c.CreateSizeAttr(size)
    c.AddTranslateOp().Set(Gf.Vec3d(*translate))
    c.AddScaleOp().Set(Gf.Vec3f(*scale))
    if edge is not None:
        c.GetPrim().CreateAttribute("warpshade:edgeLength", Sdf.ValueTypeNames.Double).Set(edge)
    return c


def _cloth(st, n=10, size=0.5, height=1.0):
    """An n x n quad sheet of edge size / n at ``height``."""
    m = UsdGeom.Mesh.Define(st, "/World/Cloth")
    m.CreatePointsAttr([Gf.Vec3f(i * size / n, j * size / n, height) for j in range(n + 1) for i in range(n + 1)])
    m.CreateFaceVertexCountsAttr([4] * (n * n))
    m.CreateFaceVertexIndicesAttr([v for j in range(n) for i in range(n) for v in
                                   (j * (n + 1) + i, j * (n + 1) + i + 1, (j + 1) * (n + 1) + i + 1, (j + 1) * (n + 1) + i)])
    m.GetPrim().CreateAttribute("warpshade:kind", Sdf.ValueTypeNames.Token).Set("cloth")


def _objects(st):
    return {o.name: o for o in scene_from_stage(st, source="t.usda").objects}


def _box_vertices(nx, ny, nz):
    """Vertices of a box of nx, ny, nz squares along x, y, z: each face a grid of its own."""
    return 2 * ((nx + 1) * (ny + 1) + (ny + 1) * (nz + 1) + (nx + 1) * (nz + 1))


def _rows(points, axis):
    return len(np.unique(np.round(points[:, axis], 5)))


def test_a_thin_scaled_slab_gets_squares_of_the_edge_across_and_one_through():
    """A 4 m x 4 m x 2 cm slab (a unit Cube scaled) for a 5 cm edge: 80 x 80 squares, one through its
    thickness (was 22 x 22 x 22 whatever its size: 18 cm squares, 22 rows through 2 cm)."""
    st = _stage(edge=0.05)
    _cube(st, "/World/Floor", scale=(4, 4, 0.02), translate=(0, 0, -0.01))
    floor = _objects(st)["/World/Floor"].mesh.points
    assert len(floor) == _box_vertices(80, 80, 1) == 13770
    assert _rows(floor, 0) == _rows(floor, 1) == 81 and _rows(floor, 2) == 2


def test_the_edge_follows_the_finest_cloth_and_else_the_scene_size():
    """A cloth of 5 cm edges in a scene 9.07 m across (an 8 x 4 x 0.5 m box, the cloth 1 m up; 1/100
    of that is 9 cm): the cloth's 5 cm is the edge, so a 20 cm cube gets 4 squares a side and the box
    160 x 80 x 10."""
    st = _stage()
    _cloth(st, n=10, size=0.5, height=1.0)
    _cube(st, "/World/Small", size=0.2, translate=(0, 0, 0.1))
    _cube(st, "/World/Big", scale=(8, 4, 0.5), translate=(0, 0, -0.25))
    objs = _objects(st)
    assert len(objs["/World/Small"].mesh.points) == _box_vertices(4, 4, 4) == 150
    assert len(objs["/World/Big"].mesh.points) == _box_vertices(160, 80, 10)
    # no cloth: 1/100 of the diagonal; a unit cube alone: edge sqrt(3)/100, ceil(100/sqrt(3)) = 58 squares
    st = _stage()
    _cube(st, "/World/Alone")
    assert len(_objects(st)["/World/Alone"].mesh.points) == _box_vertices(58, 58, 58)


def test_a_gprims_own_edge_length_overrides_the_scenes():
    st = _stage(edge=0.05)
    _cube(st, "/World/Coarse", size=1.0, edge=0.25)
    _cube(st, "/World/Scene", size=1.0, translate=(3, 0, 0))
    cyl = UsdGeom.Cylinder.Define(st, "/World/Pillar")
    cyl.CreateRadiusAttr(0.5)
    cyl.CreateHeightAttr(2.0)
    cyl.GetPrim().CreateAttribute("warpshade:edgeLength", Sdf.ValueTypeNames.Float).Set(0.1)
    objs = _objects(st)
    assert len(objs["/World/Coarse"].mesh.points) == _box_vertices(4, 4, 4)
    assert len(objs["/World/Scene"].mesh.points) == _box_vertices(20, 20, 20)
    # 48 sections (2 pi 0.5 / 0.1 = 31.4 < 48); caps 5 rings + centre each, side 20 pieces: 21 rings
    assert len(objs["/World/Pillar"].mesh.points) == 48 * (2 * 5 + 21) + 2
    assert "edgeLength" not in objs["/World/Coarse"].params


def test_spheres_and_curved_shapes_follow_the_edge_above_their_minimum():
    """A 1 m sphere for a 5 cm edge needs 4 pi / 0.05^2 = 5027 vertices: subdivision 5 (10 242; 4
    has 2562); a 10 cm one keeps the minimum 642 (subdivision 3, the shipped scenes' balls). A cylinder
    of radius 2 m: 2 pi 2 / 0.05 = 251.3 -> 252 sections."""
    st = _stage(edge=0.05)
    for name, r, x in (("Big", 1.0, 0.0), ("Small", 0.1, 5.0)):
        s = UsdGeom.Sphere.Define(st, f"/World/{name}")
        s.CreateRadiusAttr(r)
        s.AddTranslateOp().Set(Gf.Vec3d(x, 0, 0))
    c = UsdGeom.Cylinder.Define(st, "/World/Drum")
    c.CreateRadiusAttr(2.0)
    c.CreateHeightAttr(0.1)
    c.AddTranslateOp().Set(Gf.Vec3d(-10, 0, 0))
    objs = _objects(st)
    assert len(objs["/World/Big"].mesh.points) == 10242
    assert len(objs["/World/Small"].mesh.points) == 642
    drum = objs["/World/Drum"].mesh.points
    rim = np.isclose(np.linalg.norm(drum[:, :2] + [10, 0], axis=1), 2.0) & np.isclose(drum[:, 2], 0.05)
    assert rim.sum() == 2 * 252  # the top cap's rim and the side's top ring


def test_segments_are_clamped_and_the_scene_kept_within_the_vertex_budget():
    from warpshade.geometry.shapes import MAX_SEGMENTS, VERTEX_BUDGET

    # an explicit 0.1 mm edge along a 10 m rod: 1024 squares (MAX_SEGMENTS), 100 across its 1 cm
    st = _stage()
    _cube(st, "/World/Rod", scale=(10, 0.01, 0.01), edge=1e-4)
    rod = _objects(st)["/World/Rod"].mesh.points
    assert MAX_SEGMENTS == 1024 and _rows(rod, 0) == 1025 and _rows(rod, 1) == 101
    # a 1 cm cloth over a 20 m floor: 2000 squares a side clamped to 1024, 2.1 M vertices; the scene's
    # edge is coarsened (with a warning) until the gprims fit the budget
    st = _stage()
    _cloth(st, n=10, size=0.1, height=0.5)
    _cube(st, "/World/Floor", scale=(20, 20, 0.1), translate=(0, 0, -0.05))
    with pytest.warns(SceneWarning, match=f"within {VERTEX_BUDGET} vertices"):
        n = len(_objects(st)["/World/Floor"].mesh.points)
    # the fitted edge is within 1 % of the shortest that fits: a slab's count falls ~2 % per 1 % of edge
    assert 0.95 * VERTEX_BUDGET <= n <= VERTEX_BUDGET


@pytest.mark.parametrize("value, type_name", [(-1.0, "Float"), (0.0, "Double"), ("fine", "String"),
                                              (float("inf"), "Float")])
def test_a_bad_edge_length_names_the_prim_and_the_attribute(value, type_name):
    st = _stage()
    c = _cube(st, "/World/Crate")
    c.GetPrim().CreateAttribute("warpshade:edgeLength", getattr(Sdf.ValueTypeNames, type_name)).Set(value)
    with pytest.raises(SceneError, match=r"/World/Crate: warpshade:edgeLength must be a length > 0"):
        scene_from_stage(st, source="t.usda")
    st = _stage(edge=-2.0)
    _cube(st, "/World/Crate")
    with pytest.raises(SceneError, match=r"t.usda:/World: warpshade:edgeLength must be a length > 0"):
        scene_from_stage(st, source="t.usda")
