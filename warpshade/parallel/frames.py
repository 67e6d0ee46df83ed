"""Shading frames on every core and on a Dask cluster, in order, with bounded memory and retries.

The simulation is sequential, but once it has produced a frame's geometry, shading that frame is
independent of every other frame. :func:`shade_frames` takes an iterator of ``(frame, geometry)``
pairs (the simulation, running in the calling process) and yields ``(frame, result)`` pairs in the
same order while worker processes shade ahead:

* **Back-pressure**: at most ``max_in_flight`` frames are submitted and not yet yielded, so memory
  stays bounded when shading falls behind, and the simulation pauses instead of racing ahead.
* **Static structures once per worker**: workers receive a picklable *spec* once and call its
  ``build()`` (LUTs, hierarchies, BVHs...) before their first frame; per frame they receive only
  geometry (NumPy arrays), never pickled Warp state. A :class:`WorkerPool` may be started before the
  spec exists (the ``warpshade`` command starts it before reading the scene), its workers starting
  Warp and importing meanwhile.
* **Faults**: a worker that dies mid-frame costs only a retry of the frames it had not returned;
  a frame that fails ``retries + 1`` times raises an error naming the frame.
* **Chunks** (``chunk=C``): frames ``kC .. kC+C-1`` go to one worker as one task, shaded in order after
  the built shader's ``reset()`` (when it has one). A shader that keeps state from frame to frame
  (temporal reuse) then gives results that depend on ``C`` alone: not on the number of workers, on
  which worker took which chunk, or on retries (a retried chunk is shaded again from its first frame).

Backends: ``workers=0`` shades inline (no processes); ``workers>=1`` uses a pool of worker processes
(:class:`WorkerPool`: forked where :func:`worker_start_method` allows, else spawned); ``scheduler="local"``
starts a local ``dask.distributed`` cluster with ``workers`` single-threaded worker processes, and
``scheduler="tcp://HOST:PORT"`` (``tls://`` with a ``security``) uses a running cluster.
"""

from __future__ import annotations

import contextlib
import logging
import multiprocessing as mp
import os
import pickle
import signal
import sys
import tempfile
import time
import uuid
from collections import deque
from collections.abc import Callable, Iterable, Iterator
from concurrent.futures import Future, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any

import numpy as np

from .runtime import cuda_started
from .worker import (FORK_BLOCKED_SIGNALS, BuildFailed, FrameGeometry, FrameShaderSpec, ShadeFn, build_from_file,
                     import_modules, shade_chunk, shade_chunk_in_worker, shade_in_worker, start_worker)


class FrameShadingError(RuntimeError):
    """Shading a frame failed (the message names the frame)."""


WORKER_STARTUP_SECONDS = 1.5
"""Start-up of a worker pool before its first frame [s]: spawning, importing Warp and loading the
kernels from a warm cache (``benchmarks/parallel.py`` prints it: 1.1-1.5 s for one worker, 1.4-1.5 s
for two, 1.5 s for a loopback Dask cluster, on the 2-core machine). Measured with spawned workers; forked
ones (:func:`worker_start_method`) skip the imports, not re-measured."""


def default_workers() -> int:
    """All cores available to this process."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not on Linux
        return max(1, os.cpu_count() or 1)


# -- backends ----------------------------------------------------------------------------------
@contextlib.contextmanager
def _sigint_blocked(signals=frozenset({signal.SIGINT})):
    """Block SIGINT (or ``signals``) in the calling thread for the duration.

    A process spawned or forked meanwhile inherits the blocked mask, so Ctrl-C (sent to the terminal's
    whole process group) never reaches it: the run ends its workers itself, instead of each printing a
    KeyboardInterrupt traceback. This process loses nothing: a signal is taken by another thread or
    stays pending until the mask is restored.
    """
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, set(signals))
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def can_fork() -> bool:
    """Whether :class:`WorkerPool` forks its workers on this platform: on Linux (where ``fork`` is safe
    for a process without other threads; macOS's system libraries are not, Windows has no fork)."""
    return sys.platform.startswith("linux") and "fork" in mp.get_all_start_methods()


def worker_start_method() -> str:
    """How a :class:`WorkerPool` started now in this process starts its workers: ``"fork"`` where it can
    (:func:`can_fork`) while this process runs no other Python thread (a lock another thread held would stay
    held in the child for ever) and no CUDA device (a forked child cannot use the parent's CUDA context);
    else ``"spawn"``. A forked worker inherits the imported modules and the started Warp instead of paying
    them again (a spawned one imports them: about 1 s of CPU each on the 2-core machine). Native threads
    that know about fork are allowed: OpenBLAS (NumPy's, SciPy's) stops its pool before a fork."""
    import threading

    if not can_fork() or threading.active_count() > 1 or cuda_started():
        return "spawn"
    return "fork"


def _in_main_thread() -> bool:
    import threading

    return threading.current_thread() is threading.main_thread()


class _InlineBackend:
    worker_errors: tuple = ()

    def __init__(self, spec: FrameShaderSpec, token: str):
        self._shade = spec.build()

    def submit(self, frame, geometry):
        return self._now(self._shade, frame, geometry)

    def submit_chunk(self, frames, geometries):
        return self._now(shade_chunk, self._shade, frames, geometries)

    @staticmethod
    def _now(fn, *args):
        fut = Future()
        try:
            fut.set_result(fn(*args))
        except Exception as exc:  # surfaced by .result() like the other backends
            fut.set_exception(exc)
        return fut

    def recover(self) -> bool:
        return False

    def close(self, abandon: bool = False):
        pass


def start_resource_tracker_quietly() -> None:
    """Start multiprocessing's resource tracker (if it is not running) with its stderr on /dev/null.

    A run stopped by a signal exits at once (:func:`warpshade.cli.entry` uses ``os._exit``), so its
    pool's semaphores are never finalized; the tracker unlinks them when the run's end closes its
    pipe, as it should, but also prints "leaked semaphore objects" warnings below the run's one-line
    message. Nothing else is printed by the tracker.
    """
    from multiprocessing import resource_tracker

    try:
        sys.stderr.flush()
        saved = os.dup(2)
    except (OSError, ValueError):  # no usable file descriptor 2
        resource_tracker.ensure_running()
        return
    devnull = os.open(os.devnull, os.O_WRONLY)
    try:
        os.dup2(devnull, 2)
        resource_tracker.ensure_running()
    finally:
        os.dup2(saved, 2)
        os.close(saved)
        os.close(devnull)


def _started() -> None:
    """A task that does nothing (:meth:`WorkerPool._new_pool` submits one per worker)."""


class WorkerPool:
    """Worker processes for :func:`shade_frames` (``pool=``), started before the spec they will shade with
    is known, at once: forked from this process where :func:`worker_start_method` allows, after it imports
    the modules ``preload`` names (those the spec's ``build()`` imports), so that the workers inherit them
    and Warp already started; else spawned, each starting Warp and importing them while this process goes
    on. :meth:`prepare` hands them the spec: each builds its shader as soon as it is free, before any frame
    is simulated. A pool serves one :func:`shade_frames` call, which closes it; :meth:`close` a pool no call
    took. Workers start with SIGINT blocked (Ctrl-C reaches the run only, which ends them), without the
    run's signal handlers, and end with this process, whatever ends it.

    Args:
        workers: Worker processes (>= 1).
        preload: Modules the workers import before the spec comes (in this process first, if they fork).

    ``start_method`` is how the current workers started (``"fork"`` or ``"spawn"``).
    """

    worker_errors = (BrokenProcessPool,)

    def __init__(self, workers: int, preload: tuple[str, ...] = ()):
        if int(workers) < 1:
            raise ValueError(f"a worker pool needs workers >= 1, got {workers}")
        self.workers, self.preload = int(workers), tuple(preload)
        self.spec = self.token = self.spec_file = None
        self.pool = self._new_pool()

    def prepare(self, spec: FrameShaderSpec) -> None:
        """Hand ``spec`` to the workers: pickled to a file (a path keeps every message to a worker small: a
        spec in the pipe that starts a worker blocked the run for ever when the worker died as it started),
        removed by :meth:`close`; each worker builds its shader from it on its first task, and one build
        task per worker is submitted now. A pool prepares one spec."""
        if self.spec is not None:
            raise ValueError("this worker pool has a spec already (a pool serves one run)")
        token = uuid.uuid4().hex[:12]
        fd, path = tempfile.mkstemp(prefix=f"warpshade-{token}-", suffix=".spec")
        try:
            with os.fdopen(fd, "wb") as f:
                pickle.dump(spec, f, protocol=pickle.HIGHEST_PROTOCOL)
        except BaseException:
            with contextlib.suppress(OSError):
                os.remove(path)
            raise
        self.spec, self.token, self.spec_file = spec, token, path
        self._submit_builds()

    def _submit_builds(self) -> None:
        """One build task per worker (a worker that takes a second one finds its shader built), so the
        workers build while the run simulates its first frames; a failed build is reported with a frame."""
        with _sigint_blocked(), contextlib.suppress(*self.worker_errors):
            for _ in range(self.workers):
                self.pool.submit(build_from_file, self.token, self.spec_file)

    def _new_pool(self):
        """A pool whose workers are all starting: a spawning pool starts a process per task submitted while
        none is idle, a forking pool all of them at its first task. A forking pool (:func:`worker_start_method`)
        imports ``preload`` here first, once, for every worker; a retry's pool spawns if this process has
        threads by then (the run's first pool's)."""
        start_resource_tracker_quietly()
        method = worker_start_method()
        if method == "fork":
            import_modules(self.preload)
            method = worker_start_method()  # an import may have started a thread or CUDA
        self.start_method = method
        pool = ProcessPoolExecutor(self.workers, mp_context=mp.get_context(method), initializer=start_worker,
                                   initargs=(os.getpid(), self.preload))
        with _sigint_blocked(FORK_BLOCKED_SIGNALS if method == "fork" else {signal.SIGINT}):
            for _ in range(self.workers):
                pool.submit(_started)
        return pool

    def _remove_spec_file(self) -> None:
        if self.spec_file is not None:
            with contextlib.suppress(OSError):
                os.remove(self.spec_file)

    def submit(self, frame, geometry):
        return self._submit(shade_in_worker, self.token, frame, geometry, self.spec_file)

    def submit_chunk(self, frames, geometries):
        return self._submit(shade_chunk_in_worker, self.token, frames, geometries, self.spec_file)

    def _submit(self, fn, *args):
        if len(self.pool._processes or {}) >= self.workers:
            return self.pool.submit(fn, *args)
        with _sigint_blocked():  # this submit may spawn a worker
            return self.pool.submit(fn, *args)

    def worker_pids(self) -> list[int]:
        """PIDs of the live worker processes (for tests and monitoring)."""
        return [p.pid for p in (self.pool._processes or {}).values()]

    def recover(self) -> bool:
        """A worker died and broke the pool: start a fresh one. Unfinished frames are lost (True)."""
        self.pool.shutdown(wait=False, cancel_futures=True)
        self.pool = self._new_pool()
        if self.spec is not None:
            self._submit_builds()
        return True

    def close(self, abandon: bool = False):
        try:
            self._close_pool(abandon)
        finally:
            self._remove_spec_file()

    def _close_pool(self, abandon: bool) -> None:
        if not abandon:
            self.pool.shutdown(wait=True, cancel_futures=True)
            return
        # Interrupted: do not wait for the frames being shaded. The workers are killed, so nothing
        # reads the task queue any more: its feeder thread must not be joined (with the pipe full it
        # would block forever, in shutdown or at interpreter exit), and the workers are reaped with a
        # bound, SIGKILL after SIGTERM.
        procs = list((self.pool._processes or {}).values())
        for p in procs:
            p.terminate()
        call_queue = getattr(self.pool, "_call_queue", None)
        if call_queue is not None:
            call_queue.cancel_join_thread()
        self.pool.shutdown(wait=False, cancel_futures=True)
        deadline = time.monotonic() + 5.0
        for p in procs:
            p.join(timeout=max(0.0, deadline - time.monotonic()))
            if p.is_alive():
                p.kill()
                p.join(timeout=1.0)


class ClusterWarning(UserWarning):
    """A Dask scheduler is reached in a way that exposes the run (see :mod:`warpshade.parallel.cluster`)."""


class _DaskBackend:
    def __init__(self, spec: FrameShaderSpec, token: str, workers: int, scheduler: str, retries: int,
                 security=None):
        import warnings

        from distributed import Client, LocalCluster
        from distributed.client import FutureCancelledError
        from distributed.scheduler import KilledWorker

        from .cluster import unencrypted_remote

        self.worker_errors = (KilledWorker, FutureCancelledError)
        self.cluster = None
        self.plugin = f"warpshade-{token}"
        if scheduler == "local":
            # Worker processes spawned while SIGINT is ignored start with it ignored (Python and
            # asyncio then install no KeyboardInterrupt handler): Ctrl-C reaches only this process,
            # which closes the cluster. A mask does not work here: Dask's threads that spawn the
            # workers run unblocked. Cost: a Ctrl-C during the cluster's start-up is dropped.
            previous = signal.signal(signal.SIGINT, signal.SIG_IGN) if _in_main_thread() else None
            try:
                # the cluster is the run's own: its workers' log lines would follow the run's last line
                # (a task cancelled by Ctrl-C; the scheduler gone with this process: "Failed to
                # communicate with scheduler during heartbeat", logged as an error), so only critical
                # ones print; a frame's error reaches the run through its future, a worker's failed
                # build through the plugin. No dashboard, and the scheduler's HTTP server on a free
                # loopback port: Dask's default 8787 may be taken (another cluster), which printed a
                # warning after the run's output
                self.cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                                            dashboard_address=None, silence_logs=logging.CRITICAL,
                                            scheduler_kwargs={"dashboard_address": "127.0.0.1:0"})
            finally:
                if previous is not None:
                    signal.signal(signal.SIGINT, previous)
            self.client = Client(self.cluster)
        else:
            if unencrypted_remote(scheduler):
                warnings.warn(f"scheduler {scheduler} is not on this machine and the connection is not "
                              "encrypted: Dask sends pickles, which run code, so anyone on the network path "
                              "can read frames or run code here; use tls:// (--tls-ca-file, --tls-cert, "
                              "--tls-key)", ClusterWarning, stacklevel=4)
            self.client = Client(scheduler, security=security)
        self.token = token
        self.retries = retries
        from .dask_plugin import ShaderPlugin

        self.client.register_plugin(ShaderPlugin(token, spec), name=self.plugin)

    def submit(self, frame, geometry):
        # Dask reschedules a task whose worker died by itself; retries covers exceptions on top.
        return self.client.submit(shade_in_worker, self.token, frame, geometry, pure=False,
                                  key=f"warpshade-{self.token}-{frame}-{uuid.uuid4().hex[:8]}")

    def submit_chunk(self, frames, geometries):
        return self.client.submit(shade_chunk_in_worker, self.token, frames, geometries, pure=False,
                                  key=f"warpshade-{self.token}-{frames[0]}-{frames[-1]}-{uuid.uuid4().hex[:8]}")

    def recover(self) -> bool:
        return False  # the scheduler keeps running tasks; only failed futures need resubmitting

    def close(self, abandon: bool = False):
        try:
            if self.cluster is None:  # a shared cluster: workers drop this run's shader (teardown)
                self.client.unregister_worker_plugin(self.plugin)
        except Exception:  # noqa: BLE001 - the scheduler may be gone already; closing must go on
            pass
        finally:
            self.client.close()
            if self.cluster is not None:
                self.cluster.close()


def _make_backend(spec, token, workers, scheduler, retries, security=None, pool: WorkerPool | None = None):
    if pool is not None:
        if pool.spec is not spec:
            pool.prepare(spec)
        return pool
    if scheduler:
        return _DaskBackend(spec, token, workers, scheduler, retries, security)
    if workers == 0:
        return _InlineBackend(spec, token)
    pool = WorkerPool(workers)
    try:
        pool.prepare(spec)
    except BaseException:
        pool.close(abandon=True)
        raise
    return pool


# -- the ordered, bounded loop -----------------------------------------------------------------
class _Task:
    """Frames submitted as one unit: one frame, or one chunk (shaded in order after a ``reset()``)."""

    __slots__ = ("frames", "geometries", "chunked")

    def __init__(self, pairs, chunked: bool):
        self.frames = tuple(f for f, _ in pairs)
        self.geometries = tuple(g for _, g in pairs)
        self.chunked = chunked

    @property
    def label(self) -> str:
        """``frame F`` or ``frames A-B``: how an error names the task."""
        a, b = self.frames[0], self.frames[-1]
        return f"frames {a}-{b}" if self.chunked and b != a else f"frame {a}"

    def submit(self, backend):
        if self.chunked:
            return backend.submit_chunk(self.frames, self.geometries)
        return backend.submit(self.frames[0], self.geometries[0])

    def results(self, result) -> list:
        return list(result) if self.chunked else [result]


def _tasks(frames: Iterator, chunk: int | None) -> Iterator[_Task]:
    """``frames`` as tasks: one per frame, or per chunk of frames ``f`` with the same ``f // chunk``."""
    if chunk is None:
        for pair in frames:
            yield _Task((pair,), False)
        return
    buf: list = []
    for f, g in frames:
        if buf and f // chunk != buf[0][0] // chunk:  # frames that skip: the chunk ends early
            yield _Task(buf, True)
            buf = []
        buf.append((f, g))
        if (f + 1) % chunk == 0:
            yield _Task(buf, True)
            buf = []
    if buf:
        yield _Task(buf, True)


def chunk_start(frame: int, chunk: int | None) -> int:
    """First frame of ``frame``'s chunk (``frame`` itself without chunks): where a run that must produce
    ``frame`` first (``--resume``) starts shading, so that its chunks are those of a whole run."""
    return frame if not chunk else frame - frame % int(chunk)


def shade_frames(
    spec: FrameShaderSpec,
    frames: Iterable[tuple[int, FrameGeometry]],
    workers: int | None = None,
    scheduler: str | None = None,
    max_in_flight: int | None = None,
    retries: int = 2,
    on_backend: Callable[[Any], None] | None = None,
    security=None,
    chunk: int | None = None,
    pool: WorkerPool | None = None,
) -> Iterator[tuple[int, Any]]:
    """Shade frames in parallel and yield ``(frame, result)`` in input order.

    Args:
        spec: Picklable :class:`FrameShaderSpec`; ``build()`` runs once per worker.
        frames: ``(frame, geometry)`` pairs, consumed lazily (at most ``max_in_flight`` ahead).
        workers: Worker processes; None means all cores; 0 shades inline in this process.
        scheduler: None for local processes, ``"local"`` for a local Dask cluster, or a Dask
            scheduler address ``tcp://HOST:PORT`` / ``tls://HOST:PORT``. An unencrypted address that
            is not loopback gives a :class:`ClusterWarning` (Dask's pickles run code; see
            :mod:`warpshade.parallel.cluster`).
        max_in_flight: Frames taken from ``frames`` and not yet yielded (default ``2 * workers``, at
            least 2, times ``chunk``; at least ``chunk``).
        retries: How often a frame (a chunk) is resubmitted after its worker died.
        on_backend: Called with the backend once it is up (tests use it to kill a worker).
        security: ``distributed.Security`` for a scheduler address (TLS certificates,
            :func:`warpshade.parallel.cluster.scheduler_security`); None uses Dask's configuration.
        chunk: None: every frame is a task of its own. Else frames ``f`` with the same ``f // chunk`` are
            one task, shaded in order by one worker after the shader's ``reset()`` (module doc). A chunk
            is submitted once all its frames are taken, and its frames are yielded once all are shaded.
        pool: Shade on this :class:`WorkerPool` (started earlier; ``workers`` and ``scheduler`` are then
            ignored), prepared with ``spec`` here unless it was already; the call closes it.

    Raises:
        FrameShadingError: naming the frame (the chunk), when shading raised or workers died too often.
    """
    workers = pool.workers if pool is not None else default_workers() if workers is None else int(workers)
    if workers < 0:
        raise ValueError(f"workers must be >= 0, got {workers}")
    if chunk is not None:
        chunk = int(chunk)
        if chunk < 1:
            raise ValueError(f"chunk must be >= 1 frames, got {chunk}")
    if pool is not None:
        scheduler = None
    if scheduler and workers == 0:
        workers = default_workers()
    size = chunk or 1
    max_in_flight = (max(2, 2 * max(workers, 1)) * size if max_in_flight is None
                     else max(int(max_in_flight), size))  # a whole chunk must fit
    token = uuid.uuid4().hex[:12]
    try:
        backend = _make_backend(spec, token, workers, scheduler, retries, security, pool)
    except BaseException:
        if pool is not None:
            pool.close(abandon=True)
        raise
    if on_backend is not None:
        on_backend(backend)
    it = _tasks(iter(frames), chunk)
    order: deque[int] = deque()
    pending: dict[int, list] = {}  # first frame -> [task, future, failures]
    ahead = 0  # frames taken and not yet yielded
    failed = False  # an error or interruption: close without waiting for frames being shaded
    shaded_any = False
    try:
        while True:
            while ahead + size <= max_in_flight:
                task = next(it, None)
                if task is None:
                    break
                key = task.frames[0]
                if key in pending:
                    raise ValueError(f"{task.label} submitted twice")
                pending[key] = [task, _submit(backend, task), 0]
                order.append(key)
                ahead += len(task.frames)
            if not order:
                return
            key = order[0]
            entry = pending[key]
            task = entry[0]
            try:
                result = entry[1].result()
            except backend.worker_errors as exc:
                _resubmit_failed(backend, order, pending, retries, exc, shaded_any)
                continue
            except BuildFailed as exc:  # the spec is wrong (e.g. a knob out of range): no retry helps
                raise exc.args[0] from None
            except Exception as exc:
                raise FrameShadingError(f"{task.label}: shading failed: {type(exc).__name__}: {exc}") from exc
            order.popleft()
            del pending[key]
            shaded_any = True
            for frame, res in zip(task.frames, task.results(result)):
                ahead -= 1
                yield frame, _aligned(res)
    except BaseException:
        failed = True
        raise
    finally:
        backend.close(abandon=failed)


def _aligned(result):
    """``result`` with every NumPy array in it (through dicts, lists and tuples) aligned and C-contiguous.

    Dask deserialises arrays as views into its receive buffers, at offsets that need not be aligned;
    such an array exports the buffer format ``'=f'`` instead of ``'f'``, which pxr's ``Vt`` refuses
    ("Unsupported format '=f'"). Aligned contiguous arrays are returned as they are (no copy).
    """
    if isinstance(result, np.ndarray):
        return np.require(result, requirements=("C", "A"))
    if isinstance(result, dict):
        return {k: _aligned(v) for k, v in result.items()}
    if type(result) in (list, tuple):
        return type(result)(_aligned(v) for v in result)
    return result


STARTUP_DEATHS_HINT = ("worker processes died before shading any frame; if this run comes from a Python script, "
                       "its top-level code must be under `if __name__ == \"__main__\":` (every worker process imports "
                       "the script, and one that starts a run there dies), and their own error is printed above")
"""Added to the error when workers died and no frame was shaded yet."""


def _resubmit_failed(backend, order, pending, retries, exc, shaded_any: bool = True):
    """After a worker death, resubmit every pending frame whose result is lost."""
    unfinished_lost = backend.recover()
    for f in order:
        entry = pending[f]
        fut = entry[1]
        if fut.done():
            lost = fut.cancelled() or fut.exception() is not None
        else:
            lost = unfinished_lost
        if not lost:
            continue
        entry[2] += 1
        if entry[2] > retries:
            hint = "" if shaded_any else f"; {STARTUP_DEATHS_HINT}"
            raise FrameShadingError(f"{entry[0].label}: worker died {entry[2]} times while shading it "
                                    f"(last: {type(exc).__name__}: {exc}){hint}") from exc
        entry[1] = _submit(backend, entry[0])


def _submit(backend, task: _Task):
    """``task`` submitted to ``backend``, or a future holding the error when a worker death has already
    broken the backend (a process pool refuses new work once it has seen a worker die): the task is then
    resubmitted like the others that death lost, when the loop reaches it."""
    try:
        return task.submit(backend)
    except backend.worker_errors as exc:
        fut = Future()
        fut.set_exception(exc)
        return fut


class TransferSpec:
    """Spec that computes SH transfer of deforming meshes with one visibility method per mesh.

    Args:
        meshes: Object name -> :class:`~warpshade.geometry.TriMesh` (topology and rest pose).
        method: Method name (``warpshade.visibility.METHODS``).
        order: SH order.
        knobs: Method keyword arguments.
        reuse: Temporal reuse tolerance [rad] (:class:`~warpshade.visibility.reuse.TemporalReuse`), or None.

    The built shader maps ``(frame, {name: points (V, 3)})`` to ``{name: transfer (V, N*N) float32}``;
    with ``reuse`` its ``reset()`` forgets the frames seen.
    """

    def __init__(self, meshes: dict, method: str = "reference", order: int = 5, knobs: dict | None = None,
                 reuse: float | None = None):
        self.meshes = dict(meshes)
        self.method = method
        self.order = order
        self.knobs = dict(knobs or {})
        self.reuse = reuse

    def build(self) -> ShadeFn:
        from ..visibility import get_method
        from ..visibility.reuse import with_reuse

        cls = get_method(self.method)
        methods = {name: with_reuse(cls(mesh, order=self.order, **self.knobs), self.reuse)
                   for name, mesh in self.meshes.items()}

        def shade(frame: int, geometry: FrameGeometry):
            # .numpy() of a CPU array is a view of memory the next frame overwrites: copy
            return {name: m.update(geometry[name]).numpy().copy() for name, m in methods.items()}

        if self.reuse is not None:
            def reset():
                for m in methods.values():
                    m.reset()

            shade.reset = reset
        return shade
