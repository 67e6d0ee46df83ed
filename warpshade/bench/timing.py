"""Timing shared by the CLI and the benchmarks: medians of repeated runs after a warm-up."""

from __future__ import annotations

import statistics
import time

import warp as wp


def median_seconds(fn, repeat: int = 3, warmup: int = 1, clock=time.perf_counter) -> float:
    """Median wall time of ``fn()`` over ``repeat`` runs after ``warmup`` runs.

    The warm-up run absorbs Warp kernel compilation and cache loading, so they are excluded.
    Each run ends with ``wp.synchronize()`` so asynchronous launches are counted. ``clock`` may be
    ``time.process_time`` for this process's CPU time (what an idle core would need on a shared,
    oversubscribed machine; the CPU kernels are single-threaded).
    """
    for _ in range(warmup):
        fn()
        wp.synchronize()
    times = []
    for _ in range(max(1, repeat)):
        t0 = clock()
        fn()
        wp.synchronize()
        times.append(clock() - t0)
    return statistics.median(times)


def time_transfer(method, repeat: int = 3) -> float:
    """Median seconds of ``method.update()`` (transfer only: no file I/O, no compilation)."""
    return median_seconds(method.update, repeat=repeat, warmup=1)
