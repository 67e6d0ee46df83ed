"""``warpshade run``'s start-up: the parent's CPU time before its worker processes exist.

Each run is ``python -m warpshade run --no-progress --workers 2 --frames F`` on the default scene in a fresh
process, watched through ``/proc`` every 5 ms: when its first worker process appears (a child spawned by
``multiprocessing`` or forked from the run, not the resource tracker), the run's own CPU time (utime + stime,
10 ms ticks) and the wall time since launch are read; at the end the wall time and the CPU time of the run and its children.
Throughout, every process of the run (the parent and its workers) is sampled at the same 5 ms: when it was
first and last seen, its CPU time, and how long it slept (state ``S``: a worker waiting for a task or a
streamed frame, the parent waiting for results; a runnable process waiting for a core counts as awake), so
the idle time of the workers can be read at any load.
With ``--against CHECKOUT`` the two checkouts alternate (ABBA), after one untimed run of each (Warp kernels
compiled and the disk cache filled before anything is timed); the load average is recorded before each run.
Linux only.

How to run::

    python benchmarks/run_startup.py --repeat 6 --against ../main --json benchmarks/results/run_startup_startup2.json

Shared, loaded machine: read the CPU times; the wall times stretch with the load.
"""

from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
TICK = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid: int) -> float | None:
    """utime + stime of process ``pid`` [s], None once it is gone."""
    state = cpu_and_state(pid)
    return None if state is None else state[0]


def cpu_and_state(pid: int) -> tuple[float, str] | None:
    """utime + stime of process ``pid`` [s] and its state letter (``R``, ``S``...), None once it is gone."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            fields = f.read().rsplit(")", 1)[1].split()
    except OSError:
        return None
    # fields 3, 14 and 15 of stat(5), counted after the name
    return (int(fields[11]) + int(fields[12])) / TICK, fields[0]


def workers_of(pid: int) -> list[int]:
    """Worker processes of ``pid``: its children started by multiprocessing's spawn (their command line names
    ``multiprocessing``), less its resource tracker, and those forked from it (the parent's command line)."""
    kids = []
    try:
        for task in os.listdir(f"/proc/{pid}/task"):
            with open(f"/proc/{pid}/task/{task}/children") as f:
                kids += [int(k) for k in f.read().split()]
    except OSError:
        return []
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            own = f.read()
    except OSError:
        return []
    found = []
    for k in kids:
        try:
            with open(f"/proc/{k}/cmdline", "rb") as f:
                cmd = f.read()
        except OSError:
            continue
        if (b"multiprocessing" in cmd or cmd == own) and b"resource_tracker" not in cmd:
            found.append(k)
    return found


def one_run(repo: str, frames: int, workers: int) -> dict:
    """One run of checkout ``repo``: the parent's CPU time and the wall time when its first worker appeared,
    and the run's wall and CPU time (children included)."""
    with tempfile.TemporaryDirectory() as d:
        cmd = [sys.executable, "-m", "warpshade", "run", "--no-progress", "--workers", str(workers),
               "--frames", str(frames), "--out", os.path.join(d, "out.usda")]
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        p = subprocess.Popen(cmd, cwd=d, env=dict(os.environ, PYTHONPATH=repo), stdout=subprocess.DEVNULL,
                             stderr=subprocess.PIPE, text=True)
        at_spawn = None
        procs: dict[int, dict] = {}  # pid -> first/last seen [s from launch], cpu [s], slept [s]
        last = t0
        while p.poll() is None:
            now = time.perf_counter()
            kids = workers_of(p.pid)
            if at_spawn is None and kids:
                at_spawn = {"parent_cpu_seconds": cpu_seconds(p.pid), "wall_seconds": now - t0}
            for pid in [p.pid] + kids:
                got = cpu_and_state(pid)
                if got is None:
                    continue
                rec = procs.setdefault(pid, {"role": "parent" if pid == p.pid else "worker", "first_seen": now - t0,
                                             "slept": 0.0})
                rec.update(last_seen=now - t0, cpu=got[0])
                if got[1] == "S":
                    rec["slept"] += now - last
            last = now
            time.sleep(0.005)
        wall = time.perf_counter() - t0
        err = p.stderr.read()
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode:
        raise RuntimeError(f"warpshade run failed ({p.returncode}): {err[-2000:]}")
    return {"at_workers": at_spawn, "wall_seconds": wall,
            "cpu_seconds": after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime,
            "processes": [{k: round(v, 3) if isinstance(v, float) else v for k, v in rec.items()}
                          for rec in procs.values()]}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=4, help="rounds (each: one run of each checkout)")
    ap.add_argument("--frames", type=int, default=10)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--against", default=None, metavar="CHECKOUT", help="another checkout, alternated with this one")
    ap.add_argument("--json", default=None, metavar="PATH")
    args = ap.parse_args(argv)
    trees = [REPO] + ([os.path.abspath(args.against)] if args.against else [])
    for repo in trees:  # untimed: kernels compiled, disk cache filled
        one_run(repo, args.frames, args.workers)
    runs = []
    for r in range(args.repeat):
        for repo in (trees if r % 2 == 0 else trees[::-1]):
            load = os.getloadavg()[0]
            run = {"repo": repo, "load_average": load, **one_run(repo, args.frames, args.workers)}
            runs.append(run)
            s = run["at_workers"] or {}
            print(f"round {r} {repo}: parent CPU before the workers {s.get('parent_cpu_seconds')} s "
                  f"(wall {s.get('wall_seconds', float('nan')):.2f} s); run {run['wall_seconds']:.2f} s wall, "
                  f"{run['cpu_seconds']:.2f} s CPU (load {load:.2f})", flush=True)
            for rec in run["processes"]:
                print(f"    {rec['role']}: seen {rec['first_seen']:.2f}-{rec['last_seen']:.2f} s, CPU {rec['cpu']:.2f} s, "
                      f"slept {rec['slept']:.2f} s", flush=True)
    med = {}
    for repo in trees:
        mine = [x for x in runs if x["repo"] == repo and x["at_workers"]]
        med[repo] = {"parent_cpu_before_workers": statistics.median(x["at_workers"]["parent_cpu_seconds"] for x in mine),
                     "wall_before_workers": statistics.median(x["at_workers"]["wall_seconds"] for x in mine),
                     "wall_seconds": statistics.median(x["wall_seconds"] for x in mine),
                     "cpu_seconds": statistics.median(x["cpu_seconds"] for x in mine),
                     "workers_slept": statistics.median(sum(p["slept"] for p in x["processes"] if p["role"] == "worker")
                                                        for x in mine)}
        print(f"median {repo}: " + ", ".join(f"{k} {v:.2f} s" for k, v in med[repo].items()))
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"what": __doc__.split("\n\n")[1], "command": f"python -m warpshade run --no-progress --workers "
                       f"{args.workers} --frames {args.frames}", "checkouts": trees, "runs": runs, "median": med},
                      f, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
