"""``warpshade plan SCENE``: which passes and structures a scene needs, and their estimated cost."""

from __future__ import annotations

import argparse
import json

HELP = "print the plan (passes, shared structures, reuse, method per object) and estimated cost per frame"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from ..visibility.base import positive_int
    from .cmd_run import add_refine_argument, add_two_sided_argument

    parser.add_argument("scene", metavar="SCENE", help="scene file (.usd/.usda) read by warpshade.usd")
    add_refine_argument(parser)
    add_two_sided_argument(parser)
    parser.add_argument("--max-error", type=float, default=None,
                        help="error budget: per object, the fastest measured method within this mean error")
    parser.add_argument("--frontier", default=None, help="frontier.json or bench results.json (default: shipped)")
    parser.add_argument("--order", type=int, default=None,
                        help="SH order (default: the scene's warpshade:order, else warpshade run's default 4)")
    parser.add_argument("--between", choices=("spheres", "none"), default="spheres",
                        help="shadows between shading groups, as warpshade run --between (default spheres)")
    parser.add_argument("--area-lights", choices=("gears", "sh"), default="gears",
                        help="rect lights as warpshade run --area-lights: GEARS soft shadows (default) or SH")
    parser.add_argument("--area-k", type=positive_int, default=None,
                        help="GEARS light samples per side, as warpshade run --area-k (default 16)")
    parser.add_argument("--probe", type=positive_int, nargs="?", const=256, default=None, metavar="RECEIVERS",
                        help="measure instead of estimate: build each shading group as the run does and time its "
                             "transfer on the rest pose at RECEIVERS random receivers a side (default 256; costs "
                             "the groups' setup, seconds on large scenes)")
    parser.add_argument("--json", default=None, metavar="PLAN.json", help="also write the plan as JSON")
    parser.add_argument("--reflections", action="store_true", default=None,
                        help="plan the one-bounce reflection pass (as warpshade run --reflections; default: the "
                             "scene's warpshade:reflections)")


def load_scene(path: str):
    """Read a scene through the USD package (the only place that imports pxr)."""
    from .. import usd

    reader = getattr(usd, "read_scene", None)
    if reader is None:
        raise ValueError(f"{path}: reading scenes needs warpshade.usd.read_scene (the USD pipeline), not installed here")
    return reader(path)


def _frontier(path: str | None):
    """``--frontier``: a frontier file (the planner reads it), or a ``warpshade bench`` results.json, which the
    bench converts to a frontier (:func:`warpshade.bench.report.frontier_from_results`)."""
    import os

    if path is None or not os.path.isfile(path):
        return path  # the planner reads the shipped frontier, or names the missing file
    with open(path) as f:
        data = json.load(f)
    if isinstance(data, list):
        from ..bench.report import frontier_from_results

        return frontier_from_results(data)
    return path


def run(args) -> int:
    from ..planner import make_plan, naive_seconds

    from ..pipeline.refine import describe as describe_refined, refine_receivers

    scene = load_scene(args.scene)
    refined = refine_receivers(scene, args.refine_receivers)
    if refined:
        print(describe_refined(refined).strip())
    # the options warpshade run takes, resolved the way the run resolves them (pipeline.config.resolve_run)
    plan = make_plan(scene, max_error=args.max_error, frontier=_frontier(args.frontier), order=args.order,
                     between=None if args.between == "none" else args.between, area_lights=args.area_lights,
                     area_k=args.area_k, two_sided=args.two_sided, reflections=True if args.reflections else None,
                     probe=args.probe)
    print(plan.describe())
    print(f"  without reuse (every object every frame): {naive_seconds(plan):.2f} s")
    from ..pipeline.config import REUSE_AUTO, REUSE_CHUNK, resolve_reuse, reuse_text

    reuse = resolve_reuse(REUSE_AUTO, [g.method for g in plan.groups])
    print(f"  temporal reuse of warpshade run (--reuse; its default): {reuse_text(reuse, REUSE_CHUNK)}"
          + ("; the estimates above recompute every receiver every frame, the run only those due" if reuse is not None
             else ""))
    if args.json:
        from ..bench.report import write_json

        write_json(args.json, plan.to_dict(), indent=2)
    return 0
