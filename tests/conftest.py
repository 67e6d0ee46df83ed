"""Shared fixtures. Warp runs on the CPU device; meshes come from Warp's shipped assets and tiny fixtures."""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile

import numpy as np
import pytest
import warp as wp

wp.config.log_level = wp.LOG_WARNING  # no init banner or module-load lines

# the disk cache (warpshade._cache) of this test session: its own empty directory, so no test reads the
# user's cache or leaves entries there. The session's first process makes it and removes it at exit; pytest-xdist
# workers and subprocesses inherit it (the workers share its entries, e.g. the spheres' fitted log tables)
if os.environ.get("PYTEST_XDIST_WORKER") and os.environ.get("WARPSHADE_TEST_SESSION_CACHE"):
    os.environ["WARPSHADE_CACHE"] = os.environ["WARPSHADE_TEST_SESSION_CACHE"]
else:
    os.environ["WARPSHADE_CACHE"] = os.environ["WARPSHADE_TEST_SESSION_CACHE"] = tempfile.mkdtemp(prefix="warpshade-test-cache-")
    atexit.register(shutil.rmtree, os.environ["WARPSHADE_CACHE"], ignore_errors=True)

WARP_ASSETS = os.path.join(os.path.dirname(wp.__file__), "examples", "assets")


def warp_asset(name: str) -> str:
    """Path of a mesh Warp ships in ``warp/examples/assets`` (bunny.usd, bear.usd, square_cloth.usd...)."""
    path = os.path.join(WARP_ASSETS, name)
    if not os.path.isfile(path):
        pytest.fail(f"Warp asset {path} is missing: the warp-lang install is incomplete")
    return path


@pytest.fixture
def cache_root(tmp_path, monkeypatch):
    """An empty disk-cache root (warpshade._cache) for one test, with the per-process counters and warnings reset."""
    from warpshade import _cache

    root = tmp_path / "cache"
    monkeypatch.setenv(_cache.ENV, str(root))
    _cache.stats.clear()
    _cache._warned.clear()
    return root


@pytest.fixture
def rng():
    return np.random.default_rng(1234)


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory):
    """Frames of an uninterrupted single-process run of :data:`helpers.SCENE` (resume and fault tests compare
    against it, frame by frame)."""
    from helpers import COMMON, FRAMES, SCENE, frames_of
    from warpshade.cli import main

    out = tmp_path_factory.mktemp("full") / "full.usda"
    assert main(["run", SCENE, "--frames", str(FRAMES), "--out", str(out), "--workers", "0"] + COMMON) == 0
    return frames_of(out)
