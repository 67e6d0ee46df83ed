"""The worker side of :mod:`warpshade.parallel`: a spec's shader built once per worker, then frames.

A worker process (of the process pool or a Dask worker, through :mod:`.dask_plugin`) calls
:func:`init_worker` once with the run's token and spec; every frame task is then
:func:`shade_in_worker`. The state is per process, keyed by the run's token.
"""

from __future__ import annotations

import os
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


def init_worker_from_file(token: str, path: str, parent: int | None = None) -> None:
    """:func:`init_worker` with the spec read from ``path``, a pickle the parent wrote. A process pool sends
    its initializer's arguments through the pipe that starts each worker, and a worker that dies while
    it starts (a script without ``if __name__ == "__main__":`` runs itself again in it and fails) leaves
    the parent blocked for ever on a pipe fuller than its buffer: a path keeps that message small. A spec
    that cannot be read here (an object of the script's own) is kept for the first frame, as a build error."""
    import pickle

    try:
        with open(path, "rb") as f:
            spec = pickle.load(f)
    except Exception as exc:  # noqa: BLE001 - reported with the first frame, as a build failure
        if parent is not None:
            exit_with_parent(parent)
        WORKER_BUILD_ERRORS[token] = exc
        return
    init_worker(token, spec, parent)


def shade_in_worker(token: str, frame: int, geometry: FrameGeometry):
    """Shade ``frame`` with run ``token``'s shader; :class:`BuildFailed` when building it raised."""
    if token in WORKER_BUILD_ERRORS:
        raise BuildFailed(WORKER_BUILD_ERRORS[token])
    return WORKER_SHADERS[token](frame, geometry)


def shade_chunk(shade: ShadeFn, frames, geometries) -> list:
    """``shade``'s results for ``frames`` (consecutive, in order) after ``shade.reset()`` when it has one:
    a chunk's results depend on its frames alone, not on what the shader saw before."""
    reset = getattr(shade, "reset", None)
    if reset is not None:
        reset()
    return [shade(f, g) for f, g in zip(frames, geometries)]


def shade_chunk_in_worker(token: str, frames, geometries) -> list:
    """:func:`shade_chunk` with run ``token``'s shader; :class:`BuildFailed` when building it raised."""
    if token in WORKER_BUILD_ERRORS:
        raise BuildFailed(WORKER_BUILD_ERRORS[token])
    return shade_chunk(WORKER_SHADERS[token], frames, geometries)
