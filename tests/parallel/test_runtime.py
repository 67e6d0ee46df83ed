"""Warp start-up (warpshade.parallel.runtime): the CPU-only CUDA-driver notice is dropped, nothing else."""

import subprocess
import sys
from pathlib import Path

import helpers
from warpshade.parallel.runtime import MISSING_DRIVER_NOTICE, filter_startup_output

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
