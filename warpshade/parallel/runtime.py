"""Warp start-up as every warpshade process (the CLI, a worker) does it: once, quietly.

Warp's native library prints ``Warp CUDA warning: Could not find or load the NVIDIA CUDA driver``
to the C ``stderr`` when it initialises on a machine without a GPU driver. warpshade shades on the
CPU, so on such a machine that line is noise, and a run printed it once per worker process.
:func:`init_warp` initialises Warp with file descriptor 2 captured and passes every other line of
what Warp printed through to ``stderr`` unchanged; ``warpshade info`` still reports the devices.
"""

from __future__ import annotations

import os
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
