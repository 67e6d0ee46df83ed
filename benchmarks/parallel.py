"""Shading throughput with 1 and 2 worker processes, a local Dask cluster and a loopback Dask cluster.

What it shows: frames shaded per second by :func:`warpshade.parallel.shade_frames` for a deforming
mesh, and the speedup of 2 workers over 1 (target >= 1.7x on a 2-core machine).
How to run: ``python benchmarks/parallel.py [--mesh bunny.usd] [--method reference] [--frames 24]
[--json out.json]``. Worker start-up (process spawn, Warp kernel loading, static structures) is
timed separately and excluded from frames per second, like kernel compilation elsewhere.
Numbers depend on what else runs on the machine: run it on an otherwise idle machine.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np
import warp as wp

from warpshade.parallel.cluster import loopback_cluster
from warpshade.usd import load_mesh
from warpshade.parallel import TransferSpec, shade_frames

wp.config.log_level = wp.LOG_WARNING  # no init banner or module-load lines


def frames(mesh, n, start=0):
    for f in range(start, start + n):
        s = 1.0 + 0.05 * np.sin(0.7 * f + mesh.points[:, 1:2] * 3.0)
        yield f, {"mesh": (mesh.points * s).astype(np.float32)}


def measure(spec, mesh, n, **kw):
    """Frames/s over ``n`` frames after the first 2 (start-up, warm-up) have been returned."""
    t_start = time.perf_counter()
    t0 = None
    count = 0
    for f, _ in shade_frames(spec, frames(mesh, n + 2), **kw):
        count += 1
        if count == 2:
            t0 = time.perf_counter()
    t1 = time.perf_counter()
    return {"frames_per_second": n / (t1 - t0), "startup_seconds": t0 - t_start, "frames": n}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--mesh", default=os.path.join(os.path.dirname(wp.__file__), "examples", "assets", "bunny.usd"))
    ap.add_argument("--method", default="reference")
    ap.add_argument("--knobs", default='{"rays": 64}', help="method knobs as JSON")
    ap.add_argument("--order", type=int, default=5)
    ap.add_argument("--frames", type=int, default=24)
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    mesh = load_mesh(args.mesh)
    spec = TransferSpec({"mesh": mesh}, method=args.method, order=args.order, knobs=json.loads(args.knobs))
    rows = []
    configs = [("inline (no processes)", dict(workers=0)),
               ("1 worker process", dict(workers=1)),
               ("2 worker processes", dict(workers=2)),
               ("dask LocalCluster, 2 workers", dict(workers=2, scheduler="local"))]
    for name, kw in configs:
        r = measure(spec, mesh, args.frames, **kw)
        rows.append({"config": name, **r})
        print(f"{name:36s} {r['frames_per_second']:8.2f} frames/s  (start-up {r['startup_seconds']:.1f} s)",
              flush=True)
    with loopback_cluster(workers=2) as address:
        r = measure(spec, mesh, args.frames, scheduler=address)
    rows.append({"config": "dask scheduler + 2 workers (loopback processes)", **r})
    print(f"{rows[-1]['config']:36s} {r['frames_per_second']:8.2f} frames/s  (start-up {r['startup_seconds']:.1f} s)")
    one = rows[1]["frames_per_second"]
    for row in rows:
        row["speedup_vs_1_worker"] = row["frames_per_second"] / one
    print(f"\nspeedup 2 processes / 1: {rows[2]['speedup_vs_1_worker']:.2f}x   "
          f"dask loopback / 1: {rows[-1]['speedup_vs_1_worker']:.2f}x   "
          f"({mesh.num_vertices} vertices, method {args.method} {args.knobs}, order {args.order}; "
          f"cores: {os.cpu_count()})")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"mesh": mesh.name, "method": args.method, "knobs": json.loads(args.knobs), "rows": rows}, f,
                      indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
