"""The ``warpshade`` command. Each subcommand lives in its own module ``cmd_<name>.py`` defining
``HELP`` (one line), ``add_arguments(parser)`` and ``run(args) -> int``; they are found by name,
so adding a subcommand touches no other file.
"""

from __future__ import annotations

import argparse
import gc
import importlib
import os
import pkgutil
import signal
import sys
import threading
import warnings

from .._startup import end_startup_guard
from ..parallel.runtime import init_warp
from .run_pool import early_pool


def _subcommands():
    pkg = sys.modules[__name__]
    for info in sorted(pkgutil.iter_modules(pkg.__path__), key=lambda i: i.name):
        if info.name.startswith("cmd_"):
            yield info.name[4:], f"{__name__}.{info.name}"


def build_parser() -> argparse.ArgumentParser:
    from .. import __version__

    parser = argparse.ArgumentParser(prog="warpshade", description="Warp cloth/character simulation, SH soft shadows, USD export.")
    parser.add_argument("--version", action="version", version=f"warpshade {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, modname in _subcommands():
        mod = importlib.import_module(modname)
        p = sub.add_parser(name, help=mod.HELP, description=mod.HELP)
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run, _extra_ok=getattr(mod, "ACCEPTS_EXTRA", False),
                       _knob_class=getattr(mod, "knob_class", None), _knob_methods=getattr(mod, "knob_methods", None),
                       _parser=p)
    parser.commands = sub.choices
    return parser


class Terminated(KeyboardInterrupt):
    """SIGTERM (or SIGHUP) arrived: handled like Ctrl-C, so finished work is kept."""

    def __init__(self, signum: int):
        super().__init__(signum)
        self.signum = signum


def _raise_terminated(signum, frame):
    raise Terminated(signum)


def interrupted_by(exc: BaseException) -> str:
    """``"interrupted"`` or ``"terminated (SIGTERM)"`` for a :class:`KeyboardInterrupt`."""
    if isinstance(exc, Terminated):
        return f"terminated ({signal.Signals(exc.signum).name})"
    return "interrupted"


def exit_code(exc: BaseException) -> int:
    """Shell convention: 128 + the signal number (130 for Ctrl-C, 143 for SIGTERM)."""
    return 128 + (exc.signum if isinstance(exc, Terminated) else signal.SIGINT)


def _describe_knobs(sub: argparse.ArgumentParser) -> None:
    """For ``--help`` without ``--method``: every method's knob flags with their defaults, as the epilog
    of a subcommand taking method knobs (from each method's ``KNOBS``, through its ``knob_summary``)."""
    import textwrap

    knob_class = sub.get_default("_knob_class")
    head = (f"method knobs: after --method NAME, its own flags; '{sub.prog} --method NAME --help' gives each "
            "knob's meaning and allowed values. Defaults:")
    lines = textwrap.wrap(head, 100, break_on_hyphens=False)
    for name in sub.get_default("_knob_methods")():
        cls = knob_class(name)
        text = cls.knob_summary() if cls is not None and cls.knob_flags() else "no knobs"
        # lines break only between knobs: a no-break space inside each knob's entry, back to spaces after
        text = ", ".join(item.replace(" ", "\xa0") for item in text.split(", "))
        lines += [line.replace("\xa0", " ") for line in
                  textwrap.wrap(f"{name}: {text}", 100, initial_indent="  ", subsequent_indent="      ",
                                break_on_hyphens=False)]
    sub.epilog = "\n".join(lines)
    sub.formatter_class = argparse.RawDescriptionHelpFormatter


def _add_knobs(sub: argparse.ArgumentParser, knob_class) -> None:
    """Add ``knob_class``'s knob flags to a subcommand's parser, once, as a group of their own in ``--help``."""
    if getattr(sub, "knob_class", None) is knob_class:
        return
    if getattr(sub, "knob_class", None) is not None:  # a parser holds one method's knobs
        sub.error(f"--method read as both {sub.knob_class.name} and {knob_class.name}")
    knob_class.add_arguments(sub.add_argument_group(f"knobs of --method {knob_class.name}"))
    sub.knob_class = knob_class
    sub.epilog = f"other methods' knobs: {sub.prog} --help"


def _prepare_help(parser: argparse.ArgumentParser, argv: list[str]) -> None:
    """``--help`` of a subcommand taking method knobs: with ``--method NAME`` (read from the command line as it
    stands), NAME's knob flags join the parser and are listed in full; without, each method's are summarised."""
    if not any(a in ("-h", "--help") for a in argv):
        return
    sub = parser.commands.get(next((a for a in argv if not a.startswith("-")), None))
    if sub is None or sub.get_default("_knob_class") is None:
        return
    method = None
    for i, a in enumerate(argv):
        if a == "--":
            break
        if a == "--method" and i + 1 < len(argv):
            method = argv[i + 1]
        elif a.startswith("--method="):
            method = a.split("=", 1)[1]
    cls = sub.get_default("_knob_class")(method) if method else None
    if cls is not None:
        _add_knobs(sub, cls)
    else:
        _describe_knobs(sub)


def _parse(parser: argparse.ArgumentParser, argv: list[str]) -> argparse.Namespace | None:
    """Parsed arguments (None without a subcommand), with ``extra`` and ``knob_class`` set.

    Subcommands with ACCEPTS_EXTRA = True get unrecognised flags as ``args.extra``; the rest
    reject them as usual. Method knobs depend on --method: once it is known, the method's flags
    join the subcommand's parser and the command line is parsed again, so argparse checks the
    knobs, names them and the command in errors, and never takes a knob's value for a positional.
    ``--help`` is answered during the first parse, so its knob listing is prepared before
    (:func:`_prepare_help`).
    """
    _prepare_help(parser, argv)
    args, extra = parser.parse_known_args(argv)
    if not getattr(args, "_run", None):
        return None
    knob_class = args._knob_class(args.method) if args._knob_class and getattr(args, "method", None) else None
    if knob_class is not None:
        _add_knobs(args._parser, knob_class)
        args, extra = parser.parse_known_args(argv)
    args.knob_class = knob_class
    if extra and not args._extra_ok:
        parser.error(f"unrecognized arguments: {' '.join(extra)}")
    args.extra = extra
    return args


def main(argv: list[str] | None = None, *, whole_process: bool = False) -> int:
    """Entry point of the ``warpshade`` console script (:func:`entry`, ``whole_process=True``: this call is
    what the process is for, and it ends when the call returns). In a whole process the objects alive once
    the command line is parsed, nearly all of them the imported modules' (Warp's kernels and their syntax
    trees, SciPy, ``pxr``), are taken out of the cyclic garbage collector's sight (:func:`gc.freeze`): they
    live until the process ends, and every full collection of the run would scan them again.
    ``warpshade run``'s forked workers inherit them frozen. A
    call from a longer-lived process (a script, the tests) freezes nothing."""
    argv = sys.argv[1:] if argv is None else list(argv)
    pool = None
    try:
        try:
            end_startup_guard()  # from here on Ctrl-C is a KeyboardInterrupt, answered below
            pool = early_pool(argv)  # `run`'s workers start beside Warp's start and the parser's imports
            init_warp()
            parser = build_parser()
            args = _parse(parser, argv)
            if whole_process:
                gc.freeze()
        except KeyboardInterrupt as exc:  # Ctrl-C while the kernels load or the flags are read
            print("warpshade: interrupted", file=sys.stderr)
            return exit_code(exc)
        if args is None:
            parser.print_help()
            return 2
        args.early_pool = pool  # the run adopts it or closes it (warpshade.cli.run_pool.adopt)
        return _run_command(args)
    finally:
        if pool is not None:  # no-op once the run closed it; here after a parse error, an exit, a signal
            pool.close(abandon=True)


def _run_command(args: argparse.Namespace) -> int:
    """Run the parsed subcommand: user errors and signals as one line and an exit code."""
    # warnings as one line naming the command (replacing formatwarning keeps pytest's recording)
    formatwarning = warnings.formatwarning
    warnings.formatwarning = lambda message, *_a, **_k: f"warpshade {args.command}: warning: {message}\n"
    previous = {}
    if threading.current_thread() is threading.main_thread():
        previous = {sig: signal.signal(sig, _raise_terminated) for sig in (signal.SIGTERM, signal.SIGHUP)}
    try:
        return int(args._run(args) or 0)
    except (ValueError, OSError) as exc:  # user errors: one clear line, no traceback
        print(f"warpshade {args.command}: error: {exc}", file=sys.stderr)
        return 1
    except KeyboardInterrupt as exc:  # Ctrl-C, SIGTERM: one line, no traceback
        print(f"warpshade {args.command}: {interrupted_by(exc)}", file=sys.stderr)
        return exit_code(exc)
    finally:
        warnings.formatwarning = formatwarning
        for sig, handler in previous.items():
            signal.signal(sig, handler)


def entry() -> None:
    """The ``warpshade`` console script and ``python -m warpshade``: :func:`main`, then exit.

    A run stopped by a signal (exit code >= 128) has committed its frames, stopped its workers and
    said so; it then exits at once, skipping the interpreter's shutdown: ``concurrent.futures`` joins
    its pool's manager thread at exit, and that thread can block forever reading a result a killed
    worker had half written.

    Otherwise the interpreter shuts down as usual (``atexit`` handlers, buffered streams, threads), except
    for the full garbage collection it would start with: every object still alive is frozen first
    (:func:`gc.freeze`), so it is not scanned: that collection, over a heap holding Warp's kernels, SciPy and
    ``pxr``, came after the command's output was written (docs/benchmarks/history.md, branch ``runcpu``); what
    it could free is memory the process returns as it exits anyway.
    """
    code = main(whole_process=True)
    if code >= 128:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    gc.freeze()
    sys.exit(code)


if __name__ == "__main__":
    entry()
