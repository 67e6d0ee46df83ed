"""hemiraster on the default scene's shading group, front and back pass, per knob set (issue 18).

What it shows: ``usd_scenes/default.usda`` is simulated as ``warpshade run`` steps it; at frames 20,
60 and 119 its one shading group (ground, ball and two-sided cloth merged: 2820 vertices, 5376
triangles) is shaded as the run shades it (:class:`warpshade.pipeline.shading._Group`: ``update`` is
the front pass, ``update_back`` the cloth's back pass) with hemiraster at each knob set. Per frame and
knob set: process CPU seconds of the front and of the back pass of the frame, each time right after the
frame before it, as a run steps them (so what a run's frame does not recompute, such as hemiraster's
stored part of the ground's and ball's masks, ``keep_static``, is not recomputed here either; median of
``--repeat`` round-robin rounds after a warm-up round: every knob set once per round, so load drift hits
all alike; compile excluded; one Warp CPU thread) and the mean relative L2 error of the front transfer
(:mod:`warpshade.bench.metrics`) against the ray-traced reference at 4096 rays
(:func:`warpshade.bench.reference_cache.ground_truth`, cached); also the triangles rasterized per
cloth receiver in either pass and the share of the cloth's receivers whose back-pass mask ends full
(every pixel blocked).

Success criteria: none of its own; it is the per-pass view of issue 18's target 5 (the default scene
in <= 5 s warm), whose wall time ``benchmarks/default_run.py`` measures.

How to run::

    OPENBLAS_NUM_THREADS=1 python benchmarks/default_group.py [--order 4] [--repeat 3] [--json out.json]

Numbers come from a shared 2-core VM: compare the knob sets within one run.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))

import warp as wp  # noqa: E402

FRAMES = (20, 60, 119)
CONFIGS = {"defaults": {}, "coarse 256, mid 2048": {"coarse": 256, "mid": 2048},
           "coarse 256, mid 2048, refine 2.5": {"coarse": 256, "mid": 2048, "refine": 2.5},
           "mid 2048": {"mid": 2048}, "min_image 0": {"min_image": 0.0},
           "min_image 0, lut 96": {"min_image": 0.0, "lut": 96}}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--order", type=int, default=4, help="SH order (the run's default is 4)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", default=None, metavar="PATH")
    args = ap.parse_args(argv)
    wp.config.quiet = True
    wp.init()
    from warpshade.bench.metrics import transfer_errors
    from warpshade.bench.reference_cache import ground_truth
    from warpshade.geometry import TriMesh
    from warpshade.pipeline.cloth import ClothSimulation
    from warpshade.pipeline.config import resolve_knobs, resolve_run
    from warpshade.pipeline.shading import _Group
    from warpshade.usd import read_scene

    scene = read_scene(os.path.join(os.path.dirname(HERE), "usd_scenes", "default.usda"))
    (spec,) = resolve_run(scene, method="hemiraster", knobs={}).groups
    sim = ClothSimulation(scene)
    geometry = {}
    for f in range(max(FRAMES) + 1):
        g = sim.advance(f, {})
        if f in FRAMES or f + 1 in FRAMES:
            geometry[f] = {k: np.asarray(v, np.float32).copy() for k, v in g.items()}
    groups = {}
    for label, knobs in CONFIGS.items():
        s = type(spec)(**{**spec.__dict__, "knobs": resolve_knobs("hemiraster", knobs)})
        groups[label] = _Group(s, args.order, "cpu")
    ref = groups["defaults"]
    rows = []
    for f in FRAMES:
        pts = np.concatenate([geometry[f].get(n, ref.rest[a:b]) for n, a, b in
                              zip(spec.names, ref.offsets[:-1], ref.offsets[1:])]).astype(np.float32)
        truth = ground_truth(TriMesh(pts, ref.mesh.faces, name=f"default-group-frame{f}"), args.order, log=print)
        for g in groups.values():  # warm-up round (kernels loaded)
            for h in (f - 1, f):
                g.update(geometry[h])
                g.update_back()
        cpu = np.zeros((len(groups), 2, args.repeat))
        for r in range(args.repeat):
            for i, g in enumerate(groups.values()):
                g.update(geometry[f - 1])  # untimed: the frame before, as a run steps them
                g.update_back()
                t = time.process_time()
                g.update(geometry[f])
                wp.synchronize()
                cpu[i, 0, r] = time.process_time() - t
                t = time.process_time()
                g.update_back()
                wp.synchronize()
                cpu[i, 1, r] = time.process_time() - t
        for i, (label, g) in enumerate(groups.items()):
            _, (_, transfer, _) = g.update(geometry[f])
            g.update_back()
            two = g._two_rows
            back = g.back_method
            mask = back._mask.numpy()[two]
            valid = back._lut.valid.numpy().reshape(-1)[:mask.shape[1]]
            st = g.method.stats()
            rows.append({"frame": f, "label": label, "knobs": CONFIGS[label],
                         "front_cpu_seconds": float(np.median(cpu[i, 0])), "back_cpu_seconds": float(np.median(cpu[i, 1])),
                         "error_mean": float(transfer_errors(transfer, truth).mean()),
                         "triangles_per_vertex": st.get("triangles_per_vertex"),
                         "refined_per_vertex": st.get("refined_per_vertex"), "mid_per_vertex": st.get("mid_per_vertex"),
                         "front_triangles_per_cloth_receiver": float(g.method._counts.numpy()[two].mean()),
                         "back_triangles_per_cloth_receiver": float(back._counts.numpy()[two].mean()),
                         "back_full_fraction": float(((mask | ~valid) == np.uint64(2**64 - 1)).all(axis=1).mean())})
            x = rows[-1]
            print(f"frame {f:3d} {label:34s} front {x['front_cpu_seconds'] * 1e3:6.1f} ms  back "
                  f"{x['back_cpu_seconds'] * 1e3:6.1f} ms  error {x['error_mean'] * 100:.2f} %  "
                  f"tris/vertex {x['triangles_per_vertex']:.0f}, cloth front {x['front_triangles_per_cloth_receiver']:.0f} "
                  f"back {x['back_triangles_per_cloth_receiver']:.0f} ({x['back_full_fraction'] * 100:.0f} % full)", flush=True)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"scene": "usd_scenes/default.usda", "order": args.order, "truth_rays": 4096,
                       "vertices": int(ref.mesh.num_vertices), "triangles": int(len(ref.mesh.faces)),
                       "repeat": args.repeat, "rows": rows}, fh, indent=2)
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
