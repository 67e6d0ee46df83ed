"""Free drape benchmark (issue 19): cloth dropped on a sphere, no pins, at the solver's default substeps.

What it measures: ``sims/drape_sphere.py``'s scene (a 1.6 m square cloth falling onto a 0.35 m sphere on
the ground) stepped with ``XPBDSolver`` alone at its default 6 substeps, per grid: the p99 edge strain of
the worst frame (from frame 5 on) and of the last (at rest after 3 s at the default 180 frames), the guard's
steps and longest hold, the most intersecting triangle pairs at every tenth frame's end, the mean speed at
the end and the median process time a step (after frame 5; kernels cached, shared machine: rough).

Run:  python benchmarks/free_drape.py --grids 40 48 56 --solver '{"limit_sliding": true}' --json out.json
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np
import warp as wp

sys.path.insert(0, os.path.abspath(os.path.join(os.path.dirname(__file__), "..")))

from warpshade.geometry import ulp_jitter
from warpshade.sim import ClothBuilder, ColliderSet, IntersectionCounter, XPBDSolver

CENTER = (0.0, 0.35, 0.0)
RADIUS = 0.35


def drape(n: int, frames: int, solver_kw: dict, seed: int | None = None) -> dict:
    """One run on an n x n grid (``seed``: cloth coordinates jittered by an ulp, as benchmarks/cloth.py's
    ``--perturb`` does)."""
    b = ClothBuilder(bend_stiffness=2e-5)
    b.add_grid(n, n, 1.6, 1.6, origin=(-0.8, 1.0, -0.8))
    if seed is not None:
        for k, pc in enumerate(b._pieces):
            pc.points = ulp_jitter(pc.points, seed * 1000 + k).astype(np.float64)
    m = b.finalize()
    col = ColliderSet()
    col.add_plane((0.0, 1.0, 0.0), 0.0, friction=0.6)
    col.add_sphere(CENTER, RADIUS, friction=0.4)
    solver = XPBDSolver(m, col, **solver_kw)
    counter = IntersectionCounter(m.faces)
    st = m.state()
    p99, times, pairs = [], [], 0
    for f in range(frames):
        t = time.process_time()
        solver.step(st, st, 1.0 / 60.0)
        times.append(time.process_time() - t)
        p99.append(float(np.percentile(m.edge_strain(st.points.numpy()), 99)))
        if f % 10 == 9 or f == frames - 1:
            pairs = max(pairs, counter.self_pairs(st.points)[0] + counter.collider_pairs(st.points, col)[0])
    x, v = st.points.numpy(), st.velocities.numpy()
    stats = solver.stats()
    return {"grid": n, "seed": seed, "worst_p99_strain": max(p99[5:]), "end_p99_strain": p99[-1],
            "guard_steps": stats["guard_steps"], "longest_hold": stats["guard_longest_hold"], "max_pairs": int(pairs),
            "mean_speed": float(np.linalg.norm(v, axis=1).mean()),
            "min_sphere_gap": float((np.linalg.norm(x - np.array(CENTER), axis=1) - RADIUS).min()),
            "thickness": m.thickness, "ms_per_step": 1e3 * float(np.median(times[5:]))}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--grids", type=int, nargs="+", default=[40, 48, 56], help="vertices per side")
    ap.add_argument("--frames", type=int, default=180, help="1/60 s frames per run")
    ap.add_argument("--solver", default="{}", help="XPBDSolver keyword arguments, JSON")
    ap.add_argument("--seeds", type=int, nargs="*", default=None, help="also runs jittered by an ulp, per seed")
    ap.add_argument("--json", help="write the rows to this file")
    args = ap.parse_args(argv)
    wp.config.log_level = wp.LOG_WARNING
    kw = json.loads(args.solver)
    rows = []
    print(f"free drape, {args.frames} frames, solver {kw}")
    print(f"{'grid':>5}{'seed':>6}{'worst p99':>10}{'end p99':>9}{'guard':>7}{'hold':>6}{'pairs':>6}{'speed':>8}{'ms/step':>9}")
    for n in args.grids:
        for seed in [None] + list(args.seeds or []):
            r = drape(n, args.frames, kw, seed)
            rows.append(r)
            print(f"{n:>5}{'-' if seed is None else seed:>6}{r['worst_p99_strain']:>9.2%}{r['end_p99_strain']:>9.2%}"
                  f"{r['guard_steps']:>7}{r['longest_hold']:>6}{r['max_pairs']:>6}{r['mean_speed']:>8.3f}"
                  f"{r['ms_per_step']:>9.1f}", flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"frames": args.frames, "solver": kw, "rows": rows}, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
