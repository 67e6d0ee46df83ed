"""Connecting to a Dask cluster safely, and a loopback cluster of separate processes for tests.

Trust model: Dask moves tasks and results as pickles, and unpickling runs code. A scheduler (and
every worker behind it) can therefore run code in the process that connects to it, and the
connecting process runs code on the workers. Connect only to schedulers you trust, over ``tls://``
(mutual TLS, :func:`scheduler_security`) whenever the traffic leaves this machine;
:func:`unencrypted_remote` says when it would not be encrypted.

:func:`loopback_cluster` starts ``dask scheduler`` and ``dask worker`` as a user would, on
127.0.0.1 (the parallel benchmark and the tests use it); users with a cluster pass its address to
``warpshade run --scheduler tcp://HOST:PORT`` (or ``tls://HOST:PORT``) instead.
"""

from __future__ import annotations

import contextlib
import ipaddress
import os
import signal
import shutil
import socket
import subprocess
import sys
import time


def free_port() -> int:
    """A TCP port on 127.0.0.1 that was free a moment ago."""
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _split_address(address: str) -> tuple[str, str]:
    """``(scheme, host)`` of a Dask address; no scheme means ``tcp`` (as in Dask)."""
    scheme, sep, rest = address.partition("://")
    if not sep:
        scheme, rest = "tcp", address
    rest = rest.rsplit("/", 1)[0] if "/" in rest else rest
    if rest.startswith("["):  # [IPv6]:port
        return scheme, rest[1:].split("]", 1)[0]
    host = rest.rsplit(":", 1)[0] if rest.count(":") == 1 else rest
    return scheme, host


def is_loopback(host: str) -> bool:
    """Whether ``host`` names this machine's loopback interface (``localhost``, 127.0.0.0/8, ``::1``)."""
    if host.lower() in ("localhost", "localhost.localdomain"):
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:  # a host name: it may resolve anywhere
        return False


def unencrypted_remote(address: str) -> bool:
    """Whether connecting to scheduler ``address`` sends pickles over a network without TLS.

    Only ``tls://`` is encrypted; ``inproc://`` and loopback addresses never leave this machine.
    """
    scheme, host = _split_address(address)
    return scheme not in ("tls", "inproc") and not is_loopback(host)


def scheduler_security(address: str, ca_file: str | None = None, cert: str | None = None,
                       key: str | None = None):
    """The ``distributed.Security`` for connecting to ``address``, or None for Dask's configuration.

    Args:
        address: Scheduler address (``tls://HOST:PORT`` for TLS).
        ca_file: PEM file of the certificate authority that signed the scheduler's and workers'
            certificates.
        cert: PEM file of this client's certificate (Dask's TLS is mutual), optionally with its key.
        key: PEM file of the certificate's private key, if ``cert`` does not hold it.

    Without files, None lets Dask read its ``distributed.comm.tls`` configuration.

    Raises:
        ValueError: naming the option, when files are given for a non-``tls://`` address, one of
            ``ca_file`` / ``cert`` is missing, a file does not exist, or a ``tls://`` address has
            neither files nor a Dask TLS configuration.
    """
    scheme, _ = _split_address(address)
    given = {"--tls-ca-file": ca_file, "--tls-cert": cert, "--tls-key": key}
    if not any(given.values()):
        if scheme == "tls":
            import dask.config

            if not dask.config.get("distributed.comm.tls.ca-file", None):
                raise ValueError(f"--scheduler {address}: a tls:// scheduler needs --tls-ca-file and --tls-cert "
                                 "(and --tls-key), or Dask's distributed.comm.tls configuration")
        return None
    if scheme != "tls":
        flags = ", ".join(k for k, v in given.items() if v)
        raise ValueError(f"{flags}: TLS needs a tls:// scheduler address, got --scheduler {address}")
    for flag in ("--tls-ca-file", "--tls-cert"):
        if not given[flag]:
            raise ValueError(f"{flag} is missing: TLS to {address} needs --tls-ca-file and --tls-cert")
    for flag, path in given.items():
        if path and not os.path.isfile(path):
            raise ValueError(f"{flag} {path}: no such file")
    from distributed import Security

    return Security(tls_ca_file=ca_file, tls_client_cert=cert, tls_client_key=key, require_encryption=True)


def _dask_cli() -> list[str]:
    exe = shutil.which("dask", path=os.path.dirname(sys.executable)) or shutil.which("dask")
    return [exe] if exe else [sys.executable, "-m", "dask"]


@contextlib.contextmanager
def loopback_cluster(workers: int = 2, timeout: float = 60.0):
    """Run ``dask scheduler`` and ``dask worker`` processes on 127.0.0.1; yields the scheduler address.

    Each command runs in a session of its own, and on exit every process of those sessions (the
    workers' nannies and worker processes included) is terminated, then killed if still there after
    10 s. Traffic stays on the loopback interface.
    """
    from distributed import Client

    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    cli = _dask_cli()
    # workers import the same warpshade as this process (matters for source checkouts)
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = dict(os.environ, PYTHONWARNINGS="ignore",
               PYTHONPATH=os.pathsep.join([root] + [p for p in [os.environ.get("PYTHONPATH")] if p]))
    procs = []
    try:
        procs.append(subprocess.Popen(
            cli + ["scheduler", "--host", "127.0.0.1", "--port", str(port), "--no-dashboard"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env, start_new_session=True))
        procs.append(subprocess.Popen(
            cli + ["worker", address, "--nworkers", str(workers), "--nthreads", "1", "--no-dashboard",
                   "--host", "127.0.0.1"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=env, start_new_session=True))
        deadline = time.monotonic() + timeout
        while True:
            try:
                with Client(address, timeout=5) as c:
                    c.wait_for_workers(workers, timeout=max(1.0, deadline - time.monotonic()))
                break
            except (OSError, TimeoutError):
                if time.monotonic() > deadline:
                    raise TimeoutError(f"Dask cluster at {address} did not start {workers} workers in {timeout} s")
                time.sleep(0.5)
        yield address
    finally:
        stop_sessions(procs)


def stop_sessions(procs: list[subprocess.Popen], grace: float = 10.0) -> None:
    """SIGTERM every process in the sessions led by ``procs`` (started with ``start_new_session``),
    wait up to ``grace`` seconds for the leaders, then SIGKILL whatever is left of the sessions."""
    for sig in (signal.SIGTERM, signal.SIGKILL):
        for p in reversed(procs):
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(p.pid, sig)
        deadline = time.monotonic() + grace
        for p in reversed(procs):
            with contextlib.suppress(subprocess.TimeoutExpired):
                p.wait(max(0.1, deadline - time.monotonic()))
