"""Lighting costs: lat-long projection, sky projection, per-vertex local lights, exit radiance.

What it shows: which lighting steps matter per frame. Projection of a 2048x1024 map happens once per
map (cached per order); a rotating environment then costs one SH rotation per frame; local lights
(sphere, rect) cost a per-vertex evaluation when receivers move; a lighting-only change costs the
exit-radiance dot product.

Run: python benchmarks/lighting.py [--quick] [--json PATH]
Times are medians of repeats after a warm-up run (Warp compilation excluded), on one CPU thread.
"""

from __future__ import annotations

import argparse
import json
import os

import numpy as np
import warp as wp

from warpshade.usd import load_mesh
from warpshade.lighting import EnvironmentMap, RectLight, Sky, SphereLight, spin
from warpshade.radiance import exit_radiance
from warpshade.sh.projection import project_latlong
from warpshade.bench.timing import median_seconds


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller map, fewer repeats")
    ap.add_argument("--json", help="write the numbers to this file")
    args = ap.parse_args(argv)
    wp.config.log_level = wp.LOG_WARNING  # no init banner or module-load lines
    repeat = 3 if args.quick else 7
    h = 256 if args.quick else 1024
    rng = np.random.default_rng(0)
    img = (rng.random((h, 2 * h, 3)) * 4).astype(np.float32)
    mesh = load_mesh(os.path.join(os.path.dirname(wp.__file__), "examples", "assets", "bunny.usd"))
    pts = mesh.points
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    above = np.array([0.5 * (lo[0] + hi[0]), hi[1] + 0.5 * (hi[1] - lo[1]), 0.5 * (lo[2] + hi[2])])
    size = 0.25 * float(np.linalg.norm(hi - lo))
    rows = []

    def add(step, order, fn, **extra):
        sec = median_seconds(fn, repeat=repeat)
        rows.append({"step": step, "order": order, "seconds": sec, **extra})

    for order in (5, 8):
        add(f"project_latlong {2 * h}x{h} RGB (numpy)", order, lambda o=order: project_latlong(img, o))
        env = EnvironmentMap(image=img, motion=spin([0, 1, 0], 30.0))
        env.sh(order)  # cache the projection
        add("rotating environment: at_time(t).sh (per frame)", order, lambda o=order, e=env: e.at_time(0.7).sh(o))
        add("Sky().sh (model + projection, first call)", order, lambda o=order: Sky().sh(o))
        sphere = SphereLight(position=above, radius=0.2 * size, radiance=5.0)
        add(f"SphereLight.sh_at, {len(pts)} bunny vertices (numpy)", order, lambda o=order, s=sphere: s.sh_at(pts, o))
        rect = RectLight(center=above, u=[size, 0, 0], v=[0, 0, size], radiance=5.0)
        add(f"RectLight.sh_at 8x8, {len(pts)} vertices (Warp)", order, lambda o=order, r=rect: r.sh_at(pts, o))
        add(f"RectLight.sh_at_reference 8x8, {len(pts)} vertices (numpy)", order,
            lambda o=order, r=rect: r.sh_at_reference(pts, o))
        transfer = wp.array(rng.normal(size=(len(pts), order * order)).astype(np.float32), dtype=float)
        light = rng.normal(size=(order * order, 3))
        out = wp.empty(len(pts), dtype=wp.vec3)
        add(f"exit_radiance, {len(pts)} vertices (Warp, transfer on device)", order,
            lambda t=transfer, l=light, o=out: exit_radiance(t, l, 0.8, out=o))

    print(f"{'step':64s} {'order':>5s} {'ms':>10s}")
    for r in rows:
        print(f"{r['step']:64s} {r['order']:5d} {1e3 * r['seconds']:10.2f}")
    print("(medians after warm-up, compile excluded; shared, loaded 2-core machine, one Warp CPU thread)")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"rows": rows, "map_height": h, "vertices": int(len(pts))}, fh, indent=2)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
