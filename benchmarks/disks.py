"""Disk-hierarchy occlusion benchmark: transfer error and time against the ray-traced reference.

What it shows: per-frame cost and relative L2 transfer error (warpshade.bench.metrics) of ``disks`` over
its knob sweep, next to the ray-traced reference at low ray counts and, when registered,
hemispherical rasterization (``hemiraster``), on Warp's bunny and bear.
Success criteria: disks' error well below the unoccluded transfer's, at a fraction of the time of
ray tracing with comparable error.
How to run: ``python benchmarks/disks.py [--quick] [--json out.json]``. The 4096-ray ground truth
is cached in ``benchmarks/cache/`` (gitignored) after the first run.

Timing: median of ``--repeat`` runs after one warm-up run (kernel compilation excluded), Warp CPU
backend. Numbers come from a shared, loaded 2-core machine: compare within one run only.
"""

from __future__ import annotations

import argparse
import json
import os
import sys

import warp as wp

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from warpshade.bench.reference_cache import ground_truth  # noqa: E402
from warpshade.usd import load_mesh  # noqa: E402
from warpshade.bench.metrics import error_summary  # noqa: E402
from warpshade.sh import unoccluded_transfer  # noqa: E402
from warpshade.bench.timing import time_transfer  # noqa: E402
from warpshade.visibility import METHODS, get_method  # noqa: E402

ASSETS = os.path.join(os.path.dirname(wp.__file__), "examples", "assets")
CACHE = os.path.join(os.path.dirname(__file__), "cache")
TRUTH_RAYS = 4096


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="fewer configurations")
    ap.add_argument("--order", type=int, default=5)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", default=None, help="write the records here")
    args = ap.parse_args()
    wp.config.log_level = wp.LOG_WARNING  # no init banner or module-load lines
    meshes = ["bear.usd"] if args.quick else ["bunny.usd", "bear.usd"]
    configs = [("disks", k) for k in get_method("disks").sweep(args.quick)]
    configs += [("disks", {"sides": "two"})] if not args.quick else []
    configs += [("reference", {"rays": n}) for n in ((64, 256) if args.quick else (64, 256, 1024))]
    if "hemiraster" in METHODS:
        configs += [("hemiraster", k) for k in get_method("hemiraster").sweep(True)]
    records = []
    print("Disk occlusion benchmark (Warp CPU, one thread; shared loaded machine: compare within this run)")
    for name in meshes:
        mesh = load_mesh(os.path.join(ASSETS, name))
        print(f"\n{name}: {mesh.num_vertices} vertices, {mesh.num_faces} triangles, order {args.order}")
        truth = ground_truth(mesh, args.order, TRUTH_RAYS, cache_dir=CACHE, log=print)
        e0 = error_summary(unoccluded_transfer(mesh.normals, args.order), truth)
        print(f"{'method':11} {'knobs':52} {'ms':>8} {'err mean':>9} {'err p95':>8} {'err max':>8}")
        print(f"{'unoccluded':11} {'(no visibility)':52} {'':8} {e0['error_mean']:9.4f} {e0['error_p95']:8.4f} "
              f"{e0['error_max']:8.4f}")
        for method, knobs in configs:
            m = get_method(method)(mesh, order=args.order, **knobs)
            sec = time_transfer(m, repeat=args.repeat)
            err = error_summary(m.transfer_numpy(), truth)
            rec = {"method": method, "mesh": name, "knobs": m.knobs(), "seconds": sec, **err, **m.stats()}
            records.append(rec)
            ks = json.dumps(m.knobs())
            print(f"{method:11} {ks:52} {sec * 1e3:8.1f} {err['error_mean']:9.4f} {err['error_p95']:8.4f} "
                  f"{err['error_max']:8.4f}", flush=True)
    print(f"\nerror: relative L2 transfer error (warpshade.bench.metrics) against {TRUTH_RAYS} stratified rays per vertex.")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(records, f, indent=2)
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
