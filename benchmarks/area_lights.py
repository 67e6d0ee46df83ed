"""Rect lights in ``warpshade run``: GEARS soft shadows (``--area-lights gears``) vs SH projection (``sh``).

What it shows: on frames of ``usd_scenes/rect_light.usda`` (cloth falling on a ball over the ground,
under a 1.5 m × 1 m RectLight), the rect light's share of the exit radiance as each path of the run
computes it, against a ray-traced reference of the same term, and the time per frame of each path.

* ``sh``: the rect light projected to SH per vertex (order 4) and dotted with the run's shadowed
  transfer (``reference``, 256 rays: the run's default method);
* ``gears``: exact Lambert irradiance times the form-factor-weighted visible share of GEARS masks
  (k = 16; the run's default); ``gears-area``: the same with the paper's plain visible fraction;
* reference: ``(ρ/π) L ∫ V cos θ cos θ_L / r² dA`` by stratified jittered shadow rays (32×32 per seed,
  ``--seeds`` seeds averaged) from every vertex to the light, blockers = every object of the frame.
  Its own noise is reported (half the seeds against the other half).

Error: :func:`warpshade.bench.metrics.radiance_error` (mean over vertices of the RGB error norm, divided by
the mean reference norm) over all shaded vertices, and over the vertices in partial or full shadow
(reference visible share < 0.98).

Timing: CPU time (``time.process_time``; the kernels are single-threaded) of one frame's shading with
all the scene's lights (transfer, lights, radiance; ``sh`` vs ``gears``) and of the GEARS pass alone;
medians of ``--repeat`` runs after a warm-up (kernel compilation excluded). Numbers come from a shared,
loaded 2-core machine.

Success criteria: ``gears`` error well below ``sh`` error, on all vertices and on shadowed ones.
``--k 8,32`` (default) adds the GEARS path at other light sample counts (``warpshade run --area-k``).

How to run: ``python benchmarks/area_lights.py [--frames 0,40,80,119] [--seeds 4] [--k 8,32] [--json out.json]``.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np
import warp as wp

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

from warpshade.bench.metrics import radiance_error  # noqa: E402
from warpshade.pipeline import ClothSimulation, Pipeline, light_from_spec  # noqa: E402
from warpshade.pipeline.area import AreaLightShading  # noqa: E402
from warpshade.bench.timing import median_seconds  # noqa: E402
from warpshade.usd import read_scene  # noqa: E402
from warpshade.visibility.gears import LightRect, get_area_method  # noqa: E402

SCENE = os.path.join(os.path.dirname(__file__), "..", "usd_scenes", "rect_light.usda")


def simulate(scene, frames: list[int]) -> dict:
    """Moving objects' points at the wanted frames, as ``warpshade run`` produces them: ``{frame: {name: (V, 3)}}``."""
    pipe = Pipeline(scene, frames=max(frames) + 1)
    sims = ClothSimulation(scene) if any(o.kind == "cloth" for o in scene.objects) else None
    return {f: geo for f, geo in pipe._geometry_frames(sims, {"simulate": 0.0}) if f in frames}


def reference_term(points, normals, faces, light, albedo, k: int, seeds: list[int]) -> tuple[np.ndarray, np.ndarray]:
    """Ray-traced rect-light radiance (V, 3) and visible share (V,) averaged over ``seeds``."""
    from warpshade.geometry import TriMesh

    rays = get_area_method("reference")(TriMesh(points, faces), LightRect.from_light(light), k=k)
    ff = np.zeros(len(points))
    vis = np.zeros(len(points))
    for s in seeds:
        rays.seed = s
        rays.update(points, normals)
        ff += rays.form_factor.numpy()
        vis += rays.visibility.numpy()
    ff /= len(seeds)
    # one-sided UsdLux light: nothing reaches receivers behind its emitting side
    front = (points - light.center) @ light.emit_normal > 0
    # form factor F = (1/π) ∫ V cos cos / r² dA, so (ρ/π) E = (ρ/π) π L F = ρ L F
    return albedo * light.radiance[None, :] * (ff * front)[:, None], vis / len(seeds)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default=SCENE)
    ap.add_argument("--frames", default="0,40,80,119", help="comma-separated frame numbers")
    ap.add_argument("--seeds", type=int, default=4, help="reference: 32x32 jittered rays per seed")
    ap.add_argument("--k", default="8,32", help="also GEARS at these light samples per side (comma-separated; '' none)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", default=None, metavar="PATH")
    args = ap.parse_args(argv)
    wp.config.log_level = wp.LOG_WARNING
    frames = sorted(int(f) for f in args.frames.split(","))
    scene = read_scene(args.scene)
    rect_spec = next(s for s in scene.lights if s.kind == "rect")
    rect = light_from_spec(rect_spec, scene.up_axis)
    geos = simulate(scene, frames)

    def shader(area_lights, lights=None, **knobs):
        pipe = Pipeline(scene, lights=lights, area_lights=area_lights, area_knobs=knobs)
        return pipe, pipe.shader.build()

    pipe, sh_rect = shader("sh", [rect])
    _, gears_rect = shader("gears", [rect])
    _, area_rect = shader("gears", [rect], weighting="area")
    ks = [int(k) for k in args.k.split(",") if k]
    k_rect = {k: shader("gears", [rect], k=k)[1] for k in ks}
    names = [n for g in pipe.groups for n in g.names]
    albedo = np.concatenate([np.broadcast_to(a, (m.num_vertices, 3)) for g in pipe.groups
                             for a, m in zip(g.albedos, g.meshes)])
    faces = np.concatenate([m.faces + off for m, off in zip(
        [m for g in pipe.groups for m in g.meshes],
        np.cumsum([0] + [m.num_vertices for g in pipe.groups for m in g.meshes])[:-1])])
    print(f"rect-light term on {os.path.basename(args.scene)}: {len(albedo)} vertices, {len(faces)} triangles; "
          f"SH order {pipe.order}, transfer {pipe.groups[0].method} {pipe.groups[0].label}, GEARS "
          f"k={pipe.config.area_knobs['k']} grid={pipe.config.area_knobs['grid']}; "
          f"reference {args.seeds}x32x32 jittered rays per vertex")
    print(f"{'frame':>5} {'shadowed':>8} {'ref noise':>9} {'sh err':>7} {'gears err':>9} {'gears-area':>10}   "
          f"{'sh err (shadow)':>15} {'gears (shadow)':>14} {'gears-area (shadow)':>19}")
    rows = []
    for f in frames:
        geo = geos[f]
        got = {}
        for key, shade in [("sh", sh_rect), ("gears", gears_rect), ("gears-area", area_rect)] + [
                (f"gears-k{k}", fn) for k, fn in k_rect.items()]:
            out = shade(f, geo)
            got[key] = np.concatenate([out[n][2] for n in names])
            pts = np.concatenate([out[n][0] for n in names])
            nrm = np.concatenate([out[n][1] for n in names])
        seeds = list(range(args.seeds))
        ref, vis = reference_term(pts, nrm, faces, rect, albedo, 32, seeds)
        half_a, _ = reference_term(pts, nrm, faces, rect, albedo, 32, seeds[: len(seeds) // 2])
        half_b, _ = reference_term(pts, nrm, faces, rect, albedo, 32, seeds[len(seeds) // 2:])
        shadow = vis < 0.98
        row = {"frame": f, "shadowed_vertices": int(shadow.sum()), "reference_noise": radiance_error(half_a, half_b)}
        for key in got:
            row[f"error_{key}"] = radiance_error(got[key], ref)
            row[f"error_{key}_shadowed"] = radiance_error(got[key][shadow], ref[shadow]) if shadow.any() else float("nan")
        rows.append(row)
        print(f"{f:5d} {row['shadowed_vertices']:8d} {row['reference_noise']:9.4f} {row['error_sh']:7.4f} "
              f"{row['error_gears']:9.4f} {row['error_gears-area']:10.4f}   {row['error_sh_shadowed']:15.4f} "
              f"{row['error_gears_shadowed']:14.4f} {row['error_gears-area_shadowed']:19.4f}")
    if ks:
        print("GEARS light samples per side (form-factor weighting), error all / shadowed: " + "; ".join(
            f"frame {r['frame']}: " + ", ".join(f"k={k} {r[f'error_gears-k{k}']:.4f} / {r[f'error_gears-k{k}_shadowed']:.4f}"
                                                for k in ks) for r in rows))
    mean = {k: float(np.mean([r[k] for r in rows])) for k in rows[0] if k.startswith("error")}
    print("mean  " + "  ".join(f"{k[6:]} {v:.4f}" for k, v in mean.items()))

    # time per frame: all of the scene's lights, as warpshade run shades them
    f = frames[len(frames) // 2]
    timing = {}
    for key in ("sh", "gears"):
        _, shade = shader(key)
        timing[f"frame_seconds_{key}"] = median_seconds(lambda: shade(f, geos[f]), repeat=args.repeat,
                                                         clock=time.process_time)
    for k in ks:
        _, shade = shader("gears", k=k)
        timing[f"frame_seconds_gears_k{k}"] = median_seconds(lambda: shade(f, geos[f]), repeat=args.repeat,
                                                             clock=time.process_time)
    _, shade = shader("sh", [rect])
    out = shade(f, geos[f])
    pts = [np.concatenate([out[n][0] for n in g.names]) for g in pipe.groups]
    nrm = [np.concatenate([out[n][1] for n in g.names]) for g in pipe.groups]
    area = AreaLightShading([_merged(g) for g in pipe.groups], [rect])
    timing["gears_pass_seconds"] = median_seconds(lambda: area.irradiance(f / scene.fps, pts, nrm),
                                                  repeat=args.repeat, clock=time.process_time)
    print(f"CPU time per frame (frame {f}, median of {args.repeat} after a warm-up; shared loaded machine): "
          f"sh {timing['frame_seconds_sh'] * 1e3:.1f} ms, gears {timing['frame_seconds_gears'] * 1e3:.1f} ms "
          f"(GEARS pass alone {timing['gears_pass_seconds'] * 1e3:.1f} ms)"
          + "".join(f", gears k={k} {timing[f'frame_seconds_gears_k{k}'] * 1e3:.1f} ms" for k in ks))
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"scene": os.path.basename(args.scene), "frames": frames, "rows": rows, "mean": mean,
                       **timing, "reference": f"{args.seeds} seeds x 32x32 jittered rays",
                       "note": "CPU time, shared loaded 2-core machine; medians after a warm-up"}, fh, indent=2)
    return 0


def _merged(group):
    from warpshade.geometry import TriMesh

    offs = np.cumsum([0] + [m.num_vertices for m in group.meshes])
    return TriMesh(np.concatenate([m.points for m in group.meshes]),
                   np.concatenate([m.faces + o for m, o in zip(group.meshes, offs[:-1])]))


if __name__ == "__main__":
    sys.exit(main())
