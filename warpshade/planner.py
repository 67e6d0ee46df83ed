"""Model only what a scene requires: from a :class:`~warpshade.scene.Scene`, decide per object which passes
run, which shared structures get built, what can be reused across frames, and (under an error budget)
which visibility method and knobs to use — from the frontier ``warpshade bench`` measured.

Rules (issue 8):

* transfer of an object that does not move (``kind == "static"``) and whose shadow casters do not move
  is computed once and reused every frame;
* when only lighting changes, shading is a re-dot ``(ρ/π) Σ L_i T_i`` of reused transfer; when neither
  geometry nor lighting changes, the first frame's colours are reused;
* shared structures exist only when something uses them: the hemispherical-rasterization plane LUT only
  if an object uses ``hemiraster``; GEARS only with rect lights; sphere sets for inter-object shadows only
  when at least two objects exist and one casts onto another (never for a single self-shadowing object);
  reflection (one diffuse bounce) only when ``settings["reflections"]`` asks; glossy transfer only for
  objects whose material is glossy;
* with ``max_error``, each object gets the configuration of the frontier whose worst measured mean error
  is within budget and whose estimated time on this object is smallest.

Cost estimates scale the time measured on the benchmark mesh nearest in vertex count linearly by vertex
count (a first-order model: methods scale between V log F and V·F); they are estimates, printed as such.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from importlib import resources

from .scene import Scene, SceneObject

REDOT_SECONDS_PER_COEFF = 2.5e-9
"""Re-dot cost per vertex per SH coefficient per RGB channel [s] (NumPy matmul, measured on this machine:
6102×25 @ 25×3 in ~1.1 ms)."""


REFLECTION_SECONDS_PER_VERTEX_SPHERE = 1.0e-7
"""One-bounce reflection cost per receiver vertex per reflecting leaf sphere at SH order 4 [s] (both passes,
the pipeline's default cuts; CPU time of ``python benchmarks/spheres.py --reflections-only``: 141 ms for
30 588 receivers and 45 leaf spheres); scaled by (order/4)² for other orders."""

REFLECTION_SPHERES_PER_OBJECT = 15
"""Leaf spheres per object of ``warpshade run --reflections`` (``--reflection-spheres``)."""


def load_frontier(path: str | None = None) -> dict:
    """The measured frontier: ``path`` (a ``--frontier`` file or a ``results.json`` from ``warpshade bench``),
    else the one shipped in ``warpshade/data/frontier.json``."""
    if path is None:
        with resources.files("warpshade").joinpath("data/frontier.json").open() as f:
            return json.load(f)
    if not os.path.isfile(path):
        raise ValueError(f"{path}: no such frontier file")
    with open(path) as f:
        data = json.load(f)
    if isinstance(data, list):  # a results.json
        from .bench.report import frontier_from_results

        data = frontier_from_results(data)
    if "configs" not in data:
        raise ValueError(f"{path}: not a frontier (no 'configs') nor a results.json list")
    return data


def estimate_seconds(config: dict, vertices: int, key: str = "seconds") -> float:
    """Time of a frontier configuration on ``vertices`` vertices, scaled from the nearest measured mesh."""
    import math

    t = min(config["timings"], key=lambda t: abs(math.log(max(1, t["vertices"]) / max(1, vertices))))
    return float(t.get(key, 0.0)) * vertices / max(1, t["vertices"])


def _matches(config: dict, method: str, order: int, knobs: dict) -> bool:
    if config["method"] != method or config["order"] != order:
        return False
    return all(config["knobs"].get(k) == v for k, v in knobs.items())


@dataclass
class ObjectPlan:
    """What one object needs.

    Attributes:
        name: Object name.
        kind: Scene object kind.
        moves: Its geometry changes over time.
        method: Visibility method for self-shadowing (None: unoccluded transfer, no method).
        knobs: Method constructor kwargs.
        transfer: ``"every_frame"``, ``"once"`` or ``"none"`` (unoccluded closed form).
        passes: Per-frame passes in execution order.
        error: Worst measured mean error of the chosen configuration (None: not in the frontier).
        seconds_first: Estimated first-frame cost [s] (build + transfer).
        seconds_frame: Estimated cost of each later frame [s].
        reason: Why this method was chosen.
    """

    name: str
    kind: str
    vertices: int
    moves: bool
    method: str | None
    knobs: dict
    transfer: str
    passes: list[str] = field(default_factory=list)
    error: float | None = None
    seconds_first: float = 0.0
    seconds_frame: float = 0.0
    reason: str = ""
    seconds_transfer: float = 0.0
    seconds_build: float = 0.0


@dataclass
class Plan:
    """The scene's plan. ``objects`` in scene order; ``structures``: shared things to build once."""

    order: int
    frames: int
    objects: list[ObjectPlan]
    structures: list[str]
    lighting_changes: bool
    geometry_changes: bool
    max_error: float | None = None
    notes: list[str] = field(default_factory=list)

    def object(self, name: str) -> ObjectPlan:
        for o in self.objects:
            if o.name == name:
                return o
        raise KeyError(f"plan has no object {name}")

    @property
    def seconds_per_frame(self) -> float:
        """Estimated steady-state cost per frame [s] (after the first)."""
        return sum(o.seconds_frame for o in self.objects)

    @property
    def seconds_total(self) -> float:
        """Estimated cost of the whole run [s]."""
        return sum(o.seconds_first + o.seconds_frame * max(0, self.frames - 1) for o in self.objects)

    def to_dict(self) -> dict:
        import dataclasses

        return {**dataclasses.asdict(self), "seconds_per_frame": self.seconds_per_frame,
                "seconds_total": self.seconds_total}

    def describe(self) -> str:
        """Human-readable plan with estimated costs (what ``warpshade plan`` prints)."""
        lines = [f"plan: {len(self.objects)} object(s), {self.frames} frames, SH order {self.order}"
                 + (f", error budget {self.max_error}" if self.max_error is not None else "")]
        lines.append(f"  shared structures: {', '.join(self.structures) or 'none'}")
        lines.append(f"  geometry changes: {'yes' if self.geometry_changes else 'no'}; "
                     f"lighting changes: {'yes' if self.lighting_changes else 'no'}")
        for o in self.objects:
            err = "" if o.error is None else f", measured error ≤ {o.error:.3f}"
            lines.append(f"  {o.name} ({o.kind}, {o.vertices} vertices): method {o.method or 'none (unoccluded)'} "
                         f"{_knobs(o.knobs)}transfer {o.transfer}{err}")
            lines.append(f"      passes per frame: {', '.join(o.passes) or 'reuse colours'}")
            lines.append(f"      est. first frame {o.seconds_first * 1e3:.1f} ms, later frames {o.seconds_frame * 1e3:.2f} ms"
                         + (f" — {o.reason}" if o.reason else ""))
        lines.append(f"  estimated cost: {self.seconds_per_frame * 1e3:.2f} ms per frame after the first; "
                     f"{self.seconds_total:.2f} s for {self.frames} frames")
        lines += [f"  note: {n}" for n in self.notes]
        return "\n".join(lines)


def _knobs(k: dict) -> str:
    return "(" + ", ".join(f"{a}={b}" for a, b in k.items()) + ") " if k else ""


def _light_moves(light) -> bool:
    return getattr(light, "motion", None) is not None


def _is_rect(light) -> bool:
    return type(light).__name__ == "RectLight"


def default_knobs(method: str) -> dict:
    """A method's default knobs, from its own command-line defaults (``add_arguments``)."""
    import argparse

    from .visibility import get_method

    cls = get_method(method)
    p = argparse.ArgumentParser(add_help=False)
    cls.add_arguments(p)
    return cls.knobs_from_args(p.parse_args([]))


def _choose(obj: SceneObject, order: int, max_error: float | None, frontier: dict) -> tuple:
    """(method, knobs, config or None, reason) for one object."""
    v = obj.mesh.num_vertices
    if max_error is not None:
        ok = [c for c in frontier["configs"] if c["order"] == order and c["error"] <= max_error]
        if not ok:
            raise ValueError(f"{obj.name}: no measured configuration at SH order {order} meets --max-error "
                             f"{max_error} (best: {min((c['error'] for c in frontier['configs'] if c['order'] == order), default=float('nan')):.3f})")
        best = min(ok, key=lambda c: (estimate_seconds(c, v), c["error"]))
        knobs = dict(best.get("kwargs", best["knobs"]))
        return best["method"], knobs, best, f"fastest measured within error {max_error}"
    if obj.method is None:
        return None, {}, None, ""
    # the scene's knobs must match; among those, the configuration agreeing with most CLI defaults
    # (defaults may be sentinels such as "auto" that knobs() reports resolved, so agreement is scored)
    defaults = default_knobs(obj.method)
    match = [c for c in frontier["configs"] if _matches(c, obj.method, order, obj.knobs)]
    cfg = max(match, key=lambda c: sum(c["knobs"].get(k) == v for k, v in defaults.items()), default=None)
    return obj.method, dict(obj.knobs), cfg, "as the scene asks"


def make_plan(scene: Scene, max_error: float | None = None, frontier: dict | str | None = None) -> Plan:
    """Build the :class:`Plan` of ``scene``.

    Args:
        scene: The scene.
        max_error: Error budget (mean relative L2 transfer error, :mod:`warpshade.metrics`); when set,
            each object's method is chosen from the frontier, overriding the scene's choice.
        frontier: Frontier dict, a path (frontier or ``results.json``), or None for the shipped one.

    Raises:
        ValueError: an empty scene, or no configuration within ``max_error``.
    """
    if not scene.objects:
        raise ValueError(f"{scene.source}: scene has no objects")
    if max_error is None:
        max_error = scene.settings.get("max_error")
    fr = frontier if isinstance(frontier, dict) else load_frontier(frontier)
    order = int(scene.settings.get("order", 5))
    reflections = bool(scene.settings.get("reflections", False))
    lighting_changes = any(_light_moves(li) for li in scene.lights)
    moving = {o.name for o in scene.objects if o.kind != "static"}
    casters = [o for o in scene.objects if o.casts_shadows]
    shaded = [o for o in scene.objects if o.shaded]
    inter = len(scene.objects) >= 2 and any(c.name != r.name for c in casters for r in shaded)
    structures, notes, plans = [], [], []
    rect = any(_is_rect(li) for li in scene.lights)
    for obj in scene.objects:
        if not obj.shaded:
            continue
        method, knobs, cfg, reason = _choose(obj, order, max_error, fr)
        v = obj.mesh.num_vertices
        moves = obj.name in moving
        # a static receiver must redo its inter-object term if any other caster moves
        shadowed_by_moving = inter and any(c.name in moving and c.name != obj.name for c in casters)
        passes = []
        if obj.kind == "cloth":
            passes.append("simulate cloth")
        elif obj.kind == "skinned":
            passes.append("skin")
        elif obj.kind == "animated":
            passes.append("read samples")
        if moves:
            passes.append("normals")
        transfer = "none" if method is None else ("every_frame" if moves else "once")
        if method is not None and moves:
            passes.append(f"transfer ({method})")
        if inter and (moves or shadowed_by_moving):
            passes.append("inter-object shadows (sphere sets)")
        if rect and (moves or shadowed_by_moving):
            passes.append("area-light visibility (GEARS)")
        if obj.material.glossy:
            passes.append("glossy transfer")
        if reflections and (moves or shadowed_by_moving or lighting_changes):
            passes.append("reflection (one bounce)")
        relit = moves or shadowed_by_moving or lighting_changes
        if relit:
            passes.append("re-dot lighting")
        passes = [p for p in passes if p]
        t_reflect = (REFLECTION_SECONDS_PER_VERTEX_SPHERE * v * REFLECTION_SPHERES_PER_OBJECT * len(shaded)
                     * (order / 4.0) ** 2) if reflections else 0.0
        t_transfer = estimate_seconds(cfg, v) if cfg else 0.0
        t_build = estimate_seconds(cfg, v, "build_seconds") if cfg else 0.0
        redot = REDOT_SECONDS_PER_COEFF * v * order * order * 3
        if method is not None and cfg is None:
            notes.append(f"{obj.name}: {method} {_knobs(knobs)}at order {order} is not in the frontier; its cost is not estimated")
        seconds_first = t_build + t_transfer + redot + t_reflect
        seconds_frame = (t_transfer if transfer == "every_frame" else 0.0) + (redot if relit else 0.0)
        if reflections and (moves or shadowed_by_moving or lighting_changes):
            seconds_frame += t_reflect
        plans.append(ObjectPlan(obj.name, obj.kind, v, moves, method, knobs, transfer, passes,
                                cfg["error"] if cfg else None, seconds_first, seconds_frame, reason,
                                 t_transfer, t_build))
    if any(p.method == "hemiraster" for p in plans):
        structures.append("hemiraster plane LUT")
    if inter:
        structures.append("sphere sets of shadow casters")
    if rect:
        structures.append("GEARS area-light structures")
    if reflections:
        structures.append("reflection (one-bounce) transfer")
    if any(o.material.glossy for o in scene.objects if o.shaded):
        structures.append("glossy transfer")
    return Plan(order, scene.frames, plans, structures, lighting_changes, bool(moving), max_error, notes)


def apply_plan(scene: Scene, plan: Plan) -> None:
    """Set each shaded object's ``method`` and ``knobs`` to the plan's choice (what ``warpshade run
    --max-error`` does before handing the scene to the pipeline)."""
    for op in plan.objects:
        obj = scene.object(op.name)
        obj.method = op.method
        obj.knobs = dict(op.knobs)


def naive_seconds(plan: Plan) -> float:
    """Estimated cost of the same run with no reuse (every object's transfer and shading every frame)."""
    return sum(o.seconds_build + (o.seconds_first - o.seconds_build) * plan.frames for o in plan.objects)
