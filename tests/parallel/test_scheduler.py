"""``warpshade run --scheduler`` end to end against a Dask cluster started as a user starts one
(``dask scheduler``, ``dask worker --nworkers 2``, separate processes, on loopback), plain and over
TLS, and the warning for unencrypted connections that leave the machine (issue 16, item 5).

Each test starts its own scheduler and workers (nothing for ``.ci/run`` to start) and checks that
every process it started is gone afterwards."""

from __future__ import annotations

import contextlib
import json
import os
import subprocess
import sys
import time

import pytest

from helpers import COMMON, FRAMES, REPO, SCENE, assert_same_frames, frames_of, live_processes
from warpshade.cli import main
from warpshade.parallel.cluster import is_loopback, scheduler_security, stop_sessions, unencrypted_remote

# workers import warpshade from this checkout, as a user's would from their install
ENV = dict(os.environ, PYTHONPATH=REPO + os.pathsep + os.environ.get("PYTHONPATH", ""), MPLBACKEND="Agg")
DASK = [os.path.join(os.path.dirname(sys.executable), "dask")]
if not os.path.exists(DASK[0]):  # a venv without console scripts on PATH
    DASK = [sys.executable, "-m", "dask"]
RUN_TIMEOUT = 300  # s: a cold Warp kernel cache compiles for about a minute on a loaded machine


def session_members(leaders: list[int]) -> set[int]:
    """Live processes whose session is led by one of ``leaders`` (from /proc)."""
    return {p for p, fields in live_processes().items() if int(fields[3]) in leaders}


def alive(pids) -> set[int]:
    """Those of ``pids`` that are still running (not zombies)."""
    out = set()
    for p in pids:
        with contextlib.suppress(OSError):
            with open(f"/proc/{p}/stat") as f:
                if f.read().rsplit(")", 1)[1].split()[0] != "Z":
                    out.add(p)
    return out


@contextlib.contextmanager
def user_cluster(tmp_path, tls: list[str] | None = None, security=None, timeout: float = 120.0):
    """``dask scheduler --port 0 --scheduler-file F`` and ``dask worker --scheduler-file F --nworkers 2``;
    yields the scheduler's address once both workers are up. Every process is gone afterwards."""
    from distributed import Client

    sched_file = tmp_path / "scheduler.json"
    tls = tls or []
    protocol = ["--protocol", "tls"] if tls else []
    logs = [open(tmp_path / "scheduler.log", "wb"), open(tmp_path / "worker.log", "wb")]
    procs = []
    seen: set[int] = set()
    try:
        procs.append(subprocess.Popen(
            DASK + ["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                    "--scheduler-file", str(sched_file)] + protocol + tls,
            stdout=logs[0], stderr=subprocess.STDOUT, env=ENV, start_new_session=True))
        deadline = time.monotonic() + timeout
        while not sched_file.exists() or not sched_file.read_text().strip():
            assert procs[0].poll() is None, (tmp_path / "scheduler.log").read_text()
            assert time.monotonic() < deadline, "the scheduler wrote no scheduler file"
            time.sleep(0.2)
        time.sleep(0.2)  # the file is written in one go; let it be complete
        address = json.loads(sched_file.read_text())["address"]
        procs.append(subprocess.Popen(
            DASK + ["worker", "--scheduler-file", str(sched_file), "--nworkers", "2", "--nthreads", "1",
                    "--no-dashboard", "--host", "127.0.0.1"] + tls,
            stdout=logs[1], stderr=subprocess.STDOUT, env=ENV, start_new_session=True))
        with Client(address, security=security, timeout=30) as c:
            c.wait_for_workers(2, timeout=max(1.0, deadline - time.monotonic()))
        seen = session_members([p.pid for p in procs])
        assert len(seen) >= 4, seen  # scheduler, `dask worker`, and at least one process per worker
        yield address
    finally:
        seen |= session_members([p.pid for p in procs])
        stop_sessions(procs)
        for f in logs:
            f.close()
        deadline = time.monotonic() + 10
        while (left := alive(seen) | session_members([p.pid for p in procs])) and time.monotonic() < deadline:
            time.sleep(0.2)
        assert not left, f"cluster processes outlived the test: {sorted(left)}"


def tasks_run_by(address: str, security=None) -> int:
    """How many tasks with keys ``warpshade-...`` reached memory (finished) on the scheduler."""
    from distributed import Client

    def count(dask_scheduler):  # a prefix's state_counts count every transition into a state, ever
        prefix = dask_scheduler.task_prefixes.get("warpshade")
        return 0 if prefix is None else int(prefix.state_counts["memory"])

    with Client(address, security=security, timeout=30) as c:
        return c.run_on_scheduler(count)


def run_cmd(out, *extra) -> subprocess.CompletedProcess:
    cmd = [sys.executable, "-m", "warpshade", "run", SCENE, "--frames", str(FRAMES), "--out", str(out)] + COMMON
    return subprocess.run(cmd + list(extra), capture_output=True, text=True, env=ENV, timeout=RUN_TIMEOUT)


@pytest.fixture(scope="module")
def one_worker(tmp_path_factory):
    out = tmp_path_factory.mktemp("one") / "one.usda"
    r = run_cmd(out, "--workers", "1")
    assert r.returncode == 0, r.stderr
    return frames_of(out)


def test_run_on_a_user_started_cluster_writes_the_frames_of_one_worker(tmp_path, one_worker):
    with user_cluster(tmp_path) as address:
        assert address.startswith("tcp://127.0.0.1:")
        out = tmp_path / "cluster.usda"
        r = run_cmd(out, "--scheduler", address)
        assert r.returncode == 0, r.stderr
        assert "warning" not in r.stderr, r.stderr  # loopback: no warning about encryption
        # the frames were shaded on the cluster, not in the run's own process
        assert tasks_run_by(address) >= FRAMES
    # same simulation, same kernels and seeds on every worker, arrays moved bit for bit: identical
    assert_same_frames(frames_of(out), one_worker)


def write_temporary_certificate(tmp_path) -> tuple[str, str]:
    """A self-signed certificate and its key (PEM files) from ``distributed.Security.temporary()``."""
    from distributed import Security

    sec = Security.temporary()
    cert, key = tmp_path / "cert.pem", tmp_path / "key.pem"
    cert.write_text(sec.tls_client_cert)
    key.write_text(sec.tls_client_key)
    return str(cert), str(key)


def test_run_over_tls_writes_the_frames_of_one_worker(tmp_path, one_worker):
    cert, key = write_temporary_certificate(tmp_path)
    tls = ["--tls-ca-file", cert, "--tls-cert", cert, "--tls-key", key]
    security = scheduler_security("tls://127.0.0.1:1", cert, cert, key)
    with user_cluster(tmp_path, tls=tls, security=security) as address:
        assert address.startswith("tls://127.0.0.1:")
        out = tmp_path / "tls.usda"
        r = run_cmd(out, "--scheduler", address, *tls)
        assert r.returncode == 0, r.stderr
        assert tasks_run_by(address, security) >= FRAMES
        # without certificates the run is refused before it starts, naming what is missing
        r = run_cmd(tmp_path / "none.usda", "--scheduler", address)
        assert r.returncode == 1
        assert r.stderr.strip().splitlines()[-1].startswith(
            f"warpshade run: error: --scheduler {address}: a tls:// scheduler needs --tls-ca-file"), r.stderr
        assert not (tmp_path / "none.usda").exists()
    assert_same_frames(frames_of(out), one_worker)


@pytest.mark.parametrize("address, warned", [
    ("tcp://0.0.0.0:1", True),  # not loopback (connecting to it reaches this machine, refused fast)
    ("tcp://127.0.0.1:1", False),
])
def test_one_warning_line_for_an_unencrypted_address_off_this_machine(tmp_path, address, warned):
    out = tmp_path / "o.usda"
    env = dict(ENV, DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT="2s")  # nothing listens there: fail fast
    cmd = [sys.executable, "-m", "warpshade", "run", SCENE, "--frames", "2", "--out", str(out),
           "--scheduler", address] + COMMON
    r = subprocess.run(cmd, capture_output=True, text=True, env=env, timeout=RUN_TIMEOUT)
    assert r.returncode == 1, r.stderr
    err = r.stderr.splitlines()
    lines = [ln for ln in err if "warning" in ln]
    if warned:
        assert lines == [f"warpshade run: warning: scheduler {address} is not on this machine and the connection "
                         "is not encrypted: Dask sends pickles, which run code, so anyone on the network path can "
                         "read frames or run code here; use tls:// (--tls-ca-file, --tls-cert, --tls-key)"], err
    else:
        assert lines == [], err
    assert f"warpshade run: error: Timed out trying to connect to {address} after 2 s" in err, err
    assert "Traceback" not in r.stderr
    assert not out.exists()


@pytest.mark.parametrize("address, expected", [
    ("tcp://127.0.0.1:8786", False), ("127.0.0.5:8786", False), ("tcp://localhost:8786", False),
    ("tcp://[::1]:8786", False), ("inproc://10.0.0.2/1/2", False), ("tls://10.0.0.2:8786", False),
    ("tcp://10.0.0.2:8786", True), ("10.0.0.2:8786", True), ("tcp://node7.farm:8786", True),
    ("tcp://[2001:db8::1]:8786", True), ("ws://192.0.2.1:8786", True),
])
def test_unencrypted_remote(address, expected):
    assert unencrypted_remote(address) is expected


def test_is_loopback_names():
    assert is_loopback("127.0.0.1") and is_loopback("::1") and is_loopback("LOCALHOST")
    assert not is_loopback("0.0.0.0") and not is_loopback("example.org")


def test_tls_options_are_checked_before_the_run(tmp_path, capsys):
    cert = tmp_path / "c.pem"
    cert.write_text("x")
    cases = [
        (["--tls-ca-file", str(cert)], "--tls-ca-file/--tls-cert/--tls-key need --scheduler tls://HOST:PORT"),
        (["--scheduler", "tcp://127.0.0.1:1", "--tls-cert", str(cert)],
         "--tls-cert: TLS needs a tls:// scheduler address, got --scheduler tcp://127.0.0.1:1"),
        (["--scheduler", "tls://127.0.0.1:1", "--tls-cert", str(cert)],
         "--tls-ca-file is missing: TLS to tls://127.0.0.1:1 needs --tls-ca-file and --tls-cert"),
        (["--scheduler", "tls://127.0.0.1:1", "--tls-ca-file", str(cert), "--tls-cert", str(tmp_path / "no.pem")],
         f"--tls-cert {tmp_path / 'no.pem'}: no such file"),
    ]
    for extra, message in cases:
        assert main(["run", SCENE, "--frames", "1", "--out", str(tmp_path / "o.usda")] + COMMON + extra) == 1
        assert capsys.readouterr().err.splitlines() == [f"warpshade run: error: {message}"], extra
    assert os.listdir(tmp_path) == ["c.pem"]
