"""The CPU lane kernels (several constraints of one colour per thread) against the scalar kernels they
replace: the same floats, bit for bit."""

from __future__ import annotations

import numpy as np
import warp as wp

from warpshade.sim import ClothBuilder, ClothControl, XPBDSolver
from warpshade.sim import kernels as k
from warpshade.sim import lane_kernels as lk


def _crumpled_model(rng, n=13, scale=0.08):
    b = ClothBuilder(damping=0.1, bend_damping=0.1)
    ids = b.add_grid(n, n, 1.0, 1.0, origin=(-0.5, 1.0, -0.5))
    b.pin([ids[0, 0], ids[0, -1], ids[3, 4]])
    m = b.finalize()
    x = m.state().points.numpy() + rng.normal(scale=scale, size=(m.particle_count, 3)).astype(np.float32)
    return m, x


def test_lane_groups_stay_within_a_colour():
    groups = lk.lane_groups([(0, 3), (3, 17), (20, 8)], "cpu").numpy().tolist()
    assert groups == [[0, 3], [3, 8], [11, 8], [19, 1], [20, 8]]


def test_bending_lanes_equal_the_scalar_sweep_bit_for_bit(rng):
    """One sweep over every colour from crumpled positions (angles in all four quadrants, pinned
    vertices, a degenerate hinge with a zero-length edge, colours of sizes not a multiple of LANES)."""
    m, x0 = _crumpled_model(rng)
    hinges = m.hinges.numpy()
    x0[hinges[5, 3]] = x0[hinges[5, 2]]  # hinge 5's shared edge has zero length: no correction
    sizes = [cnt for _, cnt in m.hinge_colors]
    assert len(sizes) > 1 and any(c % lk.LANES for c in sizes)
    lam0 = rng.normal(scale=1e-3, size=m.hinge_count).astype(np.float32)
    ids = m.hinges.view(wp.vec4i)
    outs = []
    for lanes in (False, True):
        x = wp.array(x0, dtype=wp.vec3, device="cpu")
        lam = wp.array(lam0, dtype=float, device="cpu")
        for dt in (1.0 / 360.0, 1.0 / 60.0):
            if lanes:
                groups = lk.lane_groups(m.hinge_colors, "cpu")
                wp.launch(lk.solve_bending_lanes, dim=groups.shape[0],
                          inputs=[groups, ids, m.hinge_rest_angle, m.hinge_compliance, m.inv_mass, dt],
                          outputs=[lam, x], device="cpu")
            else:
                for off, cnt in m.hinge_colors:
                    wp.launch(k.solve_bending, dim=cnt,
                              inputs=[ids, m.hinge_rest_angle, m.hinge_compliance, m.inv_mass, off, dt],
                              outputs=[lam, x], device="cpu")
        outs.append((x.numpy(), lam.numpy()))
    (xs, ls), (xl, ll) = outs
    assert np.abs(xs - x0).max() > 1e-3  # the sweeps moved the cloth
    assert np.array_equal(xs.view(np.uint32), xl.view(np.uint32))
    assert np.array_equal(ls.view(np.uint32), ll.view(np.uint32))
    assert np.array_equal(xs[hinges[5]], xl[hinges[5]])


def test_stretch_and_damping_lanes_equal_the_scalar_sweeps_bit_for_bit(rng):
    """One stretch sweep and one stretch damping sweep over every colour from crumpled positions
    and random velocities (pinned vertices, a zero-length edge, colours of sizes not a multiple of
    LANES)."""
    m, x0 = _crumpled_model(rng)
    edges = m.edges.numpy()
    x0[edges[7, 1]] = x0[edges[7, 0]]  # edge 7 has zero length: no correction
    v0 = rng.normal(scale=0.5, size=x0.shape).astype(np.float32)
    assert len(m.edge_colors) > 1 and any(c % lk.LANES for _, c in m.edge_colors)
    lam0 = rng.normal(scale=1e-3, size=m.edge_count).astype(np.float32)
    ids = m.edges.view(wp.vec2i)
    dt = 1.0 / 360.0
    outs = []
    for lanes in (False, True):
        x = wp.array(x0, dtype=wp.vec3, device="cpu")
        v = wp.array(v0, dtype=wp.vec3, device="cpu")
        lam = wp.array(lam0, dtype=float, device="cpu")
        if lanes:
            groups = lk.lane_groups(m.edge_colors, "cpu")
            wp.launch(lk.solve_stretch_lanes, dim=groups.shape[0],
                      inputs=[groups, ids, m.edge_rest_length, m.edge_compliance, m.inv_mass, dt, 1.3],
                      outputs=[lam, x], device="cpu")
            wp.launch(lk.damp_stretch_lanes, dim=groups.shape[0],
                      inputs=[groups, ids, m.edge_compliance, m.inv_mass, x, dt, 0.1], outputs=[v], device="cpu")
        else:
            for off, cnt in m.edge_colors:
                wp.launch(k.solve_stretch, dim=cnt,
                          inputs=[ids, m.edge_rest_length, m.edge_compliance, m.inv_mass, off, dt, 1.3],
                          outputs=[lam, x], device="cpu")
            for off, cnt in m.edge_colors:
                wp.launch(k.damp_stretch, dim=cnt, inputs=[ids, m.edge_compliance, m.inv_mass, x, off, dt, 0.1],
                          outputs=[v], device="cpu")
        outs.append((x.numpy(), lam.numpy(), v.numpy()))
    (xs, ls, vs), (xl, ll, vl) = outs
    assert np.abs(xs - x0).max() > 1e-3 and np.abs(vs - v0).max() > 1e-3  # the sweeps changed both
    for a, b in ((xs, xl), (ls, ll), (vs, vl)):
        assert np.array_equal(a.view(np.uint32), b.view(np.uint32))


def test_aero_lanes_equal_the_scalar_kernel_bit_for_bit(rng):
    """Drag and lift from crumpled positions and random velocities with wind (a degenerate
    triangle, a triangle moving with the wind, a triangle count not a multiple of LANES), added
    on top of earlier sums: the same floats, in the same order."""
    m, x0 = _crumpled_model(rng, n=14)
    tris = m.tris.numpy()
    x0[tris[3, 1]] = x0[tris[3, 0]]  # triangle 3 is degenerate: no force
    wind = np.array([0.3, -0.1, 0.7], dtype=np.float32)
    v0 = rng.normal(scale=2.0, size=x0.shape).astype(np.float32)
    v0[tris[9]] = wind  # triangle 9 is at rest in the air: no force from it
    assert m.tri_count % lk.LANES
    ids = m.tris.view(wp.vec3i)
    lift0 = rng.normal(size=x0.shape).astype(np.float32)
    drag0 = rng.random(m.particle_count).astype(np.float32)
    outs = []
    for kernel, dim in ((k.accumulate_aero_forces, m.tri_count),
                        (lk.accumulate_aero_forces_lanes, -(-m.tri_count // lk.LANES))):
        lift = wp.array(lift0, dtype=wp.vec3, device="cpu")
        drag = wp.array(drag0, dtype=float, device="cpu")
        wp.launch(kernel, dim=dim, inputs=[wp.array(x0, dtype=wp.vec3, device="cpu"),
                                           wp.array(v0, dtype=wp.vec3, device="cpu"), ids, wp.vec3(*wind),
                                           1.2, 0.8, 0.3], outputs=[lift, drag], device="cpu")
        outs.append((lift.numpy(), drag.numpy()))
    (ls, ds), (ll, dl) = outs
    assert np.abs(ds - drag0).max() > 1e-3 and np.abs(ls - lift0).max() > 1e-3  # forces were added
    assert np.array_equal(ls.view(np.uint32), ll.view(np.uint32))
    assert np.array_equal(ds.view(np.uint32), dl.view(np.uint32))


def test_solver_steps_with_lanes_equal_the_scalar_kernels(rng):
    """The solver's CPU stretch, damping and bending sweeps and air forces (lanes) against the scalar
    kernels: 20 steps of a rumpled cloth falling from two pins in wind, positions and velocities bit
    for bit."""
    results = []
    for lanes in (True, False):
        m, x0 = _crumpled_model(np.random.default_rng(7), scale=0.01)
        solver = XPBDSolver(m)
        if lanes:
            assert solver._hinge_groups is not None and solver._edge_groups is not None  # the CPU solver takes the lanes
        else:
            solver._hinge_groups = solver._edge_groups = None
            solver._lanes = lambda *arrays: False
            solver._batches = lambda colours: list(colours)
        s = m.state()
        s.points.assign(x0)
        control = ClothControl(m)
        control.wind = (2.0, 0.0, 1.0)
        for _ in range(20):
            solver.step(s, s, 1.0 / 60.0, control)
        results.append((s.points.numpy(), s.velocities.numpy()))
    (xa, va), (xb, vb) = results
    assert np.abs(xa - x0).max() > 0.1  # the cloth fell
    assert np.array_equal(xa, xb) and np.array_equal(va, vb)
