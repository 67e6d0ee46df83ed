"""Dask worker plugin for :mod:`warpshade.parallel` (kept apart so importing warpshade never imports dask)."""

from distributed import WorkerPlugin

from .worker import WORKER_BUILD_ERRORS, WORKER_SHADERS, init_worker


class ShaderPlugin(WorkerPlugin):
    """Builds the shading spec once when a worker joins (also workers that join later)."""

    idempotent = False

    def __init__(self, token: str, spec):
        self.token = token
        self.spec = spec

    def setup(self, worker):
        init_worker(self.token, self.spec)

    def teardown(self, worker):
        WORKER_SHADERS.pop(self.token, None)
        WORKER_BUILD_ERRORS.pop(self.token, None)
