"""Model only what a scene requires: from a :class:`~warpshade.scene.Scene`, decide per object which passes
run, which shared structures get built, what can be reused across frames, and (under an error budget)
which visibility method and knobs to use — from the frontier ``warpshade bench`` measured.

Rules (issue 8):

* transfer of an object that does not move (``kind == "static"``) is computed once and reused every frame
  only when its whole shading group is static: ``warpshade run`` shades objects sharing a method and
  knobs as one mesh (they shadow each other), recomputed every frame when any member moves, so a static
  member of a moving group is planned ``every_frame`` (:attr:`ObjectPlan.group_moves`) and costed so;
* when only lighting changes, shading is a re-dot ``(ρ/π) Σ L_i T_i`` of reused transfer; when neither
  geometry nor lighting changes, the first frame's colours are reused;
* shared structures exist only when something uses them: the hemispherical-rasterization plane LUT only
  if an object uses ``hemiraster``; GEARS only with rect lights; sphere sets for inter-object shadows only
  when at least two objects exist, one casts onto another and the run has two or more shading groups
  between which they carry shadows (never for a single self-shadowing object, nor for objects sharing a
  group, which shadow each other through the group's method);
  objects with ``casts_shadows`` False block nothing: they are left out of the sphere sets, out of the
  GEARS blockers and out of their group method's blocker triangles, and a group without any caster is
  unoccluded (method None), as the run does;
  reflection (one diffuse bounce) only when ``settings["reflections"]`` asks; no glossy pass (a run writes
  view-independent per-vertex colours; glossy materials get a note);
* with ``max_error``, each object gets the configuration of the frontier whose worst measured mean error
  is within budget and whose estimated time on this object is smallest.

Cost model (estimates, printed as such):

* a visibility method's time per frame (and build time) is fitted per frontier configuration from the
  meshes ``warpshade bench`` measured it on, as ``t = a V + b V log2 F + c V F`` with ``a, b, c >= 0``
  (V vertices, F triangles: per-receiver fixed work, BVH-like and brute-force-like work over the
  blockers; :func:`fit_cost`); with fewer than three measured meshes, the time of the nearest mesh in
  vertex count is scaled linearly in V. A configuration missing at the plan's SH order is costed from
  the same knobs at the nearest measured order (time depends little on order: ≤ 20 % from 2 to 6 in
  the frontier);
* the other passes — between-group sphere-set shadows (setup fit + per frame), lights' SH (fixed for
  distant lights, per vertex for each local light), exit radiance, unoccluded transfer, the
  hemiraster LUT — use constants measured by ``benchmarks/planner_costs.py`` on the shipped scenes
  (``warpshade/data/pass_costs.json``);
* :attr:`Plan.groups` mirrors what ``warpshade run`` executes (the pipeline's shading groups: objects
  sharing a method and knobs are one receiver mesh, recomputed when any member moves; groups shadow
  each other through sphere sets), so :attr:`Plan.run_seconds_per_frame` is comparable to the
  ``shade`` time a run reports (``benchmarks/planner_savings.py --scenes`` prints both).
"""

from .costs import (REDOT_SECONDS_PER_COEFF, REFLECTION_SECONDS_PER_VERTEX_SPHERE, REFLECTION_SPHERES_PER_OBJECT,
                    cost_features, default_knobs, estimate_seconds, find_config, fit_cost, load_frontier,
                    load_pass_costs)
from .make import apply_plan, make_plan, naive_seconds
from .plan import GroupPlan, ObjectPlan, Plan

__all__ = ["GroupPlan", "ObjectPlan", "Plan", "REDOT_SECONDS_PER_COEFF", "REFLECTION_SECONDS_PER_VERTEX_SPHERE",
           "REFLECTION_SPHERES_PER_OBJECT", "apply_plan", "cost_features", "default_knobs", "estimate_seconds",
           "find_config", "fit_cost", "load_frontier", "load_pass_costs", "make_plan", "naive_seconds"]
