"""``warpshade:`` marks authored on the prims above a mesh or gprim (a DCC's transform over its shape,
a group holding several meshes), a scene written by Blender's own USD exporter, and the colliders a
Mesh marked ``box`` or with UsdPhysics' collision approximations becomes."""

from __future__ import annotations

import os

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom

from helpers import REPO
from warpshade.cli import main
from warpshade.scene import SceneError, SceneWarning
from warpshade.usd import read_scene

BLENDER = os.path.join(REPO, "tests", "data", "blender", "cloth_on_box.usda")


def test_blender_export_reads_marks_of_its_objects_and_mesh_data():
    """Blender 5.0.1 writes an object's custom properties on its Xform and its mesh data's on the Mesh
    (tests/data/blender/make_cloth_on_box.py): the cloth, its pins and both colliders are read."""
    s = read_scene(BLENDER)
    cloth = s.object("/root/Cloth/Grid")
    assert cloth.kind == "cloth"
    assert cloth.params["pinned"].tolist() == [0, 6, 12]
    assert s.object("/root/Box/Cube").params["collider"] == "box"
    assert s.object("/root/Ground/Plane").params["collider"] == "ground"
    # the pinned vertices are one edge of the grid, as make_cloth_on_box.py says
    assert np.ptp(cloth.mesh.points[[0, 6, 12], 1]) == 0.0


def test_blender_export_runs_the_cloth_onto_the_box(tmp_path):
    """End to end: the cloth of Blender's file falls onto the box (a collider only through the mark on
    its Xform), and the pinned edge stays where it was."""
    out = tmp_path / "out.usda"
    assert main(["run", BLENDER, "--out", str(out), "--method", "reference", "--rays", "4", "--order", "2",
                 "--refine-receivers", "off", "--no-progress"]) == 0
    stage = Usd.Stage.Open(str(out))
    grid = UsdGeom.Mesh(stage.GetPrimAtPath("/root/Cloth/Grid"))
    xf = np.array(UsdGeom.Xformable(grid.GetPrim()).ComputeLocalToWorldTransform(12)).T
    first, last = (np.asarray(grid.GetPointsAttr().Get(t), dtype=np.float64) for t in (1, 12))
    world = last @ xf[:3, :3].T + xf[:3, 3]
    np.testing.assert_array_equal(last[[0, 6, 12]], first[[0, 6, 12]])
    inside = (np.abs(world[:, 0]) < 0.45) & (np.abs(world[:, 1]) < 0.45)
    # over the box's top (z = 1 m) the cloth rests on it: at least the top, at most the top plus
    # a few thicknesses (the default contact thickness is 5 mm); without the collider it falls to the ground
    assert inside.any()
    assert world[inside, 2].min() > 0.99 and world[inside, 2].max() < 1.1


def _stage(tmp_path, mark_on, values):
    """A Y-up metre stage /World (default prim) > Group > Sheet (Xform) > Mesh with ``values``
    authored on the prim ``mark_on`` ('World', 'Group', 'Sheet' or 'Mesh') and a static floor."""
    stage = Usd.Stage.CreateNew(str(tmp_path / "marks.usda"))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/World").GetPrim())
    UsdGeom.Xform.Define(stage, "/World/Group")
    UsdGeom.Xform.Define(stage, "/World/Group/Sheet")
    mesh = UsdGeom.Mesh.Define(stage, "/World/Group/Sheet/Mesh")
    mesh.CreatePointsAttr([(0, 1, 0), (1, 1, 0), (1, 1, 1), (0, 1, 1)])
    mesh.CreateFaceVertexCountsAttr([4])
    mesh.CreateFaceVertexIndicesAttr([0, 3, 2, 1])
    floor = UsdGeom.Mesh.Define(stage, "/World/Floor")
    floor.CreatePointsAttr([(-2, 0, -2), (2, 0, -2), (2, 0, 2), (-2, 0, 2)])
    floor.CreateFaceVertexCountsAttr([4])
    floor.CreateFaceVertexIndicesAttr([0, 3, 2, 1])
    paths = {"World": "/World", "Group": "/World/Group", "Sheet": "/World/Group/Sheet", "Mesh": "/World/Group/Sheet/Mesh"}
    for name, (typ, value) in values.items():
        stage.GetPrimAtPath(paths[mark_on]).CreateAttribute(name, typ, custom=True).Set(value)
    stage.GetRootLayer().Save()
    return str(tmp_path / "marks.usda")


@pytest.mark.parametrize("mark_on", ["Group", "Sheet", "Mesh"])
def test_marks_hold_from_the_prims_above_a_mesh(tmp_path, mark_on):
    path = _stage(tmp_path, mark_on, {"warpshade:kind": (Sdf.ValueTypeNames.String, "cloth"),
                                      "warpshade:cloth:density": (Sdf.ValueTypeNames.Float, 0.3)})
    sheet = read_scene(path).object("/World/Group/Sheet/Mesh")
    assert sheet.kind == "cloth" and sheet.params["cloth"]["density"] == pytest.approx(0.3)


def test_the_nearest_mark_wins(tmp_path):
    path = _stage(tmp_path, "Group", {"warpshade:kind": (Sdf.ValueTypeNames.Token, "cloth")})
    stage = Usd.Stage.Open(path)
    stage.GetPrimAtPath("/World/Group/Sheet").CreateAttribute(
        "warpshade:kind", Sdf.ValueTypeNames.Token, custom=True).Set("static")
    stage.Save()
    assert read_scene(path).object("/World/Group/Sheet/Mesh").kind == "static"


def test_the_default_prims_attributes_stay_scene_settings(tmp_path):
    """``warpshade:kind`` on the default prim is not a mark of every mesh under it (the default prim's
    attributes are the scene's settings): reading the scene says so, naming the attribute."""
    path = _stage(tmp_path, "World", {"warpshade:kind": (Sdf.ValueTypeNames.Token, "cloth")})
    with pytest.warns(SceneWarning, match=r":/World: warpshade:kind is not a scene setting"):
        scene = read_scene(path)
    assert scene.object("/World/Group/Sheet/Mesh").kind == "static"


def test_a_vertex_list_above_several_gprims_is_an_error_naming_both(tmp_path):
    path = _stage(tmp_path, "Group", {"warpshade:pinned": (Sdf.ValueTypeNames.IntArray, [0])})
    stage = Usd.Stage.Open(path)
    UsdGeom.Sphere.Define(stage, "/World/Group/Ball").CreateRadiusAttr(0.2)
    stage.Save()
    with pytest.raises(SceneError, match=r"/World/Group: warpshade:pinned names vertices of one mesh.*/World/Group/"):
        read_scene(path)


def test_a_vertex_list_above_one_mesh_is_its_own(tmp_path):
    path = _stage(tmp_path, "Sheet", {"warpshade:kind": (Sdf.ValueTypeNames.Token, "cloth"),
                                      "warpshade:pinned": (Sdf.ValueTypeNames.IntArray, [1, 2])})
    assert read_scene(path).object("/World/Group/Sheet/Mesh").params["pinned"].tolist() == [1, 2]


def test_blender_cube_marked_box_collides_as_its_exact_box():
    """Blender's cube is an 8-vertex Mesh; marked ``box`` it collides as the box it is."""
    box = read_scene(BLENDER).object("/root/Box/Cube").params["box"]
    np.testing.assert_allclose(box["center"], [0, 0, 0.5], atol=1e-6)
    np.testing.assert_allclose(box["half_extents"], [0.5, 0.5, 0.5], atol=1e-6)
    np.testing.assert_allclose(np.abs(box["rotation"]), [0, 0, 0, 1], atol=1e-6)


def _mesh_marked_box(tmp_path, mesh):
    stage = Usd.Stage.CreateNew(str(tmp_path / "box.usda"))
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/World").GetPrim())
    m = UsdGeom.Mesh.Define(stage, "/World/Box")
    m.CreatePointsAttr(np.asarray(mesh.vertices, dtype=np.float32))
    m.CreateFaceVertexCountsAttr([3] * len(mesh.faces))
    m.CreateFaceVertexIndicesAttr(np.asarray(mesh.faces, dtype=np.int32).reshape(-1))
    m.GetPrim().CreateAttribute("warpshade:collider", Sdf.ValueTypeNames.Token, custom=True).Set("box")
    stage.GetRootLayer().Save()
    return str(tmp_path / "box.usda")


def test_a_mesh_marked_box_is_the_box_it_spans(tmp_path):
    """A rotated, moved, subdivided box mesh: its exact box (centre, half extents, rotation), to float32's
    rounding of the written points (1e-6 of a 2 m box)."""
    import trimesh
    from scipy.spatial.transform import Rotation

    rot = Rotation.from_euler("xyz", [20, -35, 70], degrees=True)
    xf = np.eye(4)
    xf[:3, :3], xf[:3, 3] = rot.as_matrix(), [0.3, -1.0, 2.0]
    mesh = trimesh.creation.box(extents=[2.0, 0.5, 1.0], transform=xf).subdivide()
    box = read_scene(_mesh_marked_box(tmp_path, mesh)).object("/World/Box").params["box"]
    np.testing.assert_allclose(box["center"], [0.3, -1.0, 2.0], atol=2e-6)
    got = Rotation.from_quat(box["rotation"]).as_matrix() * box["half_extents"]  # columns: half edges
    want = rot.as_matrix() * [1.0, 0.25, 0.5]
    # the same three half edges, each up to sign and order (a box's symmetries)
    for col in want.T:
        assert min(min(np.linalg.norm(g - col), np.linalg.norm(g + col)) for g in got.T) < 2e-6


@pytest.mark.parametrize("shape", ["open crate", "two boxes in an L"])
def test_a_mesh_marked_box_that_is_not_one_warns_and_stays_a_mesh(tmp_path, shape):
    """Neither is a box, though every face is along the same three axes: the crate lacks its lid; the L
    (a 2 x 1 x 1 block and a cube on one end, their meshes together) has faces inside its bounds and,
    with the two faces where they meet, exactly its bounding box's surface area."""
    import trimesh

    box = trimesh.creation.box(extents=[1.0, 1.0, 1.0])
    if shape == "open crate":
        mesh = trimesh.Trimesh(box.vertices, box.faces[box.face_normals[:, 2] < 0.5], process=False)
    else:
        mesh = trimesh.util.concatenate([trimesh.creation.box(extents=[2.0, 1.0, 1.0]),
                                         box.copy().apply_translation([0.5, 0.0, 1.0])])
    with pytest.warns(SceneWarning, match="/World/Box: warpshade:collider 'box' on a Mesh that is not a box"):
        obj = read_scene(_mesh_marked_box(tmp_path, mesh)).object("/World/Box")
    assert "box" not in obj.params and obj.params["collider"] == "box"


def _physics_mesh(tmp_path, mesh, approximation=None, scale=(1.0, 1.0, 1.0)):
    """A PhysicsCollisionAPI Mesh under an Xform rotated 30 degrees about Z, moved and scaled by ``scale``."""
    from pxr import Gf, UsdPhysics

    stage = Usd.Stage.CreateNew(str(tmp_path / "physics.usda"))
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/World").GetPrim())
    holder = UsdGeom.Xform.Define(stage, "/World/Holder")
    holder.AddTranslateOp().Set(Gf.Vec3d(1.0, 2.0, 3.0))
    holder.AddRotateZOp().Set(30.0)
    holder.AddScaleOp().Set(Gf.Vec3f(*scale))
    m = UsdGeom.Mesh.Define(stage, "/World/Holder/Rock")
    m.CreatePointsAttr(np.asarray(mesh.vertices, dtype=np.float32))
    m.CreateFaceVertexCountsAttr([3] * len(mesh.faces))
    m.CreateFaceVertexIndicesAttr(np.asarray(mesh.faces, dtype=np.int32).reshape(-1))
    UsdPhysics.CollisionAPI.Apply(m.GetPrim())
    if approximation is not None:
        UsdPhysics.MeshCollisionAPI.Apply(m.GetPrim()).CreateApproximationAttr(approximation)
    stage.GetRootLayer().Save()
    return str(tmp_path / "physics.usda")


def _rock():
    """A convex, irregular rock: the hull of 40 seeded points in a 0.6 x 0.4 x 0.2 box about (0.1, 0, 0)."""
    import trimesh

    pts = np.random.default_rng(7).uniform(-1.0, 1.0, (40, 3)) * [0.3, 0.2, 0.1] + [0.1, 0.0, 0.0]
    return trimesh.convex.convex_hull(pts)


def test_physics_bounding_cube_is_the_box_of_its_local_bounds(tmp_path):
    from scipy.spatial.transform import Rotation

    rock = _rock()
    obj = read_scene(_physics_mesh(tmp_path, rock, "boundingCube", (2.0, 1.0, 1.0))).object("/World/Holder/Rock")
    assert obj.params["collider"] == "box"
    lo, hi = rock.vertices.min(axis=0), rock.vertices.max(axis=0)
    rot = Rotation.from_euler("z", 30, degrees=True)
    box = obj.params["box"]
    # float32 points: bounds to ~1e-7 of the rock's 0.6 m
    np.testing.assert_allclose(box["half_extents"], 0.5 * (hi - lo) * [2.0, 1.0, 1.0], atol=1e-6)
    np.testing.assert_allclose(box["center"], rot.apply(0.5 * (lo + hi) * [2.0, 1.0, 1.0]) + [1.0, 2.0, 3.0], atol=1e-6)
    np.testing.assert_allclose(Rotation.from_quat(box["rotation"]).as_matrix(), rot.as_matrix(), atol=1e-6)


def test_physics_bounding_sphere_holds_every_point(tmp_path):
    rock = _rock()
    obj = read_scene(_physics_mesh(tmp_path, rock, "boundingSphere", (1.5, 1.5, 1.5))).object("/World/Holder/Rock")
    assert obj.params["collider"] == "sphere"
    sphere = obj.params["sphere"]
    dist = np.linalg.norm(obj.mesh.points - sphere["center"], axis=1)
    assert dist.max() <= sphere["radius"] * (1 + 1e-6) and dist.max() >= sphere["radius"] * (1 - 1e-6)
    with pytest.warns(SceneWarning, match="Rock: physics:approximation boundingSphere is not exact because"):
        obj = read_scene(_physics_mesh(tmp_path, rock, "boundingSphere", (2.0, 1.0, 1.0))).object("/World/Holder/Rock")
    assert obj.params["collider"] == "mesh" and "sphere" not in obj.params


@pytest.mark.parametrize("approximation", [None, "convexHull"])
def test_physics_mesh_collides_as_itself_or_as_the_box_it_is(tmp_path, approximation):
    import trimesh

    rock = read_scene(_physics_mesh(tmp_path, _rock(), approximation)).object("/World/Holder/Rock")
    assert rock.params["collider"] == "mesh" and "box" not in rock.params
    box = trimesh.creation.box(extents=[1.0, 0.5, 0.25])
    obj = read_scene(_physics_mesh(tmp_path, box, approximation)).object("/World/Holder/Rock")
    assert obj.params["collider"] == "box"
    np.testing.assert_allclose(np.sort(obj.params["box"]["half_extents"]), [0.125, 0.25, 0.5], atol=1e-6)
