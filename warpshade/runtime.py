"""Warp start-up as every warpshade process (the CLI, a worker) does it: once, quietly.

Warp's native library prints ``Warp CUDA warning: Could not find or load the NVIDIA CUDA driver``
to the C ``stderr`` when it initialises on a machine without a GPU driver. warpshade shades on the
CPU, so on such a machine that line is noise, and a run printed it once per worker process.
:func:`init_warp` initialises Warp with file descriptor 2 captured and passes every other line of
what Warp printed through to ``stderr`` unchanged; ``warpshade info`` still reports the devices.
"""

from __future__ import annotations

import os
import signal
import sys
import tempfile

#: The one native start-up line that :func:`init_warp` drops (warp-lang 1.19, ``cuda_util.cpp``).
_initialised = False

MISSING_DRIVER_NOTICE = b"Warp CUDA warning: Could not find or load the NVIDIA CUDA driver."


def filter_startup_output(text: bytes) -> bytes:
    """``text`` without the missing-CUDA-driver notice lines; every other line is kept."""
    lines = text.splitlines(keepends=True)
    return b"".join(line for line in lines if not line.startswith(MISSING_DRIVER_NOTICE))


def init_warp() -> None:
    """Initialise Warp once: warnings and errors only, no CUDA-driver notice on CPU-only machines."""
    import warp as wp

    wp.config.log_level = wp.LOG_WARNING  # stdout carries results: no init banner, no module-load lines
    global _initialised
    if _initialised:
        return
    _initialised = True  # wp.init() itself is idempotent; this only saves the capture
    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):  # no usable file descriptor 2 (embedded interpreters)
        wp.init()
        return
    with tempfile.TemporaryFile() as captured:
        os.dup2(captured.fileno(), 2)
        try:
            wp.init()
        finally:
            os.dup2(saved, 2)
            os.close(saved)
        captured.seek(0)
        rest = filter_startup_output(captured.read())
    if rest:
        sys.stderr.buffer.write(rest) if hasattr(sys.stderr, "buffer") else sys.stderr.write(rest.decode())
        sys.stderr.flush()


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
