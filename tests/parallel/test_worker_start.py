"""How a :class:`~warpshade.parallel.WorkerPool` starts its workers
(:func:`~warpshade.parallel.frames.worker_start_method`): forked from a process with one Python thread and no
CUDA, inheriting its imports and state but none of its signal handlers; spawned otherwise. Each case runs in a fresh interpreter, whose threads the test controls (a pytest
process may hold threads other tests left)."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys

import pytest

from helpers import REPO

PROBE = '''
import os, signal

def probe():
    import sys
    import warpshade.parallel.runtime as rt
    return {"marker": getattr(rt, "MARKER", None), "sigterm_default": signal.getsignal(signal.SIGTERM) == signal.SIG_DFL,
            "sighup_default": signal.getsignal(signal.SIGHUP) == signal.SIG_DFL,
            "blocked": sorted(int(s) for s in signal.pthread_sigmask(signal.SIG_BLOCK, [])),
            "parent": os.getppid()}
'''

SCRIPT = '''
import json, os, signal, sys, threading
import probe
import warpshade.parallel.runtime as rt
from warpshade.parallel import WorkerPool

def raising(signum, frame):  # as `warpshade run` does: SIGTERM and SIGHUP raise in the run
    raise KeyboardInterrupt


if __name__ == "__main__":  # a spawned worker imports this script
    rt.MARKER = "set in the parent"

    signal.signal(signal.SIGTERM, raising)
    signal.signal(signal.SIGHUP, raising)
    done = threading.Event()
    if sys.argv[1] == "thread":
        threading.Thread(target=done.wait, daemon=True).start()
    pool = WorkerPool(1, preload=("warpshade.pipeline.shading",))
    out = dict(pool.pool.submit(probe.probe).result(timeout=120), method=pool.start_method, me=os.getpid(),
               preloaded_here="warpshade.pipeline.shading" in sys.modules)
    worker = next(iter(pool.pool._processes.values()))
    worker.terminate()  # SIGTERM: a worker ends at once, silently, whatever the run's handlers
    worker.join(20)
    out["exitcode"] = worker.exitcode
    pool.close(abandon=True)
    done.set()
    print(json.dumps(out))
'''


def start_workers(tmp_path, threads: str) -> dict:
    (tmp_path / "probe.py").write_text(PROBE)
    (tmp_path / "script.py").write_text(SCRIPT)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), REPO, os.environ.get("PYTHONPATH", "")]))
    out = subprocess.run([sys.executable, str(tmp_path / "script.py"), threads], capture_output=True, text=True,
                         env=env, timeout=240, cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-3000:]
    assert "Traceback" not in out.stderr, out.stderr[-3000:]
    return json.loads(out.stdout.strip().splitlines()[-1])


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="workers fork on Linux only")
def test_a_single_threaded_process_forks_its_workers_which_inherit_its_imports_not_its_handlers(tmp_path):
    out = start_workers(tmp_path, "one")
    assert out["method"] == "fork"
    assert out["marker"] == "set in the parent"  # the worker is a copy of the parent: no import of its own
    assert out["preloaded_here"]  # preload imported once, in the parent, before the fork
    assert out["parent"] == out["me"]
    assert out["sigterm_default"] and out["sighup_default"]  # the run's handlers are not the worker's
    assert out["blocked"] == [int(signal.SIGINT)]  # Ctrl-C reaches the run only; SIGTERM ends a worker
    assert out["exitcode"] == -signal.SIGTERM


def test_a_process_with_another_thread_spawns_its_workers(tmp_path):
    out = start_workers(tmp_path, "thread")
    assert out["method"] == "spawn"
    assert out["marker"] is None  # a fresh interpreter
    assert not out["preloaded_here"]  # the workers import preload themselves
    assert out["sigterm_default"] and out["sighup_default"]
    assert out["blocked"] == [int(signal.SIGINT)]
    assert out["exitcode"] == -signal.SIGTERM


def test_no_fork_once_cuda_has_started(monkeypatch):
    import threading
    import types

    import warp._src.context as context

    import warpshade.parallel.frames as frames

    monkeypatch.setattr(frames, "can_fork", lambda: True)
    monkeypatch.setattr(threading, "active_count", lambda: 1)
    monkeypatch.setattr(context, "runtime", types.SimpleNamespace(cuda_devices=["cuda:0"]))
    assert frames.worker_start_method() == "spawn"
    monkeypatch.setattr(context, "runtime", types.SimpleNamespace(cuda_devices=[]))
    assert frames.worker_start_method() == "fork"
    monkeypatch.setattr(context, "runtime", None)  # Warp not started here: a forked worker starts it
    assert frames.worker_start_method() == "fork"
