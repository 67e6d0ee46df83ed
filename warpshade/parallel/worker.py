"""The worker side of :mod:`warpshade.parallel`: a spec's shader built once per worker, then frames.

A Dask worker (through :mod:`.dask_plugin`) calls :func:`init_worker` once with the run's token and
spec. A process pool's worker starts before the spec exists (:func:`start_worker`: Warp and the modules
the build will need, paid in the worker when it is spawned, inherited when it is forked) and builds the
shader from the spec's file on its first task (:func:`build_from_file`). Every frame task is then :func:`shade_in_worker` (a chunk:
:func:`shade_chunk_in_worker`). The state is per process, keyed by the run's token.
"""

from __future__ import annotations

import os
import signal
from collections.abc import Callable
from typing import Any, Protocol

FrameGeometry = dict  # object name -> positions (V, 3) float32, plus optional extra arrays
ShadeFn = Callable[[int, FrameGeometry], Any]


class FrameShaderSpec(Protocol):
    """What a worker needs to shade frames: picklable, and ``build()`` returns the per-frame function.

    ``build()`` runs once per worker and constructs every static structure; the returned callable
    ``shade(frame, geometry) -> result`` is called for each frame. Results must be picklable. A shader
    that keeps state from one frame to the next has a ``reset()`` attribute, which :func:`shade_chunk`
    calls before the first frame of each chunk.
    """

    def build(self) -> ShadeFn: ...


WORKER_SHADERS: dict[str, ShadeFn] = {}
WORKER_BUILD_ERRORS: dict[str, Exception] = {}


class BuildFailed(Exception):
    """``spec.build()`` raised in a worker; ``args[0]`` is that exception (raised again in the caller)."""


def exit_with_parent(parent: int, interval: float = 0.5) -> None:
    """Start a daemon thread that ends this process as soon as process ``parent`` is gone.

    A worker must never outlive the run, whatever killed the run (SIGKILL included, when no
    clean-up code runs): once the parent dies this process is re-parented, ``os.getppid()``
    changes, and the thread exits the process (``os._exit`` works while the main thread is
    inside a kernel launch).
    """
    import threading
    import time

    def watch():
        while os.getppid() == parent:
            time.sleep(interval)
        os._exit(1)

    threading.Thread(target=watch, name="warpshade-parent-watchdog", daemon=True).start()


def import_modules(names: tuple[str, ...]) -> None:
    """Import the modules ``names`` names; one that fails to import is left to fail where it is used (a spec's
    ``build()`` imports it again and reports the error with the first frame)."""
    import importlib

    for name in names:
        try:
            importlib.import_module(name)
        except Exception:  # noqa: BLE001 - the build imports it again and reports the error with the first frame
            pass


FORK_BLOCKED_SIGNALS = frozenset(s for s in (signal.SIGINT, signal.SIGTERM, getattr(signal, "SIGHUP", None))
                                 if s is not None)
"""Signals blocked while a pool forks its workers (:class:`~warpshade.parallel.WorkerPool`): a forked worker
inherits the run's Python handlers (``warpshade run`` raises on SIGTERM and SIGHUP), which must not run in it;
:func:`start_worker` resets them, then takes SIGTERM and SIGHUP again. SIGINT stays blocked in every worker."""


def reset_signal_handlers() -> None:
    """The signal handlers a fresh interpreter has, in a worker forked from a process that installed its own:
    every handler installed from Python back to the default (SIGINT's to Python's, KeyboardInterrupt), then
    SIGTERM and SIGHUP unblocked (:data:`FORK_BLOCKED_SIGNALS`). A spawned worker has nothing to reset."""
    for sig in signal.valid_signals():
        try:
            handler = signal.getsignal(sig)
        except (OSError, ValueError):
            continue
        if callable(handler) and handler is not signal.default_int_handler:
            signal.signal(sig, signal.default_int_handler if sig == signal.SIGINT else signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, FORK_BLOCKED_SIGNALS - {signal.SIGINT})


def start_worker(parent: int | None = None, preload: tuple[str, ...] = ()) -> None:
    """A process pool's worker start-up, before any spec is known: the run's signal handlers reset
    (:func:`reset_signal_handlers`; a forked worker inherits them); with ``parent``, this process ends when
    process ``parent`` does; Warp is started and the modules ``preload`` names are imported (those a spec's
    ``build()`` will import, :func:`import_modules`). A worker forked from a process that had done both finds
    them done."""
    reset_signal_handlers()
    if parent is not None:
        exit_with_parent(parent)
    from .runtime import init_warp

    init_warp()
    import_modules(preload)


def init_worker(token: str, spec: FrameShaderSpec, parent: int | None = None) -> None:
    """Start Warp and build ``spec``'s shader for run ``token`` in this worker (a failure is kept for the
    first frame); with ``parent``, this process ends when process ``parent`` does."""
    if parent is not None:
        exit_with_parent(parent)
    from .runtime import init_warp

    init_warp()
    try:
        WORKER_SHADERS[token] = spec.build()
    except Exception as exc:  # noqa: BLE001 - kept for the first frame: an initializer that raises
        WORKER_BUILD_ERRORS[token] = exc  # breaks the pool, and the cause would read as a dead worker


def build_from_file(token: str, path: str) -> None:
    """Build run ``token``'s shader in this worker (:func:`init_worker`) from the spec pickled at ``path``,
    unless it is built already or its build failed. A process pool's worker starts before the spec exists
    (:func:`start_worker`) and builds on the first task naming ``path``; a path keeps the tasks small. A spec
    that cannot be read here (an object of the script's own) is kept for the first frame, as a build error."""
    if token in WORKER_SHADERS or token in WORKER_BUILD_ERRORS:
        return
    import pickle

    try:
        with open(path, "rb") as f:
            spec = pickle.load(f)
    except Exception as exc:  # noqa: BLE001 - reported with the first frame, as a build failure
        WORKER_BUILD_ERRORS[token] = exc
        return
    init_worker(token, spec)


def _shader(token: str, spec_file: str | None) -> ShadeFn:
    """Run ``token``'s shader, built first from ``spec_file`` if this worker has not built it yet;
    :class:`BuildFailed` when building it raised."""
    if spec_file is not None:
        build_from_file(token, spec_file)
    if token in WORKER_BUILD_ERRORS:
        raise BuildFailed(WORKER_BUILD_ERRORS[token])
    return WORKER_SHADERS[token]


def shade_in_worker(token: str, frame: int, geometry: FrameGeometry, spec_file: str | None = None):
    """Shade ``frame`` with run ``token``'s shader (built from ``spec_file`` first if needed, :func:`_shader`)."""
    return _shader(token, spec_file)(frame, geometry)


def shade_chunk(shade: ShadeFn, frames, geometries) -> list:
    """``shade``'s results for ``frames`` (consecutive, in order) after ``shade.reset()`` when it has one:
    a chunk's results depend on its frames alone, not on what the shader saw before."""
    reset = getattr(shade, "reset", None)
    if reset is not None:
        reset()
    return [shade(f, g) for f, g in zip(frames, geometries)]


def shade_chunk_in_worker(token: str, frames, geometries, spec_file: str | None = None) -> list:
    """:func:`shade_chunk` with run ``token``'s shader (built from ``spec_file`` first if needed, :func:`_shader`)."""
    return shade_chunk(_shader(token, spec_file), frames, geometries)
