"""A shading worker's build of the default scene's group, with hemiraster's disk cache cold and warm (issue 18).

What it shows: ``warpshade run`` builds, in each shading worker process, the default scene's one shading
group (:class:`warpshade.pipeline.shading._Group`: hemiraster's front pass and the cloth's back pass)
before its first frame. This script does what a worker does in a fresh process per measurement (start
Warp, read ``usd_scenes/default.usda``, build the group) and reports the process CPU seconds of the
build alone, with the disk cache (:mod:`warpshade._cache`: far field and plane LUT) **cold** (an empty
directory), **warm** (filled by a previous build of the same checkout) and, with ``--against CHECKOUT``,
that checkout's build with its cache off (main before the cache: it builds everything every time) or, with
``--against-warm``, with a warm cache of its own (a change of the warm build against main). Also the CPU
seconds of reading the scene (``read_scene``: what the run's parent does before the group is built; a
``Sphere``'s icosphere comes from the disk cache too). The arms alternate in
each round so load drift hits all alike; medians over ``--repeat`` rounds. Warp's kernels are loaded
from its kernel cache (compiled beforehand by an untimed process of each checkout), so no compile time
is in any figure.

Success criteria: none of its own; it is a part of issue 18's target 5 (a warm-cache run of the default
scene in <= 5 s), whose wall time ``benchmarks/default_run.py`` measures.

How to run::

    OPENBLAS_NUM_THREADS=1 python benchmarks/build_cache.py [--repeat 5] [--against /path/to/main [--against-warm]] [--json out.json]

Numbers come from a shared 2-core VM: CPU seconds are the figure to trust, wall seconds are printed beside.
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import statistics
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)

CHILD = r"""
import json, os, sys, time
import warp as wp
wp.config.quiet = True
wp.init()
import warpshade
from warpshade.pipeline.config import resolve_run
from warpshade.pipeline.shading import _Group
from warpshade.usd import read_scene
c = time.process_time()
scene = read_scene(os.path.join(sys.argv[1], "usd_scenes", "default.usda"))
read = time.process_time() - c
(spec,) = resolve_run(scene, method="hemiraster", knobs={}).groups
c, w = time.process_time(), time.perf_counter()
g = _Group(spec, 4, "cpu")
c, w = time.process_time() - c, time.perf_counter() - w
try:
    from warpshade import _cache
    hits = {f"{k[0]} {k[1]}": v for k, v in _cache.stats.items()}
except ImportError:
    hits = {}
print(json.dumps({"cpu": c, "wall": w, "read_cpu": read, "file": warpshade.__file__, "cache": hits}))
"""


def child(checkout: str, cache: str) -> dict:
    env = {**os.environ, "PYTHONPATH": checkout, "WARPSHADE_CACHE": cache, "OPENBLAS_NUM_THREADS": "1"}
    out = subprocess.run([sys.executable, "-c", CHILD, checkout], env=env, cwd=checkout, capture_output=True, text=True,
                         check=True)
    res = json.loads(out.stdout.strip().splitlines()[-1])
    assert res["file"].startswith(os.path.abspath(checkout)), res["file"]
    return res


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--against", default=None, metavar="CHECKOUT", help="another checkout's build, alternating")
    ap.add_argument("--against-warm", action="store_true",
                    help="the other checkout with a warm cache of its own (default: its cache off)")
    ap.add_argument("--json", default=None, metavar="PATH")
    args = ap.parse_args(argv)
    tmp = tempfile.mkdtemp(prefix="warpshade-build-cache-")
    cold, warm = os.path.join(tmp, "cold"), os.path.join(tmp, "warm")
    other = os.path.join(tmp, "against") if args.against_warm else "none"
    try:
        child(ROOT, warm)  # untimed: loads (or compiles) the kernels, fills the warm cache
        if args.against:
            child(args.against, other)
        arms = {"cold": [], "warm": []} | ({"against": []} if args.against else {})
        for r in range(args.repeat):
            shutil.rmtree(cold, ignore_errors=True)
            arms["cold"].append(child(ROOT, cold))
            arms["warm"].append(child(ROOT, warm))
            if args.against:
                arms["against"].append(child(args.against, other))
            print(f"round {r + 1}: " + ", ".join(f"{k} {v[-1]['cpu']:.3f} s" for k, v in arms.items()), flush=True)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    print(f"\nthe default scene's group built in a fresh process, CPU seconds (wall), median of {args.repeat}:")
    summary = {}
    for k, runs in arms.items():
        summary[k] = {"cpu_median": statistics.median(x["cpu"] for x in runs),
                      "wall_median": statistics.median(x["wall"] for x in runs),
                      "cpu": [x["cpu"] for x in runs], "wall": [x["wall"] for x in runs], "cache": runs[-1]["cache"]}
        if all("read_cpu" in x for x in runs):
            summary[k].update(read_cpu_median=statistics.median(x["read_cpu"] for x in runs), read_cpu=[x["read_cpu"] for x in runs])
        label = {"cold": "cache cold", "warm": "cache warm",
                 "against": f"{args.against} (cache {'warm' if args.against_warm else 'off'})"}[k]
        read = f"; reading the scene {summary[k]['read_cpu_median']:.3f} s" if "read_cpu_median" in summary[k] else ""
        print(f"  {label:40s} {summary[k]['cpu_median']:.3f} s ({summary[k]['wall_median']:.3f} s){read}   {runs[-1]['cache']}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"script": "benchmarks/build_cache.py", "repeat": args.repeat, "against": args.against,
                       "against_cache": "warm" if args.against_warm else "off",
                       "load_average": os.getloadavg(), "arms": summary}, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
