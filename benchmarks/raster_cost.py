"""hemiraster's cost per rasterized triangle: the rasterize launches' CPU time over the triangles they rasterize (issue 18).

What it shows: per case, the process CPU time of one frame's rasterize launches
(:meth:`warpshade.visibility.hemiraster.method.HemirasterTransfer._rasterize`, timed around
``wp.synchronize()``; culls, queueing and the far field included, the SH integration and the per-frame
bounds excluded), the triangles they rasterized (``stats()``' counts, summed over receivers) and the
ratio in ns per triangle; the median of ``--rounds`` frames after two warm-up frames (compile excluded),
one Warp CPU thread. With ``--against CHECKOUT`` each case runs in separate processes of this checkout
and of the other one, alternating ``--pairs`` times (load drift hits both), and the medians of the
per-process medians are compared; the triangle counts of the two must be equal.

Cases: ``crumpled2`` (``warpshade.bench.meshes.wrinkled_cloth(64, seed=3, compress=0.75)``, order 5) at
the fastest knobs within 3 % (``--redecimate 0.1 --coarse 256 --mid 2048 --refine 1.5``) and at
``--redecimate 0.1 --min-image 0 --lut 96``; ``front`` and ``back``: the default scene's shading group
at frame 60 (order 4, default knobs; :class:`warpshade.pipeline.shading._Group`, the front pass
``update``, the back pass ``update_back``, each frame right after frame 59, as a run steps them).

Success criteria: none of its own; it is the per-triangle view of issue 18's targets 1 and 5 (the
issue's estimate: ~65 ns per rasterized triangle).

How to run::

    OPENBLAS_NUM_THREADS=1 python benchmarks/raster_cost.py [--cases crumpled2,front] [--rounds 5]
    OPENBLAS_NUM_THREADS=1 python benchmarks/raster_cost.py --against ../main --pairs 5 --json out.json

Numbers come from a shared 2-core VM: read the ratios of one run.
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
CASES = {"crumpled2": {"redecimate": 0.1, "coarse": 256, "mid": 2048, "refine": 1.5},
         "crumpled2-lut96": {"redecimate": 0.1, "min_image": 0.0, "lut": 96},
         "front": {}, "back": {}}


def measure(case: str, rounds: int, tree: str) -> dict:
    """One case in this process, with the ``warpshade`` of checkout ``tree``: median rasterize CPU ms,
    triangles rasterized, ns per triangle."""
    sys.path.insert(0, tree)
    import warp as wp

    wp.config.quiet = True
    wp.init()
    from warpshade.visibility.hemiraster import method as hm

    spent = [0.0]
    rasterize = hm.HemirasterTransfer._rasterize

    def timed(self, *args, **kwargs):
        wp.synchronize()
        t = time.process_time()
        rasterize(self, *args, **kwargs)
        wp.synchronize()
        spent[0] += time.process_time() - t

    hm.HemirasterTransfer._rasterize = timed
    if case in ("front", "back"):
        from warpshade.pipeline.cloth import ClothSimulation
        from warpshade.pipeline.config import resolve_knobs, resolve_run
        from warpshade.pipeline.shading import _Group
        from warpshade.usd import read_scene

        scene = read_scene(os.path.join(REPO, "usd_scenes", "default.usda"))
        (spec,) = resolve_run(scene, method="hemiraster", knobs={}).groups
        sim = ClothSimulation(scene)
        geometry = {}
        for f in range(61):
            g = sim.advance(f, {})
            if f >= 59:
                geometry[f] = {k: np.asarray(v, np.float32).copy() for k, v in g.items()}
        group = _Group(type(spec)(**{**spec.__dict__, "knobs": resolve_knobs("hemiraster", {})}), 4, "cpu")
        method = group.method if case == "front" else group.back_method

        def frame():
            group.update(geometry[59])
            group.update_back()
            spent[0] = 0.0
            group.update(geometry[60])
            if case == "back":
                spent[0] = 0.0
                group.update_back()
    else:
        from warpshade.bench.meshes import wrinkled_cloth
        from warpshade.visibility import get_method

        bm = wrinkled_cloth(64, seed=3, compress=0.75)
        method = get_method("hemiraster")(bm.rest, order=5, **CASES[case])

        def frame():
            method.set_points(bm.frame)
            spent[0] = 0.0
            method._compute()

    times = []
    for r in range(rounds + 2):  # two warm-up frames
        frame()
        wp.synchronize()
        if r >= 2:
            times.append(spent[0])
    ms = float(np.median(times)) * 1e3
    tris = int(method._counts.numpy().sum())
    return {"case": case, "rasterize_ms": ms, "triangles": tris, "ns_per_triangle": ms * 1e6 / tris,
            "rounds_ms": [round(t * 1e3, 2) for t in times], "load": os.getloadavg()[0]}


def child(tree: str, case: str, rounds: int) -> dict:
    """:func:`measure` in a fresh process, with the checkout ``tree``'s code."""
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    out = subprocess.run([sys.executable, os.path.abspath(__file__), "--one", case, "--tree", tree,
                          "--rounds", str(rounds)], env=env, capture_output=True, text=True, check=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--rounds", type=int, default=5, help="timed frames per process")
    ap.add_argument("--against", default=None, metavar="CHECKOUT", help="alternate with this checkout's processes")
    ap.add_argument("--pairs", type=int, default=5, help="processes per checkout and case with --against")
    ap.add_argument("--json", default=None, metavar="PATH")
    ap.add_argument("--one", default=None, help=argparse.SUPPRESS)  # internal: one case, JSON to stdout
    ap.add_argument("--tree", default=REPO, help=argparse.SUPPRESS)  # internal: the checkout --one measures
    args = ap.parse_args(argv)
    if args.one:
        print(json.dumps(measure(args.one, args.rounds, args.tree)))
        return 0
    trees = {"this": REPO} | ({"against": os.path.abspath(args.against)} if args.against else {})
    out = {"rounds": args.rounds, "pairs": args.pairs if args.against else 1, "against": args.against, "cases": {}}
    for case in args.cases.split(","):
        runs = {name: [] for name in trees}
        for p in range(out["pairs"]):
            order = list(trees.items()) if p % 2 == 0 else list(trees.items())[::-1]
            for name, tree in order:
                runs[name].append(child(tree, case, args.rounds))
        row = {}
        for name, rs in runs.items():
            tris = {r["triangles"] for r in rs}
            ms = float(np.median([r["rasterize_ms"] for r in rs]))
            row[name] = {"rasterize_ms": ms, "triangles": tris.pop(), "ns_per_triangle": ms * 1e6 / rs[0]["triangles"],
                         "process_ms": [round(r["rasterize_ms"], 2) for r in rs], "load": [round(r["load"], 1) for r in rs]}
        if args.against:
            if row["this"]["triangles"] != row["against"]["triangles"]:
                raise SystemExit(f"{case}: the checkouts rasterized different triangle counts")
            row["ratio"] = row["this"]["rasterize_ms"] / row["against"]["rasterize_ms"]
        out["cases"][case] = row
        line = " | ".join(f"{n} {r['rasterize_ms']:.1f} ms, {r['ns_per_triangle']:.1f} ns/triangle"
                          for n, r in row.items() if n != "ratio")
        print(f"{case:16s} {row['this']['triangles']:9d} triangles | {line}"
              + (f" | ratio {row['ratio']:.3f}" if args.against else ""), flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
