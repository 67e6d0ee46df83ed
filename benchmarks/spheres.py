"""Sphere-set soft shadows and one-bounce reflections: error against ray tracing and time per frame.

Scene like the thesis' (ch. 6): Warp's bunny and bear (scaled to the same height) on a ground grid,
about 30 leaf spheres, about 30 000 receiver vertices. Every object receives shadows from the other
objects' sphere sets and from its own (self-shadowing); the ground casts nothing (as in the thesis,
whose ground box has no spheres), but the ray-traced reference includes it as an occluder.

Measured: time per frame (median of ``--repeat`` runs after one warm-up, kernel compilation and the
sphere fits excluded: ``warpshade.bench.timing``) of shadows alone and shadows + reflections, for the
optimal-linear, hybrid and series exponentials; transfer error against ``ReferenceTransfer`` with
``occluders=`` (``warpshade.bench.metrics``, relative L2), with the unoccluded transfer as a baseline;
single-object self-shadowing by spheres on the bunny and bear (and by hemispherical rasterization
when that method is registered). Reference transfers are cached in ``benchmarks/cache/`` (gitignored).

Run: ``python benchmarks/spheres.py [--quick] [--json out.json]``. Numbers from a shared, loaded
machine (several processes on 2 cores) are slower than on an idle core; the CPU time of this process
per frame (``cpu fps``) is reported beside the wall time as the single-idle-core estimate.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import os
import sys
import time

import numpy as np
import warp as wp

# Measure the checkout this script belongs to (a plain `python benchmarks/spheres.py` would otherwise
# import whichever warpshade is installed).
sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
wp.config.log_level = wp.LOG_WARNING  # no init banner or module-load lines

from warpshade.bench.reference_cache import ground_truth  # noqa: E402
from warpshade.geometry import TriMesh  # noqa: E402
from warpshade.usd import load_mesh  # noqa: E402
from warpshade.bench.metrics import error_summary  # noqa: E402
from warpshade.sh.zonal import clamped_cosine_zh, unoccluded_transfer, zh_rotate  # noqa: E402
from warpshade.bench.timing import median_seconds  # noqa: E402
from warpshade.visibility import METHODS, get_method  # noqa: E402
from warpshade.visibility.spheres import SpheresTransfer, build_sphere_tree, halfspace_blocker  # noqa: E402
from warpshade.visibility.spheres.reflections import SphereReflections  # noqa: E402

ASSETS = os.path.join(os.path.dirname(wp.__file__), "examples", "assets")
CACHE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "cache")


def grid_mesh(n: int, half: float) -> TriMesh:
    """Ground grid in the xz plane at y = 0, normal +y, n×n vertices."""
    x = np.linspace(-half, half, n)
    X, Z = np.meshgrid(x, x, indexing="ij")
    pts = np.stack([X.ravel(), np.zeros(n * n), Z.ravel()], 1)
    i = np.arange(n * n).reshape(n, n)
    a, b, c, d = i[:-1, :-1].ravel(), i[1:, :-1].ravel(), i[1:, 1:].ravel(), i[:-1, 1:].ravel()
    return TriMesh(pts, np.concatenate([np.stack([a, c, b], 1), np.stack([a, d, c], 1)]), name="ground")


def placed(name: str, height: float, x: float, z: float) -> TriMesh:
    m = load_mesh(os.path.join(ASSETS, f"{name}.usd"))
    p = m.points.astype(np.float64)
    p = (p - [p[:, 0].mean(), p[:, 1].min(), p[:, 2].mean()]) * (height / np.ptp(p[:, 1])) + [x, 0.0, z]
    return TriMesh(p, m.faces, name=name)


def scene(ground_n: int):
    return {"ground": grid_mesh(ground_n, 2.5), "bunny": placed("bunny", 1.5, -0.9, 0.1),
            "bear": placed("bear", 1.5, 0.9, -0.1)}


def reference(mesh: TriMesh, occluders: list[TriMesh], order: int, rays: int) -> np.ndarray:
    """Ray-traced transfer of ``mesh`` shadowed by itself and ``occluders``, cached in ``CACHE``."""
    return ground_truth(mesh, order, rays, cache_dir=CACHE, occluders=occluders)


def sky(order: int) -> np.ndarray:
    """White-ish sky: a broad lobe from above (+y, slightly tilted) plus ambient, SH radiance (N*N, 3)."""
    lobe = zh_rotate(clamped_cosine_zh(order) * 2.0, np.array([0.3, 1.0, 0.2]))
    amb = np.zeros(order * order)
    amb[0] = 0.3 * math.sqrt(4 * math.pi)
    return np.stack([lobe + amb, 0.95 * lobe + amb, 0.9 * lobe + amb], axis=1)


def cpu_seconds(fn, repeat: int) -> float:
    """Median CPU time of this process per call (wall time on a shared machine includes waiting for a core)."""
    return median_seconds(fn, repeat=repeat, warmup=0, clock=time.process_time)


def run_scene(objs: dict, order: int, exp: str, spheres_per_object: int, repeat: int, rays: int,
              reflections: bool, trees: dict) -> dict:
    names = list(objs)
    casters = [n for n in names if n != "ground"]
    methods = {}
    ground = halfspace_blocker([0, 0, 0], [0, 1, 0], objs["ground"].bbox_diagonal())
    for n in names:
        others = [c for c in casters if c != n]
        blockers = [(trees[c], objs[c].points) for c in others] + ([ground] if n != "ground" else [])
        methods[n] = SpheresTransfer(objs[n], order=order, exp=exp, spheres=spheres_per_object, levels=3,
                                     self_shadow=n != "ground", self_tree=trees.get(n), blockers=blockers)
    refl = {}
    if reflections:
        for n in names:
            meshes = ([objs[n]] if n != "ground" else []) + [objs[c] for c in casters if c != n] + \
                ([None] if n != "ground" else [])
            refl[n] = SphereReflections(methods[n], meshes, exp="ol")
    light = sky(order)

    def frame():
        for n in names:
            methods[n].update()
        for n in refl:
            m = methods[n]
            refl[n].update(light, [[0.8, 0.7, 0.6]] * len(m.scene.trees))

    sec = median_seconds(frame, repeat=repeat)
    cpu = cpu_seconds(frame, repeat)
    out = {"order": order, "exp": exp, "reflections": reflections, "seconds_per_frame": sec,
           "frames_per_second": 1.0 / sec, "cpu_seconds_per_frame": cpu, "cpu_frames_per_second": 1.0 / cpu, "vertices": sum(objs[n].num_vertices for n in names),
           "leaf_spheres": sum(trees[c].num_leaves for c in casters)}
    if not reflections:
        t = np.concatenate([methods[n].transfer.numpy() for n in names])
        r = np.concatenate([reference(objs[n], [objs[o] for o in names if o != n], order, rays) for n in names])
        out.update({f"{k}": v for k, v in error_summary(t, r).items()})
        for n in names:  # per receiver group
            out[f"error_mean_{n}"] = error_summary(methods[n].transfer.numpy(),
                                                   reference(objs[n], [objs[o] for o in names if o != n], order,
                                                             rays))["error_mean"]
        out["fallbacks"] = int(sum(methods[n].fallback.numpy().sum() for n in names))
    else:
        direct = np.concatenate([methods[n].transfer.numpy() @ light for n in names])
        bounce = np.concatenate([refl[n].irradiance.numpy() for n in names])
        out["bounce_over_direct"] = float(np.linalg.norm(bounce, axis=1).mean() / np.linalg.norm(direct, axis=1).mean())
    return out


REFLECTION_CONFIGS = [
    ("leaves", {"cuts": False}),
    ("leaves + eq. 4.32 rule", {"exclude_intersecting": True}),
    ("leaves, self-refl. everywhere", {"self_reflection": True}),
    ("thesis first pass (sphere shadows)", {"first_pass": "spheres"}),
    ("cuts 0.5 + ratios (eq. 4.34)", {"cuts": True, "threshold": 0.5}),
    ("cuts 0.5, no ratios", {"cuts": True, "ratios": False, "threshold": 0.5}),
    ("cuts 1.0 + ratios (pipeline default)", {"cuts": True, "threshold": 1.0}),
    ("cuts 1.0, no ratios", {"cuts": True, "ratios": False, "threshold": 1.0}),
    ("cuts 1.0, eq. 4.34 as printed", {"cuts": True, "ratios": "printed", "threshold": 1.0}),
]
ALBEDO = {"ground": [0.5, 0.5, 0.5], "bunny": [0.9, 0.35, 0.2], "bear": [0.25, 0.5, 0.9]}


def bounce_reference(objs: dict, order: int, rays: int, light: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ray-traced direct exit radiance (V, 3) and reflected irradiance (V, 3) of every vertex, cached."""
    from warpshade.visibility.spheres.bounce_reference import reflected_irradiance_reference

    names = list(objs)
    direct = [np.maximum(np.asarray(ALBEDO[n]) / math.pi * (reference(objs[n], [objs[o] for o in names if o != n],
                                                                      order, rays) @ light), 0.0) for n in names]
    h = hashlib.sha1()
    for n in names:
        h.update(objs[n].points.tobytes())
    h.update(f"{order}-{rays}-{light.tobytes().hex()[:64]}-{ALBEDO}".encode())
    path = os.path.join(CACHE, f"spheres_bounce_{h.hexdigest()[:12]}.npz")
    if os.path.isfile(path):
        e = np.load(path)["irradiance"]
    else:
        pts = np.concatenate([objs[n].points for n in names])
        nrm = np.concatenate([objs[n].normals for n in names])
        e = reflected_irradiance_reference(pts, nrm, [objs[n] for n in names], direct, rays=rays)
        os.makedirs(CACHE, exist_ok=True)
        np.savez(path, irradiance=e)
    return np.concatenate(direct), e


def reflection_rows(objs: dict, order: int, rays: int, repeat: int) -> list[dict]:
    """Scene reflections (the pipeline's :class:`SceneReflections`: every object, ground included, reflects
    through its own 15 leaf spheres, 3 levels) against the ray-traced bounce; time per frame of the bounce
    alone (both passes, refits included). The first pass reads the ray-traced direct exit radiance at the
    samples, as the pipeline reads its own direct shading (one row: the thesis' sphere-shadowed samples)."""
    from warpshade.bench.metrics import radiance_error
    from warpshade.pipeline.reflections import SceneReflections

    names = list(objs)
    meshes = [objs[n] for n in names]
    light = sky(order)
    direct, e_ref = bounce_reference(objs, order, rays, light)
    rho = np.concatenate([np.broadcast_to(ALBEDO[n], (objs[n].num_vertices, 3)) for n in names]) / math.pi
    truth = direct + rho * e_ref
    t0 = time.perf_counter()
    trees = [build_sphere_tree(m.points, m.faces, 15, 3, seed=0) for m in meshes]
    fit = time.perf_counter() - t0
    pts = [m.points.astype(np.float32) for m in meshes]
    nrm = [m.normals.astype(np.float32) for m in meshes]
    albedos = [np.asarray(ALBEDO[n]) for n in names]
    rows = [{"config": "no bounce", "order": order, "bounce_error": 1.0, "radiance_error": radiance_error(direct, truth),
             "bounce_over_direct": float(np.linalg.norm(rho * e_ref, axis=1).mean() / np.linalg.norm(direct, axis=1).mean())}]
    direct_parts = np.split(direct, np.cumsum([m.num_vertices for m in meshes])[:-1])
    for label, kw in REFLECTION_CONFIGS:
        kw = dict(kw)
        # default first pass as the pipeline: the samples read the (here ray-traced) direct exit radiance
        given = None if kw.pop("first_pass", "given") == "spheres" else direct_parts
        kw = {"cuts": False, **kw}  # the rows above name every departure from the plain leaves setup
        sr = SceneReflections(meshes, order, spheres=15, levels=3, trees=trees, **kw)

        def frame():
            return sr.update(pts, nrm, light, albedos, exit_radiance=given)

        e = frame()
        sec = median_seconds(frame, repeat=repeat)
        cpu = cpu_seconds(frame, repeat)
        rows.append({"config": label, "order": order, "seconds_per_frame": sec, "cpu_seconds_per_frame": cpu,
                     "bounce_error": radiance_error(e, e_ref), "radiance_error": radiance_error(direct + rho * e, truth),
                     "fit_seconds": fit, **sr.reflections.stats()})
    return rows


def bone_refit_rows(repeat: int) -> list[dict]:
    """Spheres following skinning bones vs their vertices (point refit): on the skinned arm scene (UsdSkel)
    and the walking figure; sphere geometry differences, leaks, refit time per frame, and the transfer a
    ground under the figure gets from its spheres either way."""
    from warpshade.sim import LBSSkinner, WalkingFigure
    from warpshade.visibility.spheres.sets import SphereScene

    cases = []
    try:
        from warpshade.usd.skel import read_usd_skel

        sm = read_usd_skel(os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "usd_scenes",
                                        "skinned_arm.usda"))
        sk = LBSSkinner(sm.rest_points, sm.joint_indices, sm.joint_weights, len(sm.joint_names))
        cases.append(("skinned arm (UsdSkel)", sm.rest_points, sm.faces, sm.joint_indices, sm.joint_weights,
                      len(sm.joint_names), list(sm.transforms), sk, 8))
    except ImportError:
        pass
    fig = WalkingFigure()
    xfs = [fig.transforms(t) for t in np.linspace(0.0, 1.2, 25)]
    cases.append(("walking figure", fig.rest_points, fig.faces, fig.skinner.joint_indices.numpy(),
                  fig.skinner.joint_weights.numpy(), len(fig.joint_names), xfs, fig.skinner, 30))
    # the figure subdivided twice (16x the triangles), weights interpolated: where the point refit's O(V)
    # starts to show
    import trimesh

    dense = np.zeros((len(fig.rest_points), len(fig.joint_names)))
    fji, fjw = fig.skinner.joint_indices.numpy(), fig.skinner.joint_weights.numpy()
    np.add.at(dense, (np.repeat(np.arange(len(fji)), fji.shape[1]), fji.ravel()), fjw.ravel())
    v, f = fig.rest_points.astype(np.float64), fig.faces
    for _ in range(2):
        v, f, attr = trimesh.remesh.subdivide(v, f, vertex_attributes={"w": dense})
        dense = attr["w"]
    k = 4
    top = np.argsort(-dense, axis=1)[:, :k].astype(np.int32)
    big = LBSSkinner(v, top, np.take_along_axis(dense, top, 1), len(fig.joint_names))
    cases.append(("walking figure x16", v.astype(np.float32), f.astype(np.int32), top,
                  np.take_along_axis(dense, top, 1), len(fig.joint_names), xfs, big, 30))
    rows = []
    for name, rest, faces, ji, jw, nj, xfs, sk, nsph in cases:
        tree = build_sphere_tree(rest, faces, nsph, 3, seed=0)
        by_pts, by_bones = SphereScene([tree], [rest]), SphereScene([tree], [rest])
        by_bones.bind_bones(0, ji, jw, nj)
        dc = dr = leak = 0.0
        ratios = []
        leaf = tree.level == 0
        frames = [(x, sk.update(x).numpy().copy()) for x in xfs]
        for x, pts in frames:
            by_pts.refit([pts])
            by_bones.refit([None], [x])
            ca, ra, cb, rb = (a.numpy() for a in (by_pts.centers, by_pts.radii, by_bones.centers, by_bones.radii))
            dc = max(dc, float((np.linalg.norm(ca - cb, axis=1) / ra)[leaf].max()))
            dr = max(dr, float(np.abs(rb / ra - 1)[leaf].max()))
            ratios.append(rb[leaf] / ra[leaf])
            for s in range(tree.num_spheres):
                v = tree.vertices_of(s)
                leak = max(leak, float((np.linalg.norm(pts[v] - cb[s], axis=1) - rb[s]).max() / rb[s]))
        pts_wp = [wp.array(p, dtype=wp.vec3) for _, p in frames]
        xf_wp = [wp.array(np.asarray(x, np.float32), dtype=wp.mat44) for x, _ in frames]
        it = iter(range(10 ** 9))

        def point_refit():
            by_pts.refit([pts_wp[next(it) % len(pts_wp)]])
            wp.synchronize()

        def bone_refit():
            by_bones.refit([None], [xf_wp[next(it) % len(xf_wp)]])
            wp.synchronize()

        rows.append({"mesh": name, "vertices": len(rest), "spheres": tree.num_spheres, "joints": nj,
                     "max_center_diff_over_radius": dc, "max_radius_rel_diff": dr, "max_leak_over_radius": leak,
                     "mean_radius_ratio": float(np.mean(ratios)),
                     "point_refit_cpu_ms": 1e3 * cpu_seconds(point_refit, max(repeat, 20)),
                     "bone_refit_cpu_ms": 1e3 * cpu_seconds(bone_refit, max(repeat, 20))})
    return rows


def self_shadowing(order: int, rays: int, repeat: int) -> list[dict]:
    rows = []
    for name in ("bunny", "bear"):
        mesh = load_mesh(os.path.join(ASSETS, f"{name}.usd"))
        ref = reference(mesh, [], order, rays)
        rows.append({"mesh": name, "method": "unoccluded", **error_summary(unoccluded_transfer(mesh.normals, order), ref)})
        for spheres in (15, 30, 60):
            m = SpheresTransfer(mesh, order=order, spheres=spheres, levels=3)
            sec = median_seconds(m.update, repeat=repeat)
            rows.append({"mesh": name, "method": f"spheres ({spheres})", "seconds": sec,
                         "cpu_seconds": cpu_seconds(m.update, repeat),
                         **error_summary(m.transfer.numpy(), ref)})
        if "hemiraster" in METHODS:
            m = get_method("hemiraster")(mesh, order=order)
            sec = median_seconds(m.update, repeat=repeat)
            rows.append({"mesh": name, "method": "hemiraster", "seconds": sec, **error_summary(m.transfer.numpy(), ref)})
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="smaller ground, fewer configurations")
    ap.add_argument("--json", default=None, metavar="PATH", help="write the numbers")
    ap.add_argument("--repeat", type=int, default=3, help="timed frames after one warm-up")
    ap.add_argument("--rays", type=int, default=1024, help="reference rays per vertex")
    ap.add_argument("--reflections-only", action="store_true",
                    help="only the scene-reflection accuracy/time table (against the ray-traced bounce)")
    ap.add_argument("--bones-only", action="store_true", help="only the bone-driven vs point refit table")
    args = ap.parse_args(argv)
    bone_rows = bone_refit_rows(args.repeat)
    print("# sphere refit from skinning bones vs from vertices (CPU time per refit, median; shared, loaded machine)")
    print("# leaves: max centre distance / point-refit radius, max |r_bones / r_points - 1|, mean r_bones / r_points,"
          " max vertex outside its bone-refit sphere / radius")
    print(f"{'mesh':>22} {'V':>6} {'S':>4} {'J':>3} {'centre diff/r':>13} {'|r_b/r_p-1|':>11} {'mean r_b/r_p':>12} "
          f"{'leak/r':>7} {'points ms':>9} {'bones ms':>8}")
    for r in bone_rows:
        print(f"{r['mesh']:>22} {r['vertices']:>6} {r['spheres']:>4} {r['joints']:>3} "
              f"{r['max_center_diff_over_radius']:13.3f} {r['max_radius_rel_diff']:11.3f} {r['mean_radius_ratio']:12.3f} "
              f"{r['max_leak_over_radius']:7.3f} "
              f"{r['point_refit_cpu_ms']:9.3f} {r['bone_refit_cpu_ms']:8.3f}")
    if args.bones_only:
        if args.json:
            with open(args.json, "w") as f:
                json.dump({"bones": bone_rows}, f, indent=2)
        return 0
    ground_n = 60 if args.quick else 150
    objs = scene(ground_n)
    refl_rows = reflection_rows(objs, 4, args.rays, args.repeat)
    print(f"# one bounce (pipeline SceneReflections), order 4, {sum(m.num_vertices for m in objs.values())} receivers; "
          "error vs ray-traced bounce (relative, radiance_error); shared, loaded machine")
    print(f"{'config':>34} {'ms/frame':>9} {'cpu ms':>7} {'bounce err':>10} {'total err':>9} {'spheres/cluster':>15}")
    for r in refl_rows:
        ms = f"{r['seconds_per_frame'] * 1e3:9.1f}" if "seconds_per_frame" in r else f"{'':>9}"
        cms = f"{r['cpu_seconds_per_frame'] * 1e3:7.1f}" if "cpu_seconds_per_frame" in r else f"{'':>7}"
        spc = f"{r['reflect_spheres_per_cluster']:15.1f}" if "reflect_spheres_per_cluster" in r else f"{'':>15}"
        print(f"{r['config']:>34} {ms} {cms} {r['bounce_error']:10.3f} {r['radiance_error']:9.4f} {spc}")
    if args.reflections_only:
        if args.json:
            with open(args.json, "w") as f:
                json.dump({"reflections": refl_rows, "bones": bone_rows}, f, indent=2)
        return 0
    t0 = time.perf_counter()
    trees = {n: build_sphere_tree(objs[n].points, objs[n].faces, 15, 3, seed=0) for n in ("bunny", "bear")}
    fit_s = time.perf_counter() - t0
    orders = (4,) if args.quick else (4, 5)
    exps = ("ol", "hyb") if args.quick else ("ol", "hyb", "series")
    rows = []
    for order in orders:
        for exp in exps:
            rows.append(run_scene(objs, order, exp, 15, args.repeat, args.rays, False, trees))
        rows.append(run_scene(objs, order, "hyb", 15, args.repeat, args.rays, True, trees))
    for order in orders:
        r = np.concatenate([reference(objs[n], [objs[o] for o in objs if o != n], order, args.rays) for n in objs])
        u = np.concatenate([unoccluded_transfer(objs[n].normals, order) for n in objs])
        row = {"order": order, "exp": "unoccluded", **error_summary(u, r)}
        for n in objs:
            row[f"error_mean_{n}"] = error_summary(unoccluded_transfer(objs[n].normals, order), reference(
                objs[n], [objs[o] for o in objs if o != n], order, args.rays))["error_mean"]
        rows.append(row)
    single = self_shadowing(4, args.rays, args.repeat)
    print(f"# sphere-set shadows: {sum(m.num_vertices for m in objs.values())} receiver vertices, "
          f"{sum(t.num_leaves for t in trees.values())} leaf spheres (fit {fit_s:.1f} s); shared, loaded machine")
    print(f"{'order':>5} {'exp':>10} {'refl':>5} {'ms/frame':>9} {'fps':>6} {'cpu fps':>7} {'err mean':>9} {'err p95':>8} "
          f"{'ground':>7} {'bunny':>7} {'bear':>7}")
    for r in rows:
        ms = f"{r['seconds_per_frame'] * 1e3:9.1f}" if "seconds_per_frame" in r else f"{'':>9}"
        fps = f"{r['frames_per_second']:6.2f}" if "frames_per_second" in r else f"{'':>6}"
        cfps = f"{r['cpu_frames_per_second']:7.2f}" if "cpu_frames_per_second" in r else f"{'':>7}"
        em = f"{r['error_mean']:9.4f}" if "error_mean" in r else f"{'':>9}"
        ep = f"{r['error_p95']:8.4f}" if "error_p95" in r else f"{'':>8}"
        per = " ".join(f"{r[f'error_mean_{n}']:7.3f}" if f"error_mean_{n}" in r else f"{'':>7}"
                       for n in ("ground", "bunny", "bear"))
        print(f"{r['order']:>5} {r['exp']:>10} {str(r.get('reflections', '')):>5} {ms} {fps} {cfps} {em} {ep} {per}")
    print("# single-object self-shadowing, order 4" +
          ("" if "hemiraster" in METHODS else " (hemiraster not registered on this branch)"))
    for r in single:
        print(f"{r['mesh']:>6} {r['method']:>14} {r.get('seconds', float('nan')) * 1e3:9.1f} ms "
              f"{r['error_mean']:9.4f} {r['error_p95']:8.4f}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"scene": rows, "self_shadowing": single, "fit_seconds": fit_s, "reflections": refl_rows, "bones": bone_rows,
                       "note": "median of repeats after warm-up, compile and fit excluded; shared loaded machine"},
                      f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
