"""``warpshade bench``: speed/accuracy sweep of every visibility method (docs/conventions.md §5)."""

from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import time

HELP = "measure time, memory and error of every visibility method's knob settings; write JSON, CSV, Pareto plot"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--quick", action="store_true",
                        help="few configurations on two small meshes, orders 3 and 5, 4096-ray ground truth (< 2 minutes)")
    parser.add_argument("--out", default=None, metavar="DIR",
                        help="writes DIR/results.json, results.csv, pareto.png (required unless --animation)")
    parser.add_argument("--methods", default=None, help="comma-separated method names (default: all registered)")
    parser.add_argument("--meshes", default=None,
                        help="comma-separated mesh names (cloth, bunny, bear, character, two-objects)")
    parser.add_argument("--orders", default=None, help="comma-separated SH orders swept at default knobs "
                        "(default 2,3,4,5,6; quick 3)")
    parser.add_argument("--repeat", type=int, default=None, help="timed runs per configuration (default 5; quick 3)")
    parser.add_argument("--ground-truth-rays", type=int, default=None,
                        help="rays per vertex of the ground truth (default 16384; quick 4096)")
    parser.add_argument("--cache-dir", default=None,
                        help="ground-truth cache directory (default: 'reference' in the user cache, see "
                             "'warpshade info'; 'none' disables)")
    parser.add_argument("--frontier", default=None, metavar="FRONTIER.json",
                        help="also write the planner's frontier file (e.g. warpshade/data/frontier.json)")
    parser.add_argument("--device", default="cpu", help="Warp device (default cpu)")
    from ..bench.animation import ANIMATIONS

    anim = parser.add_argument_group("whole animations (--animation)")
    anim.add_argument("--animation", type=_animation, default=None, metavar="|".join(ANIMATIONS) + "|SCENE.usda",
                      help="instead of the sweep: shade every frame of a sequence (default: the default scene's drape; "
                           "walk: the skinned walking figure; a USD file: its first moving shading group), judge every --every-th frame against its ray-traced "
                           "truth, with temporal reuse at several tolerances beside recomputation")
    anim.add_argument("--frames", type=int, default=120, help="frames of the sequence (default 120)")
    anim.add_argument("--every", type=int, default=10, help="judge every k-th frame (default 10)")
    anim.add_argument("--order", type=int, default=4, help="SH order of the animation mode (default 4, as warpshade run)")
    anim.add_argument("--reuse-tolerances", default=None, metavar="RAD,...",
                      help="temporal reuse tolerances measured (default 0,0.05,0.1,0.2,0.5,1)")
    anim.add_argument("--reuse-chunk", type=int, default=None, metavar="FRAMES",
                      help="temporal reuse starts afresh every FRAMES frames, as in a run's chunks "
                           "(warpshade run --reuse-chunk; default: once, at frame 0)")
    anim.add_argument("--variant", action="append", default=[], metavar="KNOBS",
                      help="also measure hemiraster with these knobs and, with reuse=RAD, temporal reuse "
                           "(name=value,...; e.g. min_image=0,lut=96,reuse=2; repeatable)")
    anim.add_argument("--side", choices=("front", "back"), default="front",
                      help="a scene's front sides (default) or its back sides, judged at its two-sided members "
                           "(cloth), as warpshade run's back pass")
    anim.add_argument("--json", default=None, metavar="PATH", help="write the animation result as JSON")


def _animation(text: str) -> str:
    """An ``--animation`` value: a sequence name or a USD file that exists."""
    import argparse
    import os

    from ..bench.animation import ANIMATIONS, is_scene_path

    if text in ANIMATIONS or (is_scene_path(text) and os.path.isfile(text)):
        return text
    raise argparse.ArgumentTypeError(f"{text!r} is neither {' nor '.join(ANIMATIONS)} nor a USD file that exists")


def _cache_dir(text):
    """``--cache-dir``: absent, the ground truth's default (``reference`` in the user cache); ``none``: no cache."""
    from ..bench.reference_cache import DEFAULT_CACHE_DIR

    if text is None:
        return DEFAULT_CACHE_DIR
    return None if text.lower() == "none" else text


def _csv(text, conv=str):
    return None if text is None else [conv(x) for x in text.split(",") if x.strip()]


def run_animation(args) -> int:
    from ..bench.animation import DEFAULT_TOLERANCES, configurations, format_animation, parse_variant, run_animation
    from ..bench.report import write_json
    from ..bench.runner import machine_note

    for flag, value in (("--frames", args.frames), ("--every", args.every),
                        ("--reuse-chunk", 1 if args.reuse_chunk is None else args.reuse_chunk)):
        if value < 1:
            raise ValueError(f"{flag} must be >= 1, got {value}")
    tolerances = _csv(args.reuse_tolerances, float) or list(DEFAULT_TOLERANCES)
    configs = configurations(tolerances, variants=[parse_variant(v) for v in args.variant])
    result = run_animation(args.animation, frames=args.frames, every=args.every, order=args.order,
                           rays=args.ground_truth_rays or 4096, configs=configs, device=args.device,
                           chunk=args.reuse_chunk, side=args.side,
                           cache_dir=_cache_dir(args.cache_dir))
    result["machine"] = f"{machine_note()}; wall and process CPU time of update() per frame, compile excluded"
    print(format_animation(result))
    print(result["machine"])
    if args.json:
        write_json(args.json, result, indent=2)
        print(f"-> {args.json}")
    return 0


def run(args) -> int:
    if args.animation:
        return run_animation(args)
    if not args.out:
        raise ValueError("warpshade bench: --out DIR is required (except with --animation)")
    from ..bench import BenchSettings, run_bench
    from ..bench.report import format_table, frontier_from_results, plot_pareto, write_csv, write_json
    from ..bench.runner import machine_note

    orders = _csv(args.orders, int)
    settings = BenchSettings.for_mode(
        args.quick, methods=_csv(args.methods), meshes=_csv(args.meshes), orders=tuple(orders) if orders else None,
        repeat=args.repeat, ground_truth_rays=args.ground_truth_rays, device=args.device)
    # set apart: for_mode drops None overrides, and None (``--cache-dir none``) means no cache
    settings = dataclasses.replace(settings, cache_dir=_cache_dir(args.cache_dir))
    os.makedirs(args.out, exist_ok=True)
    t0 = time.perf_counter()
    records = run_bench(settings)
    wall = time.perf_counter() - t0
    mode = ("QUICK sweep: small meshes, few configurations, ground truth at "
            f"{settings.ground_truth_rays} rays — for smoke-testing, not for the committed results"
            if args.quick else f"full sweep, ground truth at {settings.ground_truth_rays} rays")
    note = f"{mode}; {machine_note()}; medians of up to {settings.repeat} runs after warm-up, compile excluded"
    write_json(os.path.join(args.out, "results.json"), records)
    write_csv(os.path.join(args.out, "results.csv"), records)
    plot_pareto(os.path.join(args.out, "pareto.png"), records, title=note)
    if args.frontier:
        os.makedirs(os.path.dirname(os.path.abspath(args.frontier)), exist_ok=True)
        write_json(args.frontier, {**frontier_from_results(records), "machine": note}, indent=2)
    print(format_table(records))
    print(f"\n{note}\n{len(records)} configurations in {wall:.1f} s -> {args.out}/results.json, results.csv, pareto.png"
          + (f", {args.frontier}" if args.frontier else ""))
    failed = [r for r in records if "failed" in r]
    if failed:
        print(f"{len(failed)} configuration(s) failed (recorded with 'failed')", file=sys.stderr)
    return 0
