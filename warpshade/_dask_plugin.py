"""Dask worker plugin for :mod:`warpshade.parallel` (kept apart so importing warpshade never imports dask)."""

from distributed import WorkerPlugin

from .parallel import _WORKER_BUILD_ERRORS, _WORKER_SHADERS, _init_worker


class ShaderPlugin(WorkerPlugin):
    """Builds the shading spec once when a worker joins (also workers that join later)."""

    idempotent = False

    def __init__(self, token: str, spec):
        self.token = token
        self.spec = spec

    def setup(self, worker):
        _init_worker(self.token, self.spec)

    def teardown(self, worker):
        _WORKER_SHADERS.pop(self.token, None)
        _WORKER_BUILD_ERRORS.pop(self.token, None)
