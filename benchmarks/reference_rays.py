"""Ray-traced reference throughput: CPU time of one ``ReferenceTransfer.update`` on Warp's bunny and bear.

What it shows: what the reference's rays cost (per mesh: seconds per update, million rays per second),
e.g. before and after a change of its ray kernel (run it in each tree, alternating, several times).
Success criteria: none fixed; numbers to compare within one sitting of one machine.
How to run: ``python benchmarks/reference_rays.py [--rays 256] [--order 4] [--repeat 3] [--json out.json]``.

Timing: CPU time (``time.process_time``), median of ``--repeat`` updates after one warm-up update (kernel
compilation excluded), Warp CPU backend, one thread. Numbers come from a shared, loaded 2-core machine.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import warp as wp

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from warpshade.usd import load_mesh  # noqa: E402
from warpshade.bench.timing import median_seconds  # noqa: E402
from warpshade.visibility import get_method  # noqa: E402

ASSETS = os.path.join(os.path.dirname(wp.__file__), "examples", "assets")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--rays", type=int, default=256)
    parser.add_argument("--order", type=int, default=4)
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--meshes", default="bunny,bear")
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)
    wp.config.quiet = True
    rows = []
    print(f"reference transfer, {args.rays} rays, order {args.order}: CPU time, median of {args.repeat} after a "
          "warm-up (shared, loaded machine)")
    print(f"{'mesh':<8}{'vertices':>10}{'s/update':>10}{'Mrays/s':>9}")
    for name in args.meshes.split(","):
        mesh = load_mesh(os.path.join(ASSETS, f"{name}.usd"))
        ref = get_method("reference")(mesh, order=args.order, rays=args.rays)
        sec = median_seconds(ref.update, repeat=args.repeat, warmup=1, clock=time.process_time)
        rays = mesh.num_vertices * ref.knobs()["rays"]
        rows.append({"mesh": name, "vertices": mesh.num_vertices, "rays": ref.knobs()["rays"], "order": args.order,
                     "seconds": sec, "mrays_per_second": rays / sec / 1e6})
        print(f"{name:<8}{mesh.num_vertices:>10}{sec:>10.3f}{rays / sec / 1e6:>9.2f}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
