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
