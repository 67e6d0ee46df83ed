"""``warpshade run``'s workers (:mod:`warpshade.cli.run_pool`): where they fork (Linux), started by the run after
the parent's imports, before it reads the scene; where they spawn (the tests marked ``spawning``, which make
:func:`~warpshade.parallel.frames.can_fork` say no), started before the parent starts Warp and builds its parser:
the early read of the command line, the run's check of that guess, and no worker left behind when the command
ends before the run takes the pool."""

from __future__ import annotations

import os
import subprocess
import sys
import time

import pytest

import warpshade.cli
from helpers import REPO
from warpshade.cli import main
from warpshade.cli.run_pool import early_pool
from warpshade.parallel import WorkerPool, default_workers

SCENE = os.path.join(REPO, "usd_scenes", "cloth_sphere.usda")


def children() -> int:
    import multiprocessing

    return len(multiprocessing.active_children())


def no_children_left(seconds: float = 10.0) -> bool:
    """Whether this process's worker processes are all gone within ``seconds`` (a worker SIGTERMed as
    it starts may need the close's SIGKILL, 5 s later)."""
    deadline = time.monotonic() + seconds
    while children() and time.monotonic() < deadline:
        time.sleep(0.1)
    return children() == 0


def record_children(monkeypatch, name: str, seen: dict, then=lambda: None) -> None:
    """Make ``warpshade.cli.<name>`` (``init_warp``, ``build_parser``) record the live worker processes
    in ``seen[name]``, then call ``then()`` and the real function."""
    real = getattr(warpshade.cli, name)

    def recording(*a, **k):
        seen[name] = children()
        then()
        return real(*a, **k)

    monkeypatch.setattr(warpshade.cli, name, recording)


def count_pools(monkeypatch) -> list:
    """Record every :class:`WorkerPool` started (its worker count), by patching its constructor."""
    started = []
    real = WorkerPool.__init__

    def init(self, workers, *a, **k):
        started.append(int(workers))
        real(self, workers, *a, **k)

    monkeypatch.setattr(WorkerPool, "__init__", init)
    return started


@pytest.fixture
def spawning(monkeypatch):
    """Workers spawn, as where they cannot fork (macOS, Windows): the run starts them first."""
    import warpshade.parallel.frames

    monkeypatch.setattr(warpshade.parallel.frames, "can_fork", lambda: False)


FORKING_RUN = """
import json, multiprocessing, sys
import warpshade.cli, warpshade.usd
from warpshade.parallel import WorkerPool

seen, methods = {}, []

def recording(name, real):
    def f(*a, **k):
        seen[name] = len(multiprocessing.active_children())
        return real(*a, **k)
    return f

warpshade.cli.init_warp = recording("init_warp", warpshade.cli.init_warp)
warpshade.cli.build_parser = recording("build_parser", warpshade.cli.build_parser)
warpshade.usd.read_scene = recording("read_scene", warpshade.usd.read_scene)
real_new = WorkerPool._new_pool

def new_pool(self):
    pool = real_new(self)
    methods.append((self.workers, self.start_method))
    return pool

WorkerPool._new_pool = new_pool
code = warpshade.cli.main(sys.argv[1:])
print(json.dumps({"code": code, "seen": seen, "pools": methods, "left": len(multiprocessing.active_children())}))
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="workers fork on Linux only")
def test_where_workers_fork_the_run_forks_them_after_the_imports_before_the_scene(tmp_path):
    # a fresh interpreter: one thread, as the command has (a pytest process may hold threads other tests left,
    # and then its pools spawn)
    import json

    argv = ["run", SCENE, "--frames", "2", "--order", "2", "--workers", "2", "--no-progress",
            "--out", str(tmp_path / "a.usda")]
    env = dict(os.environ, PYTHONPATH=REPO + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = subprocess.run([sys.executable, "-c", FORKING_RUN, *argv], capture_output=True, text=True, env=env,
                         timeout=300, cwd=tmp_path)
    assert out.returncode == 0, out.stderr[-3000:]
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert got["code"] == 0
    assert got["seen"] == {"init_warp": 0, "build_parser": 0, "read_scene": 2}
    assert got["pools"] == [[2, "fork"]]  # one pool, forked, after the parent's imports and before the scene
    assert got["left"] == 0


def test_the_workers_start_before_warp_and_the_parser_and_the_run_keeps_them(tmp_path, monkeypatch, spawning):
    seen, started = {}, count_pools(monkeypatch)
    record_children(monkeypatch, "init_warp", seen)
    record_children(monkeypatch, "build_parser", seen)
    argv = ["run", SCENE, "--frames", "2", "--order", "2", "--workers", "2", "--no-progress"]
    assert main(argv + ["--out", str(tmp_path / "a.usda")]) == 0
    assert seen == {"init_warp": 2, "build_parser": 2}
    assert started == [2]  # the run shaded with the pool started first, not a second one
    assert no_children_left()


def test_a_pool_the_flags_do_not_ask_for_is_replaced(tmp_path, monkeypatch, spawning):
    # "--work 1" is --workers to run's parser (argparse takes unique prefixes), not to the early read,
    # which starts the default worker count; the run closes that pool and starts one worker
    seen, started = {}, count_pools(monkeypatch)
    record_children(monkeypatch, "build_parser", seen)
    argv = ["run", SCENE, "--frames", "2", "--order", "2", "--work", "1", "--no-progress"]
    assert main(argv + ["--out", str(tmp_path / "a.usda")]) == 0
    assert started == [default_workers(), 1]
    assert seen == {"build_parser": default_workers()}
    assert no_children_left()


def test_a_usage_error_ends_the_early_workers(tmp_path, capsys, monkeypatch, spawning):
    seen = {}
    record_children(monkeypatch, "build_parser", seen)
    with pytest.raises(SystemExit) as e:
        main(["run", SCENE, "--workers", "2", "--frames", "two", "--out", str(tmp_path / "a.usda")])
    assert e.value.code == 2
    assert capsys.readouterr().err.strip().splitlines()[-1] == \
        "warpshade run: error: argument --frames: invalid int value: 'two'"
    assert seen == {"build_parser": 2}
    assert no_children_left()
    assert not list(tmp_path.iterdir())


def test_ctrl_c_while_warp_starts_ends_the_early_workers(tmp_path, capsys, monkeypatch, spawning):
    def interrupt():
        raise KeyboardInterrupt

    seen = {}
    record_children(monkeypatch, "init_warp", seen, then=interrupt)
    assert main(["run", SCENE, "--workers", "2", "--out", str(tmp_path / "a.usda")]) == 130
    assert capsys.readouterr().err.splitlines() == ["warpshade: interrupted"]
    assert seen == {"init_warp": 2}
    assert no_children_left()
    assert not list(tmp_path.iterdir())


@pytest.mark.parametrize("argv", [
    [], ["transfer", "--workers", "2"], ["run", "--help"], ["run", "-h", "--workers", "2"], ["run", "--workers", "0"],
    ["run", "--scheduler", "local"], ["run", "--workers", "two"], ["run", "--workers"],
    ["run", "--method", "no-such-method"],
])
def test_no_early_pool_for_other_commands_help_no_workers_a_cluster_or_bad_flags(argv, capsys, spawning):
    assert early_pool(argv) is None
    assert children() == 0
    assert capsys.readouterr().err == ""  # the early read prints nothing: run's own parser reports bad flags


def test_the_early_pool_reads_workers_and_method(spawning):
    pool = early_pool(["run", "scene.usda", "--frames", "3", "--workers=1", "--method", "none"])
    try:
        assert (pool.workers, pool.preload) == (1, ("warpshade.pipeline.shading",))
    finally:
        pool.close(abandon=True)
    pool = early_pool(["run", "--method", "reference", "--rays", "64"])
    try:
        assert pool.workers == default_workers()
        assert pool.preload == ("warpshade.pipeline.shading", "warpshade.visibility.reference")
    finally:
        pool.close(abandon=True)
    assert no_children_left()


@pytest.mark.parametrize("argv", [["run"], ["run", "--workers", "2"], ["run", "--method", "reference"]])
def test_no_early_pool_where_workers_fork(argv):
    assert early_pool(argv) is None
    assert children() == 0


def test_starting_the_early_pool_imports_nothing_heavy():
    # in a fresh interpreter, as the command starts: no Warp, SciPy or pipeline before the workers exist
    code = ("import sys\n"
            "from warpshade.cli import run_pool\n"
            "from warpshade.parallel import frames\n"
            "frames.can_fork = lambda: False  # workers spawn, as on macOS\n"
            "pool = run_pool.early_pool(['run', '--workers', '1'])\n"
            "heavy = [m for m in ('warp', 'scipy', 'warpshade.pipeline', 'warpshade.sh') if m in sys.modules]\n"
            "pool.close(abandon=True)\n"
            "print(heavy, pool.workers)\n")
    env = dict(os.environ, PYTHONPATH=REPO + os.pathsep + os.environ.get("PYTHONPATH", ""))
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "[] 1"
