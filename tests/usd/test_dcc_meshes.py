"""Meshes as DCC tools author them: left-handed winding, mirroring transforms and instanced references.

Each would have shaded wrongly without a word: a left-handed or mirrored mesh read with right-handed winding
has its normals pointing in (it shaded black), and the meshes inside an instanceable reference were not read
at all. Outwardness is checked against each box's own centre (an independent fact of the geometry), not
against what the reader computes.
"""

from __future__ import annotations

import numpy as np
import pytest
from pxr import Gf, Usd, UsdGeom

from warpshade.cli import main
from warpshade.usd import read_scene, read_usd_mesh

S = 0.2
BOX_POINTS = [(-S, -S, -S), (S, -S, -S), (S, S, -S), (-S, S, -S), (-S, -S, S), (S, -S, S), (S, S, S), (-S, S, S)]
BOX_QUADS = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (2, 3, 7, 6), (1, 2, 6, 5), (0, 4, 7, 3)]
"""A box whose quads are counter-clockwise seen from outside (right-handed, outward)."""


def box(stage, path, left=False):
    m = UsdGeom.Mesh.Define(stage, path)
    quads = [tuple(reversed(q)) for q in BOX_QUADS] if left else BOX_QUADS
    if left:  # the same surface, authored the other way round
        m.CreateOrientationAttr(UsdGeom.Tokens.leftHanded)
    m.CreatePointsAttr(BOX_POINTS)
    m.CreateFaceVertexCountsAttr([4] * 6)
    m.CreateFaceVertexIndicesAttr([i for q in quads for i in q])
    m.CreateSubdivisionSchemeAttr("none")
    return m


@pytest.fixture
def scene_file(tmp_path):
    asset = Usd.Stage.CreateNew(str(tmp_path / "crate.usda"))
    UsdGeom.SetStageMetersPerUnit(asset, 1.0)
    root = UsdGeom.Xform.Define(asset, "/Crate")
    asset.SetDefaultPrim(root.GetPrim())
    box(asset, "/Crate/Geom")
    asset.Save()
    st = Usd.Stage.CreateNew(str(tmp_path / "scene.usda"))
    UsdGeom.SetStageUpAxis(st, "Y")
    UsdGeom.SetStageMetersPerUnit(st, 1.0)
    world = UsdGeom.Xform.Define(st, "/World")
    st.SetDefaultPrim(world.GetPrim())
    ground = UsdGeom.Mesh.Define(st, "/World/Ground")
    ground.CreatePointsAttr([(-6, 0, -6), (6, 0, -6), (6, 0, 6), (-6, 0, 6)])
    ground.CreateFaceVertexCountsAttr([4])
    ground.CreateFaceVertexIndicesAttr([0, 3, 2, 1])
    # 2 m apart, far from each other's shadows: the same light reaches each
    places = {"Control": (0.0, 0.2, 0.0), "LeftHanded": (-4.0, 0.2, 0.0), "Mirrored": (-2.0, 0.2, 0.0),
              "MirroredParent": (2.0, 0.2, 0.0), "Instanced": (4.0, 0.2, 0.0)}
    for name in ("Control", "LeftHanded", "Mirrored"):
        b = box(st, f"/World/{name}", left=name == "LeftHanded")
        UsdGeom.XformCommonAPI(b).SetTranslate(Gf.Vec3d(*places[name]))
    UsdGeom.XformCommonAPI(st.GetPrimAtPath("/World/Mirrored")).SetScale(Gf.Vec3f(-1, 1, 1))
    parent = UsdGeom.Xform.Define(st, "/World/MirroredParent")  # the mirror on an ancestor
    UsdGeom.XformCommonAPI(parent).SetTranslate(Gf.Vec3d(*places["MirroredParent"]))
    UsdGeom.XformCommonAPI(parent).SetScale(Gf.Vec3f(1, -1, 1))
    box(st, "/World/MirroredParent/Box")
    inst = st.DefinePrim("/World/Instanced", "Xform")
    inst.GetReferences().AddReference("crate.usda")
    inst.SetInstanceable(True)
    UsdGeom.XformCommonAPI(inst).SetTranslate(Gf.Vec3d(*places["Instanced"]))
    st.Save()
    return tmp_path / "scene.usda"


BOXES = ["/World/Control", "/World/LeftHanded", "/World/Mirrored", "/World/MirroredParent/Box", "/World/Instanced/Geom"]


def outward_share(points, faces) -> float:
    """Share of the triangles whose right-handed normal points away from the mesh's centre."""
    p = np.asarray(points, np.float64)
    a, b, c = (p[faces[:, k]] for k in range(3))
    n = np.cross(b - a, c - a)
    return float(np.mean(np.einsum("ij,ij->i", n, (a + b + c) / 3 - p.mean(axis=0)) > 0))


def test_every_box_is_read_wound_outward(scene_file):
    scene = read_scene(str(scene_file))
    objs = {o.name: o for o in scene.objects}
    assert set(BOXES) <= set(objs), sorted(objs)  # the instanced reference's mesh is read too
    for name in BOXES:
        tri = objs[name].mesh
        assert outward_share(tri.points, tri.faces) == 1.0, name
        # and the vertex normals the methods use point out
        out = tri.points - tri.points.mean(axis=0)
        assert (np.einsum("ij,ij->i", tri.normals, out) > 0).all(), name


@pytest.mark.parametrize("prim", ["/World/LeftHanded", "/World/Mirrored", "/World/MirroredParent/Box"])
def test_read_usd_mesh_winds_outward(scene_file, prim):
    pts, faces, _ = read_usd_mesh(str(scene_file), prim)
    assert outward_share(pts, faces) == 1.0


def test_run_shades_them_alike_and_the_output_layers_over_the_input(scene_file, tmp_path):
    out = tmp_path / "out.usda"
    assert main(["run", str(scene_file), "--out", str(out), "--frames", "1", "--method", "reference", "--rays", "64",
                 "--order", "2", "--workers", "0", "--no-progress"]) == 0
    stage = Usd.Stage.Open(str(out))
    means = {}
    for name in BOXES:
        prim = stage.GetPrimAtPath(name)
        assert prim and prim.IsA(UsdGeom.Mesh), name
        means[name] = np.asarray(UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayColor").Get(0)).mean()
        # written with outward winding in its own space: a renderer flips it again under a mirroring parent
        m = UsdGeom.Mesh(prim)
        faces = np.asarray(m.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3)
        world = np.asarray(m.ComputeLocalToWorldTransform(0)).T
        pts = np.asarray(m.GetPointsAttr().Get(0), np.float64) @ world[:3, :3].T
        share = outward_share(pts, faces)
        assert share == (0.0 if np.linalg.det(world[:3, :3]) < 0 else 1.0), name
    # boxes in the same light, all lit alike: a box with inward normals shaded black (0) before
    control = means["/World/Control"]
    assert control > 0.05
    for name, m in means.items():
        # tolerance: 64 rays per vertex (Monte-Carlo noise of a 14-vertex mean: measured <= 3.3 %)
        assert abs(m - control) < 0.1 * control, (name, m, control)
    # layered over its input, the output's colours reach the mesh inside the instance
    over = Usd.Stage.CreateInMemory()
    over.GetRootLayer().subLayerPaths = [str(out), str(scene_file)]
    prim = over.GetPrimAtPath("/World/Instanced/Geom")
    assert not over.GetPrimAtPath("/World/Instanced").IsInstance()
    assert np.allclose(np.asarray(UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayColor").Get(0)).mean(),
                       means["/World/Instanced/Geom"])


def test_hole_faces_are_not_read(tmp_path):
    # a strip of three quads whose middle one is a hole (holeIndices, as Maya and Houdini write them)
    st = Usd.Stage.CreateNew(str(tmp_path / "holes.usda"))
    UsdGeom.SetStageMetersPerUnit(st, 1.0)
    m = UsdGeom.Mesh.Define(st, "/Strip")
    m.CreatePointsAttr([(x, 0, z) for z in (0, 1) for x in range(4)])
    m.CreateFaceVertexCountsAttr([4, 4, 4])
    m.CreateFaceVertexIndicesAttr([0, 4, 5, 1, 1, 5, 6, 2, 2, 6, 7, 3])
    m.CreateHoleIndicesAttr([1])
    st.Save()
    tri = next(o for o in read_scene(str(tmp_path / "holes.usda")).objects if o.name == "/Strip").mesh
    _, faces, _ = read_usd_mesh(str(tmp_path / "holes.usda"))
    for f in (tri.faces, faces):
        assert len(f) == 4
        # no triangle spans the hole (x from 1 to 2)
        assert not any({1, 2} <= set(t) or {5, 6} <= set(t) or {1, 6} <= set(t) or {2, 5} <= set(t) for t in f.tolist())
    m.CreateHoleIndicesAttr([3])
    st.Save()
    with pytest.raises(Exception, match="holeIndices 3 is not a face"):
        read_scene(str(tmp_path / "holes.usda"))


def _quads_mesh(stage, path, n=4):
    m = UsdGeom.Mesh.Define(stage, path)
    m.CreatePointsAttr([(x, 0, z) for z in (0, 1) for x in range(n + 1)])
    m.CreateFaceVertexCountsAttr([4] * n)
    m.CreateFaceVertexIndicesAttr([v for i in range(n) for v in (i, i + n + 1, i + n + 2, i + 1)])
    return m


def _preview_material(stage, path, rgb):
    from pxr import Sdf, UsdShade

    mat = UsdShade.Material.Define(stage, path)
    sh = UsdShade.Shader.Define(stage, path + "/Surface")
    sh.CreateIdAttr("UsdPreviewSurface")
    sh.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*rgb))
    mat.CreateSurfaceOutput().ConnectToSource(sh.ConnectableAPI(), "surface")
    return mat


def test_materials_on_face_subsets_give_their_mean_albedo_with_a_warning(tmp_path):
    from pxr import UsdShade

    from warpshade.scene import SceneWarning

    st = Usd.Stage.CreateNew(str(tmp_path / "subsets.usda"))
    UsdGeom.SetStageMetersPerUnit(st, 1.0)
    m = _quads_mesh(st, "/Mesh")
    red, blue = _preview_material(st, "/Looks/Red", (0.8, 0.1, 0.1)), _preview_material(st, "/Looks/Blue", (0.1, 0.1, 0.8))
    for name, faces, mat in (("red", [0, 1, 2], red), ("blue", [3], blue)):
        subset = UsdShade.MaterialBindingAPI(m.GetPrim()).CreateMaterialBindSubset(name, faces)
        UsdShade.MaterialBindingAPI.Apply(subset.GetPrim()).Bind(mat)
    st.Save()
    with pytest.warns(SceneWarning, match="/Mesh: materials are bound to 2 face subsets"):
        obj = next(o for o in read_scene(str(tmp_path / "subsets.usda")).objects if o.name == "/Mesh")
    assert np.allclose(obj.material.albedo, (3 * np.array([0.8, 0.1, 0.1]) + np.array([0.1, 0.1, 0.8])) / 4)


def test_a_displaycolor_per_vertex_gives_its_mean_albedo_with_a_warning(tmp_path):
    from pxr import Sdf

    from warpshade.scene import SceneWarning

    st = Usd.Stage.CreateNew(str(tmp_path / "cd.usda"))
    UsdGeom.SetStageMetersPerUnit(st, 1.0)
    m = _quads_mesh(st, "/Mesh", n=1)
    cols = [(1, 0, 0), (0, 1, 0), (0, 0, 1), (0.2, 0.2, 0.2)]
    UsdGeom.PrimvarsAPI(m).CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3fArray, UsdGeom.Tokens.vertex).Set(cols)
    st.Save()
    with pytest.warns(SceneWarning, match="displayColor varies"):
        obj = next(o for o in read_scene(str(tmp_path / "cd.usda")).objects if o.name == "/Mesh")
    assert np.allclose(obj.material.albedo, np.mean(cols, axis=0))


def test_gprims_keyed_by_their_transform(tmp_path):
    # as DCCs export them: transforms written as time samples only (one for a still object, a key per
    # frame for a moving one), which USD reads as the identity at the default time
    from warpshade.pipeline.cloth import ClothSimulation

    st = Usd.Stage.CreateNew(str(tmp_path / "keys.usda"))
    UsdGeom.SetStageUpAxis(st, "Y")
    UsdGeom.SetStageMetersPerUnit(st, 1.0)
    st.SetStartTimeCode(1)
    st.SetEndTimeCode(5)
    still = UsdGeom.Cube.Define(st, "/Still")
    still.AddTranslateOp().Set(Gf.Vec3d(3, 0.5, 0), 1)
    ball = UsdGeom.Sphere.Define(st, "/Ball")
    ball.CreateRadiusAttr(0.25)
    op = ball.AddTranslateOp()
    for t in range(1, 6):
        op.Set(Gf.Vec3d(0.1 * t, 0.25, 0), t)
    from pxr import Sdf, UsdPhysics

    UsdPhysics.CollisionAPI.Apply(ball.GetPrim())
    cloth = _quads_mesh(st, "/Cloth", n=3)
    cloth.GetPrim().CreateAttribute("warpshade:kind", Sdf.ValueTypeNames.Token, custom=True).Set("cloth")
    UsdGeom.XformCommonAPI(cloth).SetTranslate(Gf.Vec3d(0, 1, 0))
    st.Save()
    scene = read_scene(str(tmp_path / "keys.usda"))
    objs = {o.name: o for o in scene.objects}
    assert objs["/Still"].kind == "static"
    still_pts = objs["/Still"].mesh.points  # graded (finer towards the ball): the centre of its bounds
    assert np.allclose((still_pts.min(axis=0) + still_pts.max(axis=0)) / 2, (3, 0.5, 0), atol=1e-6)  # not at the origin
    b = objs["/Ball"]
    assert b.kind == "animated" and b.params["collider"] == "sphere"
    assert np.allclose(b.mesh.points.mean(axis=0), (0.1, 0.25, 0), atol=1e-6)
    for t in (1, 3, 5):
        assert np.allclose(b.params["points_at"](t).mean(axis=0), (0.1 * t, 0.25, 0), atol=1e-5)
    # it collides as the analytic sphere, moved to its keyed centre every frame (not its tessellated mesh)
    sim = ClothSimulation(scene)
    assert sim.moving_colliders == [] and len(sim.moving_spheres) == 1
    index, centers = sim.moving_spheres[0]
    assert np.allclose(centers, [(0.1 * t, 0.25, 0) for t in range(1, 6)], atol=1e-12)  # frame f at time code 1 + f
    assert sim.solver.colliders._size[index][0] == 0.25
    # a key that squashes it (a non-uniform scale) leaves it a moving mesh collider
    UsdGeom.Xformable(ball).AddScaleOp().Set(Gf.Vec3f(1.0, 0.5, 1.0), 3)
    st.Save()
    squashed = ClothSimulation(read_scene(str(tmp_path / "keys.usda")))
    assert [name for name, _ in squashed.moving_colliders] == ["/Ball"] and squashed.moving_spheres == []


def _sun_scene(path, angles, sun_path="/World/Sun"):
    """A ground under a DistantLight keyed to tilt by ``angles`` [degrees] about X, one key per frame
    (one angle: a still sun, its transform a single time sample)."""
    from pxr import UsdLux

    st = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(st, "Y")
    UsdGeom.SetStageMetersPerUnit(st, 1.0)
    st.SetStartTimeCode(0)
    st.SetEndTimeCode(len(angles) - 1)
    st.SetTimeCodesPerSecond(24)
    world = UsdGeom.Xform.Define(st, "/World")
    st.SetDefaultPrim(world.GetPrim())
    g = _quads_mesh(st, "/World/Ground", n=2)
    UsdGeom.XformCommonAPI(box(st, "/World/Box")).SetTranslate(Gf.Vec3d(1.0, 0.2, 0.5))
    sun = UsdLux.DistantLight.Define(st, sun_path)
    sun.CreateIntensityAttr(3.0)
    sun.CreateNormalizeAttr(True)  # intensity is the irradiance
    op = sun.AddRotateXOp()
    for t, a in enumerate(angles):
        op.Set(-90.0 + a, t)  # -90: shining straight down (-Z of the light onto -Y of the world)
    st.Save()
    return g


def test_a_keyed_sun_turns_frame_by_frame(tmp_path):
    # frame f of a run under a keyed sun is the run of the same scene with the sun still at frame f's pose
    angles = [0.0, 30.0, 60.0]
    _sun_scene(tmp_path / "keyed.usda", angles)
    args = ["--frames", str(len(angles)), "--method", "reference", "--rays", "64", "--order", "3", "--workers", "0",
            "--no-progress"]
    assert main(["run", str(tmp_path / "keyed.usda"), "--out", str(tmp_path / "keyed_out.usda")] + args) == 0
    keyed = Usd.Stage.Open(str(tmp_path / "keyed_out.usda"))
    colours = UsdGeom.PrimvarsAPI(keyed.GetPrimAtPath("/World/Box")).GetPrimvar("displayColor")
    for f, a in enumerate(angles):
        _sun_scene(tmp_path / f"still{f}.usda", [a])
        out = tmp_path / f"still{f}_out.usda"
        assert main(["run", str(tmp_path / f"still{f}.usda"), "--out", str(out), "--frames", "1"] + args[2:]) == 0
        still = Usd.Stage.Open(str(out))
        want = np.asarray(UsdGeom.PrimvarsAPI(still.GetPrimAtPath("/World/Box")).GetPrimvar("displayColor").Get(0))
        # same geometry, same rays (static scene): the same colours to float32 rounding of the SH rotation
        np.testing.assert_allclose(np.asarray(colours.Get(f)), want, atol=1e-5, err_msg=f"frame {f}")
    assert not np.allclose(np.asarray(colours.Get(0)), np.asarray(colours.Get(2)), atol=1e-3)  # it did turn


def test_a_closed_mesh_wound_inward_warns(tmp_path):
    # a box whose quads face its inside (a user's own winding, right-handed): the run warns, naming it
    from warpshade.scene import SceneWarning

    st = Usd.Stage.CreateNew(str(tmp_path / "inward.usda"))
    UsdGeom.SetStageMetersPerUnit(st, 1.0)
    m = UsdGeom.Mesh.Define(st, "/Inward")
    m.CreatePointsAttr(BOX_POINTS)
    m.CreateFaceVertexCountsAttr([4] * 6)
    m.CreateFaceVertexIndicesAttr([i for q in BOX_QUADS for i in reversed(q)])
    box(st, "/Outward")
    UsdGeom.XformCommonAPI(st.GetPrimAtPath("/Outward")).SetTranslate(Gf.Vec3d(1, 0, 0))
    st.Save()
    with pytest.warns(SceneWarning, match="/Inward: a closed mesh wound inward") as record:
        assert main(["run", str(tmp_path / "inward.usda"), "--out", str(tmp_path / "o.usda"), "--frames", "1",
                     "--method", "reference", "--rays", "4", "--order", "2", "--workers", "0", "--no-progress"]) == 0
    assert not [w for w in record if "/Outward" in str(w.message) and "inward" in str(w.message)]
