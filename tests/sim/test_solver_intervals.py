"""XPBDSolver's aero_interval, bend_interval and held_contact_interval: the aerodynamic forces of
one evaluation reused over the interval, a bending sweep every k substeps acting as an XPBD step of
k substeps, and the intervals' defaults and checks."""

from __future__ import annotations

import numpy as np
import pytest

from warpshade.sim import ClothBuilder, XPBDSolver

DT = 1.0 / 60.0


def _square(**kw):
    """One 10 cm square of two triangles (2 x 2 vertices) in the x-z plane."""
    b = ClothBuilder(**kw)
    b.add_grid(2, 2, 0.1, 0.1)
    return b.finalize("cpu")


def test_aero_interval_reuses_the_first_drag_over_the_step():
    # The square falls flat onto still air at 10 m/s without gravity: the flow is along the
    # normal, so the lift is 0 and each vertex's drag coefficient is D = 1/2 rho Cd |u| A_i / 3
    # (A_i its triangles' area), with mass density A_i / 3: D / m = rho Cd |u| / (2 density),
    # the same for every vertex (the square translates rigidly, no constraint acts). Evaluated once
    # per step (aero_interval = substeps), the implicit drag update u <- u / (1 + D/m h) keeps the
    # first speed's D for all six substeps: u = u0 / (1 + rho Cd u0 h / (2 density))^6.
    model = _square(density=0.2)
    rho, cd, u0, n = 1.2, 0.8, 10.0, 6
    h = DT / n
    a = rho * cd * u0 * h / (2.0 * 0.2)
    once = u0 / (1.0 + a) ** n
    every = u0
    for _ in range(n):  # re-evaluated every substep with the current speed
        every = every / (1.0 + rho * cd * every * h / (2.0 * 0.2))
    assert abs(once - every) / once > 0.02  # the two schedules differ far beyond float32 rounding

    def final_speed(interval):
        solver = XPBDSolver(model, None, substeps=n, gravity=(0.0, 0.0, 0.0), air_density=rho,
                            drag_coefficient=cd, lift_coefficient=0.3, aero_interval=interval)
        s0, s1 = model.state(), model.state()
        s0.velocities.assign(np.tile([0.0, u0, 0.0], (4, 1)).astype(np.float32))
        solver.step(s0, s1, DT)
        return s1.velocities.numpy()

    # float32 arithmetic over 6 substeps: relative error ~1e-6; 1e-5 leaves a margin
    np.testing.assert_allclose(final_speed(n)[:, 1], once, rtol=1e-5)
    np.testing.assert_allclose(final_speed(1)[:, 1], every, rtol=1e-5)
    np.testing.assert_allclose(final_speed(n)[:, [0, 2]], 0.0, atol=1e-6)


def _folded_hinge(angle):
    """The square with one wing turned by `angle` about the shared edge (edge lengths kept)."""
    # stretch nearly free (1e-6 N/m): the stretch sweeps between two bending sweeps would move vertices
    # by the substep's rate, not the step's, and the comparison below is of the bending alone
    model = _square(damping=0.0, bend_stiffness=1e-4, stretch_stiffness=1e-6)
    h = model.hinges.numpy()[0]
    x = model.rest_points_np.copy()
    p3, p4 = x[h[2]].astype(np.float64), x[h[3]].astype(np.float64)
    axis = (p4 - p3) / np.linalg.norm(p4 - p3)
    r = x[h[0]] - p3
    # Rodrigues rotation of the wing vertex about the shared edge
    r = r * np.cos(angle) + np.cross(axis, r) * np.sin(angle) + axis * np.dot(axis, r) * (1 - np.cos(angle))
    x[h[0]] = p3 + r
    return model, x.astype(np.float32)


def _step(model, x, substeps, **kw):
    solver = XPBDSolver(model, None, substeps=substeps, gravity=(0.0, 0.0, 0.0), air_density=0.0,
                        stretch_limits=False, **kw)
    s0, s1 = model.state(), model.state()
    s0.points.assign(x)
    solver.step(s0, s1, DT)
    return s1.points.numpy(), s1.velocities.numpy()


@pytest.mark.parametrize("iterations", [1, 2])
def test_bend_interval_sweep_is_an_xpbd_step_of_the_interval(iterations):
    # A folded hinge at rest, no gravity, no air, no damping: with 2 substeps and bend_interval=2
    # the first substep changes nothing (no velocity, lengths kept) and the second sweeps the
    # bending once with compliance alpha / dt^2: the same correction as one substep of dt. The
    # velocity it leaves must be that correction over dt (an XPBD step of dt), not over the
    # substep dt / 2 (which would double the bending impulse); with 2 iterations, both sweeps'.
    model, x = _folded_hinge(0.5)
    x1, v1 = _step(model, x, 1, iterations=iterations)
    x2, v2 = _step(model, x, 2, bend_interval=2, iterations=iterations)
    moved = np.abs(x1 - x).max()
    assert moved > 1e-5  # the bending acted (the fold relaxes)
    # the edge lengths are kept to float32 rounding, so the stretch sweeps move vertices by ~1e-8 m
    np.testing.assert_allclose(x2, x1, atol=1e-7)
    np.testing.assert_allclose(v2, v1, atol=1e-7 / (DT / 2), rtol=1e-4)
    # bending in both substeps (bend_interval=1) is a different step: the check above can fail
    x3, v3 = _step(model, x, 2, iterations=iterations)
    assert np.abs(x3 - x1).max() > 100 * 1e-7


@pytest.mark.parametrize("name", ["aero_interval", "bend_interval", "held_contact_interval"])
@pytest.mark.parametrize("bad", [0, -1, 1.5])
def test_intervals_reject_bad_values(name, bad):
    with pytest.raises(ValueError, match=name):
        XPBDSolver(_square(), None, **{name: bad})


def test_default_intervals_are_one():
    s = XPBDSolver(_square(), None)
    assert (s.aero_interval, s.bend_interval) == (1, 1)


def test_held_contact_interval_defaults_to_the_contact_interval():
    """Unset, a step after a guard step detects contacts as every other step does (the default path)."""
    assert XPBDSolver(_square(), None).held_contact_interval == 3
    assert XPBDSolver(_square(), None, contact_interval=2).held_contact_interval == 2
    s = XPBDSolver(_square(), None, held_contact_interval=1)
    assert (s.contact_interval, s.held_contact_interval, s.knobs()["held_contact_interval"]) == (3, 1, 1)
