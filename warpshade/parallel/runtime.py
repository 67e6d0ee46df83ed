"""Warp start-up as every warpshade process (the CLI, a worker) does it: once, quietly.

Warp's native library prints ``Warp CUDA warning: Could not find or load the NVIDIA CUDA driver``
to the C ``stderr`` when it initialises on a machine without a GPU driver. warpshade shades on the
CPU, so on such a machine that line is noise, and a run printed it once per worker process.
:func:`init_warp` initialises Warp with file descriptor 2 captured and passes every other line of
what Warp printed through to ``stderr`` unchanged; ``warpshade info`` still reports the devices.

:func:`init_warp` also makes the processes that share a kernel cache take turns compiling a module
that is missing from it (:func:`compile_one_at_a_time`): a run's workers shade with the same kernels,
which with an empty cache each would otherwise compile at the same time.
"""

from __future__ import annotations

import os
import re
import sys
import tempfile

#: The one native start-up line that :func:`init_warp` drops (warp-lang 1.19, ``cuda_util.cpp``).
_initialised = False

MISSING_DRIVER_NOTICE = b"Warp CUDA warning: Could not find or load the NVIDIA CUDA driver."


def filter_startup_output(text: bytes) -> bytes:
    """``text`` without the missing-CUDA-driver notice lines; every other line is kept."""
    lines = text.splitlines(keepends=True)
    return b"".join(line for line in lines if not line.startswith(MISSING_DRIVER_NOTICE))


def compile_lock_path(module_dir: str) -> str:
    """The lock file of a module's cache entry ``module_dir`` (``<kernel cache>/wp_<module>_<hash>``)."""
    return os.path.normpath(module_dir) + ".lock"


def compile_one_at_a_time() -> None:
    """Make this process compile a Warp module only while it holds the module's lock file
    (:func:`compile_lock_path`, an exclusive ``flock``), so that of the processes needing a module
    missing from the kernel cache one compiles it and the others wait, then load it from the cache.

    A module whose binary is in the cache is loaded without touching the lock (a warm run waits for
    nothing). Wraps ``warp``'s ``Module._compile`` (warp-lang 1.19), which after the lock is taken
    finds the binary another process compiled meanwhile and returns without compiling. Without
    ``fcntl`` (Windows) nothing changes. Idempotent.
    """
    try:
        import fcntl
    except ImportError:
        return
    from warp._src.context import Module

    compile_binary = Module._compile
    if getattr(compile_binary, "one_at_a_time", False):
        return

    def _compile(self, device=None, output_dir=None, output_name=None, *args, **kwargs):
        if output_dir is None or output_name is None or os.path.exists(os.path.join(output_dir, output_name)):
            return compile_binary(self, device, output_dir, output_name, *args, **kwargs)
        path = compile_lock_path(os.fspath(output_dir))
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX)
            return compile_binary(self, device, output_dir, output_name, *args, **kwargs)
        finally:
            os.close(fd)  # releases the lock; the empty lock file stays (removing it could race a waiter)

    _compile.one_at_a_time = True
    Module._compile = _compile


COMPILED_MODULE = re.compile(r"wp_warpshade\.[\w.]+_[0-9a-f]+")
"""A compiled warpshade module's directory in Warp's kernel cache, ``wp_<module>_<hash>`` (not a lock
file, not a build directory ``..._p<pid>_t<thread>`` still being written)."""


def kernel_cache_holds_warpshade() -> bool:
    """Whether Warp's kernel cache (``warp.config.kernel_cache_dir``, after :func:`init_warp`) holds any
    compiled warpshade module. False on a machine's (or a fresh ``WARP_CACHE_PATH``'s) first run, when
    the run's setup includes compiling every kernel it uses. A cache filled by another warpshade version also counts as holding them, though
    modules whose code changed compile again."""
    import warp as wp

    init_warp()
    try:
        names = os.listdir(wp.config.kernel_cache_dir)
    except (OSError, TypeError):  # no cache directory (yet): nothing is compiled
        return False
    return any(COMPILED_MODULE.fullmatch(n) for n in names)


def cuda_started() -> bool:
    """Whether Warp runs in this process with a CUDA device (a process forked from it could not use CUDA);
    False before :func:`init_warp`."""
    context = sys.modules.get("warp._src.context")
    runtime = getattr(context, "runtime", None)
    return runtime is not None and bool(getattr(runtime, "cuda_devices", ()))


def init_warp() -> None:
    """Initialise Warp once: warnings and errors only, no CUDA-driver notice on CPU-only machines, and
    modules missing from the kernel cache compiled by one process at a time (:func:`compile_one_at_a_time`)."""
    import warp as wp

    wp.config.log_level = wp.LOG_WARNING  # stdout carries results: no init banner, no module-load lines
    global _initialised
    if _initialised:
        return
    _initialised = True  # wp.init() itself is idempotent; this only saves the capture
    compile_one_at_a_time()
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
