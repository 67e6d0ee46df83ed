"""``warpshade run --resume`` and ``--workers``: an interrupted run continues where it stopped, and the
result equals an uninterrupted single-process run frame by frame (issue 9)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from pxr import Usd

from helpers import COMMON, FRAMES, REPO, SCENE, InterruptingWriter, assert_same_frames, frames_of
from warpshade.cli import main
from warpshade.pipeline import Pipeline
from warpshade.usd import read_scene
from warpshade.usd.validate import validation_errors



def test_resume_after_interrupt_equals_uninterrupted_run(tmp_path, uninterrupted):
    out = tmp_path / "o.usda"
    scene = read_scene(SCENE)
    pipe = Pipeline(scene, frames=FRAMES, method="reference", knobs={"rays": 4}, order=2)
    with pytest.raises(KeyboardInterrupt):
        pipe.run(InterruptingWriter(str(out), chunk=2, at=3,
                                     metadata={"scene": os.path.abspath(SCENE), "order": 2}), progress=False)
    assert Usd.Stage.Open(str(out)).GetEndTimeCode() == 2  # frames 0..2 complete and kept
    assert main(["run", SCENE, "--frames", str(FRAMES), "--out", str(out), "--resume", "--workers", "0"] + COMMON) == 0
    assert_same_frames(frames_of(out), uninterrupted)
    assert validation_errors(out) == []


def test_killed_run_resumes_with_worker_processes(tmp_path, uninterrupted):
    """A hard kill (SIGKILL) mid-run, then --resume with 2 worker processes: nothing lost or duplicated."""
    out = tmp_path / "o.usda"
    cmd = [sys.executable, "-m", "warpshade", "run", SCENE, "--frames", str(FRAMES), "--out", str(out),
           "--workers", "0"] + COMMON
    env = dict(os.environ, PYTHONPATH=REPO + os.pathsep + os.environ.get("PYTHONPATH", ""))
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env)
    deadline = time.monotonic() + 300
    try:
        while time.monotonic() < deadline and proc.poll() is None:
            # kill once the first chunk (frames 0-1) is committed
            if out.exists() and Usd.Stage.Open(str(out)).GetEndTimeCode() >= 1:
                proc.send_signal(signal.SIGKILL)
                break
            time.sleep(0.05)
    finally:
        proc.wait(30)
    done = Usd.Stage.Open(str(out)).GetEndTimeCode()
    assert 1 <= done <= FRAMES - 1, f"the kill came too late to test anything (end frame {done})"
    assert main(["run", SCENE, "--frames", str(FRAMES), "--out", str(out), "--resume", "--workers", "2"] + COMMON) == 0
    assert_same_frames(frames_of(out), uninterrupted)


def test_resume_with_other_settings_is_an_error(tmp_path, capsys):
    out = tmp_path / "o.usda"
    assert main(["run", SCENE, "--frames", "2", "--out", str(out), "--workers", "0"] + COMMON) == 0
    args = ["run", SCENE, "--frames", "4", "--out", str(out), "--resume", "--workers", "0",
            "--method", "reference", "--rays", "16", "--order", "2", "--chunk", "2", "--no-progress"]
    assert main(args) == 1
    assert "cannot resume" in capsys.readouterr().err


def test_resume_of_a_finished_run_does_nothing(tmp_path):
    out = tmp_path / "o.usda"
    assert main(["run", SCENE, "--frames", "2", "--out", str(out), "--workers", "0"] + COMMON) == 0
    before = frames_of(out)
    assert main(["run", SCENE, "--frames", "2", "--out", str(out), "--resume", "--workers", "0"] + COMMON) == 0
    after = frames_of(out)
    for prim in before:
        for (pa, ca), (pb, cb) in zip(before[prim], after[prim]):
            assert np.array_equal(pa, pb) and np.array_equal(ca, cb)


# Temporal reuse at a tolerance the cloth's motion never reaches in a chunk: each chunk keeps the transfer of
# its first frame, so a frame's colours tell which frame its chunk started at.
REUSE = ["--reuse", "100", "--reuse-chunk", "4"]


@pytest.fixture(scope="module")
def reused(tmp_path_factory):
    out = tmp_path_factory.mktemp("reused") / "reused.usda"
    assert main(["run", SCENE, "--frames", str(FRAMES), "--out", str(out), "--workers", "0"] + COMMON + REUSE) == 0
    return frames_of(out)


def test_reuse_chunks_give_the_same_frames_with_two_workers_and_after_resume(tmp_path, reused, uninterrupted):
    # reuse changes frames 1-3 against recomputation, and frame 4 starts a chunk: the checks below can fail
    changed = [f for f in range(FRAMES)
               if any(not np.array_equal(reused[p][f][1], uninterrupted[p][f][1]) for p in reused)]
    assert changed == [1, 2, 3, 5], changed
    two = tmp_path / "two.usda"
    assert main(["run", SCENE, "--frames", str(FRAMES), "--out", str(two), "--workers", "2"] + COMMON + REUSE) == 0
    assert_same_frames(frames_of(two), reused)
    # interrupted at frame 3, inside the chunk 0-3: the resumed run shades from frame 0 again
    out = tmp_path / "o.usda"
    pipe = Pipeline(read_scene(SCENE), frames=FRAMES, method="reference", knobs={"rays": 4}, order=2, reuse=100,
                    reuse_chunk=4)
    with pytest.raises(KeyboardInterrupt):
        pipe.run(InterruptingWriter(str(out), chunk=2, at=3,
                                    metadata={"scene": os.path.abspath(SCENE), "order": 2}), progress=False)
    assert Usd.Stage.Open(str(out)).GetEndTimeCode() == 2
    assert main(["run", SCENE, "--frames", str(FRAMES), "--out", str(out), "--resume", "--workers", "2"]
                + COMMON + REUSE) == 0
    assert_same_frames(frames_of(out), reused)
