"""``warpshade run``: simulate, shade and write a scene to USD (docs/conventions.md §5, §6)."""

from __future__ import annotations

import argparse
import os
import shlex
import sys
import time

from ..pipeline.refine import describe as describe_refined, refine_receivers
from .cmd_transfer import knob_class, knob_methods  # noqa: F401 - --method's knobs, which warpshade.cli.main adds

HELP = "run a scene end to end (simulate, shade, write USD); no SCENE runs the shipped default scene"
ACCEPTS_EXTRA = True  # method knobs, parsed once --method is known


def shipped_scene(name: str = "default.usda") -> str:
    """Path of a shipped scene (``usd_scenes/``, installed as package data)."""
    from ..usd.shipped import shipped_scene as locate

    return locate(name)


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
    from ..visibility import METHODS, NO_METHOD
    from ..visibility.base import nonnegative_int, positive_int

    parser.add_argument("scene", nargs="?", default=None, metavar="SCENE",
                        help="USD scene (default: usd_scenes/default.usda)")
    parser.add_argument("-o", "--out", default=None, metavar="OUT.usda",
                        help="output (default: <scene name>_shaded.usda in the current directory)")
    parser.add_argument("--frames", type=positive_int, default=None, help="frames to produce (default: the scene's)")
    parser.add_argument("--method", default=None, choices=[*sorted(METHODS), NO_METHOD],
                        help="visibility method for every object (default: the scene's, else the fastest accurate one)")
    parser.add_argument("--order", type=int, default=None, help="SH order (default: the scene's warpshade:order, else 4)")
    parser.add_argument("--max-error", type=float, default=None,
                        help="error budget: per object, the fastest measured method within this mean transfer error "
                             "(warpshade.planner; ignored with --method)")
    parser.add_argument("--write-transfer", action="store_true",
                        help="also write primvars:warpshade:transfer (N*N floats per vertex per frame) for relighting")
    parser.add_argument("--chunk", type=positive_int, default=64, help="frames per clip file (also the commit interval)")
    parser.add_argument("--workers", type=nonnegative_int, default=None,
                        help="shading worker processes while this one simulates (default: all cores; 0 shades inline)")
    parser.add_argument("--scheduler", default=None, metavar="tcp://HOST:PORT",
                        help="shade on a Dask cluster ('local' starts one; tls://HOST:PORT with --tls-*) instead "
                             "of local processes; Dask sends pickles, which run code: only connect to a "
                             "scheduler you trust")
    for flag, what in (("--tls-ca-file", "CA certificate that signed the cluster's certificates"),
                       ("--tls-cert", "this client's certificate (may hold the key too)"),
                       ("--tls-key", "this client's private key")):
        parser.add_argument(flag, default=None, metavar="PEM", help=f"TLS to a tls:// --scheduler: {what}")
    parser.add_argument("--between", choices=["spheres", "none"], default="spheres",
                        help="shadows between objects shaded by different methods: sphere sets (default) or none")
    parser.add_argument("--reflections", action="store_true", default=None,
                        help="add one bounce of diffuse reflection between all shaded objects (sphere sets, "
                             "thesis §4.3; default: the scene's warpshade:reflections, else off)")
    parser.add_argument("--no-reflections", dest="reflections", action="store_false",
                        help="no reflection bounce even if the scene asks for it")
    parser.add_argument("--reflection-spheres", type=positive_int, default=15, metavar="N",
                        help="leaf spheres per object for the reflection bounce (default 15)")
    parser.add_argument("--albedo", default=None, metavar="A|R,G,B",
                        help="albedo of objects whose scene gives none (no material diffuseColor, no constant "
                             "displayColor); default 0.8")
    parser.add_argument("--area-lights", choices=["gears", "sh"], default="gears",
                        help="rect lights: exact irradiance with GEARS soft shadows (default) or projected to SH")
    from ..pipeline.config import DEFAULT_AREA_KNOBS

    parser.add_argument("--area-k", type=positive_int, default=None,
                        help=f"GEARS light samples per side (default {DEFAULT_AREA_KNOBS['k']})")
    add_two_sided_argument(parser)
    from ..pipeline.config import REUSE, REUSE_AUTO, REUSE_CHUNK

    parser.add_argument("--reuse", type=parse_reuse, default=REUSE_AUTO, metavar="RAD|off",
                        help="temporal reuse: recompute a vertex cluster's transfer only when geometry it sees moved "
                             f"by more than this angle [rad] since its last computation; off: every frame (default "
                             f"{REUSE:g} where the method computes only the clusters due, hemiraster; else off)")

    parser.add_argument("--reuse-chunk", type=positive_int, default=None, metavar="FRAMES",
                        help="with temporal reuse: frames per chunk; a chunk is shaded in order by one worker and starts "
                             "with every vertex computed, so the output depends on this and not on --workers "
                             f"(default {REUSE_CHUNK})")
    parser.add_argument("--resume", action="store_true",
                        help="continue an interrupted run: keep the frames OUT already holds, produce the rest")
    bar = parser.add_mutually_exclusive_group()
    bar.add_argument("--no-progress", action="store_true", help="no progress bar")
    bar.add_argument("--progress", action="store_true",
                     help="a progress bar even when stderr is not a terminal (by default only on a terminal: "
                          "in a log file its redraws would pile up)")
    parser.add_argument("--device", default="cpu", help="Warp device (default cpu)")


SETUP_NOTICE_SECONDS = 10.0
"""An estimated setup at least this long [s] is announced before it starts."""


def setup_estimate(scene, method: str | None, knobs: dict, order: int, args, workers: int = 0) -> float | None:
    """The planner's estimate of the time before the run's first frame is in [s] for these settings
    (None if it cannot price them): the one-off setup, the first frame's shading and, with worker
    processes or a cluster, their start-up (:data:`~warpshade.parallel.WORKER_STARTUP_SECONDS`).

    The plan is made on a copy of the scene whose objects carry the run's method, so ``--method``
    is priced rather than the scene's own choice.
    """
    import dataclasses

    from ..planner import make_plan

    objects = [dataclasses.replace(o, method=method, knobs=dict(knobs)) if method else o for o in scene.objects]
    settings = dict(scene.settings)
    if method:
        settings.pop("max_error", None)  # a method on the command line is not the planner's to choose
    priced = dataclasses.replace(scene, objects=objects, settings=settings)
    try:
        plan = make_plan(priced, order=order, between=None if args.between == "none" else args.between,
                         area_lights=args.area_lights, area_k=args.area_k, two_sided=args.two_sided)
    except (ValueError, KeyError, OSError):  # no frontier record for these settings: no estimate
        return None
    from ..parallel import WORKER_STARTUP_SECONDS

    startup = WORKER_STARTUP_SECONDS if workers or args.scheduler else 0.0
    return plan.run_seconds_setup + plan.run_seconds_per_frame + startup


def show_progress(args) -> bool:
    """Whether ``warpshade run`` draws its progress bar: ``--progress`` or ``--no-progress`` if given, else
    only when stderr is a terminal."""
    if args.progress or args.no_progress:
        return bool(args.progress)
    return sys.stderr.isatty()


def parse_reuse(text: str):
    """A ``--reuse`` value: a tolerance [rad] (>= 0), ``off`` (None: every frame) or ``auto`` (the default,
    :func:`warpshade.pipeline.config.resolve_reuse`)."""
    from ..pipeline.config import REUSE_AUTO

    word = text.strip().lower()
    if word in ("off", "none"):
        return None
    if word == REUSE_AUTO:
        return REUSE_AUTO
    from ..visibility.reuse import check_tolerance

    try:
        return check_tolerance(word)
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected an angle >= 0 [rad], off or {REUSE_AUTO}, got {text!r}") from None


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
    # the pool warpshade.cli.main started before Warp and this parser, if any: ended on the way out by
    # main, whatever happens here; adopted below if it is the one these flags ask for
    early = getattr(args, "early_pool", None)
    from ..parallel import default_workers
    from .cmd_transfer import parse_knobs
    from .run_pool import adopt

    method = args.method
    if args.extra and method is None:
        raise ValueError(f"unknown option(s) {' '.join(args.extra)} (not an option of warpshade run, and method "
                         f"knobs need --method; warpshade run --help lists its options and each method's knobs)")
    knobs = parse_knobs(args)
    security = None
    if args.scheduler and args.scheduler != "local":
        from ..parallel.cluster import scheduler_security

        security = scheduler_security(args.scheduler, args.tls_ca_file, args.tls_cert, args.tls_key)
    elif args.tls_ca_file or args.tls_cert or args.tls_key:
        raise ValueError("--tls-ca-file/--tls-cert/--tls-key need --scheduler tls://HOST:PORT")
    if args.reuse_chunk is not None and args.reuse is None:
        raise ValueError("--reuse-chunk needs temporal reuse (not --reuse off)")
    workers = default_workers() if args.workers is None else args.workers
    pool = adopt(early, workers, method, args.scheduler)
    try:
        return _run(args, method, knobs, security, workers, pool)
    finally:
        if pool is not None:  # closed by the run once it took the pool; here after an error before that
            pool.close(abandon=True)


def _run(args, method, knobs, security, workers: int, pool) -> int:
    from ..parallel import FrameShadingError
    from ..pipeline import Pipeline, check_output
    from ..pipeline.config import reuse_text
    from ..usd import AnimationWriter, read_scene
    from . import exit_code, interrupted_by

    t0 = time.perf_counter()
    scene_path = args.scene or shipped_scene()
    scene = read_scene(scene_path)
    refined = refine_receivers(scene, args.refine_receivers)  # before the plan, which prices it
    if refined:
        print(f"warpshade run: {describe_refined(refined)[2:]}", file=sys.stderr)
    if args.max_error is not None and method is None:  # --method (NO_METHOD too) is every object's
        from ..planner import apply_plan, make_plan

        plan = make_plan(scene, max_error=args.max_error, order=args.order,
                         between=None if args.between == "none" else args.between,
                         area_lights=args.area_lights, area_k=args.area_k, two_sided=args.two_sided)
        apply_plan(scene, plan)
        print(plan.describe(), file=sys.stderr)
    out = args.out or f"{os.path.splitext(os.path.basename(scene_path))[0]}_shaded.usda"
    check_output(scene, out)
    load = time.perf_counter() - t0
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
                    refine_receivers=args.refine_receivers, security=security, two_sided=args.two_sided, reuse=args.reuse,
                    reuse_chunk=args.reuse_chunk)
    if pool is not None:
        pool.prepare(pipe.shader)  # the workers build while this process sets up the writer and simulates
    writer = AnimationWriter(out, fps=scene.fps, up_axis=scene.up_axis, meters_per_unit=scene.meters_per_unit,
                             chunk=args.chunk, resume=args.resume,
                             metadata={"scene": os.path.abspath(scene_path), "order": pipe.order,
                                       "groups": "; ".join(f"{g.method} {g.label}" for g in pipe.groups),
                                       "between": args.between, "area_lights": args.area_lights,
                                       "reflections": str(bool(pipe.reflections is not None)),
                                       "reuse": reuse_text(pipe.reuse, pipe.chunk)})
    estimate = setup_estimate(scene, method, knobs, pipe.order, args, workers)
    if pipe.compiles:
        import warp as wp

        print(f"warpshade run: Warp's kernel cache ({wp.config.kernel_cache_dir}) holds no warpshade kernels: "
              f"this first run compiles them during its setup, once (later runs load them from the cache)", file=sys.stderr)
    if estimate is not None and estimate >= SETUP_NOTICE_SECONDS:
        print(f"warpshade run: setup estimated at {estimate:.1f} s (warpshade plan prices it) before the first "
              f"frame; Ctrl-C stops it", file=sys.stderr)
    if writer.resume_frame:
        print(f"warpshade run: resuming {writer.path} at frame {writer.resume_frame}", file=sys.stderr)
    try:
        report = pipe.run(writer, progress=show_progress(args), setup_estimate=estimate, pool=pool)
    except (KeyboardInterrupt, OSError, FrameShadingError) as exc:
        kept = writer.frames_committed
        where = (f"{kept} complete frames kept in {writer.path} (--resume continues it)" if kept
                 else "previous output (if any) left untouched")
        if not isinstance(exc, KeyboardInterrupt):
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
    print(f"  temporal reuse: {reuse_text(pipe.reuse, pipe.chunk)}", file=sys.stderr)
    per = 1e3 / max(report.frames, 1)
    print(f"  load {s['load']:.2f} s | setup {s['setup']:.2f} s | simulate {s['simulate']:.2f} s "
          f"({s['simulate'] * per:.1f} ms/frame) | shade {s['shade']:.2f} s ({s['shade'] * per:.1f} ms/frame) | "
          f"write {s['write']:.2f} s ({s['write'] * per:.1f} ms/frame) | total {s['total'] + load:.2f} s",
          file=sys.stderr)
    if report.compiled:
        print("  (this run compiled Warp's kernels: its setup and first frames include that; later runs skip it)",
              file=sys.stderr)
    if workers or args.scheduler:  # the sums can exceed the wall time: say so where they are printed
        where = "scheduler's workers" if args.scheduler else f"{workers} worker process{'es' if workers != 1 else ''}"
        print(f"  (setup and shade are summed over the {where}, which run beside the simulation; total is wall time from reading the scene)",
              file=sys.stderr)
    # a command to copy and paste: paths quoted for the shell (spaces, quotes)
    print(f"  preview: warpshade preview {shlex.quote(report.path)} --contact-sheet : "
          f"-o {shlex.quote(os.path.splitext(report.path)[0] + '.png')}", file=sys.stderr)
    print(report.path)
    return 0
