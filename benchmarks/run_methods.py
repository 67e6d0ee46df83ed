"""Which visibility method should `warpshade run` use by default? Speed and radiance error per method
on frames of a shipped scene.

What it shows: the scene is simulated once (frames 0, 40, 80, 120 kept); each registered method
(default knobs, plus reference at 256 rays and unshadowed transfer) shades those frames through
the pipeline's own :class:`warpshade.pipeline.SceneShader` (one shading group: every object
shadows every other); the error is :func:`warpshade.bench.metrics.radiance_error` of the exit radiance
against reference transfer at 4096 rays (0.26 % transfer error, docs/methods/reference.md).

Success criteria: the default method (``warpshade.pipeline.METHOD_PREFERENCE``) is the fastest one
whose error is close to reference@256's.

Run:  python benchmarks/run_methods.py [--scene usd_scenes/default.usda] [--json out.json]
      [--variant min_image=0,lut=96]   (hemiraster with other knobs beside its defaults; repeatable)

Times: median seconds per frame over the 3 frames after the first (the first frame absorbs kernel
compilation and caches), structure building excluded; a shared, loaded 2-core machine.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

FRAMES = (0, 40, 80, 120)


def _object_keys(result: dict) -> list:
    """The shaded objects' keys of a ``shade`` result in a fixed order: front sides (names), then back sides
    (``back_key(name)`` tuples); the ``"_seconds"``-style entries left out."""
    fronts = sorted(k for k in result if isinstance(k, str) and not k.startswith("_"))
    return fronts + sorted(k for k in result if isinstance(k, tuple))

def main(argv=None) -> int:
    import warp as wp

    wp.config.log_level = wp.LOG_WARNING
    from warpshade.bench.metrics import radiance_error
    from warpshade.pipeline import Pipeline
    from warpshade.pipeline.cloth import ClothSimulation
    from warpshade.usd import read_scene
    from warpshade.visibility import METHODS

    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--scene", default=os.path.join(here, "usd_scenes", "default.usda"))
    p.add_argument("--order", type=int, default=4)
    p.add_argument("--json", default=None)
    p.add_argument("--variant", action="append", default=[], metavar="KNOBS",
                   help="also run hemiraster with these knobs (name=value,...; e.g. min_image=0,lut=96; repeatable)")
    args = p.parse_args(argv)
    from warpshade.bench.animation import parse_variant

    variants = []
    for text in args.variant:
        v = parse_variant(text)
        if v["reuse"] is not None:
            raise ValueError(f"--variant {text!r}: reuse needs consecutive frames; run_methods shades frames {FRAMES}")
        variants.append(("hemiraster " + " ".join(f"{k}={x}" for k, x in v["knobs"].items()), "hemiraster", v["knobs"]))

    scene = read_scene(args.scene)
    frames = [f for f in FRAMES if f < scene.frames] or [0]
    geos, sim = {}, ClothSimulation(scene) if any(o.kind == "cloth" for o in scene.objects) else None
    for f in range(max(frames) + 1):
        g = {o.name: np.asarray(o.params["points_at"](f), np.float32) for o in scene.objects
             if o.kind in ("animated", "skinned")}
        if sim is not None:
            g.update(sim.advance(f, g))
        if f in frames:
            geos[f] = {k: v.copy() for k, v in g.items()}

    configs = [("reference@4096", "reference", {"rays": 4096}), ("reference@256", "reference", {"rays": 256})]
    configs += [(m, m, {}) for m in sorted(METHODS) if m != "reference"]
    configs += variants
    configs.append(("unshadowed", None, {}))
    radiance, rows = {}, []
    for label, method, knobs in configs:
        pipe = Pipeline(scene, method=method or "reference", knobs=knobs, order=args.order)
        if method is None:
            for g in pipe.shader.groups:
                g.method, g.knobs = None, {}
        t0 = time.perf_counter()
        shade = pipe.shader.build()
        build = time.perf_counter() - t0
        times, radiance[label] = [], {}
        for f, g in geos.items():
            t0 = time.perf_counter()
            r = shade(f, g)
            times.append(time.perf_counter() - t0)
            radiance[label][f] = np.concatenate([r[n][2] for n in _object_keys(r)])
        rows.append({"method": label, "build_s": build,
                     "seconds_per_frame": statistics.median(times[1:] if len(times) > 1 else times)})
    for r in rows:
        errs = [radiance_error(radiance[r["method"]][f], radiance["reference@4096"][f]) for f in geos]
        r["radiance_error_per_frame"] = dict(zip(map(str, geos), errs))
        r["radiance_error_mean"] = float(np.mean(errs))
    print(f"{os.path.basename(args.scene)}: frames {list(geos)}, SH order {args.order}, "
          f"{sum(o.mesh.num_vertices for o in scene.objects)} vertices; shared, loaded 2-core machine")
    print(f"{'method':<34}{'build s':>9}{'s/frame':>10}{'radiance error (mean)':>24}")
    for r in rows:
        print(f"{r['method']:<34}{r['build_s']:>9.2f}{r['seconds_per_frame']:>10.3f}{r['radiance_error_mean']:>24.4f}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"scene": args.scene, "note": "shared, loaded 2-core machine", "results": rows}, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
