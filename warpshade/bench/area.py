"""Area-light part of ``warpshade bench``: GEARS visibility (k, grid) against ray-traced area-light truth.

GEARS (:class:`~warpshade.visibility.gears.GearsVisibility`) computes a different quantity from the SH
transfer methods: the fraction of a rectangular light visible from each vertex (docs/conventions.md §4), a
number in [0, 1]. Its records therefore carry ``quantity = "area_visibility"`` and their errors are
**absolute visible-fraction errors** ``|V - V*|`` per vertex (mean, 95th percentile, max), not the
relative L2 transfer error; they sit on their own Pareto panel.

Scene per benchmark mesh: the judged frame under a rectangle light (:func:`bench_light`) above it along
the mesh's up axis, half-axes 0.3 of the horizontal extents, tilted 0.4 rad (as ``benchmarks/gears.py``),
so part of every mesh is in penumbra. Ground truth: :class:`~warpshade.visibility.gears.reference.RayVisibility`
with k = 32 (1024 stratified, jittered shadow rays per vertex, seed :data:`AREA_TRUTH_SEED`), whose
standard error on a visible fraction is below 1/(2·32) per vertex. GEARS samples cell centres of a k×k
grid, so its error against the truth is the light-sampling error of k (plus any rasterization miss);
``area-rays`` records are the ray tracer at the same k (jittered, seed 0) for comparison.
"""

from __future__ import annotations

import time

import numpy as np

from .timing import median_seconds
from .records import knobs_text

AREA_TRUTH_K = 32
"""Light samples per side of the ground truth (k = 32 is the kernels' maximum: 1024 rays per vertex)."""

AREA_TRUTH_SEED = 982451653
"""Jitter seed of the area-light ground truth (independent of the ``area-rays`` records' seed 0)."""

AREA_METHODS = ("gears", "area-rays")
"""Record ``method`` names of this module: GEARS and the ray-traced comparison at the same k."""


def bench_light(points: np.ndarray, up: str = "Y", size: float = 0.3, tilt: float = 0.4):
    """A rectangle light above a point set along ``up``.

    Centre over the bounding box's middle, at the box top plus half the larger horizontal extent;
    half-axes ``size`` times the two horizontal extents; the second half-axis tilted by ``tilt`` [rad]
    out of the horizontal plane.

    Returns:
        :class:`~warpshade.visibility.gears.LightRect`.
    """
    from ..visibility.gears import LightRect

    p = np.asarray(points, dtype=np.float64)
    up_i = {"X": 0, "Y": 1, "Z": 2}[up.upper()]
    a, b = [i for i in range(3) if i != up_i]
    lo, hi = p.min(axis=0), p.max(axis=0)
    d = hi - lo
    c = 0.5 * (lo + hi)
    c[up_i] = hi[up_i] + 0.5 * max(d[a], d[b])
    u = np.zeros(3)
    u[a] = d[a] * size
    v = np.zeros(3)
    v[b] = np.cos(tilt) * d[b] * size
    v[up_i] = -np.sin(tilt) * d[b] * size
    return LightRect(tuple(c), tuple(u), tuple(v))


def area_configs(quick: bool) -> list[tuple[str, dict]]:
    """``(method, kwargs)`` pairs: GEARS's own sweep, then the ray tracer at k = 8 and 16."""
    from ..visibility.gears import get_area_method

    gears = [("gears", dict(c)) for c in get_area_method("gears").sweep(quick)]
    rays = [("area-rays", {"k": k}) for k in ((16,) if quick else (8, 16))]
    return gears + rays


def area_errors(visibility: np.ndarray, truth: np.ndarray) -> dict:
    """``{"error_mean", "error_p95", "error_max"}`` of the absolute visible-fraction error per vertex."""
    e = np.abs(np.asarray(visibility, np.float64) - np.asarray(truth, np.float64))
    return {"error_mean": float(e.mean()), "error_p95": float(np.percentile(e, 95)), "error_max": float(e.max())}


def area_truth(mesh, light, device: str = "cpu") -> np.ndarray:
    """Ray-traced visible fraction of ``light`` at every vertex of ``mesh`` (shape (V,), float32)."""
    from ..visibility.gears import get_area_method

    ref = get_area_method("reference")(mesh, light, k=AREA_TRUTH_K, device=device, jitter=True, seed=AREA_TRUTH_SEED)
    return ref.update().numpy().copy()


def measure_area(method: str, kwargs: dict, bm, light, truth: np.ndarray, repeat: int, slow_seconds: float,
                 device: str = "cpu") -> dict:
    """Time and error of one area-light configuration on one benchmark mesh (times as :func:`.runner.measure`:
    construction timed as ``build_seconds``, one untimed warm-up update on the frame, then the median)."""
    from ..visibility.gears import get_area_method

    cls = get_area_method("gears" if method == "gears" else "reference")
    kw = dict(kwargs)
    if method == "area-rays":
        kw.update(jitter=True, seed=0)
    t0 = time.perf_counter()
    m = cls(bm.rest, light, device=device, **kw)
    build_seconds = time.perf_counter() - t0
    t0 = time.perf_counter()
    m.update(bm.frame)
    first = time.perf_counter() - t0
    rep = repeat if first < slow_seconds else 1
    seconds = median_seconds(m.update, repeat=rep, warmup=0)
    vis = m.visibility.numpy()
    if bm.judged is not None:  # as the transfer records: buried vertices are not judged
        vis, truth = vis[bm.judged], truth[bm.judged]
    return {
        "method": method,
        "mesh": bm.name,
        "quantity": "area_visibility",
        "vertices": bm.rest.num_vertices,
        "triangles": bm.rest.num_faces,
        "order": None,
        "knobs": m.knobs(),
        "config": dict(kwargs),
        "seconds": seconds,
        "repeat": rep,
        "build_seconds": build_seconds,
        "judged_vertices": int(len(vis)),
        **area_errors(vis, truth),
        "finite": bool(np.isfinite(vis).all()),
        "stats": m.stats(),
        "light": {"center": list(light.center), "u": list(light.u), "v": list(light.v)},
        "ground_truth": {"method": "area-rays", "k": AREA_TRUTH_K, "jitter": True, "seed": AREA_TRUTH_SEED},
    }


def run_area(meshes, settings, log) -> list[dict]:
    """GEARS and ray-traced area-light records for every benchmark mesh (see the module doc)."""
    configs = area_configs(settings.quick)
    records = []
    warmed = set()
    tiny = _tiny()
    for bm in meshes:
        light = bench_light(bm.frame, bm.up)
        t0 = time.perf_counter()
        truth = area_truth(bm.frame_mesh, light, settings.device)
        log(f"{bm.name}: area-light ground truth ({AREA_TRUTH_K}x{AREA_TRUTH_K} jittered rays per vertex): "
            f"{time.perf_counter() - t0:.1f} s")
        for method, kwargs in configs:
            if method not in warmed:  # compile outside the timed region (one module per method)
                measure_area(method, kwargs, tiny, bench_light(tiny.frame, "Y"), np.zeros(tiny.rest.num_vertices),
                             1, 0.0, settings.device)
                warmed.add(method)
            try:
                rec = measure_area(method, kwargs, bm, light, truth, settings.repeat, settings.slow_seconds,
                                   settings.device)
            except Exception as exc:  # one broken configuration must not sink the sweep
                log(f"  {method} {kwargs}: FAILED {type(exc).__name__}: {exc}")
                records.append({"method": method, "mesh": bm.name, "quantity": "area_visibility", "order": None,
                                "knobs": kwargs, "failed": f"{type(exc).__name__}: {exc}"})
                continue
            rec["quick"] = settings.quick
            records.append(rec)
            log(f"  {method:<11} {knobs_text(rec['knobs'])}: {rec['seconds'] * 1e3:9.2f} ms  "
                f"|dV| {rec['error_mean']:.4f} (p95 {rec['error_p95']:.4f})")
    return records


def _tiny():
    """A 162-vertex icosphere, for compiling kernels before timing."""
    import trimesh

    from ..geometry.mesh import TriMesh
    from .meshes import BenchMesh

    ico = trimesh.creation.icosphere(2)
    m = TriMesh(ico.vertices, ico.faces, name="warm-up icosphere")
    return BenchMesh("warm-up", m, m.points.copy(), up="Y")
