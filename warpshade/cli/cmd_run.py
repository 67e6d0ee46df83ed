"""``warpshade run``: simulate, shade and write a scene to USD (docs/conventions.md §5, §6)."""

from __future__ import annotations

import argparse
import os
import sys
import time

from ..pipeline.refine import describe as describe_refined, refine_receivers

HELP = "run a scene end to end (simulate, shade, write USD); no SCENE runs the shipped default scene"
ACCEPTS_EXTRA = True  # method knobs, parsed once --method is known


def shipped_scene(name: str = "default.usda") -> str:
    """Path of a scene in the repository's ``usd_scenes/``."""
    here = os.path.dirname(os.path.abspath(__file__))
    return os.path.normpath(os.path.join(here, "..", "..", "usd_scenes", name))


def add_refine_argument(parser: argparse.ArgumentParser) -> None:
    """``--refine-receivers`` (shared by ``run`` and ``plan``, so the plan prices what the run shades)."""
    parser.add_argument("--refine-receivers", default="auto", metavar="EDGE|auto|off",
                        help="subdivide coarse static meshes to this edge length [scene units] so shadows have "
                             "vertices to fall on (default auto: the scene's warpshade:refineEdge, else 1/12 of "
                             "the scene's diagonal; off: never)")


def add_two_sided_argument(parser: argparse.ArgumentParser) -> None:
    """``--two-sided`` (shared by ``run`` and ``plan``, so the plan prices the back sides the run shades)."""
    from ..pipeline.shading import TWO_SIDED_MODES

    parser.add_argument("--two-sided", choices=TWO_SIDED_MODES, default="auto",
                        help="shade each side of thin surfaces with its own transfer and write a back-side mesh "
                             "(default auto: objects with warpshade:twoSided, else cloth; on: every object; off: none)")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    add_refine_argument(parser)
    from ..visibility import METHODS

    parser.add_argument("scene", nargs="?", default=None, metavar="SCENE",
                        help="USD scene (default: usd_scenes/default.usda)")
    parser.add_argument("--out", default=None, metavar="OUT.usda",
                        help="output (default: <scene name>_shaded.usda in the current directory)")
    parser.add_argument("--frames", type=int, default=None, help="frames to produce (default: the scene's)")
    parser.add_argument("--method", default=None, choices=sorted(METHODS) + ["none"],
                        help="visibility method for every object (default: the scene's, else the fastest accurate one)")
    parser.add_argument("--order", type=int, default=None, help="SH order (default: the scene's warpshade:order, else 4)")
    parser.add_argument("--max-error", type=float, default=None,
                        help="error budget: per object, the fastest measured method within this mean transfer error "
                             "(warpshade.planner; ignored with --method)")
    parser.add_argument("--write-transfer", action="store_true",
                        help="also write primvars:warpshade:transfer (N*N floats per vertex per frame) for relighting")
    parser.add_argument("--chunk", type=int, default=64, help="frames per clip file (also the commit interval)")
    parser.add_argument("--workers", type=int, default=None,
                        help="shading worker processes while this one simulates (default: all cores; 0 shades inline)")
    parser.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                        help="shade on a Dask cluster ('local' starts one) instead of local processes")
    parser.add_argument("--between", choices=["spheres", "none"], default="spheres",
                        help="shadows between objects shaded by different methods: sphere sets (default) or none")
    parser.add_argument("--reflections", action="store_true", default=None,
                        help="add one bounce of diffuse reflection between all shaded objects (sphere sets, "
                             "thesis §4.3; default: the scene's warpshade:reflections, else off)")
    parser.add_argument("--no-reflections", dest="reflections", action="store_false",
                        help="no reflection bounce even if the scene asks for it")
    parser.add_argument("--reflection-spheres", type=int, default=15, metavar="N",
                        help="leaf spheres per object for the reflection bounce (default 15)")
    parser.add_argument("--albedo", default=None, metavar="A|R,G,B",
                        help="albedo of objects whose scene gives none (no material diffuseColor, no constant "
                             "displayColor); default 0.8")
    parser.add_argument("--area-lights", choices=["gears", "sh"], default="gears",
                        help="rect lights: exact irradiance with GEARS soft shadows (default) or projected to SH")
    parser.add_argument("--area-k", type=int, default=None, help="GEARS light samples per side (default 16)")
    add_two_sided_argument(parser)
    parser.add_argument("--resume", action="store_true",
                        help="continue an interrupted run: keep the frames OUT already holds, produce the rest")
    parser.add_argument("--no-progress", action="store_true", help="no progress bar")
    parser.add_argument("--device", default="cpu", help="Warp device (default cpu)")
    parser.epilog = "Method knobs (e.g. --rays for reference) follow --method; see docs/methods/ for each method's list."


def _reclaim_knob_value(args, method_cls) -> None:
    """Undo argparse giving a knob's value to the optional SCENE positional.

    Knobs are unknown to the main parser, so in ``warpshade run --method reference --rays 64`` the
    ``64`` looks like SCENE. The first knob flag in ``args.extra`` that lacks its value gets it back.
    """
    if args.scene is None or not args.extra:
        return
    p = argparse.ArgumentParser(add_help=False)
    method_cls.add_arguments(p)
    takes_value = {opt for a in p._actions if a.nargs != 0 for opt in a.option_strings}
    for k, tok in enumerate(args.extra):
        flag = tok.split("=", 1)[0]
        if flag in takes_value and "=" not in tok and (k + 1 == len(args.extra) or args.extra[k + 1].startswith("-")):
            args.extra.insert(k + 1, args.scene)
            args.scene = None
            return


def parse_albedo(text: str | None):
    """``--albedo`` value: ``A`` or ``R,G,B`` in [0, 1] -> float or (3,) list; None stays None."""
    if text is None:
        return None
    try:
        vals = [float(v) for v in text.split(",")]
    except ValueError:
        raise ValueError(f"--albedo: expected A or R,G,B numbers, got {text!r}") from None
    if len(vals) not in (1, 3) or not all(0.0 <= v <= 1.0 for v in vals):
        raise ValueError(f"--albedo: expected one or three values in [0, 1], got {text!r}")
    return vals[0] if len(vals) == 1 else vals


def run(args) -> int:
    from ..pipeline import Pipeline, check_output
    from ..usd import AnimationWriter, read_scene
    from . import exit_code, interrupted_by
    from .cmd_transfer import parse_knobs

    knobs = {}
    method = args.method
    if method not in (None, "none"):
        from ..visibility import get_method

        cls = get_method(method)
        _reclaim_knob_value(args, cls)
        knobs = parse_knobs(cls, args.extra)
    elif args.extra:
        raise ValueError(f"unknown option(s) {' '.join(args.extra)} (method knobs need --method)")
    t0 = time.perf_counter()
    scene_path = args.scene or shipped_scene()
    scene = read_scene(scene_path)
    refined = refine_receivers(scene, args.refine_receivers)  # before the plan, which prices it
    if refined:
        print(f"warpshade run: {describe_refined(refined)[2:]}", file=sys.stderr)
    if method == "none":
        method = None
        for o in scene.objects:  # unoccluded transfer for every object
            o.method = None
    if args.max_error is not None and method is None:
        from ..planner import apply_plan, make_plan

        scene.settings["order"] = args.order or scene.settings.get("order", 4)
        plan = make_plan(scene, max_error=args.max_error, between=None if args.between == "none" else args.between,
                         area_lights=args.area_lights, area_k=args.area_k or 16, two_sided=args.two_sided)
        apply_plan(scene, plan)
        print(plan.describe(), file=sys.stderr)
    out = args.out or f"{os.path.splitext(os.path.basename(scene_path))[0]}_shaded.usda"
    check_output(scene, out)
    load = time.perf_counter() - t0
    from ..parallel import default_workers

    workers = default_workers() if args.workers is None else args.workers
    reflections = args.reflections
    if reflections is None and scene.settings.get("reflections"):
        reflections = True
    if reflections:
        reflections = {"spheres": args.reflection_spheres}
    pipe = Pipeline(scene, frames=args.frames, method=method, knobs=knobs, order=args.order,
                    write_transfer=True if args.write_transfer else None, workers=workers,
                    scheduler=args.scheduler, device=args.device,
                    between=None if args.between == "none" else args.between,
                    reflections=reflections, albedo=parse_albedo(args.albedo), area_lights=args.area_lights,
                    area_knobs={} if args.area_k is None else {"k": args.area_k},
                    refine_receivers=args.refine_receivers, two_sided=args.two_sided)
    writer = AnimationWriter(out, fps=scene.fps, up_axis=scene.up_axis, meters_per_unit=scene.meters_per_unit,
                             chunk=args.chunk, resume=args.resume,
                             metadata={"scene": os.path.abspath(scene_path), "order": pipe.order,
                                       "groups": "; ".join(f"{g.method} {g.knobs}" for g in pipe.groups),
                                       "between": args.between, "area_lights": args.area_lights,
                                       "reflections": str(bool(pipe.reflections is not None))})
    if writer.resume_frame:
        print(f"warpshade run: resuming {writer.path} at frame {writer.resume_frame}", file=sys.stderr)
    try:
        report = pipe.run(writer, progress=not args.no_progress)
    except (KeyboardInterrupt, OSError) as exc:
        kept = writer.frames_committed
        where = (f"{kept} complete frames kept in {writer.path} (--resume continues it)" if kept
                 else "previous output (if any) left untouched")
        if isinstance(exc, OSError):
            print(f"warpshade run: error: {exc}\nwarpshade run: {where}", file=sys.stderr)
            return 1
        print(f"warpshade run: {interrupted_by(exc)}; {where}", file=sys.stderr)
        return exit_code(exc)
    report.seconds["load"] = load
    s = report.seconds
    resumed = f" (resumed at frame {report.resumed_from})" if report.resumed_from else ""
    print(f"warpshade run: {scene_path}: {report.frames} frames{resumed}, {report.vertices} shaded vertices, SH order {pipe.order}",
          file=sys.stderr)
    for g in report.groups:
        print(f"  shading group: {g}", file=sys.stderr)
    if report.area_lights:
        print(f"  rect lights: {report.area_lights}", file=sys.stderr)
    per = 1e3 / max(report.frames, 1)
    print(f"  load {s['load']:.2f} s | setup {s['setup']:.2f} s | simulate {s['simulate']:.2f} s "
          f"({s['simulate'] * per:.1f} ms/frame) | shade {s['shade']:.2f} s ({s['shade'] * per:.1f} ms/frame) | "
          f"write {s['write']:.2f} s ({s['write'] * per:.1f} ms/frame) | total {s['total'] + load:.2f} s",
          file=sys.stderr)
    print(f"  preview: warpshade preview {report.path} --contact-sheet : -o {os.path.splitext(report.path)[0]}.png",
          file=sys.stderr)
    print(report.path)
    return 0
