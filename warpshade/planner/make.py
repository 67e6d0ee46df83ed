"""Making the plan: :func:`make_plan` resolves the run configuration, chooses each object's method
(under an error budget, from the frontier), and costs the run's pass graph with the cost model of
:mod:`.costs`; :func:`apply_plan` hands the choice to a scene."""

from __future__ import annotations

from ..scene import Scene, SceneObject
from .costs import (REDOT_SECONDS_PER_COEFF, REFLECTION_SECONDS_PER_VERTEX_SPHERE, REFLECTION_SPHERES_PER_OBJECT,
                    estimate_seconds, find_config, load_frontier, load_pass_costs)
from .plan import GroupPlan, ObjectPlan, Plan, knob_text


def _light_moves(light) -> bool:
    """A light that moves: with ``motion`` (a :mod:`warpshade.lighting` light) or keyed (a scene's ``LightSpec``)."""
    return getattr(light, "motion", None) is not None or getattr(light, "rotations", None) is not None


def _is_rect(light) -> bool:
    """A rect light, as a :class:`warpshade.lighting.RectLight` or a scene file's ``LightSpec``."""
    from ..lighting import RectLight

    return isinstance(light, RectLight) or getattr(light, "kind", None) == "rect"


def _is_local(light) -> bool:
    """A light whose SH depends on the receiver's position (rect, sphere), costed per vertex."""
    if hasattr(light, "kind") and isinstance(light.kind, str):
        return light.kind in ("rect", "sphere")
    return bool(getattr(light, "local", False))


def _choose(obj: SceneObject, order: int, max_error: float | None, frontier: dict) -> tuple:
    """(method, knobs, config or None, reason) for one object."""
    v = obj.mesh.num_vertices
    if max_error is not None:
        ok = [c for c in frontier["configs"] if c["order"] == order and c["error"] <= max_error]
        if not ok:
            raise ValueError(f"{obj.name}: no measured configuration at SH order {order} meets --max-error "
                             f"{max_error} (best: {min((c['error'] for c in frontier['configs'] if c['order'] == order), default=float('nan')):.3f})")
        best = min(ok, key=lambda c: (estimate_seconds(c, v, triangles=obj.mesh.num_faces), c["error"]))
        knobs = dict(best.get("kwargs", best["knobs"]))
        # empty kwargs mean the method's own defaults, but `warpshade run` gives a method named without
        # knobs its DEFAULT_KNOBS (reference: 256 rays): spell out what was measured
        knobs.update({k: best["knobs"][k] for k in _run_default_knobs(best["method"]) if k not in knobs and k in best["knobs"]})
        return best["method"], knobs, best, f"fastest measured within error {max_error}"
    if obj.method is None:
        return None, {}, None, ""
    from ..pipeline.config import knob_label, resolve_knobs

    knobs = knob_label(obj.method, resolve_knobs(obj.method, obj.knobs))
    cfg, _ = find_config(frontier, obj.method, order, knobs)
    return obj.method, knobs, cfg, "as the scene asks"


def _run_default_knobs(method: str) -> dict:
    """Knobs ``warpshade run`` gives a method the scene names without knobs (:data:`warpshade.pipeline.config.RUN_KNOBS`)."""
    from ..pipeline.config import RUN_KNOBS

    return dict(RUN_KNOBS.get(method, {}))


def make_plan(scene: Scene, max_error: float | None = None, frontier: dict | str | None = None,
              between: str | None = "spheres", area_lights: str = "gears", area_k: int | None = None,
              two_sided: str = "auto", order: int | None = None, reflections=None, config=None,
              probe: int | None = None) -> Plan:
    """Build the :class:`Plan` of ``scene``: the run configuration ``warpshade run`` resolves for it
    (:func:`warpshade.pipeline.config.resolve_run`, the same defaults), its shading groups, and the
    per-frame passes of its pass graph (:meth:`warpshade.pipeline.shading.SceneShader.passes`) costed.

    Args:
        scene: The scene.
        max_error: Error budget (mean relative L2 transfer error, :mod:`warpshade.bench.metrics`); when set,
            each object's method is chosen from the frontier, overriding the scene's choice.
        frontier: Frontier dict, a path (frontier or ``results.json``), or None for the shipped one.
        between: The run's between-group shadows (``"spheres"`` or None, as ``warpshade run --between``).
        area_lights: How the run shades rect lights (``warpshade run --area-lights``): ``"gears"``
            (exact irradiance with GEARS visibility over all shaded objects, :mod:`warpshade.pipeline.area`)
            or ``"sh"`` (projected to SH, costed as a local light).
        area_k: GEARS light samples per side (``warpshade run --area-k``; None: the run's default),
            costed from the frontier's GEARS record at this k (the nearest measured k otherwise).
        two_sided: Which objects the run shades on both sides (``warpshade run --two-sided``,
            :func:`warpshade.pipeline.shading.is_two_sided`), costed in :attr:`GroupPlan.seconds_back`.
        order: SH order (None: the scene's ``warpshade:order``, else the run's default).
        reflections: As ``warpshade run --reflections`` (None: the scene's ``warpshade:reflections``).
        config: A resolved :class:`~warpshade.pipeline.config.RunConfig` instead of the options above.
        probe: Measure instead of estimate: build every shading group as the run does and time its
            transfer (both sides) on the rest pose at this many random receivers
            (:func:`warpshade.pipeline.shading.probe_transfer`); the groups' transfer and build
            seconds are then measured, not fitted. None: estimate from the frontier only (no building).

    Raises:
        ValueError: an empty scene, a bad option, or no configuration within ``max_error``.
    """
    from ..pipeline.config import resolve_run

    if config is None:
        config = resolve_run(scene, order=order, between=between, reflections=reflections, area_lights=area_lights,
                             area_knobs=None if area_k is None else {"k": area_k}, two_sided=two_sided)
    between, area_lights, two_sided = config.between, config.area_lights, config.two_sided
    area_k = config.area_knobs["k"]
    if not scene.objects:
        raise ValueError(f"{scene.source}: scene has no objects")
    if max_error is None:
        max_error = scene.settings.get("max_error")
    fr = frontier if isinstance(frontier, dict) else load_frontier(frontier)
    order = config.order
    reflections = config.reflections is not None
    lighting_changes = any(_light_moves(li) for li in scene.lights)
    moving = {o.name for o in scene.objects if o.kind != "static"}
    # what blocks light in the run: shaded objects that cast shadows (an unshaded one, warpshade:shaded false,
    # is only a collider: the run never sees it)
    casters = [o for o in scene.objects if o.casts_shadows and o.shaded]
    shaded = [o for o in scene.objects if o.shaded]
    inter = len(scene.objects) >= 2 and any(c.name != r.name for c in casters for r in shaded)
    structures, notes, plans = [], [], []
    # with --area-lights gears the run takes rect lights out of the SH sum and runs GEARS instead
    n_rect = sum(1 for li in scene.lights if _is_rect(li)) if area_lights == "gears" else 0
    rect = n_rect > 0
    rect_moves = any(_light_moves(li) for li in scene.lights if _is_rect(li))
    pc = load_pass_costs()["constants"]
    n_local = sum(1 for li in scene.lights if _is_local(li) and not (rect and _is_rect(li)))
    chosen = {o.name: _choose(o, order, max_error, fr) for o in shaded}
    # objects sharing a method and knobs are one mesh in the run and shadow each other through it; sphere
    # sets carry shadows only between the run's shading groups (--between spheres)
    run_groups = (config.groups if max_error is None else
                  _run_groups(scene, {n: (c[0], c[1]) for n, c in chosen.items()}, two_sided))
    for g in run_groups:
        for name in g.names:
            if g.method is None and chosen[name][0] is not None:
                # no member of its group casts shadows (castsShadows false): the run shades it unoccluded
                chosen[name] = (None, {}, None, "no object of its shading group casts shadows: unoccluded")
    group_of = {name: i for i, g in enumerate(run_groups) for name in g.names}
    casting_groups = [i for i, g in enumerate(run_groups) if any(g.casts)]
    # sphere sets shadow a group by the casters of the other groups (pipeline.shading._between_group_shadows)
    other_casters = {name: sum(1 for j in casting_groups if j != group_of[name]) for name in group_of}
    sphere_sets = inter and between is not None and any(other_casters.values())
    for obj in scene.objects:
        if not obj.shaded:
            continue
        method, knobs, cfg, reason = chosen[obj.name]
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
        if sphere_sets and other_casters[obj.name] and (moves or shadowed_by_moving):
            passes.append("inter-object shadows (sphere sets)")
        if rect and (moves or shadowed_by_moving or rect_moves):
            passes.append("area-light visibility (GEARS)")
        if reflections and (moves or shadowed_by_moving or lighting_changes):
            passes.append("reflection (one bounce)")
        relit = moves or shadowed_by_moving or lighting_changes
        if relit:
            passes.append("re-dot lighting")
        passes = [p for p in passes if p]
        f = obj.mesh.num_faces
        t_transfer = estimate_seconds(cfg, v, triangles=f) if cfg else 0.0
        t_build = estimate_seconds(cfg, v, "build_seconds", triangles=f) if cfg else 0.0
        redot = REDOT_SECONDS_PER_COEFF * v * order * order * 3
        if method is not None and cfg is None:
            notes.append(f"{obj.name}: {method} {knob_text(knobs)}at order {order} is not in the frontier; its cost is not estimated")
        t_inter = _between_frame_seconds(v, other_casters[obj.name], pc) if sphere_sets and other_casters[obj.name] else 0.0
        t_gears = n_rect * _area_seconds(fr, pc, v, f, area_k) if rect else 0.0
        t_local = pc["local_light_seconds_per_vertex"] * v * n_local
        t_reflect = (REFLECTION_SECONDS_PER_VERTEX_SPHERE * v * REFLECTION_SPHERES_PER_OBJECT * len(shaded)
                     * (order / 4.0) ** 2) if reflections else 0.0
        seconds_first = t_build + t_transfer + redot + t_inter + t_gears + t_local + t_reflect
        seconds_frame = ((t_transfer if transfer == "every_frame" else 0.0) + (redot if relit else 0.0)
                         + (t_inter if "inter-object shadows (sphere sets)" in passes else 0.0)
                         + (t_gears if "area-light visibility (GEARS)" in passes else 0.0)
                         + (t_local if relit else 0.0)
                         + (t_reflect if "reflection (one bounce)" in passes else 0.0))
        plans.append(ObjectPlan(obj.name, obj.kind, v, moves, method, knobs, transfer, passes,
                                cfg["error"] if cfg else None, seconds_first, seconds_frame, reason,
                                 t_transfer, t_build))
    if any(p.method == "hemiraster" for p in plans):
        structures.append("hemiraster plane LUT")
    if sphere_sets:
        structures.append("sphere sets of shadow casters")
    if rect:
        structures.append("GEARS area-light structures")
    if reflections:
        structures.append("reflection (one-bounce) transfer")
    glossy = [o.name for o in scene.objects if o.shaded and o.material.glossy]
    if glossy:
        # displayColor is one colour per vertex: a run writes view-independent (diffuse) exit radiance, so
        # no glossy pass is planned; say so rather than cost a pass the run does not execute
        notes.append(f"glossy material on {', '.join(glossy)}: warpshade run writes diffuse (view-independent) "
                     "colours; glossy transfer for a view direction is the Python API's "
                     "(hemiraster mode='glossy', eq. 3)")
    plan = Plan(order, scene.frames, plans, structures, lighting_changes, bool(moving), max_error, notes,
                area_lights=area_lights if any(_is_rect(li) for li in scene.lights) else None)
    plan.area_k = area_k
    _plan_groups(plan, scene, fr, pc, n_local, config, run_groups, probe)
    _static_in_moving_groups(plan)
    return plan


def _static_in_moving_groups(plan: Plan) -> None:
    """A static object whose shading group has a moving member is recomputed with the group every
    frame (objects of a group shadow each other through the group's method): plan and cost it so."""
    for g in plan.groups:
        movers = [n for n in g.names if plan.object(n).moves]
        if not movers or g.method is None:
            continue
        for name in g.names:
            o = plan.object(name)
            if o.moves or o.transfer != "once":
                continue
            o.transfer, o.group_moves = "every_frame", movers
            o.passes.insert(0, f"transfer ({o.method}, with its shading group)")
            if "re-dot lighting" not in o.passes:
                o.passes.append("re-dot lighting")
                o.seconds_frame += REDOT_SECONDS_PER_COEFF * o.vertices * plan.order * plan.order * 3
            o.seconds_frame += o.seconds_transfer


def _between_frame_seconds(receivers: int, other_groups: int, pc: dict) -> float:
    """Per-frame sphere-set shadowing of ``receivers`` vertices by ``other_groups`` groups (measured fit)."""
    return pc["between_seconds_fixed"] + pc["between_seconds_per_receiver_vertex_per_other_group"] * receivers * other_groups


def _distant_lights_seconds(scene: Scene, pc: dict) -> float:
    """Per-frame SH of the scene's non-local lights (the default sky when it has none), by light kind."""
    kinds = []
    for li in scene.lights or [None]:
        if li is None:
            kinds.append("dome_texture")  # the default sky is an environment like a textured dome
        elif not _is_local(li):
            k = getattr(li, "kind", None)
            kinds.append("dome_texture" if k == "dome" and getattr(li, "texture", None) else (k or "distant"))
    fallback = max((v for k, v in pc.items() if k.startswith("light_")), default=0.0)
    return sum(pc.get(f"light_{k}_seconds", fallback) for k in kinds)


def _gears_seconds(frontier: dict, vertices: int, triangles: int, k: int = 16) -> float:
    """GEARS visibility per frame at ``k`` light samples per side (grid 16, the run's), from the frontier's
    area records (the nearest measured k when ``k`` was not measured)."""
    cfgs = [c for c in frontier.get("area", []) if c["method"] == "gears" and c["knobs"].get("grid") == 16]
    if not cfgs:
        return 0.0
    cfg = min(cfgs, key=lambda c: abs(c["knobs"].get("k", 16) - k))
    return estimate_seconds(cfg, vertices, triangles=triangles)


def _area_seconds(frontier: dict, pc: dict, vertices: int, triangles: int, k: int = 16) -> float:
    """One rect light under ``--area-lights gears`` per frame: GEARS masks (frontier) plus the exact
    irradiance and the sample weighting (measured per vertex at k = 16, ``benchmarks/planner_costs.py``;
    dominated by the weighting's k² sample sums, so scaled by (k/16)²)."""
    return (_gears_seconds(frontier, vertices, triangles, k)
            + pc.get("area_shading_seconds_per_vertex", 0.0) * vertices * (k / 16) ** 2)


def _run_groups(scene: Scene, methods: dict, two_sided: str = "auto") -> list:
    """The shading groups ``warpshade run`` forms (:func:`warpshade.pipeline.shading.group_objects`) when
    each shaded object uses ``methods[name] = (method, knobs)``."""
    import dataclasses

    from ..pipeline.shading import group_objects

    objs = [dataclasses.replace(o, method=methods[o.name][0], knobs=dict(methods[o.name][1]))
            for o in scene.objects if o.shaded]
    return group_objects(objs, None, None, two_sided=two_sided)


def _plan_groups(plan: Plan, scene: Scene, frontier: dict, pc: dict, n_local: int, config, specs: list,
                 probe: int | None = None) -> None:
    """Fill ``plan.groups`` and ``plan.passes``: the shading groups ``warpshade run`` forms (``specs``: the
    run configuration's, or :func:`_run_groups` with the plan's methods) and every pass of the run's pass
    graph (:meth:`warpshade.pipeline.shading.SceneShader.passes`), each costed; the groups' totals are
    sums of their passes. With ``probe``, each group's transfer and method build are measured
    (:func:`warpshade.pipeline.shading.probe_transfer`) instead of estimated."""
    import dataclasses

    from ..pipeline.shading import SceneShader, back_side_receivers, probe_transfer

    n = plan.order * plan.order
    shader = SceneShader.from_config(dataclasses.replace(config, groups=specs), scene)
    graph = shader.passes()
    n_objects = sum(len(spec.names) for spec in specs)  # every shaded object gets its own sphere tree
    tris = sum(m.num_faces for spec in specs for m in spec.meshes)
    caster_tris = [len(spec.blocker_faces()) for spec in specs]
    back_transfer = []
    for k, spec in enumerate(specs):
        v = sum(m.num_vertices for m in spec.meshes)
        f = sum(m.num_faces for m in spec.meshes)
        g = GroupPlan(spec.method, spec.label, list(spec.names), v, f, any(spec.moving),
                      caster_triangles=caster_tris[k])
        cfg = None
        if spec.method is None:
            g.seconds_transfer = pc["unoccluded_seconds_per_vertex"] * v
            g.cost_source = "measured constant"
        else:
            cfg, src = find_config(frontier, spec.method, plan.order, spec.label)
            if cfg is None and not probe:
                g.cost_source = "not in the frontier: transfer not estimated"
                plan.notes.append(f"group {spec.names}: {spec.method} {knob_text(spec.label)}is not in the frontier; "
                                  "its transfer cost is not estimated")
            elif cfg is not None:
                # the method's blockers are the casters' triangles; every vertex receives
                g.seconds_transfer = estimate_seconds(cfg, v, triangles=caster_tris[k])
                g.seconds_build = estimate_seconds(cfg, v, "build_seconds", triangles=caster_tris[k])
                fit = len({t["vertices"] for t in cfg["timings"]}) >= 3
                g.cost_source = ", ".join(x for x in (("fit over measured meshes" if fit else "nearest measured mesh"), src) if x)
        measured = probe_transfer(spec, plan.order, probe) if probe and spec.method is not None else None
        if measured is not None:
            g.seconds_transfer = measured["front"]
            g.seconds_build = measured["build"]
            g.cost_source = ("probed: " + (f"{measured['sampled']} random receivers a side" if measured["sampled"]
                                            else "one full update a side") + " on the rest pose")
        if (measured is None and cfg is not None and len(spec.names) > 1
                and not any("lower bound" in n for n in plan.notes)):
            plan.notes.append(
                "the transfer estimates are fitted on warpshade bench's isolated meshes; where the objects of a "
                "shading group touch (cloth on a collider or a ground, a cape on a figure) the method's near-field "
                "work grows (cape_walker's transfer measured 3.4x its estimate): read the shading time per frame "
                "as a lower bound, or measure it with warpshade plan --probe (make_plan(probe=...))")
        t_back = 0.0
        if any(spec.two_sided):
            # the back side: the method again on the group seen from the back (or the unoccluded lobe), on every
            # vertex or on the two-sided members only (back_side_receivers)
            g.two_sided = [name for name, t in zip(spec.names, spec.two_sided) if t]
            v_two = sum(m.num_vertices for m, t in zip(spec.meshes, spec.two_sided) if t)
            t_back, back_build = g.seconds_transfer, g.seconds_build
            if spec.method is None:
                back_build = 0.0
            elif back_side_receivers(spec) is not None and cfg is not None:
                t_back = estimate_seconds(cfg, v_two, triangles=caster_tris[k])
                back_build = estimate_seconds(cfg, v_two, "build_seconds", triangles=caster_tris[k])
            if measured is not None:  # the probe's build is both sides'
                t_back, back_build = measured["back"] or 0.0, 0.0
            g.seconds_build += back_build
        # the group's meshes at setup (merged members and their normals; the back side's merged members),
        # which the frontier's build_seconds (the constructor on a built mesh) leave out
        mesh_tris = f
        two = back_side_receivers(spec) if any(spec.two_sided) and spec.method is not None else None
        if two is not None:
            casts = spec.casts or [True] * len(spec.meshes)
            mesh_tris += sum(m.num_faces for i, m in enumerate(spec.meshes) if i in two or casts[i])
        if measured is None:  # (the probe's build includes them)
            g.seconds_build += pc["group_mesh_seconds_per_triangle"] * mesh_tris
        back_transfer.append(t_back)
        plan.groups.append(g)
    t_refl = (REFLECTION_SECONDS_PER_VERTEX_SPHERE * sum(g.vertices for g in plan.groups) * REFLECTION_SPHERES_PER_OBJECT
              * n_objects * (plan.order / 4.0) ** 2)
    n_rect = len(shader.rect_lights()) if config.area_lights == "gears" else 0
    t_area = n_rect * _area_seconds(frontier, pc, sum(g.vertices for g in plan.groups), sum(caster_tris),
                                    config.area_knobs["k"])

    def cost(p) -> float:
        """Estimated seconds of one pass of the graph."""
        if p.group is None:
            return t_area if p.kind in ("area", "back area") else t_refl
        g, spec = plan.groups[p.group], specs[p.group]
        v = g.vertices
        if p.kind == "transfer":
            return g.seconds_transfer
        if p.kind == "back transfer":
            return back_transfer[p.group]
        if p.kind in ("between", "back between"):
            others = sum(1 for j, t in enumerate(caster_tris) if j != p.group and t)
            return _between_frame_seconds(v, others, pc)
        if p.kind == "lights":
            return _distant_lights_seconds(scene, pc) + pc["local_light_seconds_per_vertex"] * v * n_local
        if p.kind == "radiance":
            return pc["radiance_seconds_fixed"] + pc["radiance_seconds_per_vertex_coeff"] * v * n
        if p.kind == "back radiance":
            v_two = sum(m.num_vertices for m, t in zip(spec.meshes, spec.two_sided) if t)
            return pc["radiance_seconds_per_vertex_coeff"] * v_two * n
        raise ValueError(f"no cost for pass {p.kind!r}")

    for p in graph:
        seconds = cost(p)
        plan.passes.append({"pass": p.key, "every_frame": p.every_frame, "seconds": seconds})
        if p.group is None:
            if p.kind in ("area", "back area"):
                plan.seconds_area += seconds
                plan.area_moves = p.every_frame
            elif p.every_frame:  # the reflections, shared out by vertices for the groups' lines
                for g in plan.groups:
                    g.seconds_reflections += seconds * g.vertices / max(1, sum(h.vertices for h in plan.groups))
            continue
        g = plan.groups[p.group]
        if p.kind == "between":
            g.seconds_between = seconds
        elif p.kind == "lights":
            g.seconds_lights = seconds
        elif p.kind == "radiance":
            g.seconds_radiance = seconds
        elif p.kind.startswith("back ") and (p.every_frame or p.kind != "back transfer"):
            g.seconds_back += seconds
    if config.between and sum(1 for t in caster_tris if t) and len(specs) > 1:
        # a sphere tree per group with shadow casters, fitted to their triangles
        plan.seconds_setup_between = (pc["between_build_seconds_per_group"] * sum(1 for t in caster_tris if t)
                                      + pc["between_build_seconds_per_triangle"] * sum(caster_tris))
    if config.reflections is not None:  # one sphere tree per object, fitted like the between-group trees
        plan.seconds_setup_between += (pc["between_build_seconds_per_group"] * n_objects
                                       + pc["between_build_seconds_per_triangle"] * tris)
    if any(g.method == "hemiraster" for g in plan.groups):
        plan.seconds_setup_structures += pc["hemiraster_lut_seconds"]


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
