"""Hemispherical rasterization where surfaces touch: error and time of the hierarchy's near field.

What it shows: the transfer error (mean relative L2 of the order-5 transfer, :mod:`warpshade.bench.metrics`,
against the ray-traced reference at 4096 rays, :func:`warpshade.bench.reference_cache.ground_truth`)
and the process CPU time per frame (median of repeats after a warm-up run, kernel compilation
excluded; the configurations are timed round-robin so they share the machine's load) of hemiraster
configurations on meshes where the far-field approximation used to break:

* ``wrinkled``: the 1378-vertex travelling-wrinkle cloth of ``benchmarks/hemiraster.py`` (phase 1/3);
* ``crumpled``: the benchmark's 64² cloth crumpled into deep folds (rest: flat, so the coarse mesh is
  decimated from a flat sheet; ``warpshade.bench.meshes.wrinkled_cloth``);
* ``character``: the benchmark's procedural figure with the arms lowered against the torso;
* ``two-objects``: a torus tilted until its rim nearly touches a ground grid (one merged mesh);
* ``default``: the shipped default scene (cloth draped over a ball on the ground) at frame 120, all
  objects as one merged receiver mesh, as ``warpshade run`` shades it;
* ``bunny``, ``bear``: Warp's assets, rigid.

Success criteria: the default configuration's error is close to the exact far field (``coarse=0``)
on the contact meshes, at a time close to the old hierarchy's.

How to run::

    python benchmarks/hemiraster_contact.py [--meshes crumpled,character] [--configs 'default;{"ring": 0}']
        [--repeat 3] [--json out.json]

Numbers are taken on a shared, loaded 2-core machine: CPU time excludes waiting for the core, but
not cache contention.
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

from warpshade.bench.reference_cache import ground_truth  # noqa: E402
from warpshade.geometry import TriMesh  # noqa: E402
from warpshade.bench.metrics import transfer_errors  # noqa: E402
from warpshade.visibility import get_method  # noqa: E402

ORDER = 5
CACHE = os.path.join(os.path.dirname(HERE), ".warpshade-cache", "reference")
CONFIGS = {
    "default": {},
    "old": {"ring": 4, "refine": 0.0},  # the previous defaults: 4-ring + rest-pose exclusion, no refinement
    "refine1": {"refine": 1.0},  # faster, less accurate in contact
    "nohier": {"coarse": 0},  # exact far field: every fine triangle
}


def default_scene_frame(frame: int = 120) -> tuple[TriMesh, np.ndarray]:
    """Rest mesh and frame positions of ``usd_scenes/default.usda``, every object merged (cached)."""
    from warpshade.pipeline.cloth import ClothSimulation
    from warpshade.usd import read_scene

    scene = read_scene(os.path.join(os.path.dirname(HERE), "usd_scenes", "default.usda"))
    rest = [o.mesh for o in scene.objects]
    offs = np.cumsum([0] + [m.num_vertices for m in rest])
    mesh = TriMesh(np.concatenate([m.points for m in rest]),
                   np.concatenate([m.faces + o for m, o in zip(rest, offs[:-1])]), name="default-scene")
    path = os.path.join(os.path.dirname(CACHE), f"default_scene_frame{frame}.npy")
    if os.path.isfile(path):
        return mesh, np.load(path)
    sim = ClothSimulation(scene)
    geo = {}
    for f in range(frame + 1):
        geo = sim.advance(f, {})
    pts = np.concatenate([np.asarray(geo.get(o.name, o.mesh.points), np.float32) for o in scene.objects])
    os.makedirs(os.path.dirname(path), exist_ok=True)
    np.save(path, pts)
    return mesh, pts


def load(name: str) -> tuple[TriMesh, np.ndarray]:
    """Rest mesh (the method's static structures come from it) and judged frame positions."""
    from warpshade.bench import meshes

    if name == "wrinkled":
        sys.path.insert(0, HERE)
        from hemiraster import wrinkled_cloth

        pts, faces = wrinkled_cloth(0.0)
        return TriMesh(pts, faces, name="wrinkled"), wrinkled_cloth(1 / 3)[0]
    if name == "crumpled":
        bm = meshes.wrinkled_cloth(64)
    elif name == "character":
        bm = meshes.character()
    elif name == "two-objects":
        bm = meshes.two_objects()
    elif name == "default":
        return default_scene_frame()
    else:
        bm = meshes.warp_mesh(name)
    return bm.rest, bm.frame


def measure(mesh: TriMesh, frame: np.ndarray, truth: np.ndarray, configs: list, repeat: int) -> list[dict]:
    """Error and CPU time of each configuration, timed round-robin (one run of each per round, after a
    warm-up run of each): on a shared machine every configuration sees the same load."""
    methods = []
    for _, knobs in configs:
        m = get_method("hemiraster")(mesh, order=ORDER, **knobs)
        m.set_points(frame)
        m._compute()
        wp.synchronize()
        methods.append(m)
    cpu = [[] for _ in methods]
    wall = [[] for _ in methods]
    for _ in range(repeat):
        for k, m in enumerate(methods):
            t0, c0 = time.perf_counter(), time.process_time()
            m._compute()
            wp.synchronize()
            wall[k].append(time.perf_counter() - t0)
            cpu[k].append(time.process_time() - c0)
    rows = []
    for (label, knobs), m, c, w in zip(configs, methods, cpu, wall):
        err = transfer_errors(m.transfer_numpy(), truth)
        st = m.stats()
        rows.append({"config": label, "knobs": knobs, "cpu_seconds": float(np.median(c)), "cpu_seconds_min": float(np.min(c)),
                     "seconds": float(np.median(w)), "error_mean": float(err.mean()),
                     "error_p95": float(np.percentile(err, 95)), "triangles_per_vertex": st["triangles_per_vertex"],
                     "refined_per_vertex": st.get("refined_per_vertex")})
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--meshes", default="wrinkled,crumpled,character,two-objects,default,bunny,bear")
    ap.add_argument("--configs", default=";".join(CONFIGS),
                    help=f"';'-separated names from {sorted(CONFIGS)} or JSON knob objects")
    ap.add_argument("--repeat", type=int, default=5, help="timed rounds (each config once per round)")
    ap.add_argument("--json", default=None)
    args = ap.parse_args(argv)
    wp.config.log_level = wp.LOG_WARNING
    wp.init()
    configs = []
    for c in args.configs.split(";"):
        configs.append((c, CONFIGS[c]) if c in CONFIGS else (c, json.loads(c)))
    rows = []
    print(f"{'mesh':12s} {'config':34s} {'V':>6s} {'cpu ms':>8s} {'cpu min':>8s} {'wall ms':>8s} {'tris/v':>7s} {'refined/v':>9s} "
          f"{'err %':>6s} {'p95 %':>6s}   (shared, loaded machine; order {ORDER}, truth 4096 rays)")
    for name in args.meshes.split(","):
        mesh, frame = load(name)
        fm = TriMesh(frame, mesh.faces, name=f"{name}-frame")
        truth = ground_truth(fm, ORDER, 4096, CACHE, log=lambda s: print(s, file=sys.stderr))
        for r in measure(mesh, frame, truth, configs, args.repeat):
            r.update(mesh=name, vertices=mesh.num_vertices)
            rows.append(r)
            ref = r["refined_per_vertex"]
            print(f"{name:12s} {r['config']:34s} {mesh.num_vertices:6d} {r['cpu_seconds'] * 1e3:8.1f} "
                  f"{r['cpu_seconds_min'] * 1e3:8.1f} {r['seconds'] * 1e3:8.1f} {r['triangles_per_vertex']:7.1f} "
                  f"{'-' if ref is None else f'{ref:9.1f}':>9s} {r['error_mean'] * 100:6.2f} {r['error_p95'] * 100:6.2f}",
                  flush=True)
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"note": "shared, loaded 2-core machine; CPU seconds", "rows": rows}, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
