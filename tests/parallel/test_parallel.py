"""Parallel frame shading: order, content, back-pressure, worker deaths, Dask."""

from __future__ import annotations

import os
import signal
import sys

import numpy as np
import pytest
import trimesh

from warpshade.geometry import TriMesh
from warpshade.parallel import FrameShadingError, TransferSpec, shade_frames


def wobble_frames(mesh: TriMesh, n: int, start: int = 0):
    """A deterministic deforming animation of ``mesh`` (frame -> geometry)."""
    for f in range(start, n):
        s = 1.0 + 0.2 * np.sin(0.7 * f + mesh.points[:, 0:1] * 3.0)
        yield f, {"blob": (mesh.points * s).astype(np.float32)}


@pytest.fixture(scope="module")
def blob():
    # a concave shape so transfer changes with the deformation
    tm = trimesh.creation.icosphere(2)
    v = tm.vertices * (1.0 + 0.3 * np.sin(4 * tm.vertices[:, 1:2]))
    return TriMesh(v, tm.faces, name="blob")


@pytest.fixture(scope="module")
def spec(blob):
    return TransferSpec({"blob": blob}, method="reference", order=3, knobs={"rays": 256})


@pytest.fixture(scope="module")
def inline(spec, blob):
    return dict(shade_frames(spec, wobble_frames(blob, 8), workers=0))


def assert_same(results, expected):
    assert [f for f, _ in results] == sorted(expected), "frames out of order, lost or duplicated"
    for f, r in results:
        # same kernels, same seed, same inputs: bit-identical across processes
        assert np.array_equal(r["blob"], expected[f]["blob"]), f"frame {f} differs"


def test_processes_match_inline_in_order(spec, blob, inline):
    out = list(shade_frames(spec, wobble_frames(blob, 8), workers=2, max_in_flight=3))
    assert_same(out, inline)


def test_back_pressure_limits_frames_ahead(spec, blob):
    pulled = []

    def frames():
        for f, g in wobble_frames(blob, 8):
            pulled.append(f)
            yield f, g

    seen = 0
    for f, _ in shade_frames(spec, frames(), workers=2, max_in_flight=3):
        seen += 1
        # never more than max_in_flight frames taken from the simulation beyond those yielded
        assert len(pulled) - seen <= 3 - 1
    assert seen == 8


def shade_killing_a_worker(spec, blob, wait_until_broken: bool, **kw) -> list:
    """Two workers shade 8 frames; one is SIGKILLed after frame 1 is yielded (then, with
    ``wait_until_broken``, the loop waits until the pool has noticed, before it submits more);
    ``kw``: more :func:`shade_frames` arguments."""
    import time

    backend_box = []
    out = []
    for f, r in shade_frames(spec, wobble_frames(blob, 8), workers=2, on_backend=backend_box.append,
                             **{"max_in_flight": 4, **kw}):
        out.append((f, r))
        if f == 1:
            pool = backend_box[0].pool
            pids = backend_box[0].worker_pids()
            assert pids, "no worker processes to kill"
            os.kill(pids[0], signal.SIGKILL)
            if wait_until_broken:
                deadline = time.monotonic() + 30
                while not pool._broken and time.monotonic() < deadline:  # the executor's own flag
                    time.sleep(0.01)
                assert pool._broken, "the pool did not notice the killed worker"
    return out


def test_killed_worker_loses_and_duplicates_nothing(spec, blob, inline):
    assert_same(shade_killing_a_worker(spec, blob, wait_until_broken=False), inline)


def test_worker_death_seen_before_the_next_submit_loses_nothing(spec, blob, inline):
    # the pool has noticed the death (and refuses new work) before the loop submits the next frame
    assert_same(shade_killing_a_worker(spec, blob, wait_until_broken=True), inline)


class _Boom:
    def build(self):
        def shade(frame, geometry):
            if frame == 3:
                raise ValueError("vertex 7 is NaN")
            return frame

        return shade


def test_error_names_the_frame():
    with pytest.raises(FrameShadingError, match="frame 3: .*vertex 7"):
        list(shade_frames(_Boom(), ((f, {}) for f in range(6)), workers=0))


def test_resume_from_written_frames(spec, blob, inline):
    # a resumed run asks only for the missing frames and gets the same content
    out = list(shade_frames(spec, wobble_frames(blob, 8, start=5), workers=1))
    assert [f for f, _ in out] == [5, 6, 7]
    for f, r in out:
        assert np.array_equal(r["blob"], inline[f]["blob"])


# Temporal reuse with a tolerance no motion reaches: a receiver is computed only where its state starts
# afresh, so every frame of a chunk has the transfer of the chunk's first frame, exactly as the method
# without reuse computes it there (the ``inline`` fixture).
NEVER_DUE = 1e6  # [rad]; the wobble moves the blob's clusters by well under 1 rad a frame


@pytest.fixture(scope="module")
def frozen(blob):
    return TransferSpec({"blob": blob}, method="reference", order=3, knobs={"rays": 256}, reuse=NEVER_DUE)


def assert_chunk_starts(results, inline, chunk):
    """Frame ``f`` of ``results`` holds ``inline``'s transfer of the first frame of ``f``'s chunk."""
    assert [f for f, _ in results] == sorted(inline), "frames out of order, lost or duplicated"
    assert not np.array_equal(inline[0]["blob"], inline[1]["blob"])  # the wobble changes the transfer
    for f, r in results:
        assert np.array_equal(r["blob"], inline[f - f % chunk]["blob"]), f"frame {f}"


@pytest.mark.parametrize("workers", [0, 1, 2])
def test_chunks_restart_reuse_at_their_first_frame_whatever_the_workers(frozen, blob, inline, workers):
    # frames 0-2, 3-5, 6-7; with 2 workers one chunk each at first, the third to whichever is free
    out = list(shade_frames(frozen, wobble_frames(blob, 8), workers=workers, chunk=3))
    assert_chunk_starts(out, inline, 3)


def test_chunk_back_pressure_counts_frames(frozen, blob):
    pulled = []

    def frames():
        for f, g in wobble_frames(blob, 8):
            pulled.append(f)
            yield f, g

    seen = 0
    for f, _ in shade_frames(frozen, frames(), workers=2, chunk=2, max_in_flight=4):
        seen += 1
        assert len(pulled) - seen <= 4 - 1  # two chunks of two frames at most, less the one yielded
    assert seen == 8


def test_killed_worker_mid_chunk_reshades_the_chunk_from_its_start(frozen, blob, inline):
    # the kill comes after frame 1 is yielded: the chunks 2-3 and 4-5 in flight are lost and shaded again,
    # each from its first frame
    assert_chunk_starts(shade_killing_a_worker(frozen, blob, wait_until_broken=True, chunk=2), inline, 2)


def test_chunk_error_names_the_frames():
    with pytest.raises(FrameShadingError, match="frames 2-3: .*vertex 7"):
        list(shade_frames(_Boom(), ((f, {}) for f in range(6)), workers=0, chunk=2))


def test_dask_local_cluster_matches_inline(spec, blob, inline):
    # Dask's default HTTP port busy (another cluster, another test): the run's own cluster must not
    # take it or warn about it (it serves no dashboard; was a three-line warning after the run's output)
    import socket
    import warnings

    with socket.socket() as busy, warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            busy.bind(("127.0.0.1", 8787))
            busy.listen()
        except OSError:
            pass  # already in use: the condition under test
        out = list(shade_frames(spec, wobble_frames(blob, 8), workers=2, scheduler="local"))
    assert_same(out, inline)
    assert not [str(w.message) for w in caught if "8787" in str(w.message)]


def test_dask_local_cluster_shades_chunks(frozen, blob, inline):
    out = list(shade_frames(frozen, wobble_frames(blob, 8), workers=2, scheduler="local", chunk=3))
    assert_chunk_starts(out, inline, 3)


def test_dask_local_cluster_reports_a_build_error_as_itself(blob):
    """The run's own cluster prints only critical worker logs (its workers' other lines followed the
    run's last line); a spec whose build fails in the workers still stops the run with the build's
    own error, not a dead worker or a silent hang."""
    bad = TransferSpec({"blob": blob}, method="reference", order=3, knobs={"rays": -5})
    with pytest.raises(ValueError, match="rays must be >= 1, got -5"):
        list(shade_frames(bad, wobble_frames(blob, 3), workers=2, scheduler="local"))


def test_dask_separate_process_cluster_on_loopback(spec, blob, inline):
    from warpshade.parallel.cluster import loopback_cluster

    with loopback_cluster(workers=2) as address:
        out = list(shade_frames(spec, wobble_frames(blob, 8), scheduler=address))
    assert_same(out, inline)


UNGUARDED = ("import warpshade as ws\n"
             # a spec over the 64 KiB a pipe holds (about 120 KiB: the meshes travel in it)
             "scene = ws.make_scene(ws.ground(size=1.0, resolution=41), ws.cloth_grid(resolution=40, height=0.3))\n"
             "ws.run(scene, {out!r}, frames=2, workers=2)\n")


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="workers fork on Linux only")
def test_a_script_without_a_main_guard_runs_where_workers_fork(tmp_path):
    # a forked worker does not import the script (warpshade.parallel.frames.worker_start_method)
    import subprocess

    script = tmp_path / "unguarded.py"
    script.write_text(UNGUARDED.format(out=str(tmp_path / "out.usda")))
    proc = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=240, cwd=tmp_path)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert (tmp_path / "out.usda").exists()


def test_a_script_without_a_main_guard_stops_with_an_error_that_says_why(tmp_path):
    # where workers spawn (here: the script runs a second thread, so they do not fork), each imports the
    # script, which starts a run of its own there and dies as it starts; the spec used to travel in the
    # workers' start-up message, and with a worker dead before reading it the run blocked for ever writing
    # that message
    import subprocess

    script = tmp_path / "unguarded.py"
    script.write_text("import threading\n"
                      "threading.Thread(target=threading.Event().wait, daemon=True).start()\n"
                      + UNGUARDED.format(out=str(tmp_path / "out.usda")))
    tmp = tmp_path / "tmp"
    tmp.mkdir()
    proc = subprocess.run([sys.executable, str(script)], capture_output=True, text=True, timeout=240, cwd=tmp_path,
                          env=dict(os.environ, TMPDIR=str(tmp)))  # (timeout: it hung for ever)
    assert proc.returncode != 0
    assert 'if __name__ == "__main__":' in proc.stderr.splitlines()[-1], proc.stderr[-2000:]
    assert not list(tmp.glob("warpshade-*.spec"))  # the spec file is removed with the run
