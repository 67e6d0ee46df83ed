"""``warpshade run``'s shading workers: forked once the parent has started Warp and imported the run's modules,
or, where they spawn, started first, before the parent starts Warp and builds its parser.

A spawned worker spends about 1 s of CPU starting (Warp, the pipeline's shading, the visibility method); the
parent, before it can read ``run``'s flags, spends about as long starting Warp and importing every subcommand
(``cmd_run`` pulls in the pipeline, ``warpshade.sh`` and SciPy). Where workers fork
(:func:`~warpshade.parallel.frames.can_fork`), the run starts its pool after those imports (:func:`adopt`, before
the scene is read), and each worker inherits them instead of paying them again. Elsewhere :func:`early_pool`
reads from the command line only what the pool depends on (``--workers``, ``--scheduler``, ``--method``), with
the standard library and the visibility registry, and starts the pool then, so the two overlap. The parse that
follows decides: the run :func:`adopt`\\ s the pool if it is the one that parse asks for, else closes it and
starts its own. This module imports nothing heavy (no Warp, no NumPy beyond :mod:`warpshade.parallel`'s).
"""

from __future__ import annotations

import argparse


def shading_preload(method: str | None) -> tuple[str, ...]:
    """Modules a run's workers import while they wait for the spec: the pipeline's shading and the
    visibility method (``method``; None: the default one; :data:`~warpshade.visibility.NO_METHOD`: no method)."""
    from ..visibility import METHODS, NO_METHOD, default_method

    preload = ["warpshade.pipeline.shading"]
    if method != NO_METHOD:
        preload.append(METHODS[method or default_method()].split(":")[0])
    return tuple(preload)


def start_pool(workers: int, method: str | None):
    """The run's shading workers, started before the scene is read (:class:`~warpshade.parallel.WorkerPool`):
    meanwhile they start Warp and import :func:`shading_preload`'s modules."""
    from ..parallel import WorkerPool

    return WorkerPool(workers, preload=shading_preload(method))


def _refuse(message: str):
    raise ValueError(message)


def _pool_flags() -> argparse.ArgumentParser:
    """The flags of ``run`` a worker pool depends on, as values only (``run``'s own parser checks them);
    it raises ValueError instead of printing a usage error."""
    parser = argparse.ArgumentParser(add_help=False, allow_abbrev=False, exit_on_error=False)
    parser.error = _refuse
    for flag in ("--workers", "--scheduler", "--method"):
        parser.add_argument(flag, default=None)
    return parser


def early_pool(argv: list[str]):
    """For ``warpshade run`` (``argv`` without the program name), the worker pool it will most likely
    use, started now; None where workers fork (the run forks them later, :func:`adopt`), for other commands,
    ``--help``, ``--workers 0``, ``--scheduler`` or flags this light read cannot take (abbreviated, malformed:
    ``run``'s parser then reports them). The run checks the guess (:func:`adopt`)."""
    if not argv or argv[0] != "run" or any(a in ("-h", "--help", "--version") for a in argv):
        return None
    from ..parallel.frames import can_fork

    if can_fork():
        return None
    try:
        flags, _ = _pool_flags().parse_known_args(argv[1:])
        from ..parallel import default_workers
        from ..visibility import METHODS, NO_METHOD

        workers = default_workers() if flags.workers is None else int(flags.workers)
        if workers < 1 or flags.scheduler is not None or flags.method not in (None, NO_METHOD, *METHODS):
            return None
    except (argparse.ArgumentError, ValueError):  # a flag without its value, a count that is no number
        return None
    return start_pool(workers, flags.method)


def adopt(pool, workers: int, method: str | None, scheduler: str | None):
    """The run's worker pool: ``pool`` (from :func:`early_pool`, or None) if it has ``workers`` workers
    preloading ``method``'s modules and no ``scheduler`` is asked for; else ``pool`` is closed and, when
    the run shades in local processes, a pool is started now."""
    if pool is not None:
        if not scheduler and pool.workers == workers and pool.preload == shading_preload(method):
            return pool
        pool.close(abandon=True)
    return start_pool(workers, method) if workers and not scheduler else None
