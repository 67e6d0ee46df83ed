"""A cloth dropped on a box (warpshade issue 19): the box's top corners and edges must not hold
cloth vertices step after step (the intersection guard sending the same vertices back to the
start of every step, a spike at each corner) nor stretch the skirt over them."""

import warnings

import numpy as np
import pytest

from warpshade.scene import SceneWarning


def box_drop_stage(collider="box", n=21, size=1.0, box=0.5, drop=0.3, frames=30, shear=False):
    """Z-up metre stage at 24 fps: an n x n-vertex cloth `size` m wide, `drop` m above a `box` m
    Cube (marked ``warpshade:collider`` = `collider`, or an 8-vertex Mesh box for "mesh") on a
    ground plane."""
    from pxr import Sdf, Usd, UsdGeom

    st = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(st, "Z")
    UsdGeom.SetStageMetersPerUnit(st, 1.0)
    st.SetStartTimeCode(1)
    st.SetEndTimeCode(frames)
    st.SetTimeCodesPerSecond(24)
    root = UsdGeom.Xform.Define(st, "/root")
    st.SetDefaultPrim(root.GetPrim())
    g = UsdGeom.Mesh.Define(st, "/root/Ground")
    g.CreatePointsAttr([(-3, -3, 0), (3, -3, 0), (3, 3, 0), (-3, 3, 0)])
    g.CreateFaceVertexCountsAttr([4])
    g.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    g.GetPrim().CreateAttribute("warpshade:collider", Sdf.ValueTypeNames.Token).Set("ground")
    if collider == "mesh":
        b = UsdGeom.Mesh.Define(st, "/root/Box")
        h = box / 2
        b.CreatePointsAttr([(x, y, z) for z in (0, box) for y in (-h, h) for x in (-h, h)])
        quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
        b.CreateFaceVertexCountsAttr([4] * 6)
        b.CreateFaceVertexIndicesAttr(sum(quads, []))
    else:
        b = UsdGeom.Cube.Define(st, "/root/Box")
        b.CreateSizeAttr(box)
        b.AddTranslateOp().Set((0, 0, box / 2))
        if shear:
            from pxr import Gf
            b.AddTransformOp().Set(Gf.Matrix4d(1, 0, 0, 0, 0.3, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1))
    b.GetPrim().CreateAttribute("warpshade:collider", Sdf.ValueTypeNames.Token).Set(collider)
    pts = [(-size / 2 + size * i / (n - 1), -size / 2 + size * j / (n - 1), box + drop) for j in range(n) for i in range(n)]
    quads = [[j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i] for j in range(n - 1) for i in range(n - 1)]
    c = UsdGeom.Mesh.Define(st, "/root/Cloth")
    c.CreatePointsAttr(pts)
    c.CreateFaceVertexCountsAttr([4] * len(quads))
    c.CreateFaceVertexIndicesAttr(sum(quads, []))
    c.GetPrim().CreateAttribute("warpshade:kind", Sdf.ValueTypeNames.Token).Set("cloth")
    return st


def _scene(st):
    from warpshade.usd.scene_io import scene_from_stage

    return scene_from_stage(st, source="box_drop.usda")


def test_cube_marked_box_is_the_exact_box():
    """A Cube marked ``warpshade:collider = "box"`` collides as its exact oriented box (as under
    PhysicsCollisionAPI), not as its tessellation; a sheared one warns and keeps the mesh."""
    with warnings.catch_warnings():
        warnings.simplefilter("error", SceneWarning)
        box = _scene(box_drop_stage()).object("/root/Box")
    assert box.params["collider"] == "box"
    np.testing.assert_allclose(box.params["box"]["center"], [0, 0, 0.25], atol=1e-12)
    np.testing.assert_allclose(box.params["box"]["half_extents"], [0.25] * 3, atol=1e-12)
    np.testing.assert_allclose(np.abs(box.params["box"]["rotation"]), [0, 0, 0, 1], atol=1e-12)
    with pytest.warns(SceneWarning, match="/root/Box: Cube collider is not exact because"):
        sheared = _scene(box_drop_stage(shear=True)).object("/root/Box")
    assert "box" not in sheared.params


HOLD_BOUND = 4
"""Most consecutive steps the guard may send a vertex back (measured: 0 with the Cube's exact box,
2 with the 8-vertex mesh box; 25 and growing a step a step on c5e9570, where both kept their
corners out of the corner contacts)."""
P99_BOUND, MAX_BOUND = 0.2, 0.45
"""Edge strain bounds on every frame from 14 (landing done) to 29 (measured worst: p99 0.138 / 0.152
and max 0.301 / 0.320 for the box / mesh box, margins 1.3x and 1.4x; c5e9570: p99 0.89 / 1.03,
max 2.1 / 2.6)."""


@pytest.mark.parametrize("collider", ["box", "mesh"])
def test_cloth_dropped_on_a_box_is_not_held_at_its_corners(collider):
    """A 21 x 21 cloth (5 cm edges) dropped 0.3 m onto a 0.5 m box (a Cube marked "box", or an
    8-vertex mesh marked "mesh"), landing at frame ~10: no vertex is held by the guard for more
    than a few steps, and the edge strain stays bounded over the box's top corners and edges."""
    from warpshade.pipeline.cloth import ClothSimulation

    sim = ClothSimulation(_scene(box_drop_stage(collider)))
    assert bool(sim.solver.colliders.meshes) == (collider == "mesh")
    m = sim.model
    e, rest = m.edges.numpy(), m.edge_rest_length.numpy()
    worst = [0.0, 0.0]
    for f in range(1, 30):
        x = sim.advance(f, {})["/root/Cloth"]
        if f >= 14:
            strain = np.linalg.norm(x[e[:, 0]] - x[e[:, 1]], axis=1) / rest - 1.0
            worst = [max(worst[0], float(np.percentile(strain, 99))), max(worst[1], float(strain.max()))]
    stats = sim.solver.stats()
    assert stats["guard_unresolved"] == 0
    assert stats["guard_longest_hold"] <= HOLD_BOUND, stats
    assert worst[0] < P99_BOUND and worst[1] < MAX_BOUND, worst


def _mesh_box():
    """The unit box [-0.5, 0.5]^2 x [0, 1] as 12 outward-wound triangles."""
    pts = np.array([(x, y, z) for z in (0, 1) for y in (-.5, .5) for x in (-.5, .5)], float)
    quads = [[0, 2, 3, 1], [4, 5, 7, 6], [0, 1, 5, 4], [2, 6, 7, 3], [0, 4, 6, 2], [1, 3, 7, 5]]
    return pts, np.array([[q[0], q[1], q[2]] for q in quads] + [[q[0], q[2], q[3]] for q in quads])


def test_mesh_box_edge_pushes_a_cloth_triangle_off():
    """A cloth triangle laid across a mesh box's top edge, two vertices on the top face and one on
    the side, 5 mm off the faces: its two edges that cross the box's edge cut through the solid
    (chords across a 90 degree edge). One pass of the sharp-edge projection and the vertices'
    frees it: the triangle pass (collide_mesh_edge_faces) lifts it along its normal. The cloth-edge
    pass alone pushes each cut edge along the face it is least deep under and leaves both pairs
    after that pass (checked by disabling the triangle pass)."""
    import warp as wp

    from warpshade.sim import ColliderSet, count_intersections

    pts, faces = _mesh_box()
    col = ColliderSet()
    col.add_mesh(pts, faces)
    col.begin_step()
    col.pose_substep(0.0, 1.0)
    x0 = np.array([(0.48, -0.02, 1.005), (0.505, -0.02, 0.975), (0.49, 0.03, 1.005)], np.float32)
    tris = np.array([[0, 1, 2]], np.int32)
    assert count_intersections(x0, tris, col)["collider"] == 2  # the box's top edge's two faces
    x = wp.array(x0, dtype=wp.vec3)
    inv_mass = wp.array(np.ones(3, np.float32))
    col.collide_edges(0.005, inv_mass, wp.array(np.array([[0, 1], [1, 2], [0, 2]], np.int32)), x, wp.array(tris))
    col.collide(0.005, inv_mass, x, x)
    assert count_intersections(x.numpy(), tris, col)["collider"] == 0



def test_mesh_box_edge_leaves_a_triangle_beyond_its_face_alone():
    """A cloth triangle above a mesh box's top face, tilted so that the box's top edge lies 1.2 cm
    in front of its plane, over its inside (its normal, turned towards the edge's outward side, points
    out of the side face but into the top face's plane): the triangle's point behind the edge is
    above the top face, outside the solid, so nothing pokes through it and the sharp-edge pass
    leaves it where it is (pushed along that normal it would be driven 1.6 cm towards the side)."""
    import warp as wp

    from warpshade.sim import ColliderSet, count_intersections

    pts, faces = _mesh_box()
    col = ColliderSet()
    col.add_mesh(pts, faces)
    col.begin_step()
    col.pose_substep(0.0, 1.0)
    n, t = np.array([0.8, 0.0, -0.6]), np.array([0.6, 0.0, 0.8])
    q = np.array([0.5, 0.0, 1.0]) - 0.012 * n  # the point 1.2 cm behind the edge, above the top face
    x0 = np.array([q + 0.02 * t - [0, 0.02, 0], q + 0.02 * t + [0, 0.02, 0], q - 0.005 * t], np.float32)
    tris = np.array([[0, 1, 2]], np.int32)
    assert count_intersections(x0, tris, col)["collider"] == 0
    x = wp.array(x0, dtype=wp.vec3)
    inv_mass = wp.array(np.ones(3, np.float32))
    col.collide_edges(0.005, inv_mass, wp.array(np.array([[0, 1], [1, 2], [0, 2]], np.int32)), x, wp.array(tris))
    np.testing.assert_array_equal(x.numpy(), x0)

MESH_BOX_HOLD = 6
"""Most consecutive steps the guard may send a vertex back on the user's mesh box drop: the exact
(analytic) box's longest hold on the same scene (measured 6; the mesh box measured 0, and 27,
growing a step a step, before its sharp edges pushed cloth triangles off)."""
MESH_BOX_P99 = 0.19
"""p99 edge strain at rest (frame 39) on the user's mesh box drop: the analytic box's 0.171 on the
same scene plus 10 % (the mesh box measured 0.154; 0.217 before)."""


def test_users_cloth_dropped_on_a_mesh_box():
    """Issue 19's user scene: a 2 m, 41 x 41 cloth dropped 0.6 m onto a 1 m box kept as an
    8-vertex mesh (24 fps, 8 substeps): no intersecting pair at any frame end, no vertex held by
    the guard longer than on the exact box, and the p99 strain at rest no worse than there."""
    from warpshade.pipeline.cloth import ClothSimulation
    from warpshade.sim import count_intersections

    sim = ClothSimulation(_scene(box_drop_stage("mesh", n=41, size=2.0, box=1.0, drop=0.6, frames=40)))
    m, col = sim.model, sim.solver.colliders
    assert len(col.meshes) == 1 and col.meshes[0].closed
    faces = m.tris.numpy()
    for f in range(1, 40):
        x = sim.advance(f, {})["/root/Cloth"]
        assert count_intersections(x, faces, col)["total"] == 0, f
    stats = sim.solver.stats()
    assert stats["guard_longest_hold"] <= MESH_BOX_HOLD, stats
    assert float(np.percentile(m.edge_strain(x), 99)) < MESH_BOX_P99
