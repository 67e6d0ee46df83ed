"""Hard contact scenes on short runs at small resolution: a strip folding onto itself on the
floor (the pile), a cloth wrung by two turning edges (the twist), a strip dragged over a box's
sharp edge, a cape on the walking figure, a 4 m/s drop onto a 2-triangle ground. Each asserts 0
intersecting triangle pairs (exact count, cloth-cloth and cloth-collider) at the end of every
frame, and that the scene did what makes it hard (so a scene that never touches cannot pass)."""

from __future__ import annotations

import contextlib
import importlib
import io
import os
import sys
import warnings

import numpy as np
import pytest
import trimesh

from helpers import REPO, SHIPPED
from warpshade.geometry import ulp_jitter
from warpshade.sim import ClothBuilder, ColliderSet, IntersectionCounter, WalkingFigure, XPBDSolver

FPS = 60.0


def _run(model, solver, frames, before_step=None, control=None, state=None, after_step=None):
    """Step `frames` frames; return the exact intersection count after each and the last state."""
    state = model.state() if state is None else state
    counter = IntersectionCounter(model.faces)
    counts = []
    for f in range(frames):
        if before_step is not None:
            before_step(f, (f + 1) / FPS)
        solver.step(state, state, 1.0 / FPS, control)
        n = counter.self_pairs(state.points)[0]
        if solver.colliders is not None:
            n += counter.collider_pairs(state.points, solver.colliders)[0]
        counts.append(n)
        if after_step is not None:
            after_step(f, (f + 1) / FPS, state)
    return counts, state


def _sim_module(name: str):
    """The sims/ script `name` imported as a module."""
    folder = os.path.join(REPO, "sims")
    sys.path.insert(0, folder)
    try:
        return importlib.import_module(name)
    finally:
        sys.path.remove(folder)


def _assert_free(counts, solver):
    bad = [f for f, n in enumerate(counts) if n]
    assert not bad, f"intersecting pairs at frames {bad[:5]} ({[counts[f] for f in bad[:5]]}); {solver.stats()}"


def test_pile_folds_without_intersections():
    """A 0.2 m x 0.9 m strip (5 x 22) lowered onto the floor at 1.2 m/s while swinging: it folds
    over itself. Hardness check: at the end at least 2 layers lie over one floor point."""
    b = ClothBuilder(bend_stiffness=2e-5)
    ids = b.add_grid(5, 22, 0.2, 0.9, origin=(-0.1, 1.0, 0.0), u_axis=(1, 0, 0), v_axis=(0, -1, 0))
    slots = b.attach(ids[0])
    model = b.finalize()
    col = ColliderSet()
    col.add_plane((0, 1, 0), 0.0, friction=0.6)
    solver = XPBDSolver(model, col)
    control = model.control()
    top = model.rest_points_np[ids[0]].astype(np.float64)

    def drive(f, t):
        tg = np.empty_like(top)
        tg[slots] = top + [0.1 * np.sin(2 * np.pi * 1.2 * t), -min(1.2 * t, 0.85), 0.0]
        control.set_targets(tg)

    counts, st = _run(model, solver, 50, drive, control)
    _assert_free(counts, solver)
    x = st.points.numpy()
    low = x[x[:, 1] < 0.05]
    assert len(low) > 20, "the strip never reached the floor"
    # layers: heights on the floor near the pile's centre spread over more than one thickness
    c = np.median(low[:, [0, 2]], axis=0)
    near = x[np.linalg.norm(x[:, [0, 2]] - c, axis=1) < 0.05]
    assert np.ptp(near[:, 1]) > 2 * model.thickness, "no fold: a single layer on the floor"


def test_twist_without_intersections():
    """A 0.8 m cloth (10 x 10) between two edges turning in opposite directions at 0.25 turns/s
    (edges 0.2 m closer by the end): 40 frames is a 120-degree relative turn, folds pressed
    together. Hardness check: the cloth's middle line has turned."""
    n, size, height = 10, 0.8, 1.0
    b = ClothBuilder(bend_stiffness=2e-5)
    ids = b.add_grid(n, n, size, size, origin=(-size / 2, height, -size / 2))
    left, right = ids[:, 0], ids[:, -1]
    slots = np.concatenate([b.attach(left), b.attach(right)])
    model = b.finalize()
    solver = XPBDSolver(model)
    control = model.control()
    rest = model.rest_points_np.astype(np.float64)

    def pose(p, side, t):
        a = side * 0.5 * np.pi * t
        c, s = np.cos(a), np.sin(a)
        y, z = p[:, 1] - height, p[:, 2]
        return np.stack([p[:, 0] - side * min(0.15 * t, 0.1), height + c * y - s * z, s * y + c * z], 1)

    def drive(f, t):
        tg = np.concatenate([pose(rest[left], -1.0, t), pose(rest[right], 1.0, t)])
        out = np.empty_like(tg)
        out[slots] = tg
        control.set_targets(out)

    counts, st = _run(model, solver, 40, drive, control)
    _assert_free(counts, solver)
    x = st.points.numpy()
    assert np.ptp(x[ids[:, -1], 1]) > 0.3  # the turned edge spans over 0.3 m in height


def test_box_edge_without_intersections():
    """A 0.3 m x 1.0 m strip (6 x 20) laid over a 12-triangle box, its hanging end pulled down at
    0.6 m/s over the sharp edge. Hardness check: the strip is in contact with the edge (some
    vertex within 2 thicknesses + 2 cm of the top edge line)."""
    half = 0.3
    b = ClothBuilder(bend_stiffness=2e-5)
    ids = b.add_grid(20, 6, 1.0, 0.3, origin=(0.0, 0.0, -0.15))
    end = ids[:, -1]
    slots = b.attach(end)
    model = b.finalize()
    box = trimesh.creation.box(extents=(2 * half,) * 3)
    col = ColliderSet()
    col.add_plane((0, 1, 0), 0.0)
    col.add_mesh(np.asarray(box.vertices) + [0, half, 0], np.asarray(box.faces), friction=0.5)
    solver = XPBDSolver(model, col)
    gap = 1.5 * model.thickness
    rest = model.rest_points_np.astype(np.float64)
    s = rest[:, 0]
    on_top = 13 / 19  # a vertex column on the box's corner (a triangle across it would cut the edge)
    top = np.stack([half + gap - (on_top - s), np.full_like(s, 2 * half + gap), rest[:, 2]], 1)
    side = np.stack([np.full_like(s, half + gap), 2 * half + gap - (s - on_top), rest[:, 2]], 1)
    x0 = np.where((s < on_top)[:, None], top, side)
    state = model.state()
    state.set_points(x0)
    control = model.control()
    start = x0[end]

    def drive(f, t):
        tg = np.empty_like(start)
        tg[slots] = start - [0.0, min(0.6 * t, start[0, 1] - 0.03), 0.0]
        control.set_targets(tg)

    counts, st = _run(model, solver, 30, drive, control, state)
    _assert_free(counts, solver)
    x = st.points.numpy()
    d_edge = np.hypot(x[:, 0] - half, x[:, 1] - 2 * half)
    assert d_edge.min() < 2 * model.thickness + 0.02, d_edge.min()


def test_cape_on_walking_figure_without_intersections():
    """The cape (12 x 16) on the walking figure (skinned capsule mesh, arms swinging): 80 frames.
    Hardness check: the cape touches the body (some vertex within 2 cm of a body capsule at some
    frame)."""
    fig = WalkingFigure(speed=1.0)
    b = ClothBuilder(density=0.25, bend_stiffness=3e-5)
    ids = b.add_grid(12, 16, 0.7, 0.95, origin=(-0.35, 1.47, -0.19), u_axis=(1, 0, 0), v_axis=(0, -1, -0.12))
    slots = b.attach(ids[0])
    model = b.finalize()
    top = model.rest_points_np[ids[0]].astype(np.float64)
    col = ColliderSet()
    col.add_plane((0, 1, 0), 0.0)
    body = col.add_mesh(fig.points(0.0), fig.faces, friction=0.3)
    solver = XPBDSolver(model, col)
    control = model.control()

    def drive(f, t):
        m = fig.joint_transform("torso", t)
        tg = np.empty_like(top)
        tg[slots] = top @ m[:3, :3].T + m[:3, 3]
        control.set_targets(tg)
        body.set_points(fig.points(t))

    gaps = []

    def body_gap(f, t, st):
        x = st.points.numpy().astype(np.float64)
        g = np.inf
        for p0, p1, r in fig.capsules(t):
            d = p1 - p0
            u = np.clip((x - p0) @ d / max(d @ d, 1e-12), 0.0, 1.0)
            g = min(g, float((np.linalg.norm(x - (p0 + u[:, None] * d), axis=1) - r).min()))
        gaps.append(g)

    counts, st = _run(model, solver, 80, drive, control, after_step=body_gap)
    _assert_free(counts, solver)
    assert min(gaps) < 0.02, min(gaps)


def test_fast_drop_onto_two_triangle_ground():
    """A 16 x 16 cloth thrown at 4 m/s onto a 6 m ground of 2 triangles (an open mesh collider),
    with either winding: it stays on top (the winding number of an open sheet is only +-1/2, so
    a solid test let it through)."""
    quad = np.array([[-3, 0, -3], [3, 0, -3], [3, 0, 3], [-3, 0, 3]], float)
    for faces in (np.array([[0, 2, 1], [0, 3, 2]]), np.array([[0, 1, 2], [0, 2, 3]])):
        b = ClothBuilder()
        b.add_grid(16, 16, 1.0, 1.0, origin=(0.5, 0.3, 0.5))
        model = b.finalize()
        col = ColliderSet()
        col.add_mesh(quad, faces)
        assert not col.meshes[0].closed
        solver = XPBDSolver(model, col)
        state = model.state()
        state.set_points(model.rest_points_np, np.tile([0.0, -4.0, 0.0], (model.particle_count, 1)))
        counts, st = _run(model, solver, 40, state=state)
        _assert_free(counts, solver)
        # resting a thickness above the ground (5 % allowance for the contact averaging)
        assert st.points.numpy()[:, 1].min() > 0.95 * model.thickness, faces[0]


def _shipped_cloth_counts(name: str, frames: int, jitter_seed: int | None = None):
    """Cloth-cloth and cloth-collider pairs after each of the first `frames` frames of a shipped
    scene's simulation, stepped as ``warpshade run`` steps it (no driven objects in these scenes),
    and the solver's figures. With `jitter_seed`, every cloth coordinate first moves by -1, 0 or
    +1 ulp at random: the same scene as a user's file might round it."""
    import os

    from warpshade.pipeline.cloth import ClothSimulation
    from warpshade.usd.scene_io import read_scene

    root = SHIPPED
    scene = read_scene(os.path.join(root, f"{name}.usda"))
    if jitter_seed is not None:
        for o in scene.objects:
            if o.kind == "cloth":
                o.mesh.points[...] = ulp_jitter(o.mesh.points, jitter_seed)
    sims = ClothSimulation(scene, "cpu")
    counter = IntersectionCounter(sims.model.faces)
    counts = []
    for f in range(frames):
        sims.advance(f, {})
        x = sims.state.points
        counts.append(counter.self_pairs(x)[0] + counter.collider_pairs(x, sims.solver.colliders)[0])
    return counts, sims


def test_default_scene_drape_without_intersections():
    """The default scene's cloth over 60 frames: it lands on the sphere and folds (the first fold
    one strip of triangles wide crossed itself at frame 40 when only edges bent by 0.5 rad had
    edge-edge contact); 0 pairs after every frame."""
    counts, sims = _shipped_cloth_counts("default", 60)
    _assert_free(counts, sims.solver)
    assert sims.solver.stats()["edge_contact_candidates"] > 0  # folded: crease edges in contact


def test_cloth_table_drape_without_intersections():
    """usd_scenes/cloth_table (a table exported with per-face vertices, so its rims are sharp only
    once welded) over 40 frames: the cloth hits the table and slides over its edge; 0 pairs after
    every frame and the cloth not torn by the table's edges (p99 strain below 20 %; measured
    12.9 % at worst over the full 180 frames, 79 % when the table's rims and flat inner edges
    pushed hanging cloth up onto the top)."""
    counts, sims = _shipped_cloth_counts("cloth_table", 40)
    _assert_free(counts, sims.solver)
    x = sims.state.points.numpy()
    assert x[:, 1].min() < 0.6  # part of it hangs below the table top (0.75 m)
    assert np.percentile(sims.model.edge_strain(x), 99) < 0.20


def test_stiff_default_drape_stays_unstretched_with_held_contact_interval(monkeypatch):
    """usd_scenes/default over 60 frames with the stiff solve of issue 19's strain work
    (``limit_sliding``, ``limit_every_sweep``, 12 stretch sweeps) and ``held_contact_interval=1``:
    0 pairs after every frame and the p99 edge strain at the end below 5 % (measured 0.8 %, and
    0.8-1.7 % with the cloth jittered by an ulp, seeds 0-3; at the default interval 88 % (57-104 %
    jittered): the guard holds the folding skirt from frame 31 on and the region it reverts grows
    every step, stretching the edges to the free cloth). Its longest hold is left unasserted: 2
    here but 2-23 steps jittered (27-34 at the default interval)."""
    import functools

    monkeypatch.setattr(XPBDSolver, "LIMIT_SLIDING", True)
    monkeypatch.setattr(XPBDSolver, "LIMIT_EVERY_SWEEP", True)
    monkeypatch.setattr(XPBDSolver, "HELD_CONTACT_INTERVAL", 1)
    init = XPBDSolver.__init__

    @functools.wraps(init)
    def stiff(self, *args, **kwargs):
        init(self, *args, **{**kwargs, "stretch_sweeps": 12})

    monkeypatch.setattr(XPBDSolver, "__init__", stiff)
    counts, sims = _shipped_cloth_counts("default", 60)
    _assert_free(counts, sims.solver)
    assert sims.solver.knobs()["stretch_sweeps"] == 12 and sims.solver.held_contact_interval == 1
    assert sims.solver.stats()["guard_steps"] > 0  # the guard acted: the held step's detection ran
    assert np.percentile(sims.model.edge_strain(sims.state.points.numpy()), 99) < 0.05


def test_cloth_table_rounded_differently_stays_free_of_intersections(monkeypatch):
    """The same scene with its cloth coordinates moved by an ulp (seed 2), and the table's box
    corners left out of the corner contacts (``CORNER_ANGLE_SUM`` 180, as before branch
    ``boxdrop``; with them this run's longest hold is 3 steps and no crossing forms): the contacts
    then keep making an edge-edge crossing in a fold near the floor from frame 87 on. The guard
    used to release vertices it had held for 30 steps, and the crossing stayed for the remaining
    92 of 179 frames (seeds 2 and 3 of 0..3); it now holds them until a step frees them (here for
    at most 136 consecutive steps, 15 vertices at the end of the full run)."""
    from warpshade.sim import colliders

    monkeypatch.setattr(colliders.sharp_corners, "__defaults__", (180.0,))
    counts, sims = _shipped_cloth_counts("cloth_table", 100, jitter_seed=2)
    assert not sims.solver.colliders.corner_count
    _assert_free(counts, sims.solver)
    assert sims.solver.stats()["guard_longest_hold"] > 30, sims.solver.stats()


@pytest.mark.parametrize("push_off", [True, False])
def test_attached_edges_that_drive_cloth_into_cloth_get_it_pushed_off(push_off, monkeypatch, tmp_path):
    """sims/twist (120 frames) with its cloth coordinates moved by an ulp (seed 3): at one step the
    turning attached edges press a fold into the cloth beside it, which no revert of free vertices
    undoes. The guard then finds the self-contacts afresh and runs up to PUSH_OFF_PASSES contact
    passes, which free it; without them 10 pairs stood in 4 frames (measured), which shows the check
    can fail."""
    twist = _sim_module("twist")
    finalize = ClothBuilder.finalize

    def jittered(builder, *args, **kwargs):
        for pc in builder._pieces:
            pc.points = ulp_jitter(pc.points, 3).astype(np.float64)
        return finalize(builder, *args, **kwargs)

    monkeypatch.setattr(ClothBuilder, "finalize", jittered)
    if not push_off:
        monkeypatch.setattr(XPBDSolver, "_push_off_contacts", lambda self, x, v, dt: False)
    step, counters, counts = XPBDSolver.step, {}, []

    def counted(solver, state_in, state_out, dt, control=None):
        step(solver, state_in, state_out, dt, control)
        c = counters.setdefault(id(solver), IntersectionCounter(solver.model.faces))
        counts.append(c.self_pairs(state_out.points)[0])

    monkeypatch.setattr(XPBDSolver, "step", counted)
    with contextlib.redirect_stdout(io.StringIO()):
        twist.main(["--out", str(tmp_path / "twist.usda"), "--no-shade"])
    assert len(counts) == 120
    if push_off:
        assert not any(counts), [(f, n) for f, n in enumerate(counts) if n][:5]
    else:
        assert any(counts)


def test_pile_script_without_intersections_for_one_second(tmp_path):
    """sims/pile.py at its own resolution (10 x 80) for 60 frames: the strip reaches the floor and
    starts to fold; 0 pairs after every frame (when the guard let a vertex go after 3 reverted
    steps, 5 pairs got through at frame 50, on free vertices of the layers on the floor)."""
    pile = _sim_module("pile")
    with contextlib.redirect_stdout(io.StringIO()):
        res = pile.main(["--frames", "60", "--no-shade", "--out", str(tmp_path / "pile.usda")])
    assert res["max_intersections"] == 0, res
    assert res["min_height"] < 0.05  # on the floor


def test_unresolved_guard_step_stands_as_the_contacts_left_it():
    """A flat cloth that a box already cuts through at the start of the step: no revert can
    remove that intersection (the box is kinematic), so the guard's step must be the plain step,
    bit for bit the same as with the guard off, and counted as unresolved (it used to keep the
    cloth's vertices near the box sent back to their start: in sims/table_fold.py, where the
    table slides out from under the cloth, that held cloth back while the table dragged the rest
    on, to 3961 % p99 strain)."""
    runs = {}
    for guard in (True, False):
        b = ClothBuilder()
        b.add_grid(10, 10, 0.5, 0.5, origin=(-0.25, 0.3, -0.25))
        model = b.finalize()
        col = ColliderSet()
        col.add_box((0.0, 0.3, 0.0), (0.1, 0.1, 0.1))
        solver = XPBDSolver(model, col, gravity=(0.0, -9.81, 0.0), guard=guard)
        st = model.state()
        solver.step(st, st, 1.0 / FPS)
        runs[guard] = (st.points.numpy(), solver.stats(), IntersectionCounter(model.faces).collider_pairs(st.points, col)[0])
    (x_on, stats, pairs), (x_off, _, _) = runs[True], runs[False]
    assert pairs > 0  # the box still cuts the cloth: the step could not be made free
    assert stats["guard_unresolved"] == 1, stats
    np.testing.assert_array_equal(x_on, x_off)


def test_sliding_table_corner_leaves_no_intersection():
    """sims/table_fold.py's scene (40 x 40 cloth on a table that slides away at 1.5 m/s from
    frame 72) over its first 80 frames: at frame 78 the table's top corner, moving 25 mm a frame,
    is driven into the cloth hanging over it faster than the substeps' contacts push the cloth
    off, and neither sending vertices back (the table moved on) nor the plain step removes that
    (2 cloth-table pairs, the corner 1.6 mm through); the guard's extra edge and corner passes
    must. 0 pairs after every frame and no unresolved guard step."""
    table_fold = _sim_module("table_fold")
    b = ClothBuilder(bend_stiffness=2e-5)
    b.add_grid(40, 40, 1.4, 1.4, origin=(-0.6, 1.0, -0.7))
    model = b.finalize()
    col = ColliderSet()
    col.add_plane((0.0, 1.0, 0.0), 0.0, friction=0.7)
    box = col.add_box(table_fold.table_center(0.0), table_fold.HALF, friction=0.6)
    solver = XPBDSolver(model, col)
    counts, st = _run(model, solver, 80, lambda f, t: col.set_box(box, table_fold.table_center(t)))
    _assert_free(counts, solver)
    assert solver.stats()["guard_unresolved"] == 0, solver.stats()
    x = st.points.numpy()
    assert np.abs(x[:, 0] - table_fold.table_center(80 / FPS)[0]).min() < 0.5  # the cloth is on the table


def _cone_drape(mesh_cone: bool):
    """A short, coarse version of a DCC user's scene (a cloth falling onto a table with a cone
    standing on it, Z up): a 1.2 m x 1.0 m cloth (12 x 12 vertices) pinned at two corners, 0.23 m
    above the apex of a cone (radius 0.12 m, 0.30 m high) on a flat box table; 1/30 s frames of
    8 substeps."""
    b = ClothBuilder()
    n = 12
    x, y = np.meshgrid(np.linspace(-0.6, 0.6, n), np.linspace(-0.5, 0.5, n))
    pts = np.stack([x.ravel(), y.ravel(), np.full(x.size, 0.95)], 1)
    quads = [(j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i) for j in range(n - 1) for i in range(n - 1)]
    faces = np.array([t for a, b_, c, d in quads for t in ((a, b_, c), (a, c, d))])
    ids = b.add_mesh(pts, faces)
    b.pin([ids[0], ids[n - 1]])
    model = b.finalize()
    col = ColliderSet()
    col.add_plane((0.0, 0.0, 1.0), 0.0)
    col.add_box((0.0, 0.0, 0.40), (0.4, 0.3, 0.02))
    base, apex = np.array([0.10, 0.0, 0.42]), np.array([0.10, 0.0, 0.72])
    if mesh_cone:
        cone = trimesh.creation.cone(0.12, 0.30, sections=32)
        col.add_mesh(np.asarray(cone.vertices) + base, np.asarray(cone.faces))
    else:
        col.add_cone(base, apex, 0.12)
    return model, XPBDSolver(model, col, substeps=8, gravity=(0.0, 0.0, -9.81)), apex


@pytest.mark.parametrize("mesh_cone", [False, True], ids=["analytic", "mesh"])
def test_cloth_rests_on_a_cone_apex(mesh_cone):
    """A cloth falls onto a cone's apex (an analytic cone, and a triangulated one as a mesh
    collider, its apex a sharp vertex) and settles on it: the apex pokes into the inside of a
    triangle, and into the tent's edges and vertices, where no cloth vertex nor cloth edge meets
    the cone. 0 intersecting pairs after every frame; no stretch from the intersection guard
    holding cloth back (at most 3 guard steps, none unresolved, the 99th-percentile edge strain
    under 25 % on every frame; without corner contacts for the apex: 23 guard steps, strain 39 %
    (analytic) and 73 % (mesh), the guard holding the tent over the apex while the cloth around
    falls on); and the cloth rests on the apex at the end: its point closest to the apex within 2
    thicknesses of it and above it."""
    model, solver, apex = _cone_drape(mesh_cone)
    state = model.state()
    counter = IntersectionCounter(model.faces)
    counts, p99 = [], []
    for _ in range(30):
        solver.step(state, state, 1.0 / 30.0)
        counts.append(counter.self_pairs(state.points)[0] + counter.collider_pairs(state.points, solver.colliders)[0])
        p99.append(float(np.percentile(model.edge_strain(state.points.numpy()), 99)))
    _assert_free(counts, solver)
    stats = solver.stats()
    assert stats["guard_unresolved"] == 0 and stats["guard_steps"] <= 3, stats
    assert max(p99) < 0.25, p99
    x = state.points.numpy().astype(np.float64)
    tri = x[model.faces]
    q = trimesh.triangles.closest_point(tri, np.repeat(apex[None], len(tri), 0))
    d = np.linalg.norm(q - apex, axis=1)
    assert d.min() < 2 * model.thickness, d.min()
    assert q[d.argmin()][2] > apex[2], q[d.argmin()] - apex  # the cloth is over the apex, not under it


@pytest.mark.parametrize("ball, n", [("sphere", 17), ("mesh", 21)])
def test_ball_forced_through_pinned_cloth(tmp_path, ball, n):
    """Issue 19's hammock at n x n vertices (sims/hammock.py's stage, the ball's translate
    time-sampled from y = 20 cm up to y = 95 cm at frame 18, 4.2 cm a frame as in the issue, and
    kept there): a kinematic ball pushed up through cloth pinned on two sides, as a Sphere (an
    analytic moving sphere) and as a Mesh of the same tessellation (a moving mesh collider). The
    colliders win over the cloth's constraints: 0 cloth-ball intersecting pairs at the end of
    every frame (exact count), and the cloth is still over the ball at the end (its highest vertex
    above the ball's top; before the move caps the cloth snapped back through the ball, ending
    under it). The mesh ball at 21 x 21 needs all three of its pieces: without
    ``limit_mesh_motion`` or with it capping only the depth a move reaches, the cloth ends under
    the ball; without ``collide_mesh_faces`` or the guard's retry from the start of the step,
    pairs are left at frame ends. The cloth stretches instead, far past STRAIN_WARNING, and the
    run warns once, naming the cloth and the pins as the likely cause."""
    from warpshade.pipeline.cloth import STRAIN_WARNING, ClothSimulation
    from warpshade.scene import SceneWarning
    from warpshade.usd import read_scene

    path = str(tmp_path / "hammock.usda")
    _sim_module("hammock").write_stage(path, n, ball, 24, ((0, 20.0), (18, 95.0), (23, 95.0)))
    scene = read_scene(path)
    ball_obj = next(o for o in scene.objects if o.name.endswith("Ball"))
    with pytest.warns(SceneWarning) as caught:
        sim = ClothSimulation(scene)
        assert (ball_obj.name in dict(sim.moving_colliders)) == (ball == "mesh")  # the collider kind meant
        counter = IntersectionCounter(sim.model.faces)
        counts, strain = [], []
        for f in range(scene.frames):
            geo = {ball_obj.name: np.asarray(ball_obj.params["points_at"](f), np.float32)}
            sim.advance(f, geo)
            counts.append(counter.collider_pairs(sim.state.points, sim.solver.colliders)[0])
            strain.append(float(sim.model.edge_strain(sim.state.points.numpy()).max()))
    assert counts == [0] * scene.frames, counts
    top = sim.state.points.numpy()[:, 1].max() / 0.01  # [cm]
    assert top > 95.0 + 15.0, top  # over the ball's top, not under it
    assert max(strain) > STRAIN_WARNING, max(strain)  # the conflict happened
    stretch = [w for w in caught if "cannot follow" in str(w.message)]
    assert len(stretch) == 1, [str(w.message) for w in caught]
    message = str(stretch[0].message)
    assert "/Root/Hammock" in message and "pinned" in message, message


def _hammock_with(tmp_path, define, n=33, frames=37, keys=None):
    """Run sims/hammock.py's stage (n x n, ``frames`` frames, the ball's translate keys, by default
    the script's) with its ball replaced by the prim ``define(stage, "/Root/Ball")`` returns (given
    the same time-sampled translate and the collision API); the intersecting cloth-collider pairs
    at each frame end, the cloth's highest point at the end [cm] and the simulation."""
    from pxr import Gf, Usd, UsdPhysics

    from warpshade.pipeline.cloth import ClothSimulation
    from warpshade.usd import read_scene

    hammock = _sim_module("hammock")
    keys = hammock.BALL_PATH if keys is None else keys
    path = str(tmp_path / "hammock_with.usda")
    hammock.write_stage(path, n, "sphere", frames, keys)
    stage = Usd.Stage.Open(path)
    stage.RemovePrim("/Root/Ball")
    prim = define(stage, "/Root/Ball")
    op = prim.AddTranslateOp()
    for t, y in keys:
        op.Set(Gf.Vec3d(0, y, 0), t)
    UsdPhysics.CollisionAPI.Apply(prim.GetPrim())
    stage.GetRootLayer().Save()
    scene = read_scene(path)
    obj = next(o for o in scene.objects if o.name.endswith("Ball"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        sim = ClothSimulation(scene)
        assert obj.name in dict(sim.moving_colliders)
        counter = IntersectionCounter(sim.model.faces)
        counts = []
        for f in range(scene.frames):
            sim.advance(f, {obj.name: np.asarray(obj.params["points_at"](f), np.float32)})
            counts.append(counter.collider_pairs(sim.state.points, sim.solver.colliders)[0])
    return counts, sim.state.points.numpy()[:, 1].max() / 0.01, sim


def test_mesh_cube_forced_through_pinned_cloth(tmp_path):
    """The hammock (sims/hammock.py's stage and path, 33 x 33) with its ball replaced by a 30 cm
    ``Cube`` with the same time-sampled translate, which collides as a moving closed mesh: the
    cloth stays over it with 0 intersecting pairs at every frame end. Cloth triangles are pushed
    off a closed mesh's sharp edges only while the mesh stands still
    (``MeshCollider.moving``): pushed off the moving cube's edges too, the guard could not free
    the steps from frame 29 on (212-307 pairs at frames 30-36, the cloth's top 0.2 cm under the
    cube's)."""
    from pxr import UsdGeom

    radius = _sim_module("hammock").RADIUS

    def cube(stage, name):
        prim = UsdGeom.Cube.Define(stage, name)
        prim.GetSizeAttr().Set(2 * radius)
        return prim

    counts, top, _ = _hammock_with(tmp_path, cube)
    assert counts == [0] * len(counts), counts
    assert top > 95.0 + radius, top


def test_open_mesh_dome_forced_through_pinned_cloth(tmp_path):
    """The hammock (sims/hammock.py's stage, 13 x 13, the ball's path of
    :func:`test_ball_forced_through_pinned_cloth`) with its ball replaced by an *open* dome: the
    ball's tessellation without its lower part (faces whose centre is above -0.2 of the radius),
    a moving open mesh collider, which has no inside. The cloth stays over it: 0 intersecting pairs
    at every frame end (exact count) and its highest vertex above the dome's top. On main before
    the open-mesh fixes the cloth went through (up to 133 pairs from frame 6, its top at 90.6 cm
    under the dome's 110): a vertex's side was taken against the surface's current pose, which had
    moved past it (without that fix: the same 133 pairs), and the guard's last resort pushed cloth
    triangles out of closed meshes only (without that: 165 pairs at frame 13)."""
    from pxr import Gf, UsdGeom

    from warpshade.geometry.shapes import sphere_shape

    radius = _sim_module("hammock").RADIUS
    verts, faces = sphere_shape(radius, 3)
    verts, faces = np.asarray(verts), np.asarray(faces)
    faces = faces[verts[faces].mean(1)[:, 1] > -0.2 * radius]

    def dome(stage, name):
        prim = UsdGeom.Mesh.Define(stage, name)
        prim.GetPointsAttr().Set([Gf.Vec3f(*map(float, p)) for p in verts])
        prim.GetFaceVertexCountsAttr().Set([3] * len(faces))
        prim.GetFaceVertexIndicesAttr().Set([int(i) for i in faces.reshape(-1)])
        return prim

    counts, top, sim = _hammock_with(tmp_path, dome, 13, 24, ((0, 20.0), (18, 95.0), (23, 95.0)))
    assert not sim.solver.colliders.meshes[0].closed  # the collider kind meant: an open mesh
    assert counts == [0] * len(counts), counts
    assert top > 95.0 + radius, top  # over the dome's top, not under it


def _quat(axis, degrees):
    a = np.asarray(axis, float) / np.linalg.norm(axis)
    h = np.radians(degrees) / 2
    return (*(a * np.sin(h)), np.cos(h))


_R = 0.15  # [m] the analytic solids' radius / half extent (the hammock ball's)
_SIDE = 1.5 * _R
_CORNER_UP = _quat(np.cross((1, 1, 1), (0, 1, 0)), np.degrees(np.arccos(1 / np.sqrt(3))))  # the diagonal (1, 1, 1) up
# name: (add shape at height y, move it to height y); each solid's highest point is at y + its top
_FORCED = {
    "box": (lambda c, y: c.add_box((0, y, 0), (_R,) * 3), lambda c, i, y: c.set_box(i, (0, y, 0)), _R),
    "box_edge_up": (lambda c, y: c.add_box((0, y, 0), (_R,) * 3, _quat((0, 0, 1), 45)),
                    lambda c, i, y: c.set_box(i, (0, y, 0)), _R * np.sqrt(2)),
    "box_edge_up_z": (lambda c, y: c.add_box((0, y, 0), (_R,) * 3, _quat((1, 0, 0), 45)),
                      lambda c, i, y: c.set_box(i, (0, y, 0)), _R * np.sqrt(2)),
    "box_corner_up": (lambda c, y: c.add_box((0, y, 0), (_R,) * 3, _CORNER_UP),
                      lambda c, i, y: c.set_box(i, (0, y, 0)), _R * np.sqrt(3)),
    "cylinder_along_axis": (lambda c, y: c.add_cylinder((0, y - _R, 0), (0, y + _R, 0), _R),
                            lambda c, i, y: c.set_cylinder(i, (0, y - _R, 0), (0, y + _R, 0)), _R),
    "cylinder_sideways": (lambda c, y: c.add_cylinder((0, y, -_SIDE), (0, y, _SIDE), _R),
                          lambda c, i, y: c.set_cylinder(i, (0, y, -_SIDE), (0, y, _SIDE)), _R),
    "cylinder_sideways_across": (lambda c, y: c.add_cylinder((-_SIDE, y, 0), (_SIDE, y, 0), _R),
                                 lambda c, i, y: c.set_cylinder(i, (-_SIDE, y, 0), (_SIDE, y, 0)), _R),
    "cone_tip_first": (lambda c, y: c.add_cone((0, y - _R, 0), (0, y + _R, 0), _R),
                       lambda c, i, y: c.set_cone(i, (0, y - _R, 0), (0, y + _R, 0)), _R),
    "cone_base_first": (lambda c, y: c.add_cone((0, y + _R, 0), (0, y - _R, 0), _R),
                        lambda c, i, y: c.set_cone(i, (0, y + _R, 0), (0, y - _R, 0)), _R),
    "cone_sideways": (lambda c, y: c.add_cone((-_R, y, 0), (_R, y, 0), _R),
                      lambda c, i, y: c.set_cone(i, (-_R, y, 0), (_R, y, 0)), _R),
    "capsule": (lambda c, y: c.add_capsule((0, y - _R, 0), (0, y + _R, 0), _R),
                lambda c, i, y: c.set_capsule(i, (0, y - _R, 0), (0, y + _R, 0)), 2 * _R),
}
_TILT = _quat((1, 0.3, 0.5), 20)
_TILT_HALF = (_R, 0.5 * _R, 1.5 * _R)


def _tilted_box_top() -> float:
    """The highest point of the tilted box over its centre: its corners rotated by _TILT."""
    x, y, z, w = _TILT
    # the rotation matrix's middle row (a vector's y after the rotation)
    row = np.array([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)])
    return float(np.abs(row) @ np.asarray(_TILT_HALF))


_FORCED_33 = {  # the cases that the guard's self-contact push-off after its collider passes fixed at 33 x 33
    "box_edge_up": _FORCED["box_edge_up"],
    "box_edge_up_z": _FORCED["box_edge_up_z"],
    "box_tilted": (lambda c, y: c.add_box((0, y, 0), _TILT_HALF, _TILT), lambda c, i, y: c.set_box(i, (0, y, 0)),
                   _tilted_box_top()),
}


@pytest.mark.parametrize("shape", [pytest.param(k, marks=pytest.mark.xfail(
    strict=True, reason="the corner-first box still leaves pairs at 13 x 13 (frames 16-19: 2 cloth-box pairs and "
    "5 cloth-cloth pairs the guard's collider passes made; history.md)")) if k == "box_corner_up" else k
    for k in sorted(_FORCED)])
def test_analytic_collider_forced_through_pinned_cloth(shape):
    """Issue 19's hammock with analytic moving colliders (``ColliderSet.set_box/set_cylinder/
    set_cone/set_capsule``, as :func:`test_ball_forced_through_pinned_cloth` does with a sphere): a
    1 m cloth of 13 x 13 vertices at y = 60 cm pinned along x = +-50 cm over a floor, a 30 cm solid
    driven kinematically from y = 20 cm up to 95 cm at frame 18 (4.2 cm a frame at 24 fps, 8
    substeps) and kept there. 0 cloth-collider intersecting pairs at the end of every frame (exact
    count) and the cloth over the solid at the end (its highest vertex above the solid's highest
    point: the cloth did not pass through between frame ends). On main before
    ``limit_shape_motion`` and ``collide_shape_faces`` every case but the axis-aligned and tilted
    boxes and the capsule failed: the cylinders, the cone base or side first and the box corner
    first left 12-25 pairs (frames 8-14 on), the cone tip first and the boxes edge first went
    through (the cloth's top at 60-80 cm). At 17 x 17 and more some still fail (history.md,
    "Analytic colliders forced through pinned cloth")."""
    _forced_through(_FORCED[shape], 13)


@pytest.mark.parametrize("shape", sorted(_FORCED_33))
def test_analytic_collider_forced_through_pinned_cloth_33(shape):
    """:func:`test_analytic_collider_forced_through_pinned_cloth` at 33 x 33 vertices (the hammock's
    grid) for the cases that failed there until the guard ran its self-contact push-off on the state
    its collider passes left (issue 19, branch shapegrid): on main before it, 43-55 cloth-box pairs at
    frame ends from frames 12-15 (the edge-up box about x went through, its top at 60 cm). At each
    one's first unresolved step the collider passes had left 0 cloth-box pairs and 1-4 new
    cloth-cloth pairs, and the guard kept the step as the contacts left it (39-60 cloth-box pairs)."""
    _forced_through(_FORCED_33[shape], 33)


@pytest.mark.parametrize("shape,n,pairs", [("cone_sideways", 17, True), ("cone_base_first", 21, True),
                                           ("cone_base_first", 17, False), ("cone_base_first", 33, False)])
def test_analytic_cone_forced_through_pinned_cloth_rim(shape, n, pairs):
    """:func:`test_analytic_collider_forced_through_pinned_cloth` with a cone on finer grids, the cloth
    held over its flat base (issue 19, branch conerim). On main before the substeps' cone face pass
    (``ColliderSet.collide_edges`` given ``x_start``) all four went through (the cloth's top at
    60-61 cm at the end): the cloth, held over the base by stretched edges with the rim cutting its
    triangles (4-10 pairs at substep ends, no vertex inside), slid off round the rim within one step,
    every vertex path outside the solid, and the step ended with 0 pairs. With the pass the cloth stays
    over the solid in all four (top 124-163 cm); the base-first cone at 17 and 33 still ends some frames
    with 10-17 pairs from guard steps left unresolved (the boxes' mechanism, history.md), so there
    only the top is checked (``pairs`` False)."""
    _forced_through(_FORCED[shape], n, pairs)


def _forced_through(case, n: int, pairs: bool = True) -> None:
    """Run the forced hammock with ``case`` = (add, put, top offset) at n x n vertices, 24 frames, and
    check it: 0 cloth-collider pairs at every frame end (unless ``pairs`` is False), the cloth's top
    over the solid's."""
    frames = 24
    keys = ([0, 18], [0.20, 0.95])
    b = ClothBuilder()
    b.add_grid(n, n, 1.0, 1.0, origin=(-0.5, 0.6, -0.5))
    pts = b.finalize().state().points.numpy()
    b.pin(np.flatnonzero(np.abs(np.abs(pts[:, 0]) - 0.5) < 1e-6))
    model = b.finalize()
    col = ColliderSet()
    col.add_plane((0, 1, 0), 0.0)
    add, put, top_offset = case
    i = add(col, keys[1][0])
    solver = XPBDSolver(model, col, substeps=8)
    state = model.state()
    counter = IntersectionCounter(model.faces)
    counts = []
    for f in range(frames):
        put(col, i, float(np.interp(f + 1, *keys)))
        solver.step(state, state, 1.0 / 24.0)
        counts.append(counter.collider_pairs(state.points, col)[0])
    if pairs:
        _assert_free(counts, solver)
    top = float(state.points.numpy()[:, 1].max())
    assert top > keys[1][1] + top_offset, (top, keys[1][1] + top_offset)  # over the solid, not under it
