"""Exact analytic capsule, cylinder and cone colliders (issue 15, item 3): the solver keeps cloth
outside them, the intersection count sees cloth inside them, and USD Capsule/Cylinder/Cone gprims
marked with PhysicsCollisionAPI become them.

The signed distances below are written here in NumPy from the shapes' definitions (segment
distance for the capsule, the 2-D box of the meridian section for the cylinder, the 2-D polygon
of the meridian section for the cone); they do not call warpshade.
"""

from __future__ import annotations

import os
import warnings

import numpy as np
import pytest

from helpers import DATA
from warpshade.scene import SceneWarning
from warpshade.sim import ClothBuilder, ColliderSet, XPBDSolver, count_intersections

DT = 1.0 / 60.0
NEWTON = os.path.join(DATA, "newton")


# -- oracles --------------------------------------------------------------------------------------

def _meridian(x, p0, p1):
    """(r, h): distance from the axis p0 -> p1 and height above p0 along it."""
    x, p0, p1 = (np.asarray(v, dtype=np.float64) for v in (x, p0, p1))
    u = (p1 - p0) / np.linalg.norm(p1 - p0)
    h = (x - p0) @ u
    r = np.linalg.norm((x - p0) - h[:, None] * u, axis=1)
    return r, h


def sd_capsule(x, p0, p1, radius):
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    d = p1 - p0
    t = np.clip((np.asarray(x) - p0) @ d / (d @ d), 0, 1)
    return np.linalg.norm(np.asarray(x) - (p0 + t[:, None] * d), axis=1) - radius


def sd_cylinder(x, p0, p1, radius):
    r, h = _meridian(x, p0, p1)
    half = np.linalg.norm(np.asarray(p1, float) - np.asarray(p0, float)) / 2
    q = np.stack([r - radius, np.abs(h - half) - half], 1)  # 2-D box sdf (Quilez)
    return np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0)


def _seg_dist(q, a, b):
    d = b - a
    t = np.clip((q - a) @ d / (d @ d), 0, 1)
    return np.linalg.norm(q - (a + t[:, None] * d), axis=1)


def sd_cone(x, base, apex, radius):
    """Signed distance to the symmetric meridian triangle (-R, 0), (R, 0), (0, L): outside, the
    distance to its boundary; inside, minus it (the axis is inside the section, not an edge)."""
    r, h = _meridian(x, base, apex)
    length = np.linalg.norm(np.asarray(apex, float) - np.asarray(base, float))
    q = np.stack([r, h], 1)
    tri = np.array([[-radius, 0.0], [radius, 0.0], [0.0, length]])
    dist = np.min([_seg_dist(q, tri[i], tri[(i + 1) % 3]) for i in range(3)], axis=0)
    inside = (h >= 0) & (r / radius + h / length <= 1)
    return np.where(inside, -dist, dist)


ORACLE = {"capsule": sd_capsule, "cylinder": sd_cylinder, "cone": sd_cone}


def _rot(axis, angle):
    axis = np.asarray(axis, float) / np.linalg.norm(axis)
    k = np.array([[0, -axis[2], axis[1]], [axis[2], 0, -axis[0]], [-axis[1], axis[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


# shape, axis direction (unit vector the shape's p0 -> p1 runs along), half length, radius
CASES = [
    ("capsule", (0, 0, 1), 0.15, 0.1),
    ("capsule", _rot((1, 0, 0), 0.5) @ [0, 0, 1.0], 0.15, 0.1),
    ("cylinder", (0, 1, 0), 0.1, 0.15),      # upright: cloth on the flat cap, over the sharp rim
    ("cylinder", (1, 0, 0), 0.2, 0.1),       # lying: cloth on the side
    ("cylinder", _rot((0, 0, 1), 0.6) @ [1, 0, 0.0], 0.2, 0.1),  # tilted: rim and side
    ("cone", (0, 1, 0), 0.15, 0.15),         # apex up: cloth tented on the sharp apex
    ("cone", (0, -1, 0), 0.15, 0.15),        # apex down: cloth on the flat base and its rim
    ("cone", _rot((1, 0, 1), 0.7) @ [0, 1, 0.0], 0.15, 0.15),
]


def _add(col, shape, p0, p1, radius):
    return {"capsule": col.add_capsule, "cylinder": col.add_cylinder, "cone": col.add_cone}[shape](p0, p1, radius)


def _drop(col, n=14, size=0.8, height=0.55, frames=50, self_collision=False):
    b = ClothBuilder()
    b.add_grid(n, n, size, size, origin=(-size / 2, height, -size / 2))
    m = b.finalize()
    s = XPBDSolver(m, col, self_collision=self_collision)
    st = m.state()
    xs = []
    for _ in range(frames):
        s.step(st, st, DT)
        xs.append(st.points.numpy().astype(np.float64))
    return m, np.array(xs)


def _edges_near(m, x, sd, limit, samples=9):
    """How many cloth edges come closer to the solid than ``limit`` at one of ``samples`` points."""
    e = m.edges_np
    t = np.linspace(0.0, 1.0, samples)
    q = x[e[:, 0]][:, None, :] * (1 - t)[None, :, None] + x[e[:, 1]][:, None, :] * t[None, :, None]
    d = sd(q.reshape(-1, 3)).reshape(len(e), samples)
    return int((d.min(axis=1) < limit).sum())


@pytest.mark.parametrize("shape, axis, half, radius", CASES, ids=[f"{c[0]}-{i}" for i, c in enumerate(CASES)])
def test_cloth_stays_outside_the_solid_and_touches_it(shape, axis, half, radius):
    centre = np.array([0.0, 0.25, 0.0])
    axis = np.asarray(axis, float)
    p0, p1 = centre - half * axis, centre + half * axis
    col = ColliderSet()
    _add(col, shape, p0, p1, radius)
    m, xs = _drop(col)
    sd = ORACLE[shape]
    worst = min(sd(x, p0, p1, radius).min() for x in xs)
    # the collider projection runs last in every substep, and the shapes' distances are exact: only
    # float32 rounding of positions around 0.5 m remains (measured worst 3e-7 m; bound 1e-5 m)
    assert worst >= m.thickness - 1e-5, f"{shape} {axis}: deepest vertex at {worst:.6f} m (thickness {m.thickness})"
    # contact: cloth edges resting within 2 mm of the thickness shell (an edge can rest on a side
    # between two vertex rows, so the edges are sampled, not only the vertices)
    near = _edges_near(m, xs[-1], lambda q: sd(q, p0, p1, radius), m.thickness + 2e-3)
    assert near >= 3, f"{shape}: the cloth did not reach the collider ({near} edges near it)"
    assert xs[-1][:, 1].max() < 0.55 - 0.05, "the cloth did not fall"


def test_rising_cylinder_and_cone_sweep_and_stay_exact():
    """A cylinder and a cone rising 1.5 cm a step under a falling cloth catch and lift it: the
    vertices stay outside at every frame (the sweep across substeps, the rim and apex edge pass)."""
    col = ColliderSet()
    cy = col.add_cylinder((-0.25, -0.3, 0), (-0.25, -0.1, 0), 0.1)
    co = col.add_cone((0.25, -0.3, 0), (0.25, -0.1, 0), 0.12)
    b = ClothBuilder()
    b.add_grid(20, 10, 1.0, 0.5, origin=(-0.5, 0.0, -0.25))
    m = b.finalize()
    s = XPBDSolver(m, col, self_collision=False)
    st = m.state()
    worst = np.inf
    for f in range(20):
        dz = 0.015 * (f + 1)
        col.set_cylinder(cy, (-0.25, -0.3 + dz, 0), (-0.25, -0.1 + dz, 0))
        col.set_cone(co, (0.25, -0.3 + dz, 0), (0.25, -0.1 + dz, 0))
        s.step(st, st, DT)
        x = st.points.numpy().astype(np.float64)
        worst = min(worst, sd_cylinder(x, (-0.25, -0.3 + dz, 0), (-0.25, -0.1 + dz, 0), 0.1).min(),
                    sd_cone(x, (0.25, -0.3 + dz, 0), (0.25, -0.1 + dz, 0), 0.12).min())
    assert worst >= m.thickness - 1e-5, worst
    # the shapes' tops end at y = 0.2 and the cloth started at 0: it was carried up (measured 0.27 m)
    assert x[:, 1].max() > 0.15


@pytest.mark.parametrize("shape", ["cylinder", "cone"])
def test_intersection_count_sees_cloth_inside_the_solid(shape):
    """A triangle wholly inside, one crossing the side, one crossing the cap and one outside (the
    count is exact for cylinders and cones; tests/sim/test_intersection_count.py checks it on random
    triangles)."""
    col = ColliderSet()
    _add(col, shape, (0, 0, 0), (0, 0.4, 0), 0.2)
    tris = {
        "inside": [[-0.02, 0.1, 0], [0.02, 0.1, 0], [0, 0.12, 0.02]],
        "side": [[0.1, 0.1, 0], [0.4, 0.1, 0], [0.4, 0.12, 0.05]],   # crosses the side wall
        "cap": [[0, -0.1, 0], [0.01, 0.1, 0], [-0.01, 0.05, 0.01]],  # crosses the base
        "outside": [[0.5, 0.1, 0], [0.6, 0.1, 0], [0.5, 0.2, 0]],
    }
    faces = np.array([[0, 1, 2]])
    for name, pts in tris.items():
        sd = ORACLE[shape](np.array(pts), (0, 0, 0), (0, 0.4, 0), 0.2)
        expect = name != "outside"
        assert (sd.min() <= 0) == (name in ("inside", "side", "cap"))  # the oracle agrees on the setup
        got = count_intersections(np.array(pts), faces, col)["collider"]
        assert got == int(expect), f"{shape} {name}: counted {got}"


def test_bad_cylinder_and_cone_input():
    with pytest.raises(ValueError, match="cylinder radius must be finite and > 0"):
        ColliderSet().add_cylinder((0, 0, 0), (0, 1, 0), 0.0)
    with pytest.raises(ValueError, match="cone base and apex must differ"):
        ColliderSet().add_cone((0, 1, 0), (0, 1, 0), 0.1)
    c = ColliderSet()
    i = c.add_sphere((0, 0, 0), 1.0)
    with pytest.raises(ValueError, match="is not a shape of kind"):
        c.set_cone(i, (0, 0, 0), (0, 1, 0))


# -- USD ------------------------------------------------------------------------------------------

def _stage(shape, up="Z", mpu=1.0, axis="Z", enabled=None, scale=None, rotate=None, purpose=None):
    """A hand-written stage: a Capsule/Cylinder/Cone with PhysicsCollisionAPI at the origin and an
    16 x 16-quad cloth 0.8 m wide 0.35 m above it (sizes in metres, authored in stage units)."""
    from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics

    u = 1.0 / mpu  # stage units per metre
    st = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(st, up)
    UsdGeom.SetStageMetersPerUnit(st, mpu)
    st.SetStartTimeCode(0)
    st.SetEndTimeCode(40)
    world = UsdGeom.Xform.Define(st, "/World")
    st.SetDefaultPrim(world.GetPrim())
    g = {"Capsule": UsdGeom.Capsule, "Cylinder": UsdGeom.Cylinder, "Cone": UsdGeom.Cone}[shape].Define(
        st, f"/World/{shape}")
    g.CreateAxisAttr(axis)
    g.CreateRadiusAttr(0.12 * u)
    g.CreateHeightAttr(0.3 * u)
    if rotate is not None:
        g.AddRotateXYZOp().Set(Gf.Vec3f(*rotate))
    if scale is not None:
        g.AddScaleOp().Set(Gf.Vec3f(*scale))
    if purpose is not None:
        g.CreatePurposeAttr(purpose)
    api = UsdPhysics.CollisionAPI.Apply(g.GetPrim())
    if enabled is not None:
        api.CreateCollisionEnabledAttr(enabled)
    n, size, h = 17, 0.8, 0.35
    ij = np.stack(np.meshgrid(np.linspace(-size / 2, size / 2, n), np.linspace(-size / 2, size / 2, n)), -1).reshape(-1, 2)
    pts = np.zeros((n * n, 3))
    upi = 1 if up == "Y" else 2
    other = [0, 2] if up == "Y" else [0, 1]
    pts[:, other] = ij
    pts[:, upi] = h
    quads = [[j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i] for j in range(n - 1) for i in range(n - 1)]
    if up == "Y":
        quads = [q[::-1] for q in quads]  # facing +Y
    m = UsdGeom.Mesh.Define(st, "/World/Cloth")
    m.CreatePointsAttr([Gf.Vec3f(*(p * u)) for p in pts])
    m.CreateFaceVertexCountsAttr([4] * len(quads))
    m.CreateFaceVertexIndicesAttr([int(v) for q in quads for v in q])
    m.GetPrim().CreateAttribute("warpshade:kind", Sdf.ValueTypeNames.String).Set("cloth")
    return st


def _scene(st):
    from warpshade.usd.scene_io import scene_from_stage

    return scene_from_stage(st, source="test.usda")


def _drape(scene, frames=40):
    from warpshade.pipeline.cloth import ClothSimulation

    sim = ClothSimulation(scene)
    for f in range(1, frames + 1):
        x = sim.advance(f, {})["/World/Cloth"].astype(np.float64)
        yield sim, x


def _world_shape(scene):
    obj = next(o for o in list(scene.objects) + scene.collision_only if o.params.get("collider"))
    kind = obj.params["collider"]
    return kind, obj.params.get(kind)


@pytest.mark.parametrize("shape, up, mpu, axis", [
    ("Capsule", "Z", 1.0, "X"), ("Cylinder", "Z", 1.0, "Z"), ("Cone", "Z", 1.0, "Z"),
    ("Capsule", "Y", 0.01, "Z"), ("Cylinder", "Y", 0.01, "X"), ("Cone", "Y", 0.01, "Y"),
])
def test_usd_gprim_with_physics_collision_api_is_an_analytic_collider(shape, up, mpu, axis):
    scene = _scene(_stage(shape, up, mpu, axis))
    kind, c = _world_shape(scene)
    assert kind == shape.lower() and c is not None
    u = 1.0 / mpu
    upv = np.eye(3)[1 if up == "Y" else 2]
    ax = np.eye(3)[{"X": 0, "Y": 1, "Z": 2}[axis]]
    # USD: centred on the origin; Capsule height is its cylinder part; a Cone's apex at +height/2
    ends = (c["base"], c["apex"]) if shape == "Cone" else (c["p0"], c["p1"])
    np.testing.assert_allclose(ends[0], -0.15 * u * ax, atol=1e-9 * u)
    np.testing.assert_allclose(ends[1], 0.15 * u * ax, atol=1e-9 * u)
    assert c["radius"] == pytest.approx(0.12 * u)
    if mpu != 1.0:
        # the drape is checked in metre stages only, to keep this test cheap: a centimetre stage
        # drapes as the same scene in metres (tests/usd/test_units.py)
        return
    sd = ORACLE[kind]
    worst = np.inf
    for sim, x in _drape(scene):
        worst = min(worst, sd(x, ends[0], ends[1], c["radius"]).min())
    th = sim.model.thickness
    assert sim.solver.colliders.shape_count == 1 and not sim.solver.colliders.meshes
    assert worst >= th - 1e-5 * u, (worst, th)  # float32 rounding, scaled to stage units
    last = sd(x, ends[0], ends[1], c["radius"])
    assert (last < th + 2e-3 * u).sum() >= 3, "the cloth did not drape onto the collider"
    assert (x @ upv).max() < 0.3 * u  # it fell from 0.35 m


def test_usd_collision_disabled_is_not_a_collider():
    scene = _scene(_stage("Cylinder", enabled=False))
    obj = scene.object("/World/Cylinder")
    assert "collider" not in obj.params


def test_usd_transform_scale_and_rotation():
    """Scaling a Cylinder along its axis keeps it exact (a taller cylinder); a radial scale that
    is not the same both ways, or a non-uniform scale of a Capsule, falls back to the mesh with a
    warning naming the prim; a rotation turns the axis."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", SceneWarning)
        kind, c = _world_shape(_scene(_stage("Cylinder", axis="Z", scale=(2, 2, 0.5))))
    assert kind == "cylinder"
    np.testing.assert_allclose(c["p1"] - c["p0"], [0, 0, 0.15], atol=1e-7)
    assert c["radius"] == pytest.approx(0.24)
    kind, c = _world_shape(_scene(_stage("Cone", axis="Z", rotate=(90, 0, 0))))
    np.testing.assert_allclose(c["apex"] - c["base"], [0, -0.3, 0], atol=1e-6)  # +Z turned 90 deg about X
    for shape, scale in (("Cylinder", (1, 2, 1)), ("Capsule", (1, 1, 2))):
        with pytest.warns(SceneWarning, match=rf"/World/{shape}: {shape} collider is not exact because"):
            kind, _ = _world_shape(_scene(_stage(shape, axis="Z", scale=scale)))
        assert kind == "mesh"


def test_guide_purpose_capsule_collides_but_is_not_an_object():
    scene = _scene(_stage("Capsule", axis="X", purpose="guide"))
    assert [o.name for o in scene.objects] == ["/World/Cloth"]
    assert [o.name for o in scene.collision_only] == ["/World/Capsule"]
    kind, c = _world_shape(scene)
    for sim, x in _drape(scene):
        pass
    last = sd_capsule(x, c["p0"], c["p1"], c["radius"])
    assert last.min() >= sim.model.thickness - 1e-5 and (last < sim.model.thickness + 2e-3).sum() >= 3


def test_small_cloth_lands_on_the_humanoids_guide_capsules():
    """Newton's humanoid.usda: its collision twins are guide-purpose Capsules and Spheres with
    PhysicsCollisionAPI. They become analytic colliders (16 capsules, 3 spheres, no mesh), and a
    40 cm cloth dropped over the head lands on the head sphere and the shoulder capsules and stays
    there (without them it would fall 7 m in 60 frames at 24 fps)."""
    from pxr import Gf, Sdf, Usd, UsdGeom

    st = Usd.Stage.Open(os.path.join(NEWTON, "humanoid.usda"))
    st.SetEditTarget(st.GetSessionLayer())
    n = 17
    xy = np.stack(np.meshgrid(np.linspace(-0.2, 0.2, n), np.linspace(-0.2, 0.2, n)), -1).reshape(-1, 2)
    pts = np.c_[xy, np.full(n * n, 0.35)]
    m = UsdGeom.Mesh.Define(st, "/Cloth")
    m.CreatePointsAttr([Gf.Vec3f(*p) for p in pts])
    quads = [[j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i] for j in range(n - 1) for i in range(n - 1)]
    m.CreateFaceVertexCountsAttr([4] * len(quads))
    m.CreateFaceVertexIndicesAttr([int(v) for q in quads for v in q])
    m.GetPrim().CreateAttribute("warpshade:kind", Sdf.ValueTypeNames.String).Set("cloth")
    scene = _scene(st)
    kinds = sorted(o.params["collider"] for o in scene.collision_only)
    assert kinds == ["capsule"] * 16 + ["sphere"] * 3
    from warpshade.pipeline.cloth import ClothSimulation

    sim = ClothSimulation(scene)
    assert sim.solver.colliders.shape_count == 19 and not sim.solver.colliders.meshes
    caps = [o.params["capsule"] for o in scene.collision_only if o.params["collider"] == "capsule"]
    balls = [o.params["sphere"] for o in scene.collision_only if o.params["collider"] == "sphere"]
    th = sim.model.thickness
    touching = []
    for f in range(1, 61):
        x = sim.advance(f, {})["/Cloth"].astype(np.float64)
        sd = np.min([sd_capsule(x, c["p0"], c["p1"], c["radius"]) for c in caps]
                    + [np.linalg.norm(x - b["center"], axis=1) - b["radius"] for b in balls], axis=0)
        assert sd.min() >= th - 1e-5, f"frame {f}: a vertex {th - sd.min():.2e} m deep in a capsule or sphere"
        touching.append(int((sd < th + 2e-3).sum()))
    # it settles on the head and the shoulders (measured: 60..63 vertices within 2 mm of a
    # capsule or sphere in each of the last 20 frames; the shoulder capsules alone are touched on
    # and off, as the cloth, which hardly stretches, hangs from the head just above them)
    assert min(touching[-20:]) >= 20, touching
    assert x[:, 2].mean() > 0.1, x[:, 2].mean()  # resting on the head (its top at z = 0.28)


def test_collider_passes_in_one_launch_equal_as_many_calls():
    """``collide(..., passes=k)`` (one launch, a vertex's passes stopping after one that pushed it
    nowhere) gives bit for bit the positions of k calls of one pass, on points under a sphere
    sunk into the ground, which it pushes below the ground and the ground back into it, so later passes
    still move points (checked below: a test where they did not could not see a pass dropped)."""
    import warp as wp

    col = ColliderSet()
    col.add_plane((0.0, 1.0, 0.0), 0.0, friction=0.5)
    col.add_sphere((0.0, 0.05, 0.0), 0.06, friction=0.5)
    col.begin_step()
    col.pose_substep(0.0, 1.0)
    rng = np.random.default_rng(7)
    x0 = rng.uniform((-0.06, -0.01, -0.06), (0.06, 0.12, 0.06), size=(2000, 3)).astype(np.float32)
    prev = (x0 + rng.normal(0.0, 0.01, size=x0.shape)).astype(np.float32)
    inv_mass = np.ones(len(x0), dtype=np.float32)
    inv_mass[:10] = 0.0
    w = wp.array(inv_mass, dtype=wp.float32)
    x_prev = wp.array(prev, dtype=wp.vec3)
    thickness = 0.004
    singles = [x0]
    x = wp.array(x0, dtype=wp.vec3)
    for _ in range(4):
        col.collide(thickness, w, x_prev, x)
        singles.append(x.numpy().copy())
    # later passes move points: the 2nd, 3rd and 4th single pass each change some position
    for a, b in zip(singles[1:], singles[2:]):
        assert (a != b).any()
    for k in (1, 2, 3, 4):
        xk = wp.array(x0, dtype=wp.vec3)
        col.collide(thickness, w, x_prev, xk, passes=k)
        assert np.array_equal(xk.numpy().view(np.uint32), singles[k].view(np.uint32)), k
