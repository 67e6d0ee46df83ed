"""Shading frames in parallel: worker processes, Dask clusters, and the start-up every process does.

* :mod:`.frames`: :func:`shade_frames` (ordered, back-pressured, retried) over the inline, process-pool
  (:class:`WorkerPool`, which can start before its spec is known) and Dask backends; :class:`TransferSpec`, a spec of one visibility method per mesh.
* :mod:`.worker`: the worker side (a spec built once per worker, then frames).
* :mod:`.dask_plugin`: the Dask worker plugin (imported only when a Dask backend is used).
* :mod:`.cluster`: connecting to a Dask scheduler safely, a loopback cluster for tests.
* :mod:`.runtime`: Warp start-up as every warpshade process (the CLI, a worker) does it.
"""

from .frames import (WORKER_STARTUP_SECONDS, ClusterWarning, FrameShadingError, TransferSpec, WorkerPool, default_workers,
                     shade_frames)
from .worker import FrameGeometry, FrameShaderSpec, ShadeFn

__all__ = ["ClusterWarning", "FrameGeometry", "FrameShaderSpec", "FrameShadingError", "ShadeFn", "TransferSpec",
           "default_workers", "shade_frames", "WorkerPool", "WORKER_STARTUP_SECONDS"]
