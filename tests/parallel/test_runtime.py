"""Warp start-up (warpshade.parallel.runtime): the CPU-only CUDA-driver notice is dropped, nothing else;
processes take turns compiling a module missing from the kernel cache, and wait for nothing when it is there."""

import os
import subprocess
import sys
import threading
import time
from pathlib import Path

import helpers
import pytest
import warp as wp
from warpshade.parallel.runtime import MISSING_DRIVER_NOTICE, compile_lock_path, filter_startup_output, init_warp

try:
    import fcntl
except ImportError:  # Windows
    fcntl = None

REPO = Path(helpers.REPO)


def test_filter_drops_only_the_notice():
    other = b"Warp CUDA error: Failed to get driver entry point 'cuFoo' (CUDA error 1)\n"
    text = MISSING_DRIVER_NOTICE + b" GPU execution will not be available.\n" + other + b"last line"
    assert filter_startup_output(text) == other + b"last line"
    assert filter_startup_output(other) == other


def test_run_prints_no_cuda_driver_notice(tmp_path):
    """Parent and both workers initialise Warp through init_warp: the notice never reaches stderr.

    (On a machine with a CUDA driver Warp prints no such line at all, so this holds there too.)
    """
    out = tmp_path / "o.usda"
    proc = subprocess.run(
        [sys.executable, "-m", "warpshade", "run", str(REPO / "usd_scenes" / "cloth_sphere.usda"),
         "--frames", "2", "--workers", "2", "--out", str(out)],
        cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    assert "CUDA driver" not in proc.stderr, proc.stderr
    assert out.exists()


@wp.kernel
def _double(x: wp.array[float]):
    i = wp.tid()
    x[i] = 2.0 * x[i]


def _cold_module(tmp_path, monkeypatch):
    """``_double``'s module, unloaded, with an empty kernel cache in ``tmp_path``; its native compiles
    are recorded (``time.monotonic()`` of each ``build_cpu`` call) in the returned list."""
    from warp._src import build

    init_warp()
    monkeypatch.setattr(wp.config, "kernel_cache_dir", str(tmp_path))
    calls = []
    build_cpu = build.build_cpu

    def recorded(*args, **kwargs):
        calls.append(time.monotonic())
        return build_cpu(*args, **kwargs)

    monkeypatch.setattr(build, "build_cpu", recorded)
    module = _double.module
    module.unload()
    return module, calls


def _held_lock(module):
    """Hold ``module``'s compile lock from here, as another process compiling it would."""
    path = compile_lock_path(os.path.join(wp.config.kernel_cache_dir, module.get_module_identifier()))
    fd = os.open(path, os.O_RDWR | os.O_CREAT)
    fcntl.flock(fd, fcntl.LOCK_EX)
    return fd


@pytest.mark.skipif(fcntl is None, reason="no fcntl: compile_one_at_a_time locks nothing on this OS")
def test_missing_module_waits_for_the_lock(tmp_path, monkeypatch):
    # another process holds the lock of a module missing from the cache: this one compiles it only after
    # that lock is released (without compile_one_at_a_time it compiles at once, a second before)
    module, calls = _cold_module(tmp_path, monkeypatch)
    fd = _held_lock(module)
    loader = threading.Thread(target=module.load, args=("cpu",))
    loader.start()
    loader.join(1.0)
    released = time.monotonic()
    os.close(fd)
    loader.join(120)
    assert not loader.is_alive()
    assert len(calls) == 1 and calls[0] >= released, "compiled while another process held the lock"


@pytest.mark.skipif(fcntl is None, reason="no fcntl: compile_one_at_a_time locks nothing on this OS")
def test_cached_module_ignores_the_lock(tmp_path, monkeypatch):
    # a warm cache waits for nothing: with the module's binary in the cache, loading it again (a new
    # process would) does not wait for the lock another process holds, and compiles nothing
    module, calls = _cold_module(tmp_path, monkeypatch)
    module.load("cpu")
    assert len(calls) == 1
    module.unload()
    fd = _held_lock(module)
    try:
        loader = threading.Thread(target=module.load, args=("cpu",))
        loader.start()
        loader.join(60)
        assert not loader.is_alive(), "a cached module waited for the compile lock"
    finally:
        os.close(fd)
        loader.join(60)
    assert len(calls) == 1
