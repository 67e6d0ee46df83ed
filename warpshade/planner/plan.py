"""The plan's types: what each object needs (:class:`ObjectPlan`), each shading group as the run
executes it (:class:`GroupPlan`) and the scene's :class:`Plan` with its estimates and text
(:meth:`Plan.describe`, what ``warpshade plan`` prints)."""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class ObjectPlan:
    """What one object needs.

    Attributes:
        name: Object name.
        kind: Scene object kind.
        moves: Its geometry changes over time.
        method: Visibility method for self-shadowing (None: unoccluded transfer, no method).
        knobs: Method constructor kwargs.
        transfer: ``"every_frame"``, ``"once"`` or ``"none"`` (unoccluded closed form). A static object
            is ``"every_frame"`` when its shading group moves (:attr:`group_moves`).
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
    group_moves: list[str] = field(default_factory=list)
    """Moving members of this static object's shading group, which make the run recompute its transfer
    every frame (empty: the object moves itself, or its group is static)."""


@dataclass
class GroupPlan:
    """One shading group as ``warpshade run`` executes it (:func:`warpshade.pipeline.shading.group_objects`):
    its objects are merged into one receiver mesh and shaded by one method.

    Attributes:
        method: Visibility method (None: unoccluded transfer).
        knobs: Method constructor kwargs as the run uses them (the pipeline's defaults filled in).
        names: Member objects.
        vertices, triangles: Of the merged mesh.
        moves: Any member moves, so the group's transfer is recomputed every frame.
        seconds_build: Estimated setup [s]: the group's meshes and the method's construction (both sides).
        seconds_transfer: Estimated transfer update on the merged mesh [s].
        seconds_between: Estimated per-frame shadowing by the other groups' sphere sets [s].
        seconds_lights: Estimated per-frame lights' SH at the group's points [s].
        seconds_radiance: Estimated per-frame exit radiance [s].
        seconds_reflections: Estimated per-frame one-bounce reflections onto the group [s] (the run
            recomputes them every frame).
        cost_source: Where the transfer estimate comes from (frontier configuration, fit or nearest mesh).
        caster_triangles: Triangles of the members that cast shadows (the method's blockers; objects with
            ``castsShadows`` false only receive); None: all ``triangles``.
        two_sided: Members shaded on both sides (:func:`warpshade.pipeline.shading.is_two_sided`).
        seconds_back: Estimated per-frame back-side pass [s]: the group's method a second time on the
            group seen from the back, receiving at every vertex or only at the two-sided members'
            (:func:`warpshade.pipeline.shading.back_side_receivers`; its build is added to
            ``seconds_build``), the between-group shadows again, and the two-sided members' exit radiance.
    """

    method: str | None
    knobs: dict
    names: list[str]
    vertices: int
    triangles: int
    moves: bool
    seconds_build: float = 0.0
    seconds_transfer: float = 0.0
    seconds_between: float = 0.0
    seconds_lights: float = 0.0
    seconds_radiance: float = 0.0
    seconds_reflections: float = 0.0
    cost_source: str = ""
    caster_triangles: int | None = None
    two_sided: list[str] = field(default_factory=list)
    seconds_back: float = 0.0

    def __post_init__(self):
        if self.caster_triangles is None:
            self.caster_triangles = self.triangles

    @property
    def seconds_frame(self) -> float:
        """Estimated shading time of this group per frame [s] (what the run's ``shade`` time sums)."""
        return ((self.seconds_transfer if self.moves else 0.0) + self.seconds_between + self.seconds_lights
                + self.seconds_radiance + self.seconds_reflections + self.seconds_back)


@dataclass
class Plan:
    """The scene's plan. ``objects`` in scene order; ``structures``: shared things to build once;
    ``groups``: what ``warpshade run`` executes (see :class:`GroupPlan`)."""

    order: int
    frames: int
    objects: list[ObjectPlan]
    structures: list[str]
    lighting_changes: bool
    geometry_changes: bool
    max_error: float | None = None
    notes: list[str] = field(default_factory=list)
    groups: list[GroupPlan] = field(default_factory=list)
    seconds_setup_between: float = 0.0
    seconds_setup_structures: float = 0.0
    area_lights: str | None = None
    """How the run shades the scene's rect lights (``"gears"`` or ``"sh"``), None without rect lights."""
    seconds_area: float = 0.0
    """Estimated GEARS area-light pass over all shading groups [s] (0 unless ``area_lights == "gears"``)."""
    area_moves: bool = False
    """The area-light pass reruns every frame (something moves, or a rect light does)."""
    area_k: int = 16
    """GEARS light samples per side the area-light pass is costed at."""
    passes: list = field(default_factory=list)
    """The run's pass graph (:meth:`warpshade.pipeline.shading.SceneShader.passes`), in execution order, each
    ``{"pass": key, "every_frame": bool, "seconds": estimate}``: what the run computes every frame, and what
    only on the first (nothing it depends on moves)."""

    @property
    def run_seconds_per_frame(self) -> float:
        """Estimated ``shade`` time per frame of ``warpshade run`` on this scene [s]: the passes of the pass graph
        the run recomputes every frame (the first frame's other passes are in :attr:`run_seconds_setup`)."""
        return sum(p["seconds"] for p in self.passes if p["every_frame"])

    @property
    def run_seconds_setup(self) -> float:
        """Estimated one-off cost of a run [s]: method structures, sphere trees, LUT, and the passes computed
        on the first frame only."""
        return (sum(g.seconds_build for g in self.groups) + self.seconds_setup_between + self.seconds_setup_structures
                + sum(p["seconds"] for p in self.passes if not p["every_frame"]))

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

        d = dataclasses.asdict(self)
        for g, gd in zip(self.groups, d["groups"]):
            gd["seconds_frame"] = g.seconds_frame
        return {**d, "seconds_per_frame": self.seconds_per_frame, "seconds_total": self.seconds_total,
                "run_seconds_per_frame": self.run_seconds_per_frame, "run_seconds_setup": self.run_seconds_setup}

    def describe(self) -> str:
        """Human-readable plan with estimated costs (what ``warpshade plan`` prints)."""
        lines = [f"plan: {len(self.objects)} object(s), {self.frames} frames, SH order {self.order}"
                 + (f", error budget {self.max_error}" if self.max_error is not None else "")]
        lines.append(f"  shared structures: {', '.join(self.structures) or 'none'}")
        lines.append(f"  geometry changes: {'yes' if self.geometry_changes else 'no'}; "
                     f"lighting changes: {'yes' if self.lighting_changes else 'no'}")
        for o in self.objects:
            err = "" if o.error is None else f", measured error ≤ {o.error:.3f}"
            why = f" (its shading group moves: {', '.join(o.group_moves)})" if o.group_moves else ""
            lines.append(f"  {o.name} ({o.kind}, {o.vertices} vertices): method {o.method or 'none (unoccluded)'} "
                         f"{knob_text(o.knobs)}transfer {o.transfer}{why}{err}")
            lines.append(f"      passes per frame: {', '.join(o.passes) or 'reuse colours'}")
            lines.append(f"      est. first frame {o.seconds_first * 1e3:.1f} ms, later frames {o.seconds_frame * 1e3:.2f} ms"
                         + (f" — {o.reason}" if o.reason else ""))
        lines.append(f"  estimated cost of what the scene requires (each object on its own mesh, transfer reused "
                     f"where the run reuses it): "
                     f"{self.seconds_per_frame * 1e3:.2f} ms per frame after the first; "
                     f"{self.seconds_total:.2f} s for {self.frames} frames")
        if self.groups:
            lines.append(f"  warpshade run executes {len(self.groups)} shading group(s) (objects sharing a method are one mesh):")
            for g in self.groups:
                blockers = ("" if g.caster_triangles == g.triangles
                            else f" ({g.caster_triangles} of them cast shadows: castsShadows false on the others)")
                lines.append(f"    {g.method or 'unoccluded'} {knob_text(g.knobs)}[{', '.join(g.names)}]: {g.vertices} vertices, "
                             f"{g.triangles} triangles{blockers}, transfer {'every frame' if g.moves else 'once'}")
                lines.append(f"      est. per frame {g.seconds_frame * 1e3:.1f} ms = transfer "
                             f"{(g.seconds_transfer if g.moves else 0.0) * 1e3:.1f} + between-group shadows "
                             f"{g.seconds_between * 1e3:.1f} + lights {g.seconds_lights * 1e3:.1f} + radiance "
                             f"{g.seconds_radiance * 1e3:.2f}"
                             + (f" + reflections {g.seconds_reflections * 1e3:.1f}" if g.seconds_reflections else "")
                             + (f" + back sides {g.seconds_back * 1e3:.1f} (two-sided: {', '.join(g.two_sided)})"
                                if g.two_sided else "")
                             + f"; build {g.seconds_build * 1e3:.0f} ms"
                             + (f" ({g.cost_source})" if g.cost_source else ""))
            if self.area_lights == "gears":
                lines.append(f"    area-light visibility (GEARS k={self.area_k}, grid=16) over all "
                             f"{sum(g.vertices for g in self.groups)} "
                             f"shaded vertices: est. {self.seconds_area * 1e3:.1f} ms "
                             + ("per frame" if self.area_moves else "once (nothing moves)"))
            elif self.area_lights == "sh":
                lines.append("    rect lights projected to SH (--area-lights sh): costed with the lights, no GEARS")
            every = [p["pass"] for p in self.passes if p["every_frame"]]
            once = [p["pass"] for p in self.passes if not p["every_frame"]]
            lines.append(f"  passes per frame (the run's pass graph): {', '.join(every) or 'none'}"
                         + (f"; first frame only: {', '.join(once)}" if once else ""))
            lines.append(f"  estimated run: setup {self.run_seconds_setup:.2f} s (sphere trees "
                         f"{self.seconds_setup_between:.2f} s), shading {self.run_seconds_per_frame * 1e3:.1f} ms per frame")
        lines += [f"  note: {n}" for n in self.notes]
        return "\n".join(lines)


def knob_text(k: dict) -> str:
    """Knobs as ``(a=1, b=2) `` for the plan's text (empty for none)."""
    return "(" + ", ".join(f"{a}={b}" for a, b in k.items()) + ") " if k else ""
