"""The speed/accuracy sweep: every registered method × its ``sweep(quick)`` knobs × SH orders × meshes.

What a record measures (one method configuration on one mesh):

* ``seconds``: median wall time of ``update()`` on the judged frame over ``repeat`` runs
  (:func:`warpshade.bench.timing.median_seconds`). Kernels are compiled beforehand by running the same
  configuration on a tiny icosphere, and the first update on the real mesh is an untimed warm-up, so
  compilation and cache loading are excluded.
* ``build_seconds``: constructing the method on the rest pose (static structures), compile excluded.
* ``peak_rss_bytes``: growth of the process' resident-set high-water mark (Linux ``VmHWM``, reset
  through ``/proc/self/clear_refs``) over construction plus the first update: everything the method
  allocates, host and Warp-native, including temporaries. Memory the allocator already held from
  earlier configurations can be reused without raising the mark, so small values underestimate;
  None where the kernel does not allow resetting the mark.
* ``array_bytes``: bytes of Warp and NumPy arrays the method object holds after the update (its
  persistent structures and outputs; a ``wp.Mesh`` BVH is estimated at 64 bytes per triangle).
* ``error_mean``/``error_p95``/``error_max``: :func:`warpshade.bench.metrics.error_summary` of the transfer
  against the cached ground truth (:mod:`.reference_cache`), on the method's ``order*order``
  coefficients, over the mesh's judged vertices (``judged_vertices``: all but the character's buried
  ones, :attr:`.meshes.BenchMesh.judged`).
* ``radiance_error_<env>``: :func:`warpshade.bench.metrics.radiance_error` of white-Lambertian exit radiance
  under each environment of :mod:`.environments` (band-limited to order 6, so lower orders also pay
  for the bands they drop).

GEARS (``--methods gears``, included by default) is an area-light visibility method: its records
(``quantity = "area_visibility"``, ``order = None``) come from :mod:`.area`, with errors in absolute
visible fraction against a ray-traced area-light truth.
"""

from __future__ import annotations

import gc
import json
import os
import sys
import time
from dataclasses import dataclass, field

import numpy as np

from .metrics import error_summary, radiance_error
from .timing import median_seconds
from .environments import ENV_ORDER, environments, radiance
from .meshes import BenchMesh, standard_meshes
from .records import knobs_text, pareto_mask
from .reference_cache import DEFAULT_CACHE_DIR, GROUND_TRUTH_SEED, ground_truth

QUICK_BUILD_LIMIT = 5.0
"""In quick mode, a method whose construction took longer than this [s] is measured with its first
configuration only on that mesh (keeps ``--quick`` under two minutes with slow-to-build methods)."""

DEFAULT_ORDER = 5
"""Order at which each method's knob sweep runs (the methods' constructor default)."""


@dataclass
class BenchSettings:
    """What to sweep.

    Attributes:
        quick: Few configurations, small meshes, cheaper timing (< 2 minutes in all).
        methods: Method names (default: every registered method).
        meshes: Mesh names to keep from the standard set (default: all).
        orders: SH orders swept at each method's default knobs.
        repeat: Timed runs per configuration (fewer for configurations slower than ``slow_seconds``).
        slow_seconds: An update slower than this is timed once.
        ground_truth_rays: Rays per vertex of the ground truth.
        cache_dir: Ground-truth cache directory (None: no cache).
        device: Warp device.
    """

    quick: bool = False
    methods: list[str] | None = None
    meshes: list[str] | None = None
    orders: tuple[int, ...] = (2, 3, 4, 5, 6)
    repeat: int = 5
    slow_seconds: float = 5.0
    ground_truth_rays: int = 16384
    cache_dir: str | None = DEFAULT_CACHE_DIR
    device: str = "cpu"
    log: object = field(default=None, repr=False)

    @classmethod
    def for_mode(cls, quick: bool, **overrides) -> "BenchSettings":
        """Defaults of the full or the quick sweep, with ``overrides`` (None values ignored)."""
        base = dict(orders=(3,), repeat=3, slow_seconds=0.5, ground_truth_rays=4096) if quick else {}
        base.update({k: v for k, v in overrides.items() if v is not None})
        return cls(quick=quick, **base)


def method_configs(cls, quick: bool, orders) -> list[dict]:
    """Constructor kwargs (``order`` included) for one method: its knob sweep at the default order,
    then its default knobs at each of ``orders`` (duplicates dropped, order kept)."""
    out, seen = [], set()
    for knobs in list(cls.sweep(quick)) + [{"order": o} for o in orders]:
        k = dict(knobs)
        k.setdefault("order", DEFAULT_ORDER)
        key = json.dumps(k, sort_keys=True, default=str)
        if key not in seen:
            seen.add(key)
            out.append(k)
    return out


def _read_status(field_name: str) -> int | None:
    try:
        with open("/proc/self/status") as f:
            for line in f:
                if line.startswith(field_name + ":"):
                    return int(line.split()[1]) * 1024
    except OSError:
        return None
    return None


def _reset_peak_rss() -> bool:
    try:
        with open("/proc/self/clear_refs", "w") as f:
            f.write("5")
        return True
    except OSError:
        return False


def array_bytes(obj, _seen=None, _depth=0) -> int:
    """Bytes of Warp/NumPy arrays reachable from ``obj``'s attributes (containers and nested objects
    up to three levels; the input ``mesh`` attribute is not the method's and is skipped)."""
    import warp as wp

    seen = set() if _seen is None else _seen
    if id(obj) in seen or _depth > 3:
        return 0
    seen.add(id(obj))
    if isinstance(obj, wp.array):
        return int(obj.size * wp.types.type_size_in_bytes(obj.dtype))
    if isinstance(obj, np.ndarray):
        return int(obj.nbytes)
    if isinstance(obj, wp.Mesh):
        n_tri = obj.indices.shape[0] // 3
        return array_bytes(obj.points, seen, _depth + 1) + array_bytes(obj.indices, seen, _depth + 1) + 64 * n_tri
    if isinstance(obj, dict):
        return sum(array_bytes(v, seen, _depth + 1) for v in obj.values())
    if isinstance(obj, (list, tuple)):
        return sum(array_bytes(v, seen, _depth + 1) for v in obj)
    if hasattr(obj, "__dict__") and not isinstance(obj, type) and type(obj).__module__.startswith("warpshade"):
        return sum(array_bytes(v, seen, _depth + 1) for k, v in vars(obj).items() if k != "mesh")
    return 0


def _warm_kernels(cls, config: dict, device: str) -> str | None:
    """Compile the configuration's kernels on a tiny icosphere; returns an error text if it cannot."""
    import trimesh

    from ..geometry.mesh import TriMesh

    ico = trimesh.creation.icosphere(2)
    try:
        m = cls(TriMesh(ico.vertices, ico.faces, name="warm-up icosphere"), device=device, **config)
        m.update()
        return None
    except Exception as exc:  # a method may need more geometry than 162 vertices; then compile counts
        return f"{type(exc).__name__}: {exc}"


_WARMED: set = set()
"""Methods whose kernels are compiled: Warp compiles a whole module at its first launch, so one warm-up
per method covers all its knob settings and orders (order is a runtime argument)."""


def measure(cls, config: dict, bm: BenchMesh, truth: np.ndarray, lights: dict, settings: BenchSettings) -> dict:
    """Time, memory and errors of one method configuration on one benchmark mesh (see module doc)."""
    warm_error = None
    if cls.name not in _WARMED:
        warm_error = _warm_kernels(cls, config, settings.device)
        if warm_error is None:
            _WARMED.add(cls.name)
    gc.collect()
    rss0 = _read_status("VmRSS")
    can_peak = _reset_peak_rss() and rss0 is not None
    t0 = time.perf_counter()
    method = cls(bm.rest, device=settings.device, **config)
    build_seconds = time.perf_counter() - t0
    t0 = time.perf_counter()
    method.update(bm.frame)
    first_seconds = time.perf_counter() - t0
    peak = _read_status("VmHWM") if can_peak else None
    repeat = settings.repeat if first_seconds < settings.slow_seconds else 1
    seconds = median_seconds(method.update, repeat=repeat, warmup=0)
    transfer = method.transfer_numpy()
    n = transfer.shape[1]
    if bm.judged is not None:  # errors over the judged vertices only (time covers all)
        transfer, truth = transfer[bm.judged], truth[bm.judged]
    rec = {
        "method": cls.name,
        "mesh": bm.name,
        "vertices": bm.rest.num_vertices,
        "triangles": bm.rest.num_faces,
        "order": method.order,
        "knobs": method.knobs(),
        "config": {k: v for k, v in config.items() if k != "order"},
        "seconds": seconds,
        "repeat": repeat,
        "build_seconds": build_seconds,
        "judged_vertices": int(len(transfer)),
        **error_summary(transfer, truth[:, :n]),
    }
    for env, light in lights.items():
        rec[f"radiance_error_{env}"] = radiance_error(radiance(transfer, light), radiance(truth, light))
    rec["peak_rss_bytes"] = (peak - rss0) if peak is not None else None
    rec["array_bytes"] = array_bytes(method)
    rec["finite"] = bool(np.isfinite(transfer).all())
    rec["stats"] = method.stats()
    if warm_error:
        rec["note"] = f"kernels not pre-compiled ({warm_error}); build/memory include compilation"
    return rec


def run_bench(settings: BenchSettings) -> list[dict]:
    """Run the sweep; returns the records (each also carries ``pareto``: on its mesh's frontier)."""
    from ..visibility import METHODS, get_method

    from .area import AREA_METHODS, run_area

    log = settings.log or (lambda msg: print(msg, file=sys.stderr, flush=True))
    names = settings.methods or sorted(METHODS) + ["gears"]
    # "gears" (area-light visibility) is measured by .area, with the ray tracer at equal k beside it
    area = any(n in AREA_METHODS for n in names)
    classes = [get_method(n) for n in names if n not in AREA_METHODS]
    meshes = standard_meshes(settings.quick)
    if settings.meshes:
        meshes = [m for m in meshes if m.name in settings.meshes]
        if not meshes:
            raise ValueError(f"no benchmark mesh among {settings.meshes} (known: "
                             f"{', '.join(m.name for m in standard_meshes(settings.quick))})")
    configs = {cls.name: method_configs(cls, settings.quick, settings.orders) for cls in classes}
    max_order = max([ENV_ORDER] + [c["order"] for cs in configs.values() for c in cs])
    records = []
    for bm in meshes if classes else []:
        log(f"{bm.name}: {bm.rest.num_vertices} vertices, {bm.rest.num_faces} triangles — {bm.description}")
        truth = ground_truth(bm.frame_mesh, max_order, settings.ground_truth_rays, settings.cache_dir,
                             settings.device, log=log)
        lights = environments(ENV_ORDER, up=bm.up)
        for cls in classes:
            for i, config in enumerate(configs[cls.name]):
                if settings.quick and i > 0 and records and records[-1].get("build_seconds", 0) > QUICK_BUILD_LIMIT:
                    log(f"  {cls.name}: build took {records[-1]['build_seconds']:.1f} s > {QUICK_BUILD_LIMIT} s; quick mode "
                        f"measures only its first configuration on {bm.name} ({len(configs[cls.name]) - 1} skipped)")
                    break
                try:
                    rec = measure(cls, config, bm, truth, lights, settings)
                except Exception as exc:  # one broken configuration must not sink the sweep
                    log(f"  {cls.name} {config}: FAILED {type(exc).__name__}: {exc}")
                    records.append({"method": cls.name, "mesh": bm.name, "order": config.get("order"),
                                    "knobs": config, "failed": f"{type(exc).__name__}: {exc}"})
                    continue
                rec["ground_truth"] = {"method": "reference", "rays": settings.ground_truth_rays,
                                       "seed": GROUND_TRUTH_SEED}
                rec["quick"] = settings.quick
                records.append(rec)
                log(f"  {cls.name:<11} order {rec['order']} {knobs_text(rec['knobs'])}: {rec['seconds'] * 1e3:9.2f} ms  "
                    f"err {rec['error_mean']:.4f} (p95 {rec['error_p95']:.4f})")
    if area:
        records += run_area(meshes, settings, log)
    mark_pareto(records)
    return records


def mark_pareto(records: list[dict]) -> None:
    """Set ``pareto`` on every measured record: on the time/``error_mean`` frontier of all methods' records
    with the same mesh, SH order and quantity (errors of different orders compare different coefficient
    sets; area-light visibility errors are another quantity altogether)."""
    by_mesh: dict[tuple, list[dict]] = {}
    for r in records:
        if "failed" not in r:
            by_mesh.setdefault((r["mesh"], r["order"], r.get("quantity", "transfer")), []).append(r)
    for recs in by_mesh.values():
        mask = pareto_mask([r["seconds"] for r in recs], [r["error_mean"] for r in recs])
        for r, m in zip(recs, mask):
            r["pareto"] = bool(m)


def machine_note() -> str:
    """One line on where the numbers were taken (the printed table and ``results.md`` quote it)."""
    import platform

    import warp as wp

    return (f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores shared with other jobs "
            f"(a loaded machine: absolute times are noisy, ratios less so), Warp {wp.config.version} CPU, one thread")
