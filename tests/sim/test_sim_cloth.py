"""XPBD cloth: accuracy, energy, contacts, self-collision, extremes and bad input."""

from __future__ import annotations

import numpy as np
import pytest
import warp as wp

from warpshade.geometry import MeshError
from warpshade.sim import ClothBuilder, ColliderSet, SimulationError, XPBDSolver
from warpshade.sim.oracle import dihedral_angle_np, point_triangle_distance_np

from conftest import warp_asset

DT = 1.0 / 60.0


def _edge_strain(model, x):
    e = model.edges_np
    return np.linalg.norm(x[e[:, 0]] - x[e[:, 1]], axis=1) / model.edge_rest_length.numpy() - 1.0


def _run(solver, state, frames, control=None, each=None):
    for f in range(frames):
        solver.step(state, state, DT, control)
        if each is not None:
            each(f, state.points.numpy())
    return state.points.numpy()


# -- kernels against references ----------------------------------------------------------------


def test_dihedral_angle_kernel_matches_numpy(rng):
    from warpshade.sim.kernels import dihedral_angle

    @wp.kernel
    def eval_dihedral(x: wp.array2d[wp.vec3], out: wp.array[float]):
        i = wp.tid()
        out[i] = dihedral_angle(x[i, 0], x[i, 1], x[i, 2], x[i, 3])

    x = rng.normal(size=(64, 4, 3)).astype(np.float32)
    out = wp.zeros(64, dtype=float)
    wp.launch(eval_dihedral, dim=64, inputs=[wp.array(x, dtype=wp.vec3)], outputs=[out])
    ref = dihedral_angle_np(x[:, 0], x[:, 1], x[:, 2], x[:, 3])
    np.testing.assert_allclose(out.numpy(), ref, atol=2e-5)
    # analytic: wing folded by 90 degrees about the x axis
    flat = dihedral_angle_np([0, 0, 1], [0, 0, -1], [0, 0, 0], [1, 0, 0])
    folded = dihedral_angle_np([0, 0, 1], [0, 1, 0], [0, 0, 0], [1, 0, 0])
    assert abs(flat[0]) < 1e-12 and abs(abs(folded[0]) - np.pi / 2) < 1e-12


def test_dihedral_gradients_match_finite_differences(rng):
    from warpshade.sim.kernels import dihedral_gradients

    @wp.kernel
    def eval_gradients(x: wp.array2d[wp.vec3], out: wp.array[wp.mat33]):
        i = wp.tid()
        out[i] = dihedral_gradients(x[i, 0], x[i, 1], x[i, 2], x[i, 3])

    x = rng.normal(size=(16, 4, 3))
    out = wp.zeros(16, dtype=wp.mat33)
    wp.launch(eval_gradients, dim=16, inputs=[wp.array(x.astype(np.float32), dtype=wp.vec3)], outputs=[out])
    g = out.numpy()
    eps = 1e-6
    for h in range(16):
        for k in range(4):
            fd = np.zeros(3)
            for c in range(3):
                xp, xm = x[h].copy(), x[h].copy()
                xp[k, c] += eps
                xm[k, c] -= eps
                fd[c] = (dihedral_angle_np(*xp)[0] - dihedral_angle_np(*xm)[0]) / (2 * eps)
            got = g[h][k] if k < 3 else -g[h].sum(axis=0)
            # float32 kernel vs float64 central differences (O(eps^2) truncation): 1e-3 relative
            np.testing.assert_allclose(got, fd, rtol=1e-3, atol=1e-3 * np.abs(fd).max(),
                                       err_msg=f"hinge {h} vertex {k}: {x[h].tolist()}")


def test_bending_damping_removes_hinge_oscillation():
    """A hinge (edge pinned) kicked into bending keeps oscillating without bending damping
    (XPBD's own dissipation is slow) and settles with it. The angle is measured, not the speed:
    the wings' common rigid rotation about the pinned edge is not bending and is not damped."""
    pts = np.array([[0, 0, 1], [0, 0, -1], [0, 0, 0], [1, 0, 0]], dtype=float)
    faces = np.array([[0, 2, 3], [1, 3, 2]])
    late = []
    for bd in (0.0, 0.05):
        b = ClothBuilder(bend_stiffness=1.0, stretch_stiffness=np.inf, bend_damping=bd)
        b.add_mesh(pts, faces)
        b.pin([2, 3])
        m = b.finalize()
        s = XPBDSolver(m, gravity=(0, 0, 0), air_density=0.0, self_collision=False)
        st = m.state()
        vel = np.zeros_like(pts)
        vel[0, 1] = 1.0
        st.set_points(pts, vel)
        amp = []
        _run(s, st, 120, each=lambda f, x: amp.append(abs(dihedral_angle_np(*x)[0])))
        late.append(max(amp[-20:]))
    # measured: 0.048 rad undamped vs 1e-4 rad damped after 2 s
    assert late[1] < 0.05 * late[0], late


def test_bending_relaxes_a_bent_hinge_to_its_rest_angle():
    """Two triangles, flat at rest, folded by 60 degrees: bending alone must unfold them (a wrong
    gradient sign folds them further, which is how this test once failed)."""
    pts = np.array([[0, 0, 1], [0, 0, -1], [0, 0, 0], [1, 0, 0]], dtype=float)
    faces = np.array([[0, 2, 3], [1, 3, 2]])
    b = ClothBuilder(bend_stiffness=np.inf, stretch_stiffness=np.inf)
    b.add_mesh(pts, faces)
    m = b.finalize()
    s = XPBDSolver(m, gravity=(0, 0, 0), air_density=0.0, self_collision=False)
    st = m.state()
    bent = pts.copy()
    bent[1] = [0, np.sin(np.radians(60)), -np.cos(np.radians(60))]
    st.set_points(bent)
    angles = []
    for _ in range(10):
        s.step(st, st, DT)
        x = st.points.numpy()
        angles.append(abs(dihedral_angle_np(x[0], x[1], x[2], x[3])[0]))
    # rigid hinge (zero compliance): flat within a few steps, up to float32 rounding
    assert angles[-1] < 1e-3, angles


def test_terminal_velocity_of_a_falling_plate_matches_flat_plate_drag():
    """A free horizontal cloth falls flat, so drag = 1/2 rho Cd A v^2 balances m g:
    v_t = sqrt(2 m g / (rho Cd A)) (lift vanishes for a flow normal to the plate)."""
    density, rho, cd = 0.1, 1.2, 0.8
    b = ClothBuilder(density=density)
    b.add_grid(6, 6, 0.5, 0.5, origin=(0, 2, 0))
    m = b.finalize()
    s = XPBDSolver(m, air_density=rho, drag_coefficient=cd, lift_coefficient=0.3, self_collision=False)
    st = m.state()
    _run(s, st, 120)
    v = st.velocities.numpy()[:, 1].mean()
    expect = np.sqrt(2 * density * 9.81 / (rho * cd))
    # the transient decays as exp(-2 g t / v_t): after 2 s it is far below 0.1 %. Velocities come
    # from float32 position differences, resolved to ulp(|x|) / h ~ 1e-4 m/s for |x| < 2 m (the
    # test starts low for that reason: from 10 m up the error exceeds 0.2 %).
    assert -v == pytest.approx(expect, rel=2e-3)



@pytest.mark.parametrize("drag", [0.0, 3.0])
def test_linear_drag_decays_velocity_exponentially(drag):
    """Linear drag alone (no gravity, air or contact): a cloth moving rigidly at v0 keeps its shape
    and its velocity after a step is v0 exp(-drag dt); without drag it keeps v0."""
    b = ClothBuilder()
    b.add_grid(4, 4, 0.2, 0.2, origin=(0.0, 0.1, 0.0))
    m = b.finalize()
    s = XPBDSolver(m, gravity=(0.0, 0.0, 0.0), air_density=0.0, drag=drag, self_collision=False, tethers=False)
    st = m.state()
    v0 = np.tile(np.float32([1.0, 0.0, 0.5]), (m.particle_count, 1))
    st.velocities.assign(v0)
    s.step(st, st, DT)
    # velocities come from float32 position differences: ulp(0.3 m) / (dt / 6) ~ 1e-5 m/s against
    # 0.5-1 m/s, so 1e-4 relative; the decay tested is 5 %
    np.testing.assert_allclose(st.velocities.numpy(), v0 * np.exp(-drag * DT), rtol=1e-4)

# -- accuracy and energy ----------------------------------------------------------------------


def test_hanging_cloth_edge_strain_below_one_percent():
    """A 1 m cloth with 32 x 32 vertices hanging from its two top corners, default stiffness and
    solver settings, after 2 s (at rest)."""
    b = ClothBuilder()
    ids = b.add_grid(32, 32, 1.0, 1.0, origin=(-0.5, 2.0, 0.0), u_axis=(1, 0, 0), v_axis=(0, -1, 0))
    b.pin([ids[0, 0], ids[0, -1]])
    m = b.finalize()
    st = m.state()
    x = _run(XPBDSolver(m), st, 120)
    strain = _edge_strain(m, x)
    assert strain.max() < 0.01, f"max strain {strain.max():.4f} at edge {m.edges_np[strain.argmax()]}"
    assert x[:, 1].min() < 1.2  # really hanging (sagged), not held flat


def test_one_launch_over_all_colours_is_the_per_colour_sweep():
    """On the CPU the coloured stretch, bending and damping sweeps run as one launch over all
    colours (XPBDSolver._batches; for stretch, stretch damping and bending the lane kernels over
    groups within each colour); a launch runs its threads in index order there, so the result
    must be bit-for-bit the scalar kernels' per-colour launches' (damping on, so the damping sweeps
    are covered)."""
    def build():
        b = ClothBuilder(damping=0.1, bend_damping=0.1)
        ids = b.add_grid(12, 12, 1.0, 1.0, origin=(-0.5, 1.0, -0.5))
        b.pin([ids[0, 0], ids[0, -1]])
        return b.finalize()
    merged_model, colour_model = build(), build()
    merged, per_colour = XPBDSolver(merged_model), XPBDSolver(colour_model)
    per_colour._batches = lambda colours: list(colours)
    per_colour._edge_groups = per_colour._hinge_groups = None  # the scalar kernels
    assert len(merged_model.edge_colors) > 1 and len(merged_model.hinge_colors) > 1
    a, b = merged_model.state(), colour_model.state()
    xa, xb = _run(merged, a, 30), _run(per_colour, b, 30)
    assert np.array_equal(xa, xb) and np.array_equal(a.velocities.numpy(), b.velocities.numpy())
    assert np.abs(xa - merged_model.state().points.numpy()).max() > 0.1  # the cloth really moved


def _released_cloth(**builder_kw):
    b = ClothBuilder(**builder_kw)
    ids = b.add_grid(16, 16, 1.0, 1.0, origin=(-0.5, 2.0, -0.5))
    b.pin([ids[0, 0], ids[0, -1]])
    m = b.finalize()
    return m, XPBDSolver(m, self_collision=False), m.state()


@pytest.mark.parametrize("stiffness", [50.0, 200.0])
def test_energy_does_not_grow_without_input(stiffness):
    """Cloth released horizontally from two pinned corners in still air: kinetic + gravitational
    + elastic energy never exceeds its initial value (nothing injects energy; drag, dampers and
    XPBD dissipate). Membrane stiffnesses where one XPBD sweep per substep converges, so that
    1/2 k C^2 is the energy the solver actually stores."""
    m, s, st = _released_cloth(stretch_stiffness=stiffness)
    e0 = st.energy()["total"]
    totals = []
    _run(s, st, 120, each=lambda f, x: totals.append(st.energy()["total"]))
    # float32 positions of ~1 m carry ~1e-7 m error, worth ~1e-6 J of potential energy per vertex
    # (256 vertices): 1e-4 J covers it
    assert max(totals) <= e0 + 1e-4, (e0, max(totals), int(np.argmax(totals)))
    assert totals[-1] < e0 - 0.5  # the cloth fell: potential energy was released and dissipated


def test_mechanical_energy_does_not_grow_at_default_stiffness():
    """At the default (near-inextensible) stiffness the constraints are stiff beyond what one sweep
    resolves, so 1/2 k C^2 of the transient solver lag is not stored energy; kinetic + potential
    energy must still never exceed its initial value."""
    m, s, st = _released_cloth()
    e = st.energy()
    e0 = e["kinetic"] + e["potential"]
    mech = []
    _run(s, st, 120, each=lambda f, x: mech.append(st.energy()["kinetic"] + st.energy()["potential"]))
    assert max(mech) <= e0 + 1e-4, (e0, max(mech), int(np.argmax(mech)))


# -- colliders ---------------------------------------------------------------------------------


def _drop(colliders, n=12, size=0.8, height=0.6, frames=45, friction_check=None, **solver_kw):
    b = ClothBuilder()
    b.add_grid(n, n, size, size, origin=(-size / 2, height, -size / 2))
    m = b.finalize()
    s = XPBDSolver(m, colliders, self_collision=False, **solver_kw)
    st = m.state()
    frames_x = []
    _run(s, st, frames, each=lambda f, x: frames_x.append(x.copy()))
    return m, np.array(frames_x)


@pytest.mark.parametrize("shape", ["plane", "sphere", "capsule", "box"])
def test_no_penetration_of_analytic_colliders(shape):
    col = ColliderSet()
    if shape == "plane":
        col.add_plane((0, 1, 0), 0.1)
        sd = lambda x: x[:, 1] - 0.1  # noqa: E731
    elif shape == "sphere":
        col.add_sphere((0, 0.3, 0), 0.2)
        sd = lambda x: np.linalg.norm(x - [0, 0.3, 0], axis=1) - 0.2  # noqa: E731
    elif shape == "capsule":
        col.add_capsule((-0.2, 0.3, 0), (0.2, 0.3, 0), 0.1)
        sd = lambda x: np.linalg.norm(x - np.stack([np.clip(x[:, 0], -0.2, 0.2), np.full(len(x), 0.3),  # noqa: E731
                                                    np.zeros(len(x))], 1), axis=1) - 0.1
    else:
        ang = 0.4
        q = (0.0, np.sin(ang / 2), 0.0, np.cos(ang / 2))
        col.add_box((0, 0.2, 0), (0.15, 0.1, 0.15), q)
        rot = np.array([[np.cos(ang), 0, np.sin(ang)], [0, 1, 0], [-np.sin(ang), 0, np.cos(ang)]])

        def sd(x):
            lp = (x - [0, 0.2, 0]) @ rot  # world -> box frame
            qd = np.abs(lp) - [0.15, 0.1, 0.15]
            return np.linalg.norm(np.maximum(qd, 0), axis=1) + np.minimum(qd.max(axis=1), 0)
    m, xs = _drop(col)
    worst = min(sd(x).min() for x in xs)
    # the collider projection runs last in every substep: only float32 rounding remains (1e-6 m)
    assert worst >= m.thickness - 1e-5, f"{shape}: deepest vertex at {worst:.6f} m (thickness {m.thickness})"
    assert min(sd(xs[-1])) < m.thickness + 0.01  # the cloth did reach the collider


def test_no_penetration_of_moving_mesh_collider():
    import trimesh

    ico = trimesh.creation.icosphere(subdivisions=2, radius=0.2)
    col = ColliderSet()
    mc = col.add_mesh(np.asarray(ico.vertices) + [0, 0.3, 0], np.asarray(ico.faces))
    b = ClothBuilder()
    b.add_grid(12, 12, 0.8, 0.8, origin=(-0.4, 0.6, -0.4))
    m = b.finalize()
    s = XPBDSolver(m, col, self_collision=False)
    st = m.state()
    worst = np.inf
    for f in range(45):
        centre = np.array([0.0, 0.3 + 0.2 * min(f, 20) / 20, 0.0])  # the sphere rises into the cloth
        mc.set_points(np.asarray(ico.vertices) + centre)
        s.step(st, st, DT)
        x = st.points.numpy()
        v = np.asarray(ico.vertices) + centre
        d = point_triangle_distance_np(x, v[ico.faces[:, 0]], v[ico.faces[:, 1]], v[ico.faces[:, 2]]).min(axis=1)
        inside = np.linalg.norm(x - centre, axis=1) < 0.19  # well inside the polyhedron
        assert not inside.any(), f"frame {f}: vertex {int(np.flatnonzero(inside)[0])} inside the mesh"
        worst = min(worst, d.min())
    # exact projection onto the BVH's closest point: float32 rounding only
    assert worst >= m.thickness - 1e-4, worst


# -- self-collision ------------------------------------------------------------------------------


def _folded_strip(n_len=40, n_wid=8, length=1.0, width=0.25, gap=0.04, y0=0.01):
    """A strip folded over itself like a U lying on its side: lower layer at y0, upper layer at
    y0 + gap, joined by a half circle. Returns points, faces, and the lower/upper vertex masks."""
    half = length / 2 - np.pi * gap / 4
    s = np.linspace(0, length, n_len)
    r = gap / 2
    pts2 = []
    for si in s:
        if si <= half:
            pts2.append((half - si, y0))
        elif si <= half + np.pi * r:
            a = (si - half) / r
            pts2.append((-r * np.sin(a), y0 + r - r * np.cos(a)))
        else:
            pts2.append((si - half - np.pi * r, y0 + gap))
    pts2 = np.array(pts2)
    zs = np.linspace(0, width, n_wid)
    pts = np.array([[x, y, z] for z in zs for x, y in pts2])
    faces = []
    for j in range(n_wid - 1):
        for i in range(n_len - 1):
            a = j * n_len + i
            faces += [[a, a + n_len, a + 1], [a + 1, a + n_len, a + n_len + 1]]
    # interior vertices only: at the strip's borders and free ends a layer can slide past the
    # other's edge, edge over edge, which vertex-triangle contact does not see (a documented
    # limitation); there the partner test would also compare vertices no longer one above the other
    inner = np.repeat((np.arange(n_wid) > 0) & (np.arange(n_wid) < n_wid - 1), n_len)
    lower = np.tile((s < half - 0.1) & (s > 0.06), n_wid) & inner
    upper = np.tile((s > half + np.pi * r + 0.1) & (s < length - 0.06), n_wid) & inner
    return pts, np.array(faces), lower, upper, n_len


@pytest.mark.parametrize("self_collision, guard", [(True, True), (False, True), (False, False)])
def test_folded_cloth_never_passes_through_itself(self_collision, guard):
    """The upper layer is thrown down onto the lower one at 4 m/s (12 mm per substep, more than
    twice the 5 mm thickness). With self-collision every upper vertex stays above the lower layer
    at every frame; with the intersection guard alone (no contact forces) the layers do not cross
    either, the guard holding the vertices the step would push through; with neither they cross
    at once (which shows the check can fail)."""
    pts, faces, lower, upper, n_len = _folded_strip()
    b = ClothBuilder(bend_stiffness=1e-6)
    b.add_mesh(pts, faces)
    m = b.finalize()
    col = ColliderSet()
    col.add_plane((0, 1, 0), 0.0)
    s = XPBDSolver(m, col, self_collision=self_collision, guard=guard)
    st = m.state()
    vel = np.zeros_like(pts)
    vel[pts[:, 1] > pts[:, 1].max() - 1e-6, 1] = -4.0  # the whole flat upper layer
    st.set_points(pts, vel)
    # partner of each upper vertex: the lower vertex it lies over (mirror about the fold)
    idx = np.arange(len(pts))
    i, j = idx % n_len, idx // n_len
    partner = j * n_len + (n_len - 1 - i)
    crossed = []
    for f in range(30):
        s.step(st, st, DT)
        x = st.points.numpy()
        sep = x[upper, 1] - x[partner[upper], 1]
        crossed.append(sep.min())
    if self_collision:
        # never crossed; the 4 m/s impact may squeeze the contact layer below the thickness for a
        # frame (one Jacobi pass per contact iteration against the ground underneath), after
        # which the layers settle a thickness apart (10 % allowance for the averaging)
        assert min(crossed) > 0.0, f"layers crossed by {-min(crossed):.4f} m at frame {int(np.argmin(crossed))}"
        assert crossed[-1] > 0.9 * m.thickness, crossed[-5:]
    elif guard:
        # the guard alone (no contact forces to hold the layers) keeps them apart: it holds the
        # upper layer's vertices where they were, step after step, and says for how long (measured:
        # 19 consecutive steps at most)
        assert min(crossed) > 0.0, f"layers crossed by {-min(crossed):.4f} m at frame {int(np.argmin(crossed))}"
        assert s.stats()["guard_longest_hold"] >= 10, s.stats()
    else:
        assert min(crossed) < 0.0


# -- extremes and failure ---------------------------------------------------------------------------


@pytest.mark.parametrize("stretch", [1e8, np.inf])
def test_extreme_stiffness_large_step_tiny_mass_stay_finite(stretch):
    """Stiffness 1e8 N/m (and inextensible), dt 1/30 s with one substep, vertex mass ~1e-6 kg,
    with wind, ground, a sphere and self-collision on."""
    n = 12
    area = 0.5 * 0.5
    b = ClothBuilder(density=1e-6 * n * n / area, stretch_stiffness=stretch, bend_stiffness=1e8)
    ids = b.add_grid(n, n, 0.5, 0.5, origin=(-0.25, 0.5, -0.25))
    b.pin([ids[0, 0]])
    m = b.finalize()
    assert m.mass.max() < 3e-6
    col = ColliderSet()
    col.add_plane()
    col.add_sphere((0.1, 0.2, 0.0), 0.15)
    s = XPBDSolver(m, col, substeps=1)
    st = m.state()
    ctl = m.control()
    ctl.set_wind((20.0, 0.0, 5.0))
    for _ in range(60):
        s.step(st, st, 1.0 / 30.0, ctl)
    x = st.points.numpy()
    assert np.isfinite(x).all() and np.isfinite(st.velocities.numpy()).all()
    assert np.abs(x).max() < 10.0  # finite and not flung away


def test_nonfinite_state_stops_with_step_and_vertex():
    b = ClothBuilder()
    b.add_grid(4, 4, 1.0, 1.0)
    m = b.finalize()
    s = XPBDSolver(m)
    st = m.state()
    s.step(st, st, DT)
    x = st.points.numpy()
    x[5] = np.nan
    st.points.assign(x)  # bypass set_points' validation, as a corrupted buffer would
    out = m.state()
    before = out.points.numpy().copy()
    with pytest.raises(SimulationError, match=r"step 1: vertex \d+ became non-finite.*input state was already "
                                              r"non-finite at vertex 5"):
        s.step(st, out, DT)
    assert np.array_equal(out.points.numpy(), before)  # no garbage written


def test_bad_mesh_input_names_the_culprit():
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], dtype=float)
    b = ClothBuilder()
    with pytest.raises(MeshError, match="triangle 1 .* degenerate"):
        b.add_mesh(np.vstack([pts, [[2, 0, 0]]]), [[0, 1, 2], [0, 1, 4]])
    with pytest.raises(MeshError, match=r"triangle 1 \[1, 2, 3\] is inverted relative to its neighbour 0 "
                                        r"\[0, 1, 2\] .*Recalculate Outside"):
        b.add_mesh(pts, [[0, 1, 2], [1, 2, 3]])
    with pytest.raises(MeshError, match=r"triangle 0 \[0, 0, 2\] repeats a vertex"):
        b.add_mesh(pts, [[0, 0, 2], [1, 3, 2]])
    bad = pts.copy()
    bad[2, 1] = np.nan
    with pytest.raises(MeshError, match="vertex 2 has a non-finite position"):
        b.add_mesh(bad, [[0, 1, 2], [1, 3, 2]])
    with pytest.raises(MeshError, match="vertex 3 is not used"):
        b.add_mesh(pts, [[0, 1, 2]])


def _grid_faces(n: int) -> tuple[np.ndarray, list[list[int]]]:
    """A flat n x n grid of 2 n^2 consistently oriented triangles: points (V, 3), faces."""
    pts = np.array([[i, 0.0, j] for j in range(n + 1) for i in range(n + 1)]) / n
    faces = []
    for j in range(n):
        for i in range(n):
            v = j * (n + 1) + i
            faces += [[v, v + n + 1, v + n + 2], [v, v + n + 2, v + 1]]
    return pts, faces


def test_non_manifold_edge_is_named_before_orientation():
    # a flap on the interior edge (4, 5) of a 3x3 grid: the orientation check alone called it "inverted"
    pts, faces = _grid_faces(3)
    with pytest.raises(MeshError, match=r"sheet: edge \(4, 9\) is shared by 3 triangles \[6, 7, 18\] "
                                        r"\(non-manifold.*Non Manifold"):
        ClothBuilder().add_mesh(np.vstack([pts, [[0.5, 1.0, 0.5]]]), faces + [[4, 9, 16]], name="sheet")


@pytest.mark.parametrize("winding", [[0, 1, 2], [0, 2, 1]])
def test_duplicate_face_is_named(winding):
    # the same 3 vertices twice, in the same or the opposite winding: the orientation check called it "inverted"
    pts, faces = _grid_faces(3)
    dup = [faces[7][k] for k in winding]
    with pytest.raises(MeshError, match=rf"sheet: duplicate face: triangles 7 and 18 have the same vertices "
                                        rf"\[{dup[0]}, {dup[1]}, {dup[2]}\] \(1 such duplicates\).*Fix Overlaps"):
        ClothBuilder().add_mesh(pts, faces + [dup], name="sheet")


def test_repeated_index_names_triangle_and_clean_up():
    pts, faces = _grid_faces(3)
    with pytest.raises(MeshError, match=r"sheet: triangle 18 \[4, 4, 9\] repeats a vertex \(degenerate.*"
                                        r"Degenerate Dissolve"):
        ClothBuilder().add_mesh(pts, faces + [[4, 4, 9]], name="sheet")


@pytest.mark.parametrize("kwargs, match", [
    ({"density": -1.0}, "density must be > 0"),
    ({"thickness": np.nan}, "thickness must be finite"),
    ({"bend_stiffness": -2.0}, "bend_stiffness must be >= 0"),
    ({"stretch_stiffness": 0.0}, "stretch_stiffness must be > 0"),
])
def test_bad_builder_parameters(kwargs, match):
    with pytest.raises(ValueError, match=match):
        ClothBuilder(**kwargs)


@pytest.mark.parametrize("kwargs, match", [
    ({"substeps": 0}, "substeps"), ({"iterations": 1.5}, "iterations"), ({"drag": -1}, "drag must be >= 0"),
    ({"relaxation": 2.5}, "relaxation"), ({"gravity": (0, np.inf, 0)}, "gravity"),
])
def test_bad_solver_parameters(kwargs, match):
    b = ClothBuilder()
    b.add_grid(3, 3, 1.0, 1.0)
    m = b.finalize()
    with pytest.raises(ValueError, match=match):
        XPBDSolver(m, **kwargs)
    with pytest.raises(ValueError, match="dt must be finite and > 0"):
        XPBDSolver(m).step(m.state(), m.state(), 0.0)


def test_usd_cloth_mesh_from_warp_assets():
    """Warp's square_cloth.usd (2500 vertices, in centimetres) as cloth pinned along one edge."""
    from warpshade import load_mesh

    mesh = load_mesh(warp_asset("square_cloth.usd"))
    b = ClothBuilder()
    # the asset lies in the xy plane in centimetres: metres, and stand it up
    ids = b.add_mesh(mesh.points[:, [0, 2, 1]] * 0.01 + [0, 1.0, 0], mesh.faces[:, [0, 2, 1]], name=mesh.name)
    top = ids[np.isclose(mesh.points[:, 1], mesh.points[:, 1].min())]
    b.pin(top)
    m = b.finalize()
    st = m.state()
    x = _run(XPBDSolver(m, self_collision=True), st, 10)
    assert np.isfinite(x).all() and x[:, 1].min() < 1.0 - 1e-3


def test_pins_stay_and_attachments_follow_their_targets():
    b = ClothBuilder()
    ids = b.add_grid(8, 8, 0.5, 0.5, origin=(0, 1, 0))
    b.pin([ids[0, 0]])
    slots = b.attach(ids[0, 1:])
    m = b.finalize()
    s = XPBDSolver(m)
    st, ctl = m.state(), m.control()
    rest = m.rest_points_np
    for f in range(20):
        target = rest[ids[0, 1:]] + [0.0, 0.0, 0.01 * (f + 1)]  # slide the attached edge along z
        ordered = np.empty_like(target)
        ordered[slots] = target
        ctl.set_targets(ordered)
        s.step(st, st, DT, ctl)
        x = st.points.numpy()
        np.testing.assert_allclose(x[ids[0, 1:]], target, atol=1e-6, err_msg=f"frame {f}")
        assert np.array_equal(x[ids[0, 0]], rest[ids[0, 0]])
    with pytest.raises(ValueError, match=r"target 2 \(vertex \d+\) is not finite"):
        bad = ordered.copy()
        bad[2, 0] = np.nan
        ctl.set_targets(bad)
    with pytest.raises(ValueError, match="attach: vertex 3 attached twice"):
        b.attach([3, 3])


@pytest.mark.parametrize("call, match", [
    (lambda c: c.add_sphere((0, 0, 0), -1.0), "sphere radius must be finite and > 0"),
    (lambda c: c.add_capsule((0, 0, 0), (0, np.nan, 0), 0.1), "capsule p1 must be 3 finite numbers"),
    (lambda c: c.add_box((0, 0, 0), (1, 0, 1)), "half_extents must be > 0"),
    (lambda c: c.add_plane((0, 0, 0)), "plane normal must be non-zero"),
    (lambda c: c.add_plane((0, 1, 0), friction=-1), "friction must be finite and >= 0"),
    (lambda c: c.add_mesh(np.array([[0, 0, 0], [1, 0, 0], [0, np.inf, 0]]), [[0, 1, 2]]), "vertex 2 is not finite"),
])
def test_bad_collider_input(call, match):
    with pytest.raises(ValueError, match=match):
        call(ColliderSet())


def test_tethers_never_pull_a_cloth_at_rest():
    """Tethers only act on stretch: a convex flat piece (Euclidean lengths), an L-shaped flat
    piece (edge-path lengths) and a second, unpinned piece (which must get no tethers to the other
    pieces' pins) stay exactly at rest without gravity."""
    b = ClothBuilder()
    g = b.add_grid(9, 9, 0.8, 0.8)
    b.pin([g[0, 0], g[8, 8]])
    pts = np.array([[x, 0.0, z] for z in range(5) for x in range(5)], dtype=float) * 0.1 + [2, 0, 0]
    faces = []
    for j in range(4):
        for i in range(4):
            if i >= 2 and j >= 2:  # cut the corner out: an L
                continue
            a = j * 5 + i
            faces += [[a, a + 5, a + 1], [a + 1, a + 5, a + 6]]
    used = np.unique(faces)
    remap = np.full(25, -1)
    remap[used] = np.arange(len(used))
    ell = b.add_mesh(pts[used], remap[np.array(faces)])
    b.pin([ell[remap[4]]])  # end of one arm: straight lines to the other arm cross the cut-out
    b.add_grid(4, 4, 0.3, 0.3, origin=(0, 1, 0))  # unpinned
    m = b.finalize()
    anchors = m.tether_anchor.numpy()
    assert (anchors[-16:] == -1).all()  # the unpinned piece has no tethers
    st = m.state()
    _run(XPBDSolver(m, gravity=(0, 0, 0), air_density=0.0), st, 10)
    np.testing.assert_allclose(st.points.numpy(), m.rest_points_np, atol=1e-6)
