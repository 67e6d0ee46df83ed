"""The ``warpshade`` command's start-up guard: Ctrl-C while ``import warpshade`` runs is answered with one
line and exit code 130, not the import machinery's traceback. Standard library only, so that it is in
place before anything heavy loads."""

from __future__ import annotations

import os
import signal
import sys


def launched_as_command() -> bool:
    """Whether this process is the ``warpshade`` command: ``python -m warpshade`` or the console script
    (not a program importing the package, not a worker process)."""
    argv = list(getattr(sys, "orig_argv", []))
    for i, a in enumerate(argv[:-1]):
        if a == "-m" and argv[i + 1] in ("warpshade", "warpshade.cli"):
            return True
        if a in ("-mwarpshade", "-mwarpshade.cli"):
            return True
    return os.path.basename(sys.argv[0] if sys.argv else "").removesuffix(".exe") == "warpshade"


def _interrupted_while_loading(signum, frame) -> None:
    """SIGINT before the command has started: nothing is written yet, so say so in one line and exit
    at once with 130 (a KeyboardInterrupt here would print the import machinery's traceback)."""
    try:
        os.write(2, b"warpshade: interrupted\n")
    except OSError:
        pass
    os._exit(128 + signal.SIGINT)


def guard_startup() -> None:
    """In the ``warpshade`` command, answer Ctrl-C during ``import warpshade`` with one line and exit
    code 130. :func:`end_startup_guard` hands SIGINT back to Python once the command catches it."""
    if launched_as_command() and signal.getsignal(signal.SIGINT) is signal.default_int_handler:
        signal.signal(signal.SIGINT, _interrupted_while_loading)


def end_startup_guard() -> None:
    """Restore Python's SIGINT handler (KeyboardInterrupt) if :func:`guard_startup` replaced it."""
    if signal.getsignal(signal.SIGINT) is _interrupted_while_loading:
        signal.signal(signal.SIGINT, signal.default_int_handler)
