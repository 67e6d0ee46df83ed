"""UsdGeom PointInstancer, as Houdini's Solaris writes a scatter (:func:`scatter_stage` says what is imitated):
every instance of a prototype Mesh is shaded, casts shadows and collides as an object of its own, written at ``<instancer>_instances/instance_<id>/...`` with the instancer deactivated in the output."""

import warnings

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdPhysics, Vt

from warpshade.cli import main
from warpshade.pipeline.cloth import ClothSimulation
from warpshade.scene import SceneError
from warpshade.usd.scene_io import scene_from_stage

ROCK = np.array([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0), (-1, -1, 2), (1, -1, 2), (1, 1, 2), (-1, 1, 2)],
                dtype=np.float64) * 10.0  # a 20 cm box standing on its base [cm]
ROCK_FACES = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
TREE = np.array([(-5, -5, 0), (5, -5, 0), (5, 5, 0), (-5, 5, 0), (0, 0, 60)], dtype=np.float64)  # a 60 cm pyramid
TREE_FACES = [(0, 3, 2, 1), (0, 1, 4), (1, 2, 4), (2, 3, 4), (3, 0, 4)]

POSITIONS = np.array([(0, 0, 0), (60, 0, 0), (-60, 20, 0), (0, 70, 0), (40, -50, 0)], dtype=np.float64)
ANGLES = np.array([0.0, 30.0, 90.0, 45.0, 180.0])  # about +Z [degrees]
SCALES = np.array([(1, 1, 1), (1.5, 1.5, 1.5), (1, 2, 0.5), (1, 1, 1), (0.5, 0.5, 0.5)], dtype=np.float64)
PROTO_INDICES = [0, 1, 0, 1, 0]
IDS = [10, 11, 12, 13, 14]


def _mesh(stage, path, pts, faces, colour):
    m = UsdGeom.Mesh.Define(stage, path)
    m.CreatePointsAttr([Gf.Vec3f(*p) for p in pts])
    m.CreateFaceVertexCountsAttr([len(f) for f in faces])
    m.CreateFaceVertexIndicesAttr([i for f in faces for i in f])
    m.CreateDisplayColorAttr([Gf.Vec3f(*colour)])
    return m


def quat_z(deg):
    """Rotation about +Z as a GfQuath (real first), as the instancer's ``orientations`` hold it."""
    a = np.radians(deg) / 2
    return Gf.Quath(float(np.cos(a)), Gf.Vec3h(0.0, 0.0, float(np.sin(a))))


def scatter_stage(time_sampled=False, collider=False):
    """A Z-up centimetre stage: a 4 m ground, a sun, and ``/World/scatter/instancer1``: a PointInstancer with
    prototypes ``rock`` (an Xform over a Mesh box, translated 5 cm up: its own transform, applied under every
    instance) and ``tree`` (a Mesh pyramid) under a ``Prototypes`` Scope, five instances (``positions``,
    ``orientations`` as quath, ``scales``, ``protoIndices``, ``ids``), instance id 13 hidden by ``invisibleIds``.
    As Houdini's Solaris writes a Scatter and Instancer LOP: the prototypes under the instancer, the arrays written
    as time samples at frame 1 (``time_sampled``: positions keyed at frames 1 and 11, rising 1 cm a frame).
    ``collider``: PhysicsCollisionAPI on the ``rock`` prototype's root."""
    st = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(st, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(st, 0.01)
    st.SetTimeCodesPerSecond(24)
    st.SetStartTimeCode(1)
    st.SetEndTimeCode(4)
    world = UsdGeom.Xform.Define(st, "/World")
    st.SetDefaultPrim(world.GetPrim())
    _mesh(st, "/World/ground", [(-200, -200, 0), (200, -200, 0), (200, 200, 0), (-200, 200, 0)], [(0, 1, 2, 3)],
          (0.5, 0.5, 0.5))
    sun = UsdLux.DistantLight.Define(st, "/World/sun")
    sun.CreateIntensityAttr(3.0)
    sun.CreateNormalizeAttr(True)
    UsdGeom.XformCommonAPI(sun).SetRotate((30, 0, 20))
    scatter = UsdGeom.Xform.Define(st, "/World/scatter")
    UsdGeom.XformCommonAPI(scatter).SetTranslate((10, 0, 0))
    pi = UsdGeom.PointInstancer.Define(st, "/World/scatter/instancer1")
    UsdGeom.Scope.Define(st, "/World/scatter/instancer1/Prototypes")
    rock = UsdGeom.Xform.Define(st, "/World/scatter/instancer1/Prototypes/rock")
    UsdGeom.XformCommonAPI(rock).SetTranslate((0, 0, 5))
    _mesh(st, "/World/scatter/instancer1/Prototypes/rock/mesh_0", ROCK, ROCK_FACES, (0.6, 0.5, 0.4))
    _mesh(st, "/World/scatter/instancer1/Prototypes/tree", TREE, TREE_FACES, (0.2, 0.6, 0.2))
    if collider:
        UsdPhysics.CollisionAPI.Apply(rock.GetPrim())
    pi.CreatePrototypesRel().SetTargets([rock.GetPath(), Sdf.Path("/World/scatter/instancer1/Prototypes/tree")])
    one = Usd.TimeCode(1)
    positions = pi.CreatePositionsAttr()
    positions.Set(Vt.Vec3fArray.FromNumpy(POSITIONS.astype(np.float32)), one)
    if time_sampled:
        positions.Set(Vt.Vec3fArray.FromNumpy((POSITIONS + (0, 0, 10)).astype(np.float32)), Usd.TimeCode(11))
    pi.CreateOrientationsAttr().Set([quat_z(a) for a in ANGLES], one)
    pi.CreateScalesAttr().Set(Vt.Vec3fArray.FromNumpy(SCALES.astype(np.float32)), one)
    pi.CreateProtoIndicesAttr().Set(PROTO_INDICES, one)
    pi.CreateIdsAttr().Set(IDS, one)
    pi.CreateInvisibleIdsAttr().Set([13], one)
    return st


GROUP = "/World/scatter/instancer1_instances"
SHIFT = np.array([10.0, 0.0, 0.0])  # /World/scatter's translate
ROCK_LIFT = np.array([0.0, 0.0, 5.0])  # the rock prototype root's own translate


def _expected(i):
    """Instance ``i``'s world points, by the PointInstancer schema's rule written out independently of UsdGeom:
    scatter translate, then position, orientation, scale, then the prototype root's own transform."""
    local = ROCK + ROCK_LIFT if PROTO_INDICES[i] == 0 else TREE
    half = np.radians(ANGLES[i]) / 2
    c, s = float(np.float16(np.cos(half))), float(np.float16(np.sin(half)))  # as the quath holds them
    # the unit-quaternion rotation formula on the stored half floats, not renormalized (as GfMatrix4d.SetRotate
    # does): up to 5e-4 off a rotation, 1e-3 cm at these sizes
    rot = np.array([[1 - 2 * s * s, -2 * c * s, 0], [2 * c * s, 1 - 2 * s * s, 0], [0, 0, 1]])
    return (local * SCALES[i]) @ rot.T + POSITIONS[i] + SHIFT


def _path(i):
    return f"{GROUP}/instance_{IDS[i]}/" + ("rock/mesh_0" if PROTO_INDICES[i] == 0 else "tree")


def test_instances_are_objects_at_their_places():
    scene = scene_from_stage(scatter_stage(), source="scatter.usda")
    names = [o.name for o in scene.objects]
    kept = [i for i in range(len(IDS)) if IDS[i] != 13]  # 13 is in invisibleIds
    assert names == ["/World/ground"] + [_path(i) for i in kept]
    for i in kept:
        obj = scene.object(_path(i))
        assert obj.kind == "static" and obj.prim_path == _path(i)
        # float32 points of up to ~100 cm: 1e-4 cm is a few units in the last place
        np.testing.assert_allclose(obj.mesh.points, _expected(i), atol=1e-4)
        assert obj.material.albedo_authored
        np.testing.assert_allclose(obj.material.albedo, (0.6, 0.5, 0.4) if PROTO_INDICES[i] == 0 else (0.2, 0.6, 0.2),
                                   rtol=1e-6)
        # the instancer is handed to the writer to be deactivated
        assert ("/World/scatter/instancer1", "PointInstancer", None, False, False) in obj.prim_xforms


def test_time_sampled_positions_move_the_instances():
    scene = scene_from_stage(scatter_stage(time_sampled=True), source="scatter.usda")
    obj = scene.object(_path(0))
    assert obj.kind == "animated"
    for code, rise in ((1, 0.0), (6, 5.0), (11, 10.0)):  # positions keyed at 1 and 11, 10 cm apart: linear between
        np.testing.assert_allclose(obj.params["points_at"](code), _expected(0) + (0, 0, rise), atol=1e-4)


def _broken(attr, value):
    st = scatter_stage()
    st.GetPrimAtPath("/World/scatter/instancer1").GetAttribute(attr).Set(value, Usd.TimeCode(1))
    return st


@pytest.mark.parametrize("attr,value,message", [
    ("protoIndices", [0, 1, 5, 1, 0], (r"instancer1: protoIndices\[2\] = 5 at time code 1 is out of range: "
                                       "prototypes has 2 targets")),
    ("protoIndices", [0, 1, -1, 1, 0], r"protoIndices\[2\] = -1"),
    ("scales", [Gf.Vec3f(1, 1, 1)] * 4, "instancer1: scales has 4 values at time code 1 for the 5 instances"),
    ("positions", [Gf.Vec3f(0, 0, 0)] * 3, "instancer1: positions has 3 values"),
    ("ids", [1, 2, 3, 3, 4], "instancer1: ids at time code 1 holds the same id twice"),
])
def test_bad_instancer_data_is_named(attr, value, message):
    with pytest.raises(SceneError, match=message):
        scene_from_stage(_broken(attr, value), source="scatter.usda")


def test_missing_prototype_is_named():
    st = scatter_stage()
    UsdGeom.PointInstancer(st.GetPrimAtPath("/World/scatter/instancer1")).GetPrototypesRel().AddTarget("/World/nothing")
    st.GetPrimAtPath("/World/scatter/instancer1").GetAttribute("protoIndices").Set([0, 1, 2, 1, 0], Usd.TimeCode(1))
    with pytest.raises(SceneError, match=r"instancer1: prototypes\[2\] targets /World/nothing, which is not an active"):
        scene_from_stage(st, source="scatter.usda")


def test_gprim_prototypes_are_instanced():
    """Omniverse's point-instancing samples instance Cube and Sphere prototypes: each instance is the gprim
    tessellated with the scene's gprims, placed by its instance's transform; a nested instancer is skipped with
    a warning."""
    st = scatter_stage()
    ball = UsdGeom.Sphere.Define(st, "/World/scatter/instancer1/Prototypes/tree/ball")
    ball.CreateRadiusAttr(5.0)
    UsdGeom.XformCommonAPI(ball).SetTranslate((0, 0, 70))  # on the tree's top
    UsdGeom.PointInstancer.Define(st, "/World/scatter/instancer1/Prototypes/tree/nested")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = scene_from_stage(st, source="scatter.usda")
    assert any("skipping /World/scatter/instancer1/Prototypes/tree/nested (PointInstancer)" in str(w.message)
               for w in caught)
    balls = [o for o in scene.objects if o.name.endswith("/tree/ball")]
    assert [o.name for o in balls] == [f"{GROUP}/instance_11/tree/ball"]  # 13, the other tree, is hidden
    # instance 11: scale 1.5, turned 30 degrees about Z, at (60, 0, 0) + the scatter's shift; the ball's centre
    # (0, 0, 70) of the prototype goes to (70, 0, 105) and its radius to 7.5
    pts = balls[0].mesh.points.astype(np.float64)
    centre = 0.5 * (pts.min(axis=0) + pts.max(axis=0))
    np.testing.assert_allclose(centre, (70.0, 0.0, 105.0), atol=1e-3)
    radii = np.linalg.norm(pts - centre, axis=1)
    # the tessellation's vertices lie on the sphere (float32 points and the quath's 5e-4 off a rotation)
    np.testing.assert_allclose(radii, 7.5, rtol=2e-3)
    assert len(pts) > 12


def test_instances_of_a_collider_prototype_collide():
    """PhysicsCollisionAPI on the rock prototype's root: a cloth dropped on instance 10 (its top at 25 cm) rests
    on it (without the collision it falls to the ground, 25 cm lower)."""
    st = scatter_stage(collider=True)
    UsdGeom.SetStageUpAxis(st, UsdGeom.Tokens.z)
    n, size = 10, 16.0
    cloth = UsdGeom.Mesh.Define(st, "/World/cloth")
    cloth.CreatePointsAttr([Gf.Vec3f(10 + i * size / n - size / 2, j * size / n - size / 2, 30.0)
                            for j in range(n + 1) for i in range(n + 1)])
    cloth.CreateFaceVertexCountsAttr([4] * (n * n))
    cloth.CreateFaceVertexIndicesAttr([v for j in range(n) for i in range(n) for v in
                                       (j * (n + 1) + i, j * (n + 1) + i + 1, (j + 1) * (n + 1) + i + 1,
                                        (j + 1) * (n + 1) + i)])
    cloth.GetPrim().CreateAttribute("warpshade:kind", Sdf.ValueTypeNames.String, custom=True).Set("cloth")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scene = scene_from_stage(st, source="scatter.usda")
    assert scene.object(_path(0)).params["collider"] == "mesh"
    sim = ClothSimulation(scene)
    for f in range(1, 25):  # 1 s at 24 fps: 0.5 g t² is 4.9 m, the cloth has long landed
        x = sim.advance(f, {})["/World/cloth"]
    centre = x[(n // 2) * (n + 1) + n // 2]
    # on the rock's top (25 cm) within the cloth's thickness (0.5 cm) and the contact's slack
    assert 24.0 < centre[2] < 26.5, centre


def test_run_writes_each_instance_shaded(tmp_path):
    """``warpshade run`` end to end: each instance is a mesh of its own with its own colours, and the output
    layered over the input shows the shaded instances, not the instancer's."""
    src = tmp_path / "scatter.usda"
    scatter_stage().Export(str(src))
    out = tmp_path / "out.usda"
    assert main(["run", str(src), "--out", str(out), "--workers", "0", "--method", "reference", "--rays", "16",
                 "--order", "2", "--frames", "1", "--refine-receivers", "off", "--no-progress"]) == 0
    stage = Usd.Stage.Open(str(out))
    meshes = [str(p.GetPath()) for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)]
    kept = [i for i in range(len(IDS)) if IDS[i] != 13]
    assert sorted(meshes) == sorted(["/World/ground"] + [_path(i) for i in kept])
    colours = {}
    for i in kept:
        mesh = UsdGeom.Mesh(stage.GetPrimAtPath(_path(i)))
        world = np.asarray(mesh.ComputeLocalToWorldTransform(1), dtype=np.float64).T
        pts = np.asarray(mesh.GetPointsAttr().Get(1), dtype=np.float64)
        np.testing.assert_allclose(pts @ world[:3, :3].T + world[:3, 3], _expected(i), atol=1e-3)
        colours[i] = np.asarray(UsdGeom.PrimvarsAPI(mesh).GetPrimvar("displayColor").Get(1))
        assert colours[i].shape == (len(pts), 3) and colours[i].max() > 0
    # the two rocks turned 0 and 90 degrees (and scaled differently) are not lit alike
    assert not np.allclose(colours[0], colours[2])
    # layered over its input (as docs/guide/dcc.md suggests), the instancer is off and the instances show
    layered = Usd.Stage.CreateInMemory()
    layered.GetRootLayer().subLayerPaths = [str(out), str(src)]
    assert not layered.GetPrimAtPath("/World/scatter/instancer1").IsActive()
    assert layered.GetPrimAtPath(_path(0)).IsA(UsdGeom.Mesh)


def test_prototypes_under_an_over_are_instanced_and_not_drawn():
    """The USD way to keep prototypes out of the scene (OpenUSD's point-instancing guide): under an ``over``
    (or a ``class``), which the stage's traversal skips and the instancer still instances."""
    st = scatter_stage()
    pi = UsdGeom.PointInstancer(st.GetPrimAtPath("/World/scatter/instancer1"))
    layer = st.GetRootLayer()
    Sdf.CreatePrimInLayer(layer, "/Protos/rock/mesh_0")  # overs, then the prototype defined under them
    for path, tname in (("/Protos/rock", "Xform"), ("/Protos/rock/mesh_0", "Mesh")):
        spec = layer.GetPrimAtPath(path)
        spec.specifier, spec.typeName = Sdf.SpecifierDef, tname
    mesh = UsdGeom.Mesh(st.GetPrimAtPath("/Protos/rock/mesh_0"))
    mesh.CreatePointsAttr([Gf.Vec3f(*p) for p in ROCK])
    mesh.CreateFaceVertexCountsAttr([len(f) for f in ROCK_FACES])
    mesh.CreateFaceVertexIndicesAttr([i for f in ROCK_FACES for i in f])
    assert not st.GetPrimAtPath("/Protos/rock").IsDefined()
    pi.GetPrototypesRel().SetTargets(["/Protos/rock", "/World/scatter/instancer1/Prototypes/tree"])
    scene = scene_from_stage(st, source="scatter.usda")
    names = [o.name for o in scene.objects]
    assert f"{GROUP}/instance_12/rock/mesh_0" in names and not any(n.startswith("/Protos") for n in names)
    np.testing.assert_allclose(scene.object(f"{GROUP}/instance_12/rock/mesh_0").mesh.points.min(axis=0)[2], 0.0,
                               atol=1e-4)  # this rock prototype has no 5 cm lift of its own


def test_per_instance_display_color():
    """Houdini writes a scatter's point colour ``Cd`` as the instancer's ``primvars:displayColor``, one an
    instance: it is the albedo of each instance whose mesh binds no material."""
    st = scatter_stage()
    pv = UsdGeom.PrimvarsAPI(st.GetPrimAtPath("/World/scatter/instancer1")).CreatePrimvar(
        "displayColor", Sdf.ValueTypeNames.Color3fArray, UsdGeom.Tokens.vertex)
    colours = [(0.1, 0.2, 0.3), (0.4, 0.5, 0.6), (0.7, 0.8, 0.9), (0.2, 0.2, 0.2), (0.9, 0.1, 0.1)]
    pv.Set([Gf.Vec3f(*c) for c in colours])
    scene = scene_from_stage(st, source="scatter.usda")
    for i in (0, 1, 2, 4):
        np.testing.assert_allclose(scene.object(_path(i)).material.albedo, colours[i], rtol=1e-6)
    pv.Set([Gf.Vec3f(*c) for c in colours[:3]])
    with pytest.raises(SceneError, match="instancer1: primvars:displayColor has 3 values for the 5 instances"):
        scene_from_stage(st, source="scatter.usda")


def test_gprim_instances_count_in_the_vertex_budget():
    """50 Cube instances (20 cm) beside a fine cloth (1 cm edges, which sets the gprims' target edge): the gprims'
    vertex budget counts every instance, so their tessellation is coarsened, with the warning, to fit it (counted
    once, each cube would get the cloth's edge: 2646 vertices, 132 300 in all)."""
    from warpshade.geometry.shapes import VERTEX_BUDGET

    st = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(st, "Y")
    UsdGeom.SetStageMetersPerUnit(st, 1.0)
    st.SetDefaultPrim(UsdGeom.Xform.Define(st, "/World").GetPrim())
    n = 40
    cloth = UsdGeom.Mesh.Define(st, "/World/Cloth")
    cloth.CreatePointsAttr([Gf.Vec3f(i * 0.01, 1.0, j * 0.01) for j in range(n + 1) for i in range(n + 1)])
    cloth.CreateFaceVertexCountsAttr([4] * (n * n))
    cloth.CreateFaceVertexIndicesAttr([v for j in range(n) for i in range(n) for v in
                                       (j * (n + 1) + i, (j + 1) * (n + 1) + i, (j + 1) * (n + 1) + i + 1,
                                        j * (n + 1) + i + 1)])
    cloth.GetPrim().CreateAttribute("warpshade:kind", Sdf.ValueTypeNames.String, custom=True).Set("cloth")
    pi = UsdGeom.PointInstancer.Define(st, "/World/Crates")
    UsdGeom.Cube.Define(st, "/World/Crates/Prototypes/crate").CreateSizeAttr(0.2)
    pi.CreatePrototypesRel().SetTargets(["/World/Crates/Prototypes/crate"])
    pi.CreatePositionsAttr([Gf.Vec3f(0.3 * (k % 10), 0.1, -0.5 - 0.3 * (k // 10)) for k in range(50)])
    pi.CreateProtoIndicesAttr([0] * 50)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = scene_from_stage(st, source="crates.usda")
    crates = [o for o in scene.objects if o.name.startswith("/World/Crates_instances/")]
    assert len(crates) == 50
    assert sum(o.mesh.num_vertices for o in crates) <= VERTEX_BUDGET
    assert any("to stay within" in str(w.message) for w in caught)
