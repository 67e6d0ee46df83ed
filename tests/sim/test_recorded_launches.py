"""RecordedLaunches: one record per kernel, dimension and arguments, launching what wp.launch would."""

from __future__ import annotations

import numpy as np
import warp as wp

from warpshade.sim.launches import CpuLaunch, RecordedLaunches, recorded


@wp.kernel
def axpy(a: float, x: wp.array[float], y: wp.array[float]):
    i = wp.tid()
    y[i] = y[i] + a * x[i]


def test_a_record_is_kept_per_arguments_and_reads_the_arrays_when_launched():
    rec = RecordedLaunches("cpu")
    x = wp.array(np.arange(4, dtype=np.float32), device="cpu")
    y = wp.zeros(4, dtype=float, device="cpu")
    rec.launch(axpy, 4, [2.0, x], [y])
    rec.launch(axpy, 4, [2.0, x], [y])
    assert len(rec) == 1  # the same kernel, dim and arguments: one record, launched twice
    np.testing.assert_array_equal(y.numpy(), 4.0 * np.arange(4))
    x.assign(np.ones(4, dtype=np.float32))  # a record holds the array, not its values
    rec.launch(axpy, 4, [2.0, x], [y])
    np.testing.assert_array_equal(y.numpy(), 4.0 * np.arange(4) + 2.0)
    rec.launch(axpy, 4, [-1.0, x], [y])  # another scalar: another record
    rec.launch(axpy, 2, [-1.0, x], [y])  # another dimension: another record
    z = wp.zeros(4, dtype=float, device="cpu")
    rec.launch(axpy, 4, [-1.0, x], [z])  # another array: another record
    assert len(rec) == 4
    np.testing.assert_array_equal(y.numpy(), 4.0 * np.arange(4) + 2.0 - 1.0 - np.array([1.0, 1.0, 0.0, 0.0]))
    np.testing.assert_array_equal(z.numpy(), -np.ones(4))


def test_the_records_start_afresh_beyond_max_recorded():
    rec = RecordedLaunches("cpu")
    rec.MAX_RECORDED = 3
    x = wp.ones(2, dtype=float, device="cpu")
    y = wp.zeros(2, dtype=float, device="cpu")
    for a in (1.0, 2.0, 3.0, 4.0):  # a time that grows: a new key every call
        rec.launch(axpy, 2, [a, x], [y])
    assert len(rec) == 1  # cleared at the fourth, which is then the only record
    np.testing.assert_array_equal(y.numpy(), [10.0, 10.0])


def test_cpu_launch_runs_the_recorded_launch_and_follows_set_param_by_name():
    x = wp.array(np.arange(4, dtype=np.float32), device="cpu")
    y = wp.zeros(4, dtype=float, device="cpu")
    cmd = wp.launch(axpy, dim=4, inputs=[2.0, x], outputs=[y], device="cpu", record_cmd=True)
    fast = recorded(cmd)
    assert isinstance(fast, CpuLaunch)
    fast.launch()
    np.testing.assert_array_equal(y.numpy(), 2.0 * np.arange(4))
    fast.set_param_by_name("a", -1.0)  # the structure follows the record's new argument
    fast.launch()
    np.testing.assert_array_equal(y.numpy(), np.arange(4))
    cmd.launch()  # the record itself holds it too
    np.testing.assert_array_equal(y.numpy(), 0.0 * np.arange(4))
    x.assign(np.ones(4, dtype=np.float32))  # arrays are read when launched
    fast.launch()
    np.testing.assert_array_equal(y.numpy(), -np.ones(4))


def test_solver_feels_wind_through_its_recorded_launches():
    """The wind is set on the recorded prediction and air-force launches every step: a cloth in
    a side wind drifts along it, and a change of wind between steps is felt."""
    from warpshade.sim import ClothBuilder, ClothControl, XPBDSolver
    b = ClothBuilder()
    b.add_grid(6, 6, 0.5, 0.5, origin=(-0.25, 1.0, -0.25))
    m = b.finalize()
    solver = XPBDSolver(m, self_collision=False, guard=False)
    control = ClothControl(m)
    s = m.state()
    x0 = s.points.numpy()[:, 0].mean()
    control.wind = (5.0, 0.0, 0.0)
    for _ in range(10):
        solver.step(s, s, 1.0 / 60.0, control)
    x1 = s.points.numpy()[:, 0].mean()
    control.wind = (-20.0, 0.0, 0.0)
    for _ in range(10):
        solver.step(s, s, 1.0 / 60.0, control)
    x2 = s.points.numpy()[:, 0].mean()
    assert x1 > x0 + 1e-4 and x2 < x1 - 1e-4
