"""One run configuration, resolved once: what ``warpshade run``, ``warpshade plan`` and the bench agree on.

:func:`resolve_run` turns a scene and the run's options into a :class:`RunConfig` — SH order, the
shading groups with their method and normalised knobs, between-group shadows, reflections, how rect
lights are shaded and with which GEARS knobs, two-sided shading. The run
(:class:`warpshade.pipeline.Pipeline`) executes it, the planner (:func:`warpshade.planner.make_plan`)
costs it, and both read the per-frame passes from the same pass graph
(:meth:`warpshade.pipeline.shading.SceneShader.passes`). Every default a run has is written here once.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

DEFAULT_ORDER = 4
"""SH order of a run unless the scene (``warpshade:order``) or ``--order`` says otherwise."""

RUN_KNOBS = {"reference": {"rays": 256}}
"""Knobs a run gives a method named with no knobs at all (reference: 256 rays, 3.6 % relative L2 error,
measured in docs/methods/reference.md); other knobs take the method's own defaults (its ``KNOBS``).
``warpshade run --method M`` passes all of M's knobs (its flags' defaults), so this applies to methods
named by a scene or by the Python API without knobs."""

REUSE = 2.0
"""Temporal reuse tolerance [rad] of a run unless told otherwise (``warpshade run --reuse RAD|off``,
``Pipeline(reuse=...)``; :func:`resolve_reuse`), for runs whose shaded groups' methods compute only the
receivers due (``compute_rows``: hemiraster). On the frontier where measured (``warpshade bench
--animation``, chunks of :data:`REUSE_CHUNK`, docs/benchmarks/index.md "Whole animations"): the error of
recomputing every frame within the truth's noise, for less time, on the default scene's drape, the skinned
walk, usd_scenes/cape_walker.usda and flag_wind.usda and a hand-made cloth over a pedestal."""

REUSE_AUTO = "auto"
"""``reuse`` value meaning :data:`REUSE` where it applies (:func:`resolve_reuse`); the default."""

REUSE_CHUNK = 30
"""Frames per chunk of a run with temporal reuse (``--reuse-chunk``): each chunk is shaded in order by one
worker and starts with every receiver computed (:func:`warpshade.parallel.shade_frames`), so the output
depends on this number and not on the workers. Half a second at 60 frames/s: a restart costs one full
frame in 30, and 120 frames make four chunks, two per worker on two cores."""

AREA_MODES = ("gears", "sh")
"""``--area-lights`` values: ``gears`` (:mod:`.area`) or ``sh`` (rect lights projected to SH like other local lights)."""

WEIGHTINGS = ("cosine", "area")
"""``cosine``: form-factor-weighted visible share (default); ``area``: the paper's fraction of visible samples."""

DEFAULT_AREA_KNOBS = {"k": 16, "grid": 16, "weighting": "cosine"}
"""GEARS knobs of a run's rect lights: 16×16 light samples (0.22 % mean visibility error against 32×32
rays on the five benchmark meshes, ``warpshade bench``'s area sweep), a 16×16 acceleration grid, the
form-factor-weighted visible share."""

BETWEEN_MODES = ("spheres", None)
"""Shadows between shading groups: sphere sets, or none."""


@dataclass
class GroupSpec:
    """Objects shaded as one receiver mesh (they shadow each other) by one visibility method.

    Attributes:
        method: A ``warpshade.visibility.METHODS`` name, or None for unshadowed (analytic) transfer.
        knobs: Method keyword arguments, resolved (:func:`~.config.resolve_knobs`: every knob of the method).
        names: Object names, in order.
        meshes: Their rest meshes (topology fixed).
        albedos: Their albedos, linear RGB, shape (3,) each.
        moving: Whether each object moves (static objects keep their rest points).
        casts: Whether each object casts shadows (``warpshade:castsShadows``; empty: all do). An object
            that does not is a receiver only: its triangles block no light in any pass (not even its own).
        two_sided: Whether each object is shaded on both sides (:func:`is_two_sided`; empty: none is).
    """

    method: str | None
    knobs: dict
    names: list = field(default_factory=list)
    meshes: list = field(default_factory=list)
    albedos: list = field(default_factory=list)
    moving: list = field(default_factory=list)
    casts: list = field(default_factory=list)
    two_sided: list = field(default_factory=list)

    @property
    def label(self) -> dict:
        """The knobs that differ from the method's defaults (how the group is shown)."""
        return knob_label(self.method, self.knobs)

    def blocker_faces(self) -> np.ndarray:
        """Triangles of the members that cast shadows, indexed into the merged group mesh, shape (F_c, 3), int32."""
        offsets = np.cumsum([0] + [m.num_vertices for m in self.meshes])
        casts = self.casts or [True] * len(self.meshes)
        parts = [m.faces + off for m, off, c in zip(self.meshes, offsets[:-1], casts) if c]
        return np.concatenate(parts).astype(np.int32) if parts else np.zeros((0, 3), np.int32)


TWO_SIDED_MODES = ("auto", "on", "off")
"""Values of the two-sided knob (``warpshade run --two-sided``, ``Pipeline(two_sided=...)``)."""


def is_two_sided(obj, mode: str = "auto") -> bool:
    """Whether a :class:`warpshade.scene.SceneObject` is shaded on both sides: ``"on"`` every object,
    ``"off"`` none, ``"auto"`` its ``two_sided`` (``warpshade:twoSided``) if set, else cloth only.

    Raises:
        ValueError: for a mode not in :data:`TWO_SIDED_MODES`.
    """
    if mode not in TWO_SIDED_MODES:
        raise ValueError(f"two-sided must be one of {', '.join(TWO_SIDED_MODES)}, got {mode!r}")
    if mode != "auto":
        return mode == "on"
    return bool(obj.two_sided) if obj.two_sided is not None else obj.kind == "cloth"


def group_objects(objects, method: str | None = None, knobs: dict | None = None,
                  default_albedo=None, two_sided: str = "auto") -> list[GroupSpec]:
    """Group shaded objects by (method, knobs), knobs resolved (:func:`~.config.resolve_knobs`: every knob,
    validated, defaults filled in), so objects whose knobs differ only in spelling out defaults share a
    group. A group none of whose members casts shadows (``casts_shadows`` False) gets method None:
    nothing in it blocks light, so its transfer is unoccluded.

    Args:
        objects: :class:`warpshade.scene.SceneObject` list.
        method: Override every object's method (``--method``; ``"none"``, :data:`~warpshade.visibility.NO_METHOD`:
            no method, every object unoccluded), or None to use each object's.
        knobs: Knobs with ``method``.

    Raises:
        ValueError: an unknown method or knob, or knobs with ``"none"``.
        default_albedo: Albedo (scalar or RGB) of objects whose material's albedo was not authored
            (``Material.albedo_authored``), or None to keep the material's default.
        two_sided: Which objects are shaded on both sides (:func:`is_two_sided`).
    """
    override = method is not None
    if override:
        from ..visibility import NO_METHOD, transfer_method

        method = transfer_method(method)
        if method is None and knobs:
            raise ValueError(f"knobs {', '.join(sorted(knobs))} given with method '{NO_METHOD}' (no visibility method, "
                             "so no knobs)")
    by_key: dict = {}
    for obj in objects:
        if not obj.shaded:
            continue
        name, given = (method, knobs) if override else (obj.method, obj.knobs)
        kn = resolve_knobs(name, given)
        key = (name, tuple(sorted(kn.items())))
        g = by_key.setdefault(key, GroupSpec(name, kn))
        g.names.append(obj.name)
        g.meshes.append(obj.mesh)
        albedo = obj.material.albedo
        if default_albedo is not None and not obj.material.albedo_authored:
            albedo = np.broadcast_to(np.asarray(default_albedo, dtype=np.float64), (3,))
        g.albedos.append(np.array(albedo, dtype=np.float64))
        g.moving.append(obj.kind != "static")
        g.casts.append(bool(obj.casts_shadows))
        g.two_sided.append(is_two_sided(obj, two_sided))
    for g in by_key.values():
        if g.method is not None and not any(g.casts):
            # nothing in the group blocks light (castsShadows false on every member): its own transfer is the
            # unoccluded one whatever the method; it stays a group of its own, so other groups' sphere sets
            # still shadow it
            g.method, g.knobs = None, {}
    return list(by_key.values())


def resolve_knobs(method: str | None, knobs: dict | None) -> dict:
    """The knobs a run builds ``method`` with: every knob of the method's schema, the given ones
    validated and coerced, the rest at their defaults; no knobs at all means :data:`RUN_KNOBS`.
    Equal configurations give equal dicts (``{}`` and the defaults spelled out group together).

    Raises:
        ValueError: an unknown method or knob, or a bad value, naming it.
    """
    if method is None:
        return {}
    from ..visibility import get_method

    given = dict(knobs or {}) or dict(RUN_KNOBS.get(method, {}))
    return get_method(method).normalise_knobs(given)


def knob_label(method: str | None, knobs: dict) -> dict:
    """The knobs of a resolved set that differ from the method's defaults (how a group is shown and looked up
    in the frontier)."""
    if method is None:
        return {}
    from ..visibility import get_method

    return get_method(method).knob_changes(knobs)


def resolve_reuse(reuse, methods) -> float | None:
    """The temporal reuse tolerance [rad] of a run whose shading groups use ``methods`` (method names, None for
    unoccluded groups), or None for none: ``reuse`` itself when a number (>= 0) or None; for
    :data:`REUSE_AUTO`, :data:`REUSE` when every group with a method has one that computes only the
    receivers due (``compute_rows``), else None (others recompute every receiver whenever one is due:
    not measured on the frontier).

    Raises:
        ValueError: a negative or non-finite tolerance, or another string than :data:`REUSE_AUTO`.
    """
    if reuse is None:
        return None
    if isinstance(reuse, str):
        if reuse != REUSE_AUTO:
            raise ValueError(f"reuse must be a tolerance [rad], None (off) or {REUSE_AUTO!r}, got {reuse!r}")
        from ..visibility import get_method

        named = [m for m in methods if m is not None]
        return REUSE if named and all(hasattr(get_method(m), "compute_rows") for m in named) else None
    from ..visibility.reuse import check_tolerance

    return check_tolerance(reuse)


def reuse_text(reuse: float | None, chunk: int | None) -> str:
    """How a run's temporal reuse is shown (run summary, output metadata, ``warpshade plan``)."""
    return "off (every receiver every frame)" if reuse is None else f"{reuse:g} rad, chunks of {chunk} frames"


def resolve_area_knobs(area_knobs: dict | None) -> dict:
    """GEARS knobs of a run: :data:`DEFAULT_AREA_KNOBS` overridden by ``area_knobs``, validated against the
    GEARS schema (``k``, ``grid``) and :data:`WEIGHTINGS`.

    Raises:
        ValueError: an unknown knob or a bad value, naming it.
    """
    given = dict(area_knobs or {})
    unknown = [k for k in given if k not in DEFAULT_AREA_KNOBS]
    if unknown:
        raise ValueError(f"area lights: unknown knob '{unknown[0]}' (its knobs: {', '.join(DEFAULT_AREA_KNOBS)})")
    out = {**DEFAULT_AREA_KNOBS, **given}
    if out["weighting"] not in WEIGHTINGS:
        raise ValueError(f"area-light weighting must be one of {', '.join(WEIGHTINGS)}, got {out['weighting']!r}")
    from ..visibility import get_method

    schema = {k.name: k for k in get_method("gears", kind="area").SCHEMA}
    for name in ("k", "grid"):
        try:
            out[name] = schema[name].coerce(out[name])
        except ValueError as exc:
            raise ValueError(f"area lights: {exc}") from None
    return out


@dataclass
class RunConfig:
    """Everything a run decides before its first frame (:func:`resolve_run`).

    Attributes:
        order: SH order.
        groups: Shading groups (:class:`~.shading.GroupSpec`), knobs resolved (:func:`resolve_knobs`).
        between: Between-group shadows (``"spheres"`` or None).
        reflections: One-bounce reflection keyword arguments (:class:`~.reflections.SceneReflections`), or None.
        area_lights: Rect lights: ``"gears"`` or ``"sh"``.
        area_knobs: GEARS knobs (:data:`DEFAULT_AREA_KNOBS` filled in).
        two_sided: Two-sided mode (``"auto"``, ``"on"``, ``"off"``).
        write_transfer: Also write the transfer.
    """

    order: int
    groups: list = field(default_factory=list)
    between: str | None = "spheres"
    reflections: dict | None = None
    area_lights: str = "gears"
    area_knobs: dict = field(default_factory=lambda: dict(DEFAULT_AREA_KNOBS))
    two_sided: str = "auto"
    write_transfer: bool = False


def resolve_run(scene, method: str | None = None, knobs: dict | None = None, order: int | None = None,
                between: str | None = "spheres", reflections=None, area_lights: str = "gears",
                area_knobs: dict | None = None, two_sided: str = "auto", albedo=None,
                write_transfer: bool | None = None, methods: dict | None = None) -> RunConfig:
    """The :class:`RunConfig` of a run of ``scene`` with these options (the ``Pipeline`` arguments).

    Args:
        scene: The scene (receivers already refined, :mod:`.refine`).
        method, knobs: One method (and its knobs) for every shaded object, or None for each object's own.
        order: SH order (None: ``warpshade:order``, else :data:`DEFAULT_ORDER`).
        between: ``"spheres"`` or None.
        reflections: True (defaults), a dict of keyword arguments, False, or None (the scene's
            ``warpshade:reflections``, default off).
        area_lights: One of :data:`AREA_MODES`.
        area_knobs: GEARS knobs over :data:`DEFAULT_AREA_KNOBS`.
        two_sided: One of :data:`~.shading.TWO_SIDED_MODES`.
        albedo: Albedo of objects whose scene gives none (None: the material's default).
        write_transfer: None for the scene's ``warpshade:writeTransfer``.
        methods: Object name -> ``(method, knobs)`` replacing the objects' own (the planner's choice under an
            error budget); ignored with ``method``.

    Raises:
        ValueError: a bad option, knob or albedo, naming it.
    """
    from ..sh.basis import check_order

    order = check_order(order if order is not None else scene.settings.get("order", DEFAULT_ORDER))
    if albedo is not None:
        a = np.asarray(albedo, dtype=np.float64)
        if a.shape not in ((), (3,)) or not np.all((a >= 0) & (a <= 1)):
            raise ValueError(f"albedo must be a scalar or RGB in [0, 1], got {a.tolist()}")
    if two_sided not in TWO_SIDED_MODES:
        raise ValueError(f"two_sided must be one of {', '.join(TWO_SIDED_MODES)}, got {two_sided!r}")
    if between not in BETWEEN_MODES:
        raise ValueError(f"between-group shadows must be 'spheres' or None, got {between!r}")
    if area_lights not in AREA_MODES:
        raise ValueError(f"area lights must be one of {', '.join(AREA_MODES)}, got {area_lights!r}")
    objects = scene.objects
    if methods and method is None:
        import dataclasses

        objects = [dataclasses.replace(o, method=methods[o.name][0], knobs=dict(methods[o.name][1]))
                   if o.name in methods else o for o in objects]
    groups = group_objects(objects, method, knobs, default_albedo=albedo, two_sided=two_sided)
    if reflections is None:
        reflections = bool(scene.settings.get("reflections", False))
    if reflections is True:
        reflections = {}
    return RunConfig(order=order, groups=groups, between=between,
                     reflections=reflections if isinstance(reflections, dict) else None,
                     area_lights=area_lights, area_knobs=resolve_area_knobs(area_knobs), two_sided=two_sided,
                     write_transfer=bool(write_transfer if write_transfer is not None
                                         else scene.settings.get("writeTransfer", False)))


__all__ = ["AREA_MODES", "BETWEEN_MODES", "DEFAULT_AREA_KNOBS", "DEFAULT_ORDER", "REUSE", "REUSE_AUTO", "REUSE_CHUNK",
           "RUN_KNOBS", "TWO_SIDED_MODES", "WEIGHTINGS", "GroupSpec", "RunConfig", "group_objects", "is_two_sided",
           "knob_label", "resolve_area_knobs", "resolve_knobs", "resolve_reuse", "resolve_run", "reuse_text"]
