"""Cost of two-sided shading (``warpshade run --two-sided``): shading time per frame with and without the back sides.

What it measures: on every shipped scene with a cloth (``usd_scenes/``), the per-frame ``shade`` call that
``warpshade run`` makes (:class:`warpshade.pipeline.shading.SceneShader`, inline), once with the default
(``--two-sided auto``: cloth shaded on both sides) and once with ``--two-sided off``, on the same simulated
frame; the two are timed interleaved (A, B, A, B...) after one warm-up call each (kernel compilation
excluded), and the median of each is printed with the planner's estimate (:mod:`warpshade.planner`) of
both, and the build time of each shader.

Success criteria: the back side costs at most about one more pass of the shading group's visibility
method (a ratio on/off of about 2 or less): the pass runs on the whole group (with ``reference`` and static
other members, on the two-sided members alone: :func:`warpshade.pipeline.shading.back_side_receivers`).
From the back a drape sees the ground and the body it lies on, so its pass rasterizes more than the
front's, which sees mostly sky.

How to run::

    python benchmarks/two_sided.py [--frame 30] [--repeat 5] [--order 4] [--scenes default flag_wind] [--json PATH]

Wall time on a shared, loaded machine (±20 %): compare the two columns of one run, not runs.
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import platform
import sys
import time

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

SCENES = os.path.join(os.path.dirname(__file__), "..", "usd_scenes")


def _frame_geometry(pipe, frame: int) -> dict:
    """Positions of every moving object at ``frame``, simulated as ``warpshade run`` does."""
    from warpshade.pipeline import ClothSimulation

    sims = ClothSimulation(pipe.scene, pipe.device) if any(o.kind == "cloth" for o in pipe.scene.objects) else None
    secs = {"simulate": 0.0}
    for f, geo in pipe._geometry_frames(sims, secs):
        if f == frame:
            return geo
    raise ValueError(f"{pipe.scene.source}: has {pipe.frames} frames, asked for frame {frame}")


def measure(path: str, frame: int, repeat: int, order: int) -> dict:
    import warp as wp

    from warpshade.pipeline import Pipeline
    from warpshade.planner import make_plan
    from warpshade.usd import read_scene

    row = {"scene": os.path.basename(path)}
    shaders, plans = {}, {}
    for mode in ("auto", "off"):
        scene = read_scene(path)
        pipe = Pipeline(scene, order=order, two_sided=mode)
        t = time.perf_counter()
        shaders[mode] = pipe.shader.build()
        row[f"build_s_{mode}"] = time.perf_counter() - t
        scene.settings["order"] = order
        plans[mode] = make_plan(scene, two_sided=mode).run_seconds_per_frame
        if mode == "auto":
            row["two_sided"] = [n for g in pipe.groups for n, t2 in zip(g.names, g.two_sided) if t2]
        row["vertices"] = sum(m.num_vertices for g in pipe.groups for m in g.meshes)
        geo = _frame_geometry(pipe, min(frame, pipe.frames - 1))
    times = {"auto": [], "off": []}
    for mode in times:  # warm-up
        shaders[mode](frame, geo)
    for _ in range(repeat):
        for mode in times:
            t = time.perf_counter()
            shaders[mode](frame, geo)
            wp.synchronize()
            times[mode].append(time.perf_counter() - t)
    for mode in times:
        row[f"shade_s_{mode}"] = float(np.median(times[mode]))
        row[f"plan_s_{mode}"] = plans[mode]
    row["ratio"] = row["shade_s_auto"] / row["shade_s_off"]
    return row


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frame", type=int, default=30, help="frame whose geometry is shaded (default 30)")
    ap.add_argument("--repeat", type=int, default=5, help="timed calls per mode after one warm-up (default 5)")
    ap.add_argument("--order", type=int, default=4, help="SH order (default 4, warpshade run's)")
    ap.add_argument("--scenes", nargs="*", default=None, help="scene names in usd_scenes/ (default: those with a cloth)")
    ap.add_argument("--json", default=None, metavar="PATH", help="also write the rows as JSON")
    args = ap.parse_args(argv)
    paths = sorted(glob.glob(os.path.join(SCENES, "*.usda")))
    if args.scenes:
        paths = [os.path.join(SCENES, f"{s}.usda") for s in args.scenes]
    else:
        from warpshade.usd import read_scene

        paths = [p for p in paths if any(o.kind == "cloth" for o in read_scene(p).objects)]
    rows = []
    print(f"{'scene':18s} {'verts':>6s} {'two-sided':>22s} {'on ms':>8s} {'off ms':>8s} {'on/off':>6s} "
          f"{'plan on':>8s} {'plan off':>8s} {'build on/off s':>15s}")
    for p in paths:
        r = measure(p, args.frame, args.repeat, args.order)
        rows.append(r)
        print(f"{r['scene']:18s} {r['vertices']:6d} {','.join(r['two_sided']):>22s} {r['shade_s_auto'] * 1e3:8.1f} "
              f"{r['shade_s_off'] * 1e3:8.1f} {r['ratio']:6.2f} {r['plan_s_auto'] * 1e3:8.1f} "
              f"{r['plan_s_off'] * 1e3:8.1f} {r['build_s_auto']:7.2f}/{r['build_s_off']:.2f}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"machine": platform.node(), "frame": args.frame, "repeat": args.repeat, "order": args.order,
                       "rows": rows}, fh, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
