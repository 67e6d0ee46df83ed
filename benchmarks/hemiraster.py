"""Hemispherical rasterization benchmark: Kautz et al. 2004 Table 1 on this machine, knob sweep, ray-casting baselines.

What it shows: for (a) a wrinkled cloth of 1378 vertices (53×26 grid, deterministic travelling
wrinkles), (b) Warp's bunny.usd and (c) Warp's bear.usd, the average triangles rasterized per vertex,
the transfer time per frame (median of repeats after a warm-up run, kernel compilation excluded;
the hemiraster configurations are timed round-robin so load changes hit all alike)
and the mean relative L2 error of the order-5 transfer (:mod:`warpshade.bench.metrics`) against the
ray-traced reference at 4096 rays, averaged over a few animation frames; then a sweep of the
method's knobs; then the rays that the Warp ray-traced reference and an embree (``embreex``) script
need for the same error, and their time there.

Success criteria (issue 3): cloth <= 2.5 % error at >= 30 frames/s; at equal error >= 10× faster
than the reference and embree.

How to run::

    python benchmarks/hemiraster.py [--quick] [--json out.json] [--meshes cloth,bunny,bear]

Times are the median process CPU time per frame (all threads summed, so embree's thread pool is
counted as one core's work; Warp's CPU backend runs one thread) and, in brackets, wall time.
Reference transfers are cached in ``benchmarks/.cache/`` (gitignored). Numbers were taken on a
shared, loaded machine: treat times as upper bounds and compare ratios.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time

import numpy as np
import warp as wp

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))

from warpshade.geometry import TriMesh  # noqa: E402
from warpshade.usd import load_mesh  # noqa: E402
from warpshade.bench.reference_cache import TRUTH_VERSION  # noqa: E402
from warpshade.bench.metrics import transfer_errors  # noqa: E402
from warpshade.sh import sh_eval  # noqa: E402
from warpshade.visibility import get_method  # noqa: E402
from warpshade.visibility.hemiraster.oracle import tangent_frame_np  # noqa: E402

CACHE = os.path.join(HERE, ".cache")
ORDER = 5
REF_RAYS = 4096
# Knobs tuned for the Table 1 cloth (issue 3's 30 FPS at <= 2.5 % target), found by interleaved
# A/B timing of knob combinations in one process (same load for all): a coarser far field (the
# paper used 160 low-res triangles), refinement at 1.5 deviations with no separate k-ring, and the
# tiny-image culls at 0.75 px (far field) and 0.25 px (refined near field). They are cloth-specific:
# on the bear the same knobs are slower and less accurate (coarse 256 refines far more there).
TUNED = {"cloth": {"coarse": 256, "refine": 1.5, "ring": 0, "min_image": 0.75, "fine_image": 0.25}}
TARGET_ERROR = 0.025
PAPER_TABLE1 = {"cloth": {"vertices": 1378, "triangles": 2560, "lowres": 160, "tris": 236.4, "fps": 15.5,
                          "error": 0.0247}}


# ------------------------------------------------------------------------------------------ scenes
def wrinkled_cloth(t: float = 0.0, nx: int = 53, ny: int = 26) -> tuple[np.ndarray, np.ndarray]:
    """A 1 m × 0.5 m cloth with travelling wrinkles (phase ``t`` in wavelengths): 1378 vertices, 2600 triangles."""
    x, y = np.meshgrid(np.linspace(0, 1, nx), np.linspace(0, 0.5, ny), indexing="ij")
    z = (0.03 * np.sin(2 * np.pi * (6 * x + t) + 2 * np.sin(4 * np.pi * y)) * (0.6 + 0.4 * np.cos(2 * np.pi * y))
         + 0.02 * np.sin(2 * np.pi * (3 * y + t) + 4 * x))
    pts = np.stack([x, y, z], -1).reshape(-1, 3)
    idx = np.arange(nx * ny).reshape(nx, ny)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    return pts.astype(np.float32), np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])


def twist(points: np.ndarray, degrees: float) -> np.ndarray:
    """Twist about the vertical (y for Warp's assets) axis by ``degrees`` from bottom to top."""
    p = points.astype(np.float64)
    h = (p[:, 1] - p[:, 1].min()) / max(np.ptp(p[:, 1]), 1e-30)
    c = p.mean(axis=0)
    ang = np.radians(degrees) * h
    x, z = p[:, 0] - c[0], p[:, 2] - c[2]
    out = p.copy()
    out[:, 0] = c[0] + np.cos(ang) * x - np.sin(ang) * z
    out[:, 2] = c[2] + np.sin(ang) * x + np.cos(ang) * z
    return out.astype(np.float32)


def scene(name: str) -> tuple[TriMesh, list[np.ndarray]]:
    """Rest mesh and animation frames (vertex positions) of a benchmark model."""
    if name == "cloth":
        pts, faces = wrinkled_cloth(0.0)
        return TriMesh(pts, faces, name="wrinkled cloth"), [wrinkled_cloth(t)[0] for t in (0.0, 1 / 3, 2 / 3)]
    mesh = load_mesh(os.path.join(os.path.dirname(wp.__file__), "examples", "assets", f"{name}.usd"))
    return mesh, [mesh.points, twist(mesh.points, 20.0)]


def reference(name: str, mesh: TriMesh, frames: list[np.ndarray]) -> list[np.ndarray]:
    """4096-ray reference transfer per frame, cached on disk."""
    os.makedirs(CACHE, exist_ok=True)
    # tagged with the ray tracer's truth version: a change of how rays start recomputes the truth
    path = os.path.join(CACHE, f"hemiraster_ref_{name}_o{ORDER}_r{REF_RAYS}_f{len(frames)}_{TRUTH_VERSION}.npz")
    if os.path.isfile(path):
        z = np.load(path)
        if all(np.array_equal(z[f"points{i}"], f) for i, f in enumerate(frames)):
            return [z[f"transfer{i}"] for i in range(len(frames))]
    ref = get_method("reference")(mesh, order=ORDER, rays=REF_RAYS, seed=0)
    out = []
    for i, f in enumerate(frames):
        t0 = time.perf_counter()
        out.append(ref.update(f).numpy().copy())
        print(f"  reference {name} frame {i}: {time.perf_counter() - t0:.1f} s", file=sys.stderr)
    np.savez(path, **{f"points{i}": f for i, f in enumerate(frames)}, **{f"transfer{i}": t for i, t in enumerate(out)})
    return out


# ------------------------------------------------------------------------------------------ measure
def timed(fn, repeat: int) -> tuple[float, float]:
    """Median wall and CPU seconds of ``fn()`` over ``repeat`` runs after one warm-up run (compile excluded).

    On a shared machine the wall time includes waiting for the core; the process CPU time does not
    (it still pays for cache contention), so both are reported. Wall times of the Warp kernels
    agree with :func:`warpshade.bench.timing.median_seconds`.
    """
    fn()
    wp.synchronize()
    wall, cpu = [], []
    for _ in range(max(1, repeat)):
        t0, c0 = time.perf_counter(), time.process_time()
        fn()
        wp.synchronize()
        wall.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return float(np.median(wall)), float(np.median(cpu))


def measure(method, frames, refs, repeat: int) -> dict:
    """Median seconds per frame over the frames (compile excluded) and mean error over the frames."""
    walls, cpus, errs = [], [], []
    for f, r in zip(frames, refs):
        method.set_points(f)
        w, c = timed(method._compute, repeat)
        walls.append(w)
        cpus.append(c)
        errs.append(transfer_errors(method.transfer_numpy(), r).mean())
    return {"seconds": float(np.median(walls)), "cpu_seconds": float(np.median(cpus)),
            "error_mean": float(np.mean(errs)), "triangles_per_vertex": method.stats().get("triangles_per_vertex")}


def measure_round_robin(methods: list, frames, refs, repeat: int) -> list[dict]:
    """:func:`measure` for several methods, interleaved: each round times every method on every frame
    once, so a change of machine load hits all configurations alike (the machine is shared).

    A warm-up round first (kernel compilation excluded); then per method and frame the median over
    ``repeat`` rounds, per method the median over frames (times) and the mean over frames (errors).
    """
    for m in methods:
        for f in frames:
            m.set_points(f)
            m._compute()
    wp.synchronize()
    wall = np.zeros((len(methods), len(frames), max(1, repeat)))
    cpu = np.zeros_like(wall)
    for rnd in range(max(1, repeat)):
        for i, m in enumerate(methods):
            for j, f in enumerate(frames):
                m.set_points(f)
                wp.synchronize()
                t0, c0 = time.perf_counter(), time.process_time()
                m._compute()
                wp.synchronize()
                wall[i, j, rnd] = time.perf_counter() - t0
                cpu[i, j, rnd] = time.process_time() - c0
    rows = []
    for i, m in enumerate(methods):
        errs = []
        for f, r in zip(frames, refs):
            m.set_points(f)
            m._compute()
            errs.append(transfer_errors(m.transfer_numpy(), r).mean())
        rows.append({"seconds": float(np.median(np.median(wall[i], axis=1))),
                     "cpu_seconds": float(np.median(np.median(cpu[i], axis=1))),
                     "error_mean": float(np.mean(errs)), "triangles_per_vertex": m.stats().get("triangles_per_vertex")})
    return rows


def concentric_disk_np(u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shirley–Chiu concentric map of [0,1)² onto the unit disk (the reference's sampling, in NumPy)."""
    a, b = 2 * u - 1, 2 * v - 1
    big = a * a > b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(big, a, b)
        phi = np.where(big, (np.pi / 4) * (b / a), np.pi / 2 - (np.pi / 4) * (a / b))
    phi = np.where((a == 0) & (b == 0), 0.0, phi)
    return r * np.cos(phi), r * np.sin(phi)


class EmbreeTransfer:
    """What a careful user would script with embree: stratified cosine-weighted rays, SH projection in NumPy.

    Per vertex ``s×s`` jittered strata mapped to the disk (Shirley–Chiu) and lifted to the
    hemisphere (pdf cos/π), occlusion rays with ``embreex``, estimator ``(π/N) Σ y_i V``: the same
    estimator as the Warp reference, so the two differ only in the ray caster and the host code.
    """

    def __init__(self, faces: np.ndarray, order: int, rays: int, seed: int = 0):
        self.faces, self.order, self.seed = faces, order, seed
        self.strata = max(1, int(round(math.sqrt(rays))))

    def __call__(self, points: np.ndarray, normals: np.ndarray) -> np.ndarray:
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        scene = rtcore_scene.EmbreeScene()  # rebuilt every frame: the mesh deforms
        TriangleMesh(scene, points[self.faces].astype(np.float32))
        rng = np.random.default_rng(self.seed)
        nv, s = len(points), self.strata
        n = s * s
        out = np.zeros((nv, self.order * self.order))
        eps = 1e-5 * float(np.linalg.norm(np.ptp(points, axis=0)))
        cell = np.stack(np.meshgrid(np.arange(s), np.arange(s), indexing="ij"), -1).reshape(-1, 2)
        chunk = max(1, 200_000 // n)
        for c0 in range(0, nv, chunk):
            c1 = min(nv, c0 + chunk)
            jit = rng.random((c1 - c0, n, 2))
            x, y = concentric_disk_np((cell[:, 0] + jit[..., 0]) / s, (cell[:, 1] + jit[..., 1]) / s)
            local = np.stack([x, y, np.sqrt(np.maximum(0.0, 1 - x * x - y * y))], -1)
            frames = np.stack([tangent_frame_np(nrm) for nrm in normals[c0:c1]])
            dirs = np.einsum("vij,vnj->vni", frames, local).reshape(-1, 3)
            org = np.repeat(points[c0:c1] + eps * normals[c0:c1], n, axis=0)
            hit = scene.run(org.astype(np.float32), dirs.astype(np.float32), query="OCCLUDED")
            vis = np.asarray(hit).reshape(c1 - c0, n) == -1  # -1: nothing hit
            y_sh = sh_eval(dirs, self.order).reshape(c1 - c0, n, -1)
            out[c0:c1] = np.einsum("vni,vn->vi", y_sh, vis) * (np.pi / n)
        return out


def ray_curve(kind: str, mesh, frames, refs, ray_counts, repeat: int) -> list[dict]:
    """Time and error of a ray-casting baseline at several ray counts."""
    rows = []
    for n in ray_counts:
        if kind == "reference":
            m = get_method("reference")(mesh, order=ORDER, rays=n, seed=1)
            rows.append({"rays": n, **measure(m, frames, refs, repeat)})
        else:
            hm = get_method("reference")(mesh, order=1, rays=1)  # only for its angle-weighted normals
            walls, cpus, errs = [], [], []
            for f, r in zip(frames, refs):
                hm.set_points(f)
                nrm = hm.normals.numpy()
                fn = EmbreeTransfer(mesh.faces, ORDER, n, seed=1)
                w, c = timed(lambda: fn(f, nrm), max(1, repeat // 2))
                walls.append(w)
                cpus.append(c)
                errs.append(transfer_errors(fn(f, nrm), r).mean())
            rows.append({"rays": n, "seconds": float(np.median(walls)), "cpu_seconds": float(np.median(cpus)),
                         "error_mean": float(np.mean(errs))})
        print(f"  {kind:9s} rays {n:5d}: {rows[-1]['seconds'] * 1e3:9.1f} ms wall {rows[-1]['cpu_seconds'] * 1e3:9.1f} ms "
              f"cpu  error {rows[-1]['error_mean'] * 100:.2f} %", file=sys.stderr)
    return rows


def at_error(curve: list[dict], target: float, key: str = "cpu_seconds") -> dict:
    """Rays and seconds (``key``) a baseline needs for ``target`` error (log-log interpolation of its curve)."""
    r = np.array([c["rays"] for c in curve], float)
    e = np.array([c["error_mean"] for c in curve])
    s = np.array([c[key] for c in curve])
    if target >= e[0]:
        return {"rays": float(r[0]), "seconds": float(s[0]), "extrapolated": target > e[0]}
    if target < e[-1]:  # beyond the curve: extrapolate error ~ rays^-slope, time ~ rays
        slope = math.log(e[-2] / e[-1]) / math.log(r[-1] / r[-2])
        rays = r[-1] * (e[-1] / target) ** (1 / slope)
        return {"rays": float(rays), "seconds": float(s[-1] * rays / r[-1]), "extrapolated": True}
    i = int(np.flatnonzero(e <= target)[0])
    w = math.log(e[i - 1] / target) / math.log(e[i - 1] / e[i])
    rays = math.exp(math.log(r[i - 1]) + w * math.log(r[i] / r[i - 1]))
    secs = math.exp(math.log(s[i - 1]) + w * math.log(s[i] / s[i - 1]))
    return {"rays": rays, "seconds": secs, "extrapolated": False}


def equal_error(entry: dict, row: dict) -> dict:
    """Rays and time each ray caster of ``entry`` needs for ``row``'s error, and the speedups (CPU, wall)."""
    out = {"error": row["error_mean"], "hemiraster_cpu_seconds": row["cpu_seconds"], "hemiraster_seconds": row["seconds"]}
    for kind in ("reference", "embree"):
        if f"{kind}_curve" in entry:
            eq = at_error(entry[f"{kind}_curve"], row["error_mean"], "cpu_seconds")
            eq["speedup"] = eq["seconds"] / row["cpu_seconds"]
            wall = at_error(entry[f"{kind}_curve"], row["error_mean"], "seconds")
            eq["wall_seconds"] = wall["seconds"]
            eq["wall_speedup"] = wall["seconds"] / row["seconds"]
            out[kind] = eq
    return out


# ------------------------------------------------------------------------------------------ main
def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="few configurations and ray counts")
    ap.add_argument("--meshes", default="cloth,bunny,bear")
    ap.add_argument("--repeat", type=int, default=5, help="timed runs (rounds) per frame after one warm-up")
    ap.add_argument("--json", default=None, metavar="PATH")
    ap.add_argument("--no-embree", action="store_true")
    args = ap.parse_args(argv)
    wp.config.log_level = wp.LOG_WARNING  # no init banner or module-load lines
    cls = get_method("hemiraster")
    results = {"machine_note": "shared, loaded 2-core machine (other jobs running)", "order": ORDER,
               "reference_rays": REF_RAYS, "meshes": {}}
    ray_counts = (16, 64, 256) if args.quick else (16, 32, 64, 128, 256, 512, 1024)
    for name in args.meshes.split(","):
        mesh, frames = scene(name)
        print(f"{name}: {mesh.num_vertices} vertices, {mesh.num_faces} triangles, {len(frames)} frames",
              file=sys.stderr)
        refs = reference(name, mesh, frames)
        entry = {"vertices": mesh.num_vertices, "triangles": mesh.num_faces, "frames": len(frames), "sweep": []}
        # the sweep, the tuned knobs and the PVS (paper §3.2, built from the recorded frames and
        # evaluated on them) are timed round-robin (:func:`measure_round_robin`)
        sweep = cls.sweep(quick=args.quick)
        methods = [cls(mesh, order=ORDER, **knobs) for knobs in sweep]
        if name in TUNED:
            methods.append(cls(mesh, order=ORDER, **TUNED[name]))
        methods.append(cls(mesh, order=ORDER, pvs_frames=np.stack(frames)))
        rows = measure_round_robin(methods, frames, refs, args.repeat)
        for knobs, m, row in zip(sweep, methods, rows):
            row = {"knobs": knobs, **row, "stats": m.stats()}
            entry["sweep"].append(row)
            print(f"  hemiraster {json.dumps(knobs):28s} {row['seconds'] * 1e3:8.2f} ms wall {row['cpu_seconds'] * 1e3:8.2f} ms cpu "
                  f"{row['triangles_per_vertex']:7.1f} tris/v  error {row['error_mean'] * 100:.2f} %", file=sys.stderr)
        default = entry["sweep"][0]
        if name in TUNED:
            entry["tuned"] = {"knobs": TUNED[name], **rows[len(sweep)], "stats": methods[len(sweep)].stats()}
            print(f"  hemiraster tuned {json.dumps(TUNED[name])} {entry['tuned']['cpu_seconds'] * 1e3:8.2f} ms cpu "
                  f"error {entry['tuned']['error_mean'] * 100:.2f} %", file=sys.stderr)
        entry["pvs"] = rows[-1]
        del methods
        entry["lowres_triangles"] = default["stats"]["blocker_triangles"]
        entry["reference_curve"] = ray_curve("reference", mesh, frames, refs, ray_counts, args.repeat)
        if not args.no_embree:
            entry["embree_curve"] = ray_curve("embree", mesh, frames, refs, ray_counts, args.repeat)
        entry["equal_error"] = equal_error(entry, default)
        if "tuned" in entry:
            entry["equal_error_tuned"] = equal_error(entry, entry["tuned"])
        # the best measured knob setting within the target error, against each ray caster
        rows = [r for r in entry["sweep"] + [entry.get("tuned")] if r and r["error_mean"] <= TARGET_ERROR]
        entry["best_equal_error"] = {}
        for kind in ("reference", "embree"):
            if f"{kind}_curve" in entry and rows:
                eqs = [(equal_error(entry, r)[kind]["speedup"], r) for r in rows]
                sp, r = max(eqs, key=lambda x: x[0])
                entry["best_equal_error"][kind] = {"knobs": r["knobs"], "error": r["error_mean"],
                                                   "cpu_seconds": r["cpu_seconds"], "speedup": sp}
        results["meshes"][name] = entry
    print_table(results)
    if args.json:
        with open(args.json, "w") as f:
            json.dump(results, f, indent=2, default=float)
    return 0


def print_table(results: dict) -> None:
    names = list(results["meshes"])
    print("\nTable 1 (Kautz et al. 2004) on this machine -- order 5, default knobs; FPS from the median "
          "process CPU time per frame (wall-clock FPS in brackets), one core, compile excluded; "
          + results["machine_note"])
    rows = [
        ("#Vertices", lambda e: f"{e['vertices']}"),
        ("#Triangles", lambda e: f"{e['triangles']}"),
        ("#Lowres-Triangles", lambda e: f"{e['lowres_triangles']}"),
        ("Avg. #Tris", lambda e: f"{e['sweep'][0]['triangles_per_vertex']:.1f}"),
        ("Avg. #Tris (with PVS)", lambda e: f"{e['pvs']['triangles_per_vertex']:.1f}"),
        ("FPS", lambda e: f"{1 / e['sweep'][0]['cpu_seconds']:.1f} ({1 / e['sweep'][0]['seconds']:.1f})"),
        ("FPS with PVS", lambda e: f"{1 / e['pvs']['cpu_seconds']:.1f} ({1 / e['pvs']['seconds']:.1f})"),
        ("Average L2 error in V*", lambda e: f"{e['sweep'][0]['error_mean'] * 100:.2f}%"),
        ("FPS, tuned knobs", lambda e: (f"{1 / e['tuned']['cpu_seconds']:.1f} ({1 / e['tuned']['seconds']:.1f})"
                                        if "tuned" in e else "-")),
        ("Avg. #Tris, tuned knobs", lambda e: f"{e['tuned']['triangles_per_vertex']:.1f}" if "tuned" in e else "-"),
        ("Error, tuned knobs", lambda e: f"{e['tuned']['error_mean'] * 100:.2f}%" if "tuned" in e else "-"),
    ]
    print(f"| {'Model':24s} | " + " | ".join(f"{n:>12s}" for n in names) + " |")
    print("|" + "---|" * (len(names) + 1))
    for label, fn in rows:
        print(f"| {label:24s} | " + " | ".join(f"{fn(results['meshes'][n]):>12s}" for n in names) + " |")
    print("\nEqual error: rays and CPU time the ray casters need for hemiraster's error (wall-time speedup in brackets)")
    for n in names:
        e = results["meshes"][n]
        for label, key in (("defaults", "equal_error"), ("tuned", "equal_error_tuned")):
            if key not in e:
                continue
            eq = e[key]
            parts = [f"{n} ({label}): hemiraster {eq['hemiraster_cpu_seconds'] * 1e3:.1f} ms at {eq['error'] * 100:.2f} %"]
            for kind in ("reference", "embree"):
                if kind in eq:
                    x = eq[kind]
                    parts.append(f"{kind} {x['rays']:.0f} rays {x['seconds'] * 1e3:.0f} ms "
                                 f"({x['speedup']:.1f}x [{x['wall_speedup']:.1f}x]){' extrapolated' if x['extrapolated'] else ''}")
            print("  " + "; ".join(parts))
        for kind, b in e.get("best_equal_error", {}).items():
            print(f"  {n}: best measured setting vs {kind} (error <= {TARGET_ERROR * 100:.1f} %): {json.dumps(b['knobs'])} "
                  f"{b['cpu_seconds'] * 1e3:.1f} ms at {b['error'] * 100:.2f} %, {b['speedup']:.1f}x")
    print("\nSweep (knobs changed from the defaults):")
    for n in names:
        for row in results["meshes"][n]["sweep"]:
            print(f"  {n:6s} {json.dumps(row['knobs']):28s} {row['cpu_seconds'] * 1e3:8.2f} ms cpu {row['seconds'] * 1e3:8.2f} ms wall "
                  f"{row['triangles_per_vertex']:7.1f} tris/v  error {row['error_mean'] * 100:5.2f} %")


if __name__ == "__main__":
    sys.exit(main())
