"""SH exponential accuracy and speed: optimal-linear vs hybrid vs series (thesis eqs. 3.25-3.32).

What it shows:
  1. Accuracy against ||f^|| on realistic inputs: ``f`` = sums of SH logs of 1-64 random sphere blockers
     above a receiver (thesis eq. 3.63). Errors are ``|result - reference| / sqrt(4 pi)`` (a fraction of the
     unoccluded visibility vector), against (a) the exact product exponential ``exp*`` (eq. 3.25, by
     eigen-decomposition) and (b) the true visibility (projection of the product of the blocker
     indicators by 200x400 Gauss-Legendre quadrature).
  2. Stress: blocker-log shapes rescaled to ||f^|| = 1..100 with the DC that makes ``exp*`` O(1); relative
     deviation from ``exp*`` and the fraction of finite results (OL drifts, float64 series cancels).
  3. Time per evaluation: NumPy (batched, float64) and Warp (CPU, float32, one thread per vector), plus
     per-vertex SH products, ZH rotation (array-row vs vector-type accumulation) and rotation matrices.

Success criteria: hybrid error close to exp*'s own error against the truth at every ||f^||; OL error
growing with ||f^||; hybrid finite everywhere.

How to run:
    python benchmarks/sh_exp.py [--orders 5 8] [--quick] [--json sh_exp.json]

Timings are medians of repeated runs after a warm-up run (Warp compilation excluded), taken on a
shared, loaded 2-core machine: compare ratios rather than absolute values.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time

import numpy as np
import warp as wp

from warpshade.sh import sh_eval
from warpshade.sh.exp import DEFAULT_HYBRID_THRESHOLD, SQRT_4PI, sh_exp, training_vectors, zh_log
from warpshade.sh.kernels import (multiply_sh, product_table_arrays, sh_exp_warp, zh_normalization_array,
                                  zh_rotate_accumulate, zh_vector_funcs)
from warpshade.sh.products import product_matrix
from warpshade.sh.projection import sphere_quadrature
from warpshade.sh.rotation import rotation_from_axis_angle, rotation_matrix
from warpshade.sh.zonal import sphere_visibility_zh, zh_rotate
from warpshade.bench.timing import median_seconds

BINS = [0, 1, 2, 5, 10, 20, 35, 50, 100, 1e9]
METHODS = ["ol", "hybrid", "series", "exact"]


def blocker_sets(order, count, rng, dirs, weights):
    """Sums of blocker logs and the true visibility vectors, shapes (count, n*n)."""
    y = sh_eval(dirs, order) * weights[:, None]
    logs, truth = [], []
    for s in range(count):
        k = int(rng.integers(1, [4, 16, 64][s % 3] + 1))
        r = rng.uniform(0.05, 1.0, k)
        d = rng.normal(size=(k, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        d[:, 2] = np.abs(d[:, 2])
        logs.append(zh_rotate(zh_log(sphere_visibility_zh(r, order)), d).sum(0))
        truth.append(np.all(dirs @ d.T < np.cos(r)[None, :], axis=1).astype(float) @ y)
    return np.array(logs), np.array(truth)


def accuracy_table(order, count, rng, quad):
    f, truth = blocker_sets(order, count, rng, *quad)
    mag = np.linalg.norm(f[:, 1:], axis=1)
    with np.errstate(all="ignore"):
        res = {m: sh_exp(f, m) for m in METHODS}
        res["hybrid_warp"] = sh_exp_warp(f, "hybrid").astype(np.float64)
        res["ol_warp"] = sh_exp_warp(f, "ol").astype(np.float64)
    rows = []
    for lo, hi in zip(BINS[:-1], BINS[1:]):
        sel = (mag >= lo) & (mag < hi)
        if not sel.any():
            continue
        row = {"bin": [lo, hi if hi < 1e9 else None], "count": int(sel.sum())}
        for name, r in res.items():
            e_truth = np.linalg.norm(r[sel] - truth[sel], axis=1) / SQRT_4PI
            e_exact = np.linalg.norm(r[sel] - res["exact"][sel], axis=1) / SQRT_4PI
            row[name] = {"vs_truth_median": float(np.median(e_truth)), "vs_truth_max": float(e_truth.max()),
                         "vs_exact_median": float(np.median(e_exact)), "vs_exact_max": float(e_exact.max())}
        rows.append(row)
    return rows


def stress_table(order, count):
    u = training_vectors(order, count, seed=123)
    lam_max = np.linalg.eigvalsh(product_matrix(u)).max(axis=1)
    rows = []
    for m in [1.0, 5.0, 10.0, 20.0, 50.0, 75.0, 100.0]:
        f = m * u
        f[:, 0] = -SQRT_4PI * m * lam_max
        with np.errstate(all="ignore"):
            ex = sh_exp(f, "exact")
            row = {"magnitude": m}
            for name in ["ol", "hybrid", "series"]:
                r = sh_exp(f, name)
                fin = np.all(np.isfinite(r), axis=1)
                e = np.linalg.norm(r - ex, axis=1) / np.linalg.norm(ex, axis=1)
                row[name] = {"finite": float(fin.mean()), "rel_median": float(np.median(np.where(fin, e, np.inf)))}
            r = sh_exp_warp(f, "hybrid").astype(np.float64)
            e = np.linalg.norm(r - ex, axis=1) / np.linalg.norm(ex, axis=1)
            row["hybrid_warp"] = {"finite": float(np.all(np.isfinite(r), axis=1).mean()), "rel_median": float(np.median(e))}
        rows.append(row)
    return rows


@wp.kernel(enable_backward=False)
def _rotate_rows(d: wp.array2d[wp.vec3], zh: wp.array2d[float], order: int, kz: wp.array[float],
                 out: wp.array2d[float]):
    v = wp.tid()
    for b in range(d.shape[1]):
        zh_rotate_accumulate(d[v, b], zh, b, 1.0, order, kz, out, v)


def timing_table(order, n, repeat, rng):
    u = training_vectors(order, 64, seed=7)
    f = np.concatenate([m * u for m in np.linspace(0.5, 50, (n + 63) // 64)])[:n]
    f[:, 0] = -3.0
    out = {}
    for name in METHODS:
        k = n if name in ("ol", "hybrid") else max(8, n // 32)
        t = median_seconds(lambda: sh_exp(f[:k], name), repeat=repeat)
        out[f"numpy_{name}_us"] = t / k * 1e6
    for name in ["ol", "hybrid"]:
        t = median_seconds(lambda: sh_exp_warp(f, name), repeat=repeat)
        out[f"warp_{name}_us"] = t / n * 1e6
    # Per-vertex products (the inner loop of the hybrid squarings).
    nn = order * order
    a = wp.array(rng.normal(size=(n, nn)).astype(np.float32), dtype=float)
    b = wp.array(rng.normal(size=(n, nn)).astype(np.float32), dtype=float)
    c = wp.zeros((n, nn), dtype=float)
    table = product_table_arrays(order)
    t = median_seconds(lambda: wp.launch(multiply_sh, dim=n, inputs=[a, b, nn, table], outputs=[c]), repeat=repeat)
    out["warp_product_us"] = t / n * 1e6
    # ZH rotation: 32 lobes per vertex, row accumulation vs vector-type accumulation.
    lobes = 32
    d = wp.array(rng.normal(size=(n, lobes, 3)).astype(np.float32), dtype=wp.vec3)
    zh = rng.normal(size=(lobes, order)).astype(np.float32)
    rows = wp.zeros((n, nn), dtype=float)
    kz = zh_normalization_array(order)
    zha = wp.array(zh, dtype=float)

    def run_rows():
        rows.zero_()
        wp.launch(_rotate_rows, dim=n, inputs=[d, zha, order, kz], outputs=[rows])

    out["warp_zh_rotate_rows_ns"] = median_seconds(run_rows, repeat=repeat) / (n * lobes) * 1e9
    fn = zh_vector_funcs(order)
    vec_out = wp.zeros(n, dtype=fn.vec_sh)
    zhv = wp.array(zh, dtype=fn.vec_zh)
    kzv = fn.zh_constants()
    kernel = fn.accumulate_lobes
    out["warp_zh_rotate_vector_ns"] = median_seconds(
        lambda: wp.launch(kernel, dim=n, inputs=[d, zhv, kzv], outputs=[vec_out]), repeat=repeat) / (n * lobes) * 1e9
    r = rotation_from_axis_angle([1.0, 2.0, 3.0], 0.7)
    out["numpy_rotation_matrix_ms"] = median_seconds(lambda: rotation_matrix(r, order), repeat=repeat) * 1e3
    return out


def fmt(x):
    return f"{x:.1e}" if x < 1e3 else f"{x:.0e}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--orders", type=int, nargs="+", default=[5, 8])
    ap.add_argument("--quick", action="store_true", help="fewer samples and repeats")
    ap.add_argument("--json", metavar="PATH", help="write all numbers as JSON")
    args = ap.parse_args(argv)
    wp.config.log_level = wp.LOG_WARNING  # no init banner or module-load lines
    wp.init()
    rng = np.random.default_rng(0)
    count = 60 if args.quick else 300
    repeat = 3 if args.quick else 7
    quad = sphere_quadrature(200, 400)
    result = {"machine": platform.processor() or platform.machine(), "python": sys.version.split()[0],
              "warp": wp.__version__, "hybrid_threshold": DEFAULT_HYBRID_THRESHOLD,
              "note": "shared, loaded 2-core machine; medians after warm-up, compilation excluded", "orders": {}}
    for order in args.orders:
        t0 = time.perf_counter()
        acc = accuracy_table(order, count, rng, quad)
        stress = stress_table(order, 16 if args.quick else 48)
        timing = timing_table(order, 2048 if args.quick else 8192, repeat, rng)
        result["orders"][str(order)] = {"accuracy": acc, "stress": stress, "timing": timing}
        print(f"\n## order {order}  ({order * order} coefficients; {count} blocker sets; hybrid threshold "
              f"{DEFAULT_HYBRID_THRESHOLD}; {time.perf_counter() - t0:.0f} s)")
        print("\nError |exp - truth| / sqrt(4pi), median (max), truth = projected product of blocker indicators")
        print("| ‖f̂‖ | n | OL | hybrid | series | exact exp* | hybrid Warp f32 |")
        print("| --- | --- | --- | --- | --- | --- | --- |")
        for row in acc:
            lo, hi = row["bin"]
            cells = [f"{fmt(row[m]['vs_truth_median'])} ({fmt(row[m]['vs_truth_max'])})"
                     for m in ["ol", "hybrid", "series", "exact", "hybrid_warp"]]
            print(f"| {lo}–{hi if hi is not None else '∞'} | {row['count']} | " + " | ".join(cells) + " |")
        print("\nDeviation from exact exp*, |exp - exp*| / sqrt(4pi), median")
        print("| ‖f̂‖ | OL | hybrid | series | hybrid Warp f32 |")
        print("| --- | --- | --- | --- | --- |")
        for row in acc:
            lo, hi = row["bin"]
            cells = [fmt(row[m]["vs_exact_median"]) for m in ["ol", "hybrid", "series", "hybrid_warp"]]
            print(f"| {lo}–{hi if hi is not None else '∞'} | " + " | ".join(cells) + " |")
        print("\nStress: rescaled shapes, DC so that exp* = O(1); relative deviation from exp* (median), finite fraction")
        print("| ‖f̂‖ | OL | hybrid | series (f64) | hybrid Warp f32 |")
        print("| --- | --- | --- | --- | --- |")
        for row in stress:
            cells = [f"{fmt(row[m]['rel_median'])} ({row[m]['finite']:.0%} finite)"
                     for m in ["ol", "hybrid", "series", "hybrid_warp"]]
            print(f"| {row['magnitude']:g} | " + " | ".join(cells) + " |")
        t = timing
        print("\nTime per evaluation (µs; ‖f̂‖ spread over 0.5..50)")
        print("| | OL | hybrid | series | exact | product | ZH rotate rows / vector (ns) | rotation matrix (ms) |")
        print("| --- | --- | --- | --- | --- | --- | --- | --- |")
        print(f"| NumPy f64 | {t['numpy_ol_us']:.2f} | {t['numpy_hybrid_us']:.1f} | {t['numpy_series_us']:.0f} | "
              f"{t['numpy_exact_us']:.0f} | | | {t['numpy_rotation_matrix_ms']:.2f} |")
        print(f"| Warp f32 | {t['warp_ol_us']:.2f} | {t['warp_hybrid_us']:.1f} | | | {t['warp_product_us']:.2f} | "
              f"{t['warp_zh_rotate_rows_ns']:.0f} / {t['warp_zh_rotate_vector_ns']:.0f} | |")
    print("\nTimings: shared, loaded 2-core machine; medians of repeats after a warm-up run, compilation excluded.")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(result, fh, indent=1)
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
