"""The planner costs the passes the run executes: for every shipped scene, the passes of the plan (made with
make_plan's defaults, resolved as warpshade run resolves them) are the passes a real run computes on its
first frame, and the ones the plan marks every_frame are exactly those it computes again on later frames
(the run decides what to reuse from its caches at run time; the plan predicts it from the scene)."""

from __future__ import annotations

import glob
import os

import pytest

from helpers import SHIPPED
from warpshade.pipeline import Pipeline
from warpshade.planner import make_plan
from warpshade.usd import AnimationWriter, read_scene

SCENES = sorted(glob.glob(os.path.join(SHIPPED, "*.usda")))


@pytest.mark.parametrize("path", SCENES, ids=[os.path.basename(p) for p in SCENES])
def test_passes_planned_are_the_passes_run(path, tmp_path):
    scene = read_scene(path)
    pipe = Pipeline(scene, frames=2, workers=0)  # refines the scene's receivers in place, as warpshade run
    plan = make_plan(scene)
    assert plan.order == pipe.order
    assert [(g.method, g.knobs, g.names) for g in plan.groups] == [(g.method, g.label, g.names) for g in pipe.groups]
    report = pipe.run(AnimationWriter(str(tmp_path / "out.usda"), fps=scene.fps, up_axis=scene.up_axis),
                      progress=False)
    first, later = report.passes
    assert list(first) == [p["pass"] for p in plan.passes]
    assert list(later) == [p["pass"] for p in plan.passes if p["every_frame"]]


def test_a_static_scene_reuses_its_transfer_and_the_plan_says_so(tmp_path):
    # the same check where reuse matters: nothing moves, so transfer (and GEARS) run on frame 0 only
    scene = read_scene(os.path.join(SHIPPED, "rect_light.usda"))
    for o in scene.objects:
        o.kind = "static"
    pipe = Pipeline(scene, frames=2, workers=0, method="reference", knobs={"rays": 16}, order=2)
    plan = make_plan(scene, config=pipe.config)
    once = [p["pass"] for p in plan.passes if not p["every_frame"]]
    assert "transfer[0]" in once and "area" in once
    report = pipe.run(AnimationWriter(str(tmp_path / "out.usda"), fps=scene.fps), progress=False)
    assert list(report.passes[0]) == [p["pass"] for p in plan.passes]
    assert not set(once) & set(report.passes[1])
