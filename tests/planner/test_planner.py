"""The planner: structures only when used, reuse for static objects, error-budget method choice."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from helpers import SHIPPED
from warpshade.bench.meshes import grid
from warpshade.geometry import TriMesh
from warpshade.lighting import RectLight, default_environment, spin
from warpshade.planner import estimate_seconds, make_plan, naive_seconds
from warpshade.scene import Material, Scene, SceneObject

# Hand-built frontier (numbers invented for the test, not measured): four methods at order 4, the
# order `warpshade run` and make_plan default to (pipeline.config.DEFAULT_ORDER).
FRONTIER = {"configs": [
    {"method": "reference", "order": 4, "knobs": {"rays": 1024}, "error": 0.015, "error_p95": 0.02,
     "timings": [{"mesh": "a", "vertices": 1000, "triangles": 2000, "seconds": 0.5, "build_seconds": 0.01}]},
    # what `warpshade run` uses for "reference" without knobs (pipeline.config.RUN_KNOBS)
    {"method": "reference", "order": 4, "knobs": {"rays": 256}, "error": 0.035, "error_p95": 0.05,
     "timings": [{"mesh": "a", "vertices": 1000, "triangles": 2000, "seconds": 0.125, "build_seconds": 0.01}]},
    {"method": "hemiraster", "order": 4, "knobs": {"mask": 32}, "error": 0.04, "error_p95": 0.1,
     "timings": [{"mesh": "a", "vertices": 1000, "triangles": 2000, "seconds": 0.1, "build_seconds": 0.2}]},
    {"method": "disks", "order": 4, "knobs": {"lod": 2.0}, "error": 0.2, "error_p95": 0.3,
     "timings": [{"mesh": "a", "vertices": 1000, "triangles": 2000, "seconds": 0.01, "build_seconds": 0.0}]},
]}


def ico(name="ball", kind="static", method="reference", **kw):
    m = trimesh.creation.icosphere(2)
    return SceneObject(name, TriMesh(m.vertices, m.faces, name=name), kind, method=method, **kw)


def ground(kind="static", method="reference"):
    p, f = grid(8, 4.0)
    return SceneObject("ground", TriMesh(p, f, name="ground"), kind, method=method)


def test_single_self_shadowing_object_needs_no_shared_structures():
    plan = make_plan(Scene([ico()], frames=10), frontier=FRONTIER)
    assert plan.structures == []  # no LUT, no sphere sets, no GEARS, no bounce
    o = plan.object("ball")
    assert o.transfer == "once" and o.passes == [] and o.seconds_frame == 0.0


def test_structures_appear_only_when_used():
    scene = Scene([ico(method="hemiraster", material=Material(roughness=0.3)), ground()],
                  lights=[RectLight(center=(0, 3, 0), u=(0.5, 0, 0), v=(0, 0, 0.5))],
                  settings={"reflections": True}, frames=5)
    plan = make_plan(scene, frontier=FRONTIER)
    assert {"hemiraster plane LUT", "sphere sets of shadow casters", "GEARS area-light structures",
            "reflection (one-bounce) transfer"} <= set(plan.structures)
    # the run writes per-vertex (view-independent) colours: a glossy material is noted, not planned as a pass
    assert not any("glossy" in x for x in plan.structures + [p for o in plan.objects for p in o.passes])
    assert any("glossy material on ball" in n for n in plan.notes)


def test_static_object_reused_moving_object_every_frame_and_caster_forces_update():
    # different methods: two shading groups in the run, the ground's own group is static
    plan = make_plan(Scene([ico("cloth", kind="cloth"), ground(method="hemiraster")], frames=20), frontier=FRONTIER)
    cloth, gr = plan.object("cloth"), plan.object("ground")
    assert cloth.transfer == "every_frame" and "transfer (reference)" in cloth.passes
    # the ground does not move: its self-transfer is computed once, but the moving cloth shadows it
    # through the sphere sets between the run's groups
    assert gr.transfer == "once" and gr.group_moves == [] and "inter-object shadows (sphere sets)" in gr.passes
    assert "sphere sets of shadow casters" in plan.structures
    assert plan.seconds_total < naive_seconds(plan)


def test_static_object_in_a_moving_shading_group_is_planned_every_frame():
    # same method and knobs: one shading group, which warpshade run recomputes every frame because the
    # cloth moves (the cloth can shadow the ground within the group), so the ground's transfer is not reused
    plan = make_plan(Scene([ico("cloth", kind="cloth"), ground()], frames=20), frontier=FRONTIER)
    gr = plan.object("ground")
    (g,) = plan.groups
    assert g.moves and g.names == ["cloth", "ground"]
    assert gr.transfer == "every_frame" and gr.group_moves == ["cloth"]
    assert "transfer (reference, with its shading group)" in gr.passes
    assert gr.seconds_frame >= gr.seconds_transfer > 0  # costed as recomputed, not reused
    # one group: its members shadow each other through the method, so no sphere sets are planned
    assert "sphere sets of shadow casters" not in plan.structures
    assert not any("sphere sets" in p for o in plan.objects for p in o.passes)
    # all members static: the group's transfer is reused, and the plan says so
    still = make_plan(Scene([ico("ball"), ground()], frames=20), frontier=FRONTIER)
    assert [o.transfer for o in still.objects] == ["once", "once"] and not still.groups[0].moves
    assert all(o.seconds_frame == 0.0 for o in still.objects)


def test_lighting_only_change_is_a_redot():
    sky = default_environment().with_motion(spin((0, 1, 0), 10.0))
    plan = make_plan(Scene([ico()], lights=[sky], frames=10), frontier=FRONTIER)
    o = plan.object("ball")
    assert plan.lighting_changes and o.transfer == "once" and o.passes == ["re-dot lighting"]
    assert 0 < o.seconds_frame < 1e-3  # 162 vertices × 25 coefficients × 3 channels


@pytest.mark.parametrize("budget, want", [(0.05, "hemiraster"), (0.02, "reference"), (0.5, "disks")])
def test_error_budget_picks_fastest_within_budget(budget, want):
    plan = make_plan(Scene([ico()], frames=3), max_error=budget, frontier=FRONTIER)
    assert plan.object("ball").method == want


def test_impossible_budget_is_a_clear_error():
    with pytest.raises(ValueError, match="max-error"):
        make_plan(Scene([ico()]), max_error=0.001, frontier=FRONTIER)


def test_cost_scales_from_nearest_mesh():
    cfg = {"timings": [{"vertices": 1000, "seconds": 1.0}, {"vertices": 10000, "seconds": 20.0}]}
    assert estimate_seconds(cfg, 2000) == pytest.approx(2.0)
    assert estimate_seconds(cfg, 8000) == pytest.approx(16.0)


def test_shipped_frontier_loads_and_covers_every_method_at_order_5():
    from warpshade.planner import load_frontier
    from warpshade.visibility import METHODS

    fr = load_frontier()
    have = {c["method"] for c in fr["configs"] if c["order"] == 5}
    # GEARS is an area-light method (different output), not a transfer method swept by bench
    assert {m for m in METHODS if m != "gears"} <= have, have
    assert all(np.isfinite(c["error"]) for c in fr["configs"])


def test_apply_plan_sets_each_objects_method():
    from warpshade.planner import apply_plan

    scene = Scene([ico("a", method=None), ico("b", kind="cloth", method="disks")], frames=2)
    plan = make_plan(scene, max_error=0.05, frontier=FRONTIER)
    apply_plan(scene, plan)
    assert [o.method for o in scene.objects] == ["hemiraster", "hemiraster"]
    assert scene.object("a").knobs == {"mask": 32}  # knobs when the frontier has no constructor kwargs


def test_fit_cost_recovers_known_coefficients():
    from warpshade.planner import cost_features, fit_cost

    # seconds generated from a known a V + b V log2 F + c V F (a, b, c chosen, not measured)
    v = np.array([500, 1200, 2500, 4000, 6100])
    f = np.array([1000, 2300, 4900, 7900, 12200])
    coef = np.array([2e-5, 3e-6, 4e-9])
    t = cost_features(v, f) @ coef
    np.testing.assert_allclose(fit_cost(cost_features(v, f), t), coef, rtol=1e-6)


def test_fit_cost_equals_scipy_nnls_on_noisy_and_constrained_data():
    """The support enumeration against SciPy's NNLS: random timings with noise, some whose unconstrained fit
    has negative coefficients (so the bound is active), and the shipped frontier's configurations."""
    from scipy.optimize import nnls

    from warpshade.planner import cost_features, fit_cost, load_frontier

    def reference(features, seconds):  # the weighting and scaling fit_cost documents, solved by scipy
        x, y = np.asarray(features, float), np.asarray(seconds, float)
        w, scale = 1.0 / y, np.abs(x).max(axis=0)
        return nnls(x * w[:, None] / scale, y * w)[0] / scale

    rng = np.random.default_rng(7)
    active = 0
    for _ in range(200):
        n = int(rng.integers(3, 9))
        v, f = rng.integers(100, 20000, n), rng.integers(200, 40000, n)
        coef = rng.uniform(-1, 1, 3) * np.array([1e-5, 1e-6, 1e-9])
        t = np.abs(cost_features(v, f) @ coef) * rng.uniform(0.7, 1.3, n) + 1e-6
        ours, theirs = fit_cost(cost_features(v, f), t), reference(cost_features(v, f), t)
        active += int((theirs == 0).any())
        np.testing.assert_allclose(ours, theirs, rtol=1e-7, atol=1e-12 * np.abs(theirs).max())
    assert active > 20  # the bound was active in many draws: the enumeration was tested where it matters
    for cfg in load_frontier()["configs"]:
        rows = [t for t in cfg["timings"] if t.get("triangles")]
        if len(rows) >= 3:
            feats = cost_features([t["vertices"] for t in rows], [t["triangles"] for t in rows])
            secs = [t["seconds"] for t in rows]
            np.testing.assert_allclose(fit_cost(feats, secs), reference(feats, secs), rtol=1e-7,
                                       atol=1e-12 * np.abs(reference(feats, secs)).max())


def test_estimate_uses_triangles_when_three_meshes_are_measured():
    # exactly linear in V·F (brute force over blockers): doubling V and F quadruples the time;
    # the nearest-mesh rule (linear in V) would say 2x
    cfg = {"timings": [{"vertices": v, "triangles": 2 * v, "seconds": 1e-7 * v * 2 * v} for v in (1000, 2000, 4000)]}
    assert estimate_seconds(cfg, 8000, triangles=16000) == pytest.approx(1e-7 * 8000 * 16000, rel=1e-6)
    assert estimate_seconds(cfg, 8000) == pytest.approx(2 * cfg["timings"][2]["seconds"])  # no F: nearest mesh, x2


def test_groups_mirror_the_pipeline_and_cost_the_between_pass():
    from warpshade.pipeline import Pipeline

    scene = Scene([ico("ball", method="hemiraster"), ground(method="reference"), ico("cloth", kind="cloth")],
                  frames=4)
    plan = make_plan(scene, frontier=FRONTIER)
    want = [(g.method, g.names) for g in Pipeline(scene).groups]
    assert [(g.method, g.names) for g in plan.groups] == want  # same grouping as warpshade run
    by = {tuple(g.names): g for g in plan.groups}
    still = by[("ball",)]
    assert not still.moves and still.seconds_frame == still.seconds_between + still.seconds_lights + still.seconds_radiance
    assert by[("ground", "cloth")].moves  # a static object shares its group's recomputation
    assert all(g.seconds_between > 0 for g in plan.groups) and plan.seconds_setup_between > 0
    assert plan.seconds_setup_structures > 0  # hemiraster plane LUT
    alone = make_plan(scene, frontier=FRONTIER, between=None)
    assert all(g.seconds_between == 0 for g in alone.groups) and alone.seconds_setup_between == 0


def test_run_defaults_knobs_and_rect_light_spec():
    from warpshade.scene import LightSpec

    scene = Scene([ico()], lights=[LightSpec("rect", "/Panel", width=1.0, height=1.0)], frames=3)
    plan = make_plan(scene, frontier=FRONTIER)
    # the pipeline gives "reference" without knobs 256 rays (pipeline.DEFAULT_KNOBS): plan and cost that
    assert plan.object("ball").knobs == {"rays": 256} and plan.groups[0].knobs == {"rays": 256}
    assert plan.object("ball").error == 0.035
    assert "GEARS area-light structures" in plan.structures  # a scene file's rect light counts
    # the run's default (--area-lights gears) shades the rect light in the GEARS pass, not in the lights' SH
    # (no other light: no SH light cost at all)
    assert plan.groups[0].seconds_lights == 0.0 and plan.area_lights == "gears"
    sh = make_plan(scene, frontier=FRONTIER, area_lights="sh")
    assert sh.groups[0].seconds_lights > 0.0 and sh.seconds_area == 0 and sh.area_lights == "sh"


def test_budget_choice_spells_out_measured_knobs_for_the_run():
    # the frontier's default-knob configuration has empty kwargs; the run must not swap in its 256-ray default
    fr = {"configs": [{**FRONTIER["configs"][0], "kwargs": {}}]}
    plan = make_plan(Scene([ico()], frames=2), max_error=0.02, frontier=fr)
    assert plan.object("ball").knobs == {"rays": 1024}


def test_plan_cli_on_shipped_rect_light_scene(tmp_path):
    import json
    import os

    from warpshade.cli import main as cli_main

    scene = os.path.join(SHIPPED, "rect_light.usda")
    out = tmp_path / "plan.json"
    assert cli_main(["plan", scene, "--json", str(out)]) == 0
    plan = json.loads(out.read_text())
    # what `warpshade run` does with this scene: order 4, one group of all three objects with the run's
    # default method and knobs (pipeline.default_method / DEFAULT_KNOBS), recomputed every frame because
    # the cloth moves; the UsdLux RectLight is seen
    from warpshade.pipeline import DEFAULT_KNOBS, default_method

    assert plan["order"] == 4 and "GEARS area-light structures" in plan["structures"]
    (g,) = plan["groups"]
    method = default_method()
    assert g["method"] == method and g["knobs"] == DEFAULT_KNOBS.get(method, {}) and g["moves"]
    assert g["names"] == ["/World/Ground", "/World/Ball", "/World/Cloth"] and g["vertices"] == 2820
    assert g["seconds_lights"] > 0 and g["seconds_transfer"] > 0 and g["seconds_between"] == 0
    # the run's default --area-lights gears: one GEARS pass over the merged group, every frame (the cloth moves)
    assert plan["area_lights"] == "gears" and plan["area_moves"] and plan["seconds_area"] > 0
    assert plan["run_seconds_per_frame"] == pytest.approx(g["seconds_frame"] + plan["seconds_area"])


def test_probe_times_the_runs_groups_on_a_random_sample_of_their_receivers(monkeypatch):
    # make_plan(probe=K) builds each group as the run does and times its transfer at K random receivers a
    # side (compute_rows); without probe nothing is built. Which rows it computes is checked here; how close
    # its extrapolation comes to the run's time is benchmarks/planner_savings.py --scenes --probe's.
    from warpshade.visibility.hemiraster.method import HemirasterTransfer

    calls = []
    original = HemirasterTransfer.compute_rows

    def spy(self, rows):
        calls.append((id(self), np.asarray(rows).copy()))
        return original(self, rows)

    monkeypatch.setattr(HemirasterTransfer, "compute_rows", spy)
    p, f = grid(24, 1.0)  # 576 vertices, two-sided in the run (a cloth)
    cloth = SceneObject("cloth", TriMesh(p + (0.0, 0.0, 0.3), f, name="cloth"), "cloth", method="hemiraster")
    gp, gf = grid(8, 4.0)  # 64 vertices
    scene = Scene([cloth, SceneObject("ground", TriMesh(gp, gf, name="ground"), "static", method="hemiraster")],
                  frames=3)
    estimated = make_plan(scene, frontier=FRONTIER)
    assert calls == [] and "probed" not in estimated.groups[0].cost_source
    plan = make_plan(scene, frontier=FRONTIER, probe=64)
    (g,) = plan.groups
    assert g.names == ["cloth", "ground"] and g.two_sided == ["cloth"] and g.vertices == 640
    assert g.cost_source.startswith("probed: 64 random receivers")
    methods = list(dict.fromkeys(k for k, _ in calls))  # front, then back, in the order they were probed
    assert len(methods) == 2
    front, back = ([rows for k, rows in calls if k == m] for m in methods)
    for rows, bound in [(r, 640) for r in front] + [(r, 576) for r in back]:  # the back: the cloth's rows only
        assert len(rows) in (1, 64) and len(np.unique(rows)) == len(rows) and 0 <= rows.min() and rows.max() < bound
    assert {len(r) for r in front} == {len(r) for r in back} == {1, 64}  # one receiver and the sample
    assert not np.array_equal(np.sort(front[-1]), np.arange(64))  # a random sample, not the first rows
    assert g.seconds_transfer > 0 and g.seconds_back > 0 and g.seconds_build > 0


def test_probe_times_a_full_update_of_a_method_without_receiver_subsets():
    scene = Scene([ico(method="reference", knobs={"rays": 16})], frames=3)
    plan = make_plan(scene, frontier=FRONTIER, probe=32)
    (g,) = plan.groups
    assert g.cost_source == "probed: one full update a side on the rest pose" and g.seconds_transfer > 0


def test_plan_cli_probe_on_shipped_skinned_arm(tmp_path):
    import json
    import os

    from warpshade.cli import main as cli_main

    scene = os.path.join(SHIPPED, "skinned_arm.usda")
    out = tmp_path / "plan.json"
    assert cli_main(["plan", scene, "--probe", "16", "--json", str(out)]) == 0
    (g,) = json.loads(out.read_text())["groups"]
    assert g["cost_source"] == "probed: 16 random receivers a side on the rest pose" and g["seconds_transfer"] > 0
