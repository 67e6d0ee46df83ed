"""hemiraster and GEARS against embree ray casting, in the same run, on Warp's bunny and bear.

What it shows (issue 18, target 3):

* **Transfer at equal error.** hemiraster at its defaults (order 5, one Warp CPU thread; median wall
  time of ``update()`` after a warm-up) and its mean transfer error against the project's ray-traced
  ground truth (:func:`warpshade.bench.reference_cache.ground_truth`, 4096 rays, cached); then embree
  (``embreex``) at stratified cosine-weighted ray counts ``s*s`` (s = 2, 4, 6... from a start below the
  answer), the SH projection done in NumPy *untimed*: the peer's time is the occlusion casting alone
  (:class:`EmbreeCaster`), the wall time of casting every vertex's rays (median of ``--repeat``), on one
  thread and on two. The peer's figure is at the smallest ``s*s`` whose mean error on the same vertices
  is at most hemiraster's (no interpolation, no extrapolation), and the speed-up is its two-thread
  casting time over hemiraster's update time (the one-thread figure is published beside it).
* **GEARS at equal light samples.** GEARS (k = 16, grid 16, one thread) against k×k jittered shadow
  rays per vertex to a rect light over the mesh: Warp's BVH ray tracer (one thread) and embree's
  casting alone (one thread and two), with the mean |visibility difference| between them.

embreex's ``EmbreeScene.run`` casts its rays one at a time (``rtcOccluded1``) on the calling thread,
with the GIL released; embree's own thread pool only builds the BVH. So the two-thread peer cuts the
rays into parts cast concurrently from two Python threads on the one scene. Every ray's answer is
independent of the thread that casts it: the run checks that the two-thread answers equal the
one-thread answers, ray for ray. Each timing reports ``threads_used``, process CPU time over wall time
during the casts (≈ 2 when both threads really ran; less when other processes held a core).

How to run::

    OPENBLAS_NUM_THREADS=1 python benchmarks/embree_peer.py --parts transfer --json benchmarks/results/embree_peer_2threads.json
    OPENBLAS_NUM_THREADS=1 python benchmarks/embree_peer.py --parts gears --json benchmarks/results/embree_peer_gears_2threads.json

Numbers come from a shared 2-core machine: A and B are timed alternately (hemiraster, embree on one
thread, embree on two, hemiraster...), so drift hits all; compare within one run.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))

from warpshade.bench.meshes import warp_mesh  # noqa: E402
from warpshade.bench.reference_cache import GROUND_TRUTH_SEED, ground_truth  # noqa: E402
from warpshade.bench.metrics import transfer_errors  # noqa: E402
from warpshade.sh import sh_eval  # noqa: E402
from warpshade.visibility import get_method  # noqa: E402
from warpshade.visibility.hemiraster.oracle import tangent_frame_np  # noqa: E402

ORDER = 5
TRUTH_RAYS = 4096


def concentric_disk(u: np.ndarray, v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Shirley–Chiu concentric map of [0,1)² onto the unit disk (the reference's sampling)."""
    a, b = 2 * u - 1, 2 * v - 1
    big = a * a > b * b
    with np.errstate(divide="ignore", invalid="ignore"):
        r = np.where(big, a, b)
        phi = np.where(big, (np.pi / 4) * (b / a), np.pi / 2 - (np.pi / 4) * (a / b))
    phi = np.where((a == 0) & (b == 0), 0.0, phi)
    return r * np.cos(phi), r * np.sin(phi)


class EmbreeCaster:
    """embree occlusion queries against a triangle mesh, cast on one thread or several.

    ``occluded`` returns embreex's answer per ray (int32: 0 blocked, -1 free). With ``threads > 1`` the
    rays are cut into ``PARTS_PER_THREAD * threads`` contiguous parts that a pool of ``threads`` Python
    threads casts with ``EmbreeScene.run`` on the one committed scene (``run`` releases the GIL; a thread
    that finishes early takes the next part, so uneven parts of the mesh balance out); the answers are
    the same rays' answers in the same order.
    """

    PARTS_PER_THREAD = 8

    def __init__(self, points: np.ndarray, faces: np.ndarray):
        from embreex import rtcore_scene
        from embreex.mesh_construction import TriangleMesh

        self.scene = rtcore_scene.EmbreeScene()
        TriangleMesh(self.scene, np.asarray(points)[faces].astype(np.float32))
        # run() commits the BVH on its first call, unguarded: commit here, before any concurrent cast
        self.scene.run(np.zeros((1, 3), np.float32), np.array([[0, 0, 1]], np.float32), query="OCCLUDED")
        self.pools: dict[int, ThreadPoolExecutor] = {}

    def _cast(self, org, dirs, dists, a: int, b: int) -> np.ndarray:
        return self.scene.run(org[a:b], dirs[a:b], dists=None if dists is None else dists[a:b], query="OCCLUDED")

    def occluded(self, org: np.ndarray, dirs: np.ndarray, dists: np.ndarray | None = None,
                 threads: int = 1) -> np.ndarray:
        """Answers for rays ``org + t dirs``, ``0 < t < dists`` (float32 arrays; no ``dists``: unbounded)."""
        n = len(org)
        if threads <= 1:
            return self._cast(org, dirs, dists, 0, n)
        if threads not in self.pools:
            self.pools[threads] = ThreadPoolExecutor(max_workers=threads)
        pool = self.pools[threads]
        cuts = np.linspace(0, n, self.PARTS_PER_THREAD * threads + 1).astype(int)
        parts = pool.map(lambda ab: self._cast(org, dirs, dists, *ab), zip(cuts[:-1], cuts[1:]))
        return np.concatenate(list(parts))

    def close(self) -> None:
        for pool in self.pools.values():
            pool.shutdown()
        self.pools.clear()


def cosine_rays(points, normals, s: int, seed: int):
    """Per vertex s×s jittered strata, concentric disk, lifted to the hemisphere (pdf cos/π):
    origins (V*s*s, 3) and directions (V*s*s, 3) float32, and the directions as float64."""
    rng = np.random.default_rng(seed)
    nv, n = len(points), s * s
    cell = np.stack(np.meshgrid(np.arange(s), np.arange(s), indexing="ij"), -1).reshape(-1, 2)
    jit = rng.random((nv, n, 2))
    x, y = concentric_disk((cell[:, 0] + jit[..., 0]) / s, (cell[:, 1] + jit[..., 1]) / s)
    local = np.stack([x, y, np.sqrt(np.maximum(0.0, 1 - x * x - y * y))], -1)
    frames = np.stack([tangent_frame_np(nrm) for nrm in normals])
    dirs = np.einsum("vij,vnj->vni", frames, local).reshape(-1, 3)
    eps = 1e-5 * float(np.linalg.norm(np.ptp(points, axis=0)))
    org = np.repeat(points + eps * normals, n, axis=0)
    return org.astype(np.float32), dirs.astype(np.float32), dirs


def project(dirs: np.ndarray, visible: np.ndarray, nv: int, n: int) -> np.ndarray:
    """The estimator ``(π/N) Σ y_i V`` per vertex, shape (V, ORDER²) (untimed NumPy)."""
    out = np.zeros((nv, ORDER * ORDER))
    chunk = max(1, 2_000_000 // n)
    for c0 in range(0, nv, chunk):
        c1 = min(nv, c0 + chunk)
        y = sh_eval(dirs[c0 * n:c1 * n], ORDER).reshape(c1 - c0, n, -1)
        out[c0:c1] = np.einsum("vni,vn->vi", y, visible[c0:c1]) * (np.pi / n)
    return out


def timed(*fns, repeat: int) -> list[tuple[float, float, object]]:
    """Per function: median wall and process CPU seconds over ``repeat`` runs after one warm-up, and its
    last result; the functions take turns (f, g, f, g...), so load drift hits each alike."""
    import warp as wp

    res = [fn() for fn in fns]
    wp.synchronize()
    walls, cpus = [[] for _ in fns], [[] for _ in fns]
    for _ in range(repeat):
        for i, fn in enumerate(fns):
            w, c = time.perf_counter(), time.process_time()
            res[i] = fn()
            wp.synchronize()
            walls[i].append(time.perf_counter() - w)
            cpus[i].append(time.process_time() - c)
    return [(float(np.median(w)), float(np.median(c)), r) for w, c, r in zip(walls, cpus, res)]


def cast_both(caster: EmbreeCaster, org, dirs, dists=None, extra=None, repeat: int = 5):
    """Time ``caster`` on one thread and on two on the same rays (and ``extra``, e.g. the method again,
    in the same alternation); check the two answers are identical. Returns the timings
    (``cast_seconds_1thread`` / ``_2threads``, CPU seconds and ``threads_used`` of each), the answers,
    and ``extra``'s median wall time (None without it)."""
    fns = [lambda t=t: caster.occluded(org, dirs, dists, threads=t) for t in (1, 2)] + ([extra] if extra else [])
    res = timed(*fns, repeat=repeat)
    (w1, c1, hits1), (w2, c2, hits2) = res[:2]
    if not np.array_equal(hits1, hits2):
        raise AssertionError(f"two-thread embree answers differ from one-thread on "
                             f"{int((hits1 != hits2).sum())} of {len(hits1)} rays")
    row = {"cast_seconds_1thread": w1, "cast_cpu_seconds_1thread": c1, "threads_used_1thread": c1 / w1,
           "cast_seconds_2threads": w2, "cast_cpu_seconds_2threads": c2, "threads_used_2threads": c2 / w2,
           "answers_identical": True}
    return row, hits2, (res[2][0] if extra else None)


def transfer_peer(name: str, repeat: int, log) -> dict:
    bm = warp_mesh(name)
    mesh = bm.rest
    truth = ground_truth(mesh, ORDER, TRUTH_RAYS, log=log)
    hemi = get_method("hemiraster")(mesh, order=ORDER)
    [(hw, hc, _)] = timed(hemi.update, repeat=repeat)
    h_err = float(transfer_errors(hemi.transfer.numpy(), truth).mean())
    normals = hemi.normals.numpy().astype(np.float64)
    points = mesh.points.astype(np.float64)
    caster = EmbreeCaster(points, mesh.faces)
    log(f"{name}: {mesh.num_vertices} vertices; hemiraster {hw * 1e3:.1f} ms wall ({hc * 1e3:.1f} ms cpu), "
        f"error {h_err * 100:.3f} %")
    curve, s, found = [], 24, None
    tried = {}
    while found is None and 2 <= s <= 128:
        org, dirs32, dirs = cosine_rays(points, normals, s, seed=1)
        # interleaved: hemiraster again at this load
        times, hits, hw2 = cast_both(caster, org, dirs32, extra=hemi.update, repeat=repeat)
        visible = (np.asarray(hits).reshape(len(points), s * s) == -1).astype(np.float64)
        err = float(transfer_errors(project(dirs, visible, len(points), s * s), truth).mean())
        row = {"rays": s * s, "error_mean": err, **times, "hemiraster_seconds_interleaved": hw2}
        curve.append(row)
        tried[s] = err <= h_err
        log(f"  embree {s * s:5d} rays: cast {times['cast_seconds_1thread'] * 1e3:8.1f} ms on one thread "
            f"({times['threads_used_1thread']:.2f} cores), {times['cast_seconds_2threads'] * 1e3:8.1f} ms on two "
            f"({times['threads_used_2threads']:.2f} cores), error {err * 100:.3f} %  [hemiraster again {hw2 * 1e3:.1f} ms]")
        if err <= h_err:
            if (s - 2) in tried or s == 2:
                found = row
            else:
                s -= 2
        else:
            if (s + 2) in tried and tried[s + 2]:
                found = next(r for r in curve if r["rays"] == (s + 2) ** 2)
            else:
                s += 2
    caster.close()
    hemi_wall = float(np.median([hw] + [r["hemiraster_seconds_interleaved"] for r in curve]))
    out = {"mesh": name, "vertices": mesh.num_vertices, "triangles": mesh.num_faces, "order": ORDER,
           "ground_truth": {"method": "reference", "rays": TRUTH_RAYS, "seed": GROUND_TRUTH_SEED},
           "hemiraster": {"knobs": "defaults", "seconds": hemi_wall, "cpu_seconds": hc, "error_mean": h_err,
                          "threads": 1},
           "embree_curve": sorted(curve, key=lambda r: r["rays"])}
    if found:
        out["embree_at_equal_error"] = found
        out["speedup_2threads"] = found["cast_seconds_2threads"] / hemi_wall
        out["speedup_1thread"] = found["cast_seconds_1thread"] / hemi_wall
        log(f"  => embree needs {found['rays']} rays ({found['error_mean'] * 100:.3f} % <= {h_err * 100:.3f} %): "
            f"{found['cast_seconds_2threads'] * 1e3:.1f} ms casting on 2 threads "
            f"({found['cast_seconds_1thread'] * 1e3:.1f} ms on one) vs hemiraster {hemi_wall * 1e3:.1f} ms "
            f"on one: {out['speedup_2threads']:.1f}x ({out['speedup_1thread']:.1f}x against one thread)")
    return out


def gears_peer(name: str, k: int, repeat: int, log) -> dict:
    from warpshade.visibility.gears import LightRect, get_area_method

    mesh = warp_mesh(name).rest
    light = LightRect.over_points(mesh.points, size=0.3, height=1.4, tilt=0.4)
    g = get_area_method("gears")(mesh, light, k=k, grid=16)
    r = get_area_method("reference")(mesh, light, k=k, jitter=True)
    (gw, _, _), (rw, _, _) = timed(g.update, r.update, repeat=repeat)
    vis_g, vis_r = g.visibility.numpy(), r.visibility.numpy()
    # embree: the same k×k jittered light points, rays from just above each vertex, casting timed alone
    normals = r.normals.numpy().astype(np.float64) if hasattr(r, "normals") else g.normals.numpy()
    points = mesh.points.astype(np.float64)
    caster = EmbreeCaster(points, mesh.faces)
    rng = np.random.default_rng(3)
    c, u, v = (np.asarray(x, np.float64) for x in (light.center, light.u, light.v))
    ii, jj = np.meshgrid(np.arange(k), np.arange(k), indexing="ij")
    jit = rng.random((len(points), k * k, 2))
    sgrid = -1 + 2 * (ii.ravel()[None, :] + jit[..., 0]) / k
    tgrid = -1 + 2 * (jj.ravel()[None, :] + jit[..., 1]) / k
    q = c + sgrid[..., None] * u + tgrid[..., None] * v
    eps = 1e-5 * float(np.linalg.norm(np.ptp(points, axis=0)))
    p = (points + eps * normals)[:, None, :]
    d = q - p
    dist = np.linalg.norm(d, axis=2)
    org = np.repeat(p, k * k, axis=1).reshape(-1, 3).astype(np.float32)
    dirs = (d / dist[..., None]).reshape(-1, 3).astype(np.float32)
    tfar = (dist * (1 - 1e-6)).reshape(-1).astype(np.float32)
    times, hits, gw2 = cast_both(caster, org, dirs, tfar, extra=g.update, repeat=repeat)
    caster.close()
    vis_e = 1.0 - (np.asarray(hits).reshape(len(points), k * k) != -1).mean(axis=1)
    gears_wall = float(np.median([gw, gw2]))
    e1, e2 = times["cast_seconds_1thread"], times["cast_seconds_2threads"]
    out = {"mesh": name, "k": k, "light_samples": k * k, "grid": 16, "gears_seconds": gears_wall,
           "warp_rays_seconds": rw, "embree": times,
           "speedup_vs_warp_rays": rw / gears_wall, "speedup_vs_embree_2threads": e2 / gears_wall,
           "speedup_vs_embree_1thread": e1 / gears_wall,
           "mean_abs_diff_gears_vs_warp_rays": float(np.abs(vis_g - vis_r).mean()),
           "mean_abs_diff_embree_vs_warp_rays": float(np.abs(vis_e - vis_r).mean())}
    log(f"{name} GEARS k={k}: {gears_wall * 1e3:.1f} ms; Warp rays {rw * 1e3:.1f} ms ({out['speedup_vs_warp_rays']:.1f}x); "
        f"embree casting {e2 * 1e3:.1f} ms on two threads ({times['threads_used_2threads']:.2f} cores; "
        f"{out['speedup_vs_embree_2threads']:.1f}x), {e1 * 1e3:.1f} ms on one ({times['threads_used_1thread']:.2f} "
        f"cores; {out['speedup_vs_embree_1thread']:.1f}x); "
        f"|dV| gears {out['mean_abs_diff_gears_vs_warp_rays']:.4f}, embree {out['mean_abs_diff_embree_vs_warp_rays']:.4f}")
    return out


def main(argv=None) -> int:
    import warp as wp

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--meshes", default="bunny,bear")
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--k", type=int, default=16, help="GEARS light samples per side")
    ap.add_argument("--parts", default="transfer,gears", help="which comparisons to run (comma-separated)")
    ap.add_argument("--json", default=None, metavar="PATH")
    args = ap.parse_args(argv)
    parts = {p for p in args.parts.split(",") if p}
    if not parts <= {"transfer", "gears"}:
        ap.error(f"--parts: transfer and/or gears, got {args.parts!r}")
    wp.config.log_level = wp.LOG_WARNING
    wp.init()

    def log(msg):
        print(msg, file=sys.stderr, flush=True)

    meshes = [m for m in args.meshes.split(",") if m]
    load0 = os.getloadavg()[0]
    transfer = [transfer_peer(m, args.repeat, log) for m in meshes] if "transfer" in parts else []
    gears = [gears_peer(m, args.k, args.repeat, log) for m in meshes] if "gears" in parts else []
    if transfer:
        print(f"\n{'mesh':6} {'hemiraster ms':>13} {'err %':>6} {'embree rays':>11} {'err %':>6} "
              f"{'1 thread ms':>11} {'x':>6} {'2 threads ms':>12} {'cores':>5} {'x':>6}")
    for t in transfer:
        e = t.get("embree_at_equal_error", {})
        nan = float("nan")
        print(f"{t['mesh']:6} {t['hemiraster']['seconds'] * 1e3:13.1f} {t['hemiraster']['error_mean'] * 100:6.2f} "
              f"{e.get('rays', 0):11d} {e.get('error_mean', nan) * 100:6.2f} "
              f"{e.get('cast_seconds_1thread', nan) * 1e3:11.1f} {t.get('speedup_1thread', nan):5.1f}x "
              f"{e.get('cast_seconds_2threads', nan) * 1e3:12.1f} {e.get('threads_used_2threads', nan):5.2f} "
              f"{t.get('speedup_2threads', nan):5.1f}x")
    if gears:
        print(f"\n{'mesh':6} {'k':>3} {'GEARS ms':>9} {'Warp rays ms':>12} {'x':>6} {'embree 1t ms':>12} {'x':>6} "
              f"{'embree 2t ms':>12} {'cores':>5} {'x':>6}")
    for g in gears:
        e = g["embree"]
        print(f"{g['mesh']:6} {g['k']:3d} {g['gears_seconds'] * 1e3:9.1f} {g['warp_rays_seconds'] * 1e3:12.1f} "
              f"{g['speedup_vs_warp_rays']:5.1f}x {e['cast_seconds_1thread'] * 1e3:12.1f} "
              f"{g['speedup_vs_embree_1thread']:5.1f}x {e['cast_seconds_2threads'] * 1e3:12.1f} "
              f"{e['threads_used_2threads']:5.2f} {g['speedup_vs_embree_2threads']:5.1f}x")
    load1 = os.getloadavg()[0]
    note = ("embree: embreex, casting time alone, on one thread and on two (the rays cut into parts cast from two "
            "Python threads; answers checked identical); 'cores' = process CPU / wall during the two-thread casts; "
            "hemiraster and GEARS: one Warp CPU thread; wall-time medians after a warm-up, A/B interleaved; "
            f"2-core machine, 1-minute load average {load0:.2f} at the start and {load1:.2f} at the end (this run "
            "included)")
    print(note)
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"transfer": transfer, "gears": gears, "machine": note}, f, indent=2)
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
