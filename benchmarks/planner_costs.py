"""Per-pass costs the planner uses besides the visibility methods (which come from ``warpshade bench``).

What it measures, on the objects and lights of every shipped scene in ``usd_scenes/`` (real data),
through the same functions ``warpshade run`` calls (:mod:`warpshade.pipeline.shading`):

* between-group shadows (sphere sets, ``--between spheres``): fitting one sphere tree per group at
  setup (seconds per triangle of the group) and, per frame, each group's shadowing by the others'
  spheres (seconds per receiver vertex per other group);
* lights: per frame, ``lights_sh`` of the scene's lights at the shaded points (a fixed cost per light
  kind for distant lights and domes, seconds per vertex per local light for rect and sphere lights);
* exit radiance (``(ρ/π) Σ L_i T_i``, a Warp kernel): seconds per vertex per SH coefficient;
* unoccluded transfer (groups with no method): seconds per vertex;
* rect lights under ``--area-lights gears`` besides the GEARS masks (which the frontier costs): the
  exact irradiance and the sample weighting (:mod:`warpshade.pipeline.area`), seconds per vertex per light;
* the hemispherical-rasterization plane LUT (built once per run): seconds;
* a shading group's meshes at setup (``TriMesh`` of the merged members, its vertex normals; the
  back side's merged and flipped meshes again): seconds per triangle (the frontier's ``build_seconds``
  time the method's constructor on a mesh that is already built).

Each pass's constants are a non-negative least-squares fit over the scenes with relative residuals
(:func:`warpshade.planner.fit_cost`) of ``fixed + per-unit × count``; the script prints each measurement
against its fitted value so the fit can be judged.

Success criteria: the fitted constants reproduce each measurement within a factor 2.

How to run::

    python benchmarks/planner_costs.py [--order 4] [--repeat 3] [--json PATH] [--write-data]
    python benchmarks/planner_costs.py --loo     # leave-one-mesh-out check of the method cost fit
    python benchmarks/planner_costs.py --group-mesh-only [--write-data]   # only the group-mesh constant

``--write-data`` writes ``warpshade/data/pass_costs.json`` (what the planner loads). Timings: median
of ``--repeat`` runs after one warm-up run (kernel compilation excluded), wall time on a shared,
loaded 2-core machine.
"""

from __future__ import annotations

import argparse
import glob
import json
import os
import platform
import sys
import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))

SCENES = os.path.join(os.path.dirname(__file__), "..", "usd_scenes")
DATA = os.path.join(os.path.dirname(__file__), "..", "warpshade", "data", "pass_costs.json")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--order", type=int, default=4, help="SH order (the pipeline's default is 4)")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", default=None, help="write all measurements and the fitted constants here")
    ap.add_argument("--write-data", action="store_true", help="write warpshade/data/pass_costs.json")
    ap.add_argument("--loo", action="store_true",
                    help="only: leave-one-mesh-out check of the planner's method cost fit on the shipped frontier")
    ap.add_argument("--group-mesh-only", action="store_true",
                    help="only: measure group_mesh_seconds_per_triangle (with --write-data, update just that constant)")
    args = ap.parse_args(argv)
    if args.loo:
        return leave_one_out()
    if args.group_mesh_only:
        return group_mesh_only(args.repeat, args.write_data)

    import warp as wp

    wp.config.quiet = True
    from warpshade.lighting import lights_sh
    from warpshade.planner import fit_cost
    from warpshade.pipeline.area import AreaLightShading, is_area_light
    from warpshade.pipeline.lights import light_from_spec
    from warpshade.pipeline.shading import GroupSpec, _between_group_shadows, _Group, _shadow_by_others
    from warpshade.radiance import exit_radiance
    from warpshade.bench.timing import median_seconds
    from warpshade.usd import read_scene
    from warpshade.visibility.hemiraster import tables

    order, rep = args.order, args.repeat
    rows = {"between_build": [], "between_frame": [], "lights_local": [], "radiance": [], "unoccluded": [],
            "area_shading": [], "group_mesh": []}
    print(f"pass costs at SH order {order} (median of {rep} after a warm-up; shared loaded 2-core machine)")
    print(f"{'scene':<16}{'pass':<16}{'count':>12}{'ms':>10}")
    for path in sorted(glob.glob(os.path.join(SCENES, "*.usda"))):
        scene = read_scene(path)
        name = os.path.splitext(os.path.basename(path))[0]
        objs = [o for o in scene.objects if o.shaded]
        # one group per object, no visibility method: isolates the passes measured here
        groups = [_Group(GroupSpec(None, {}, [o.name], [o.mesh], [np.ones(3)], [False]), order, "cpu") for o in objs]
        geo = {}
        updated = [g.update(geo)[1] for g in groups]  # (points, transfer, normals) per group
        v_all = sum(g.mesh.num_vertices for g in groups)

        def log(kind, features, sec):
            rows[kind].append((name, [float(x) for x in features], sec))
            print(f"{name:<16}{kind:<16}{features[-1]:>12.0f}{sec * 1e3:>10.2f}", flush=True)

        def fresh(g):
            g.cached = None  # a group whose members do not move caches its transfer
            return g.update(geo)[1]

        log("group_mesh", [_triangles(objs)], _group_mesh_seconds(objs, rep))
        for g in groups:
            log("unoccluded", [1, g.mesh.num_vertices], median_seconds(lambda g=g: fresh(g), repeat=rep))
        if len(groups) > 1:
            between = []
            sec = median_seconds(lambda: between.append(_between_group_shadows(groups, order, "cpu")), repeat=1)
            between = between[-1]
            log("between_build", [len(groups), sum(g.mesh.num_faces for g in groups)], sec)
            for i, g in enumerate(groups):
                pts, tr, nrm = updated[i]
                sec = median_seconds(lambda i=i, pts=pts, tr=tr, nrm=nrm: _shadow_by_others(
                    between[i], i, pts, tr, nrm, updated, "cpu"), repeat=rep)
                log("between_frame", [1, g.mesh.num_vertices * (len(groups) - 1)], sec)
        lights = [light_from_spec(s, scene.up_axis) for s in scene.lights]
        pts = np.concatenate([u[0] for u in updated])
        local = [li for li in lights if li.local]
        for spec, li in zip(scene.lights, lights):
            if not li.local:  # per light kind: a textured dome re-projects its map, a distant light is a formula
                kind = "dome_texture" if spec.kind == "dome" and spec.texture else spec.kind
                rows.setdefault(f"light_{kind}", [])
                log(f"light_{kind}", [1], median_seconds(lambda li=li: lights_sh([li], order, pts), repeat=rep))
        if local:
            log("lights_local", [v_all * len(local)], median_seconds(lambda: lights_sh(local, order, pts), repeat=rep))
        rect = [li for li in lights if is_area_light(li)]
        if rect:
            area = AreaLightShading([g.mesh for g in groups], rect)  # the run's GEARS knobs (DEFAULT_AREA_KNOBS)
            area.irradiance(0.0, [u[0] for u in updated], [u[2] for u in updated])  # masks for the weighting

            def weigh():  # what AreaLightShading.irradiance adds to the GEARS masks
                for vis, li in zip(area.visibility, rect):
                    w = vis.weighted_visibility(out=area._w).numpy()
                    phi = li.projected_solid_angle(vis.points, vis.normals, out=area._phi).numpy()
                    (phi.astype(np.float64) * w)[:, None] * li.radiance

            log("area_shading", [v_all * len(rect)], median_seconds(weigh, repeat=rep))
        transfer = np.concatenate([u[1] for u in updated])
        L = lights_sh(lights, order, pts)
        loc = L[1]
        log("radiance", [1, v_all * order * order],
            median_seconds(lambda: exit_radiance(transfer, L[0], 1.0, loc).numpy(), repeat=rep))
    tables.build_lut(16, 4, None, "cpu")  # compiles the LUT kernel
    lut_seconds = median_seconds(lambda: _fresh_lut(tables), repeat=rep)
    print(f"{'-':<16}{'hemiraster LUT':<16}{'32/48':>12}{lut_seconds * 1e3:>10.2f}")
    # pass -> names of its constants, in the order of its features
    names = {"between_build": ("between_build_seconds_per_group", "between_build_seconds_per_triangle"),
             "between_frame": ("between_seconds_fixed", "between_seconds_per_receiver_vertex_per_other_group"),
             "lights_local": ("local_light_seconds_per_vertex",),
             "area_shading": ("area_shading_seconds_per_vertex",),
             "radiance": ("radiance_seconds_fixed", "radiance_seconds_per_vertex_coeff"),
             "unoccluded": ("unoccluded_seconds_fixed", "unoccluded_seconds_per_vertex"),
             "group_mesh": ("group_mesh_seconds_per_triangle",)}
    names.update({k: (f"{k}_seconds",) for k in rows if k.startswith("light_")})
    consts = {"hemiraster_lut_seconds": lut_seconds}
    print("\nfitted constants (measured / fitted, over the rows of each pass):")
    worst = 1.0
    for kind, keys in names.items():
        x = np.array([f for _, f, _ in rows[kind]])
        y = np.array([t for _, _, t in rows[kind]])
        coef = fit_cost(x, y)
        consts.update(zip(keys, map(float, coef)))
        ratios = y / np.maximum(x @ coef, 1e-12)
        worst = max(worst, float(np.max(np.maximum(ratios, 1 / ratios))))
        print(f"  {kind:<14} " + ", ".join(f"{k} = {c:.3e}" for k, c in zip(keys, coef))
              + f"   ratios {ratios.min():.2f}..{ratios.max():.2f}")
    print(f"  hemiraster_lut_seconds = {lut_seconds:.3e}")
    print(f"worst measured/fitted factor: {worst:.2f}")
    note = (f"benchmarks/planner_costs.py --order {order}: {platform.machine()}, {os.cpu_count()} cores shared with other "
            f"jobs (loaded), Warp {wp.config.version} CPU one thread; medians of {rep} after a warm-up")
    out = {"constants": consts, "order": order, "note": note,
           "measurements": {k: [{"scene": n, "features": c, "seconds": s} for n, c, s in v] for k, v in rows.items()}}
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1)
    if args.write_data:
        with open(DATA, "w") as f:
            json.dump({"constants": consts, "order": order, "note": note}, f, indent=1)
        print(f"wrote {os.path.normpath(DATA)}")
    return 0


def leave_one_out() -> int:
    """Predict each frontier timing from the configuration's other meshes: the V/F fit
    (:func:`warpshade.planner.estimate_seconds` with triangles) against scaling the nearest mesh by V."""
    from warpshade.planner import estimate_seconds, load_frontier

    fit, near = [], []
    pooled: dict = {}  # one constructor call's timings on every mesh, as the planner's find_config pools them
    for c in load_frontier()["configs"]:
        key = json.dumps([c["method"], c["order"], c.get("kwargs", c["knobs"])], sort_keys=True)
        pooled.setdefault(key, []).extend(c["timings"])
    for timings in pooled.values():
        best = {}
        for t in timings:  # fastest timing per mesh, as the planner
            if t["mesh"] not in best or t["seconds"] < best[t["mesh"]]["seconds"]:
                best[t["mesh"]] = t
        if len(best) < 4:  # three left to fit
            continue
        for m, t in best.items():
            rest = {"timings": [x for k, x in best.items() if k != m]}
            fit.append(abs(np.log(estimate_seconds(rest, t["vertices"], triangles=t["triangles"]) / t["seconds"])))
            near.append(abs(np.log(estimate_seconds(rest, t["vertices"]) / t["seconds"])))
    print(f"leave-one-mesh-out over {len(fit)} timings (configurations measured on >= 4 meshes), "
          "factor between predicted and measured:")
    for name, e in (("fit a V + b V log2 F + c V F", fit), ("nearest mesh scaled by V", near)):
        e = np.exp(np.array(e))
        print(f"  {name:<30} median {np.median(e):.2f}  90 % {np.percentile(e, 90):.2f}  worst {e.max():.2f}")
    return 0


def _triangles(objs) -> int:
    return sum(o.mesh.num_faces for o in objs)


def _group_mesh_seconds(objs, rep: int) -> float:
    """Median seconds of building one group's mesh from the objects' meshes, as ``_Group`` does."""
    from warpshade.bench.timing import median_seconds
    from warpshade.geometry import TriMesh

    offs = np.cumsum([0] + [o.mesh.num_vertices for o in objs])
    pts = [o.mesh.points for o in objs]
    faces = [o.mesh.faces + off for o, off in zip(objs, offs[:-1])]
    return median_seconds(lambda: TriMesh(np.concatenate(pts), np.concatenate(faces), name="group"), repeat=rep)


def group_mesh_only(rep: int, write: bool) -> int:
    """Measure and fit ``group_mesh_seconds_per_triangle`` alone on the shipped scenes."""
    from warpshade.planner import fit_cost
    from warpshade.usd import read_scene

    x, y = [], []
    for path in sorted(glob.glob(os.path.join(SCENES, "*.usda"))):
        objs = [o for o in read_scene(path).objects if o.shaded]
        x.append([_triangles(objs)])
        y.append(_group_mesh_seconds(objs, rep))
        print(f"{os.path.basename(path):<20}{x[-1][0]:>8} triangles {y[-1] * 1e3:>8.2f} ms", flush=True)
    (c,) = fit_cost(np.array(x, dtype=float), np.array(y))
    ratios = np.array(y) / np.maximum(np.array(x)[:, 0] * c, 1e-12)
    print(f"group_mesh_seconds_per_triangle = {c:.3e}   ratios {ratios.min():.2f}..{ratios.max():.2f}")
    if write:
        with open(DATA) as f:
            data = json.load(f)
        data["constants"]["group_mesh_seconds_per_triangle"] = float(c)
        data["note"] += ("; group_mesh_seconds_per_triangle measured alone later "
                         "(benchmarks/planner_costs.py --group-mesh-only, same machine, loaded)")
        with open(DATA, "w") as f:
            json.dump(data, f, indent=1)
        print(f"wrote {os.path.normpath(DATA)}")
    return 0


def _fresh_lut(tables) -> None:
    """Build the default plane LUT (mask 32, cube 48) from scratch (the in-memory copy dropped first)."""
    tables._LUT_CACHE.pop((32, 48), None)
    tables.build_lut(32, 48, None, "cpu")


if __name__ == "__main__":
    raise SystemExit(main())
