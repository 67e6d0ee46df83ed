"""Whole animations in the benchmark (``warpshade bench --animation``): every frame shaded in sequence,
every k-th frame judged against the ray-traced truth of that frame.

Sequences (:func:`sequence`):

* ``default``: the shipped default scene (a cloth dropped over a ball onto the ground), simulated
  as ``warpshade run`` simulates it; the receiver is its shading group (ground, ball and cloth merged,
  the ground refined as the run refines it), front sides only (``--two-sided off``).
* ``walk``: the skinned :class:`warpshade.sim.figure.WalkingFigure` walking along +z at 60 frames/s;
  vertices buried inside another capsule in a judged frame are not judged (as the bench's
  ``character`` mesh).
* a USD file's path: its first shading group with a moving member, simulated and merged alike, front
  sides only.

Each configuration (method, knobs, temporal reuse tolerance) runs the whole sequence on a fresh
instance after a warm-up instance compiled its kernels, the configurations taking turns frame by
frame (load drift on a shared machine hits all alike); per frame the wall and process CPU time of
``update`` are recorded, and on judged frames :func:`warpshade.bench.metrics.error_summary` against
:func:`.reference_cache.ground_truth` (cached) of that frame.
"""

from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass, field

import numpy as np
import warp as wp

from .. import _cache
from .._atomic import replace_atomically
from ..geometry.mesh import TriMesh
from .meshes import BENCH_KIND
from .metrics import error_summary
from .reference_cache import DEFAULT_CACHE_DIR, GROUND_TRUTH_SEED, ground_truth

ANIMATIONS = ("default", "walk")
"""Sequence names of :func:`sequence`."""

DEFAULT_TOLERANCES = (0.0, 0.05, 0.1, 0.2, 0.5, 1.0)
"""Temporal reuse tolerances [rad] measured beside plain recomputation."""

SEQUENCE_CACHE = _cache.USER
"""Where simulated sequences are cached by default: ``<user cache root>/bench`` (:func:`warpshade._cache.directory`)."""


@dataclass
class Sequence:
    """Frames of one receiver mesh.

    Attributes:
        name: Sequence name.
        rest: Topology and rest pose (what methods are built on).
        frames: Positions per frame, shape (T, V, 3), float32.
        judged: ``judged(frame)``: bool mask of the vertices judged in that frame (V,), or None for all.
        description: One line for the table.
    """

    name: str
    rest: TriMesh
    frames: np.ndarray
    judged: object = field(default=lambda frame: None, repr=False)
    description: str = ""


def _scene(path: str, label: str, frames: int, cache_dir: str | None, side: str = "front") -> Sequence:
    """The frames of a USD scene's first moving shading group, simulated as ``warpshade run`` simulates
    them (cached under ``cache_dir`` by the scene file's content and ``frames``). ``side="back"``: the group
    seen from its back (:func:`warpshade.pipeline.shading.flipped`, as the run's back pass), judged at its
    two-sided members' vertices only (``two_sided="auto"``: cloth, ``warpshade:twoSided``)."""
    import hashlib

    from ..pipeline import Pipeline
    from ..usd import read_scene

    scene = read_scene(path)
    pipe = Pipeline(scene, frames=frames, two_sided="auto" if side == "back" else "off", reuse=None)
    shaded = [g for g in pipe.groups if g.method is not None]
    if not shaded:
        raise ValueError(f"{path}: no shading group with a visibility method")
    group = next((g for g in shaded if any(g.moving)), shaded[0])
    offsets = np.cumsum([0] + [m.num_vertices for m in group.meshes])
    faces = np.concatenate([m.faces + o for m, o in zip(group.meshes, offsets[:-1])]).astype(np.int32)
    rest = np.concatenate([m.points for m in group.meshes]).astype(np.float32)
    with open(path, "rb") as fh:
        digest = hashlib.sha256(fh.read()).hexdigest()[:12]
    stem = os.path.splitext(os.path.basename(path))[0]
    cache_dir = _cache.resolve(cache_dir, BENCH_KIND)
    cached = os.path.join(cache_dir, f"animation_{stem}_{digest}_f{frames}.npz") if cache_dir else None
    description = (f"{label}, {frames} simulated frames: {', '.join(group.names)} as one receiver "
                   f"({len(rest)} vertices), front sides")
    mesh = TriMesh(rest, faces, name=f"{stem} scene group")
    judged = lambda frame: None  # noqa: E731 - every vertex
    if side == "back":
        from ..pipeline.shading import flipped

        two = np.concatenate([np.full(m.num_vertices, bool(t)) for m, t in zip(group.meshes, group.two_sided)])
        if not two.any():
            raise ValueError(f"{path}: the group {', '.join(group.names)} has no two-sided member (no back side)")
        mesh = flipped(mesh)
        judged = lambda frame: two  # noqa: E731 - the two-sided members' back sides
        description = description.replace("front sides", f"back sides, judged at the two-sided members' "
                                                          f"{int(two.sum())} vertices")
    if cached and os.path.isfile(cached):
        z = np.load(cached)
        if z["frames"].shape == (frames, len(rest), 3) and np.array_equal(z["faces"], faces):
            return Sequence(stem, mesh, z["frames"], judged, description)
    out = np.empty((frames, len(rest), 3), dtype=np.float32)
    for f, geo in pipe.simulate():
        out[f] = np.concatenate([geo[n] if mv else group.meshes[k].points
                                 for k, (n, mv) in enumerate(zip(group.names, group.moving))])
    if cached:
        os.makedirs(cache_dir, exist_ok=True)
        replace_atomically(lambda tmp: np.savez(tmp, frames=out, faces=faces), cached)
    return Sequence(stem, mesh, out, judged, description)


def _walk(frames: int, fps: float = 60.0) -> Sequence:
    from ..sim.figure import WalkingFigure
    from .meshes import character

    fig = WalkingFigure()
    rest = TriMesh(fig.rest_points, fig.faces, name="walking-figure")
    pts = np.stack([fig.points(f / fps) for f in range(frames)]).astype(np.float32)
    # the same pose and buried-vertex test as the bench's character mesh
    return Sequence("walk", rest, pts, lambda f: character(f / fps).judged,
                    f"skinned WalkingFigure walking along +z, {frames} frames at {fps:g} frames/s "
                    f"({rest.num_vertices} vertices); buried vertices not judged")


def sequence(name: str, frames: int = 120, cache_dir: str | None = SEQUENCE_CACHE, side: str = "front") -> Sequence:
    """The named animation (:data:`ANIMATIONS`), or the scene of a USD file path (:func:`is_scene_path`),
    with ``frames`` frames; ``side="back"``: a scene's back sides (:func:`_scene`)."""
    if side not in ("front", "back"):
        raise ValueError(f"side must be front or back, got {side!r}")
    if name == "default":
        from ..usd.shipped import shipped_scene

        return _scene(shipped_scene("default.usda"), "usd_scenes/default.usda", frames, cache_dir, side)
    if name == "walk":
        if side == "back":
            raise ValueError("the walk has no back side (a closed figure)")
        return _walk(frames)
    if is_scene_path(name):
        return _scene(name, name, frames, cache_dir, side)
    raise ValueError(f"unknown animation {name!r} (known: {', '.join(ANIMATIONS)}, or a USD file)")


def is_scene_path(name: str) -> bool:
    """Whether an animation name is a USD file (``.usd``, ``.usda``, ``.usdc``): its first moving
    shading group is the sequence."""
    return os.path.splitext(name)[1].lower() in (".usd", ".usda", ".usdc")


def parse_variant(text: str) -> dict:
    """The configuration of a ``--variant`` text, ``"name=value,..."``: hemiraster knobs coerced to their
    types (only those that differ from the defaults are kept), and ``reuse=RAD`` for temporal reuse
    (``"min_image=0,lut=96,reuse=2"``). Returns ``{"method", "knobs", "reuse"}``.

    Raises:
        ValueError: a part without ``=``, an unknown knob or a bad value (naming it).
    """
    from ..visibility import get_method
    from ..visibility.knobs import changes, normalise

    pairs, reuse = {}, None
    for part in (p.strip() for p in text.split(",")):
        if not part:
            continue
        name, eq, value = part.partition("=")
        if not eq:
            raise ValueError(f"--variant {text!r}: {part!r} is not name=value")
        name = name.strip().replace("-", "_")
        if name == "reuse":
            try:
                reuse = float(value)
            except ValueError:
                raise ValueError(f"--variant {text!r}: reuse must be a number [rad], got {value.strip()!r}") from None
        else:
            pairs[name] = value.strip()
    schema = get_method("hemiraster").SCHEMA
    return {"method": "hemiraster", "knobs": changes(schema, normalise(schema, pairs, "hemiraster")), "reuse": reuse}


def configurations(tolerances=DEFAULT_TOLERANCES, peer_rays: int = 256, variants=()) -> list[dict]:
    """Configurations measured: hemiraster at its defaults, recomputed every frame and with temporal
    reuse at each tolerance, each of ``variants`` (configurations of :func:`parse_variant`), and the
    ray-traced reference at ``peer_rays`` rays."""
    out = [{"method": "hemiraster", "knobs": {}, "reuse": None}]
    out += [{"method": "hemiraster", "knobs": {}, "reuse": float(t)} for t in tolerances]
    out += [dict(v) for v in variants]
    out += [{"method": "reference", "knobs": {"rays": peer_rays}, "reuse": None}]
    return out


def run_animation(name: str, frames: int = 120, every: int = 10, order: int = 4, rays: int = 4096,
                  tolerances=DEFAULT_TOLERANCES, cache_dir: str | None = DEFAULT_CACHE_DIR,
                  configs: list[dict] | None = None, device: str = "cpu", log=None, chunk: int | None = None,
                  side: str = "front") -> dict:
    """Measure every configuration on the whole sequence; returns ``{"animation", "description",
    "frames", "every", "judged_frames", "order", "ground_truth", "chunk", "records"}`` with one record per
    configuration (its errors over time, ``errors``: per judged frame). ``chunk``: temporal reuse starts
    afresh every ``chunk`` frames, as in a run's chunks (``warpshade run --reuse-chunk``); None: once.
    ``side``: ``"back"`` judges a scene's back sides (:func:`sequence`)."""
    from ..visibility import get_method
    from ..visibility.reuse import with_reuse

    log = log or (lambda msg: print(msg, file=sys.stderr, flush=True))
    seq = sequence(name, frames, side=side)
    judged_frames = list(range(0, frames, every))
    log(f"{name}: {seq.description}; judged every {every} frames ({len(judged_frames)} frames)")
    truths = {}
    for f in judged_frames:
        truths[f] = ground_truth(TriMesh(seq.frames[f], seq.rest.faces, name=f"{name}-frame{f}"), order, rays,
                                 cache_dir, device, log=log)
    masks = {f: seq.judged(f) for f in judged_frames}
    cfgs = configs or configurations(tolerances)
    runs = []
    for cfg in cfgs:
        cls = get_method(cfg["method"])
        warm = cls(seq.rest, order=order, device=device, **cfg["knobs"])  # compile outside the timing
        warm.update(seq.frames[0])
        runs.append({"method": with_reuse(cls(seq.rest, order=order, device=device, **cfg["knobs"]), cfg["reuse"]),
                     "walls": [], "cpus": [], "errors": [], "computed": []})
    # frame by frame, every configuration in turn: load drift on the shared machine hits all alike
    for f in range(frames):
        for cfg, run in zip(cfgs, runs):
            m = run["method"]
            w0, c0 = time.perf_counter(), time.process_time()
            if chunk and f % chunk == 0 and cfg["reuse"] is not None:
                m.reset()
            m.update(seq.frames[f])
            wp.synchronize()
            run["walls"].append(time.perf_counter() - w0)
            run["cpus"].append(time.process_time() - c0)
            run["computed"].append(m.last_computed / seq.rest.num_vertices if cfg["reuse"] is not None else 1.0)
            if f in truths:
                t, truth = m.transfer_numpy(), truths[f]
                if masks[f] is not None:
                    t, truth = t[masks[f]], truth[masks[f]]
                run["errors"].append({"frame": f, **error_summary(t, truth[:, : t.shape[1]])})
    records = []
    for cfg, run in zip(cfgs, runs):
        walls, errors = run["walls"], run["errors"]
        rec = {"method": cfg["method"], "knobs": cfg["knobs"], "reuse": cfg["reuse"],
               "seconds_per_frame": float(np.mean(walls)), "cpu_seconds_per_frame": float(np.mean(run["cpus"])),
               "seconds_median": float(np.median(walls)), "seconds_first_frame": walls[0],
               "error_mean": float(np.mean([e["error_mean"] for e in errors])),
               "error_p95": float(np.mean([e["error_p95"] for e in errors])),
               "error_mean_worst_frame": float(np.max([e["error_mean"] for e in errors])),
               "computed_fraction": float(np.mean(run["computed"])),
               "computed_per_frame": [round(c, 4) for c in run["computed"]],
               "seconds_per_frame_series": [round(w, 5) for w in walls], "errors": errors}
        records.append(rec)
        log(f"  {label(rec):<32} {rec['seconds_per_frame'] * 1e3:8.1f} ms/frame  err {rec['error_mean'] * 100:5.2f} % "
            f"(p95 {rec['error_p95'] * 100:5.2f} %, worst frame {rec['error_mean_worst_frame'] * 100:5.2f} %)  "
            f"computed {rec['computed_fraction'] * 100:5.1f} %")
    return {"animation": name, "description": seq.description, "frames": frames, "every": every,
            "judged_frames": judged_frames, "order": order, "vertices": seq.rest.num_vertices,
            "ground_truth": {"method": "reference", "rays": rays, "seed": GROUND_TRUTH_SEED}, "chunk": chunk,
            "side": side, "records": records}


def label(rec: dict) -> str:
    """``method knobs [reuse TOL]`` of a record."""
    knobs = " ".join(f"{k}={v}" for k, v in rec["knobs"].items())
    reuse = "" if rec["reuse"] is None else f" reuse {rec['reuse']:g}"
    return f"{rec['method']}{' ' + knobs if knobs else ''}{reuse}"


def format_animation(result: dict) -> str:
    """The printed table: per configuration, time per frame, errors over time and what reuse saved."""
    recs = result["records"]
    base = next((r for r in recs if r["method"] == "hemiraster" and r["reuse"] is None), recs[0])
    lines = [f"{result['animation']}: {result['description']}",
             f"order {result['order']}, {result['frames']} frames, judged every {result['every']} "
             f"({len(result['judged_frames'])} frames) against reference at {result['ground_truth']['rays']} rays"
             + (f", reuse afresh every {result['chunk']} frames" if result.get("chunk") else ""),
             f"{'configuration':<32} {'ms/frame':>9} {'cpu ms':>8} {'saved':>7} {'err mean':>9} {'err p95':>8} "
             f"{'worst frame':>11} {'+err':>7} {'computed':>9}"]
    for r in recs:
        saved = 1.0 - r["seconds_per_frame"] / base["seconds_per_frame"]
        lines.append(f"{label(r):<32} {r['seconds_per_frame'] * 1e3:9.1f} {r['cpu_seconds_per_frame'] * 1e3:8.1f} "
                     f"{saved * 100:6.1f}% {r['error_mean'] * 100:8.2f}% {r['error_p95'] * 100:7.2f}% "
                     f"{r['error_mean_worst_frame'] * 100:10.2f}% {(r['error_mean'] - base['error_mean']) * 100:+6.2f}% "
                     f"{r['computed_fraction'] * 100:8.1f}%")
    lines.append("saved and +err: against hemiraster recomputed every frame; errors are means over the judged "
                 "frames of each frame's mean / p95 over its vertices")
    return "\n".join(lines)


__all__ = ["ANIMATIONS", "DEFAULT_TOLERANCES", "Sequence", "configurations", "format_animation", "is_scene_path",
           "label", "parse_variant", "run_animation", "sequence"]
