"""The default scene end to end: ``python -m warpshade run --no-progress`` wall time, one worker
against two, and where the time goes.

What it shows (issue 18, target 5: 120 frames <= 5 s warm wall, two workers >= 1.9x one):

* ``runs``: the command as a user types it (fresh process, the default scene, its 120 frames), a
  first untimed run to warm the Warp kernel cache, then ``--repeat`` rounds of ``--workers 1`` and
  ``--workers 2`` alternately (interleaved: load drift hits both), each with the wall time of the
  whole process, the part of it after the run printed its last line (the output's path: the
  interpreter's shutdown, ``exit_seconds``) and the stage times the run prints (load, setup,
  simulate, shade summed over workers, write, total).
* ``profile``: one inline run (``--workers 0``) in this process under ``cProfile``: the functions with
  the most cumulative time, and the split of shading into the group's front and back passes and the
  rest (lights, exit radiance, between-group shadows), from timers around ``_Group.update`` and
  ``_Group.update_back``.

* ``--cold ROUNDS``: instead, first runs as after installing (an empty Warp kernel cache and an empty
  warpshade cache, two workers), wall and CPU time; ``--against CHECKOUT`` alternates them with another
  checkout's (e.g. main's, to compare a change of the compile time).
* ``--against CHECKOUT`` without ``--cold``: warm runs with one and two workers of both checkouts, in
  alternate order from round to round, with the load average before each run; medians of wall and
  CPU time per checkout and worker count.

How to run::

    python benchmarks/default_run.py --repeat 3 --json benchmarks/results/default_run.json
    python benchmarks/default_run.py --cold 3 --against ../main --json benchmarks/results/first_run.json
    python benchmarks/default_run.py --repeat 3 --against ../main --json benchmarks/results/default_run_startup.json

Shared, loaded 2-core machine: read the ratios, and the stage split, more than the absolute times.
"""

from __future__ import annotations

import argparse
import cProfile
import io
import json
import os
import pstats
import re
import resource
import statistics
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
STAGES = re.compile(r"load ([\d.]+) s \| setup ([\d.]+) s \| simulate ([\d.]+) s .*\| shade ([\d.]+) s .*\| "
                    r"write ([\d.]+) s .*\| total ([\d.]+) s")


def one_run(workers: int, frames: int | None, extra: list[str], repo: str = REPO, cold: bool = False) -> dict:
    """One ``warpshade run`` of checkout ``repo`` in a fresh process: wall time, CPU time of the process and
    its workers, and the printed stage times [s]. ``cold``: with an empty Warp kernel cache and an empty
    warpshade cache (``WARP_CACHE_PATH``, ``WARPSHADE_CACHE`` in the run's temporary directory), as a
    first run after installing."""
    with tempfile.TemporaryDirectory() as d:
        cmd = [sys.executable, "-m", "warpshade", "run", "--no-progress", "--out", os.path.join(d, "out.usda"),
               "--workers", str(workers)] + (["--frames", str(frames)] if frames else []) + extra
        env = dict(os.environ, PYTHONPATH=repo)
        if cold:
            env.update(WARP_CACHE_PATH=os.path.join(d, "warp"), WARPSHADE_CACHE=os.path.join(d, "warpshade"))
        before = resource.getrusage(resource.RUSAGE_CHILDREN)
        t0 = time.perf_counter()
        p = subprocess.Popen(cmd, cwd=d, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        p.stdout.readline()  # the output's path, the run's last line (its stderr is a few lines: no deadlock)
        printed = time.perf_counter() - t0
        _, stderr = p.communicate()
        wall = time.perf_counter() - t0
        after = resource.getrusage(resource.RUSAGE_CHILDREN)
    if p.returncode:
        raise RuntimeError(f"warpshade run failed ({p.returncode}): {stderr[-2000:]}")
    m = STAGES.search(stderr)
    stages = dict(zip(("load", "setup", "simulate", "shade", "write", "total"), map(float, m.groups()))) if m else {}
    cpu = after.ru_utime + after.ru_stime - before.ru_utime - before.ru_stime
    return {"workers": workers, "wall_seconds": wall, "cpu_seconds": cpu, "stages": stages,
            "exit_seconds": wall - printed}


def cold_rounds(rounds: int, against: str | None, frames: int | None, extra: list[str]) -> dict:
    """``rounds`` cold first runs (two workers) of this checkout and, with ``against``, of that checkout
    too, alternately (ABBA order: load drift hits both alike); the runs and the medians."""
    trees = [REPO] + ([os.path.abspath(against)] if against else [])
    runs = []
    for r in range(rounds):
        for repo in (trees if r % 2 == 0 else trees[::-1]):
            runs.append({"repo": repo, **one_run(2, frames, extra, repo=repo, cold=True)})
            print(f"cold round {r} {repo}: {runs[-1]['wall_seconds']:.1f} s wall, {runs[-1]['cpu_seconds']:.1f} s CPU",
                  flush=True)
    med = {}
    for repo in trees:
        mine = [x for x in runs if x["repo"] == repo]
        med[repo] = {k: statistics.median(x[k] for x in mine) for k in ("wall_seconds", "cpu_seconds")}
        print(f"median cold {repo}: {med[repo]['wall_seconds']:.1f} s wall, {med[repo]['cpu_seconds']:.1f} s CPU")
    return {"command": "python -m warpshade run --no-progress --workers 2, WARP_CACHE_PATH and WARPSHADE_CACHE "
                       "empty " + " ".join(extra), "runs": runs, "median": med}


def warm_rounds(rounds: int, against: str, frames: int | None, extra: list[str]) -> dict:
    """``rounds`` rounds of warm runs with one and two workers of this checkout and of ``against``, the two
    checkouts in alternate order from round to round (load drift hits both alike); one untimed run of each
    first warms the kernel cache. The runs, the load average before each, and per checkout and worker
    count the medians of wall and CPU time (the run's and its workers')."""
    trees = [REPO, os.path.abspath(against)]
    for repo in trees:
        one_run(2, frames, extra, repo=repo)
    runs = []
    for r in range(rounds):
        for repo in (trees if r % 2 == 0 else trees[::-1]):
            for w in (1, 2):
                load = os.getloadavg()[0]
                runs.append({"repo": repo, "load_average": load, **one_run(w, frames, extra, repo=repo)})
                print(f"round {r} {repo} workers {w}: {runs[-1]['wall_seconds']:.2f} s wall, "
                      f"{runs[-1]['cpu_seconds']:.2f} s CPU, {runs[-1]['exit_seconds']:.2f} s after the last line "
                      f"(load {load:.2f})", flush=True)
    med = {}
    for repo in trees:
        for w in (1, 2):
            mine = [x for x in runs if x["repo"] == repo and x["workers"] == w]
            med[f"{repo} workers {w}"] = {k: statistics.median(x[k] for x in mine)
                                          for k in ("wall_seconds", "cpu_seconds", "exit_seconds")}
        m1, m2 = med[f"{repo} workers 1"], med[f"{repo} workers 2"]
        print(f"median {repo}: 1 worker {m1['wall_seconds']:.2f} s wall {m1['cpu_seconds']:.2f} s CPU, 2 workers "
              f"{m2['wall_seconds']:.2f} s wall {m2['cpu_seconds']:.2f} s CPU, "
              f"{m1['wall_seconds'] / m2['wall_seconds']:.2f}x")
    return {"command": "python -m warpshade run --no-progress --workers W " + " ".join(extra), "frames": frames or 120,
            "checkouts": trees, "runs": runs, "median": med}


def profile_inline(frames: int | None, top: int = 25) -> dict:
    """cProfile of an inline run (``workers=0``) and the split of the group passes' time."""
    sys.path.insert(0, REPO)
    from warpshade.pipeline import Pipeline, shading
    from warpshade.usd import AnimationWriter, read_scene
    from warpshade.usd.shipped import shipped_scene

    split = {"front": 0.0, "back": 0.0}
    originals = {"front": shading._Group.update, "back": shading._Group.update_back}

    def timed(key):
        real = originals[key]

        def wrapped(self, *a, **k):
            t = time.perf_counter()
            out = real(self, *a, **k)
            split[key] += time.perf_counter() - t
            return out
        return wrapped

    # the group's front pass (_Group.update) and back pass (_Group.update_back: its method's update, or
    # compute_rows at the two-sided rows through update_rows), each with its NumPy copies
    shading._Group.update, shading._Group.update_back = timed("front"), timed("back")
    try:
        scene = read_scene(shipped_scene("default.usda"))
        with tempfile.TemporaryDirectory() as d:
            pipe = Pipeline(scene, frames=frames, workers=0)
            writer = AnimationWriter(os.path.join(d, "out.usda"), fps=scene.fps, up_axis=scene.up_axis,
                                     meters_per_unit=scene.meters_per_unit)
            prof = cProfile.Profile()
            t0 = time.perf_counter()
            prof.enable()
            report = pipe.run(writer, progress=False)
            prof.disable()
            wall = time.perf_counter() - t0
    finally:
        shading._Group.update, shading._Group.update_back = originals["front"], originals["back"]
    s = io.StringIO()
    pstats.Stats(prof, stream=s).sort_stats("cumulative").print_stats(top)
    return {"frames": report.frames, "wall_seconds": wall, "stages": report.seconds,
            "shade_split": {**split, "other": report.seconds["shade"] - split["front"] - split["back"]},
            "top_cumulative": s.getvalue()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=2, help="rounds of --workers 1 and 2 after the warm-up run")
    ap.add_argument("--frames", type=int, default=None, help="frames (default: the scene's 120)")
    ap.add_argument("--no-profile", action="store_true")
    ap.add_argument("--json", default=None, metavar="PATH")
    ap.add_argument("--also", default=None, metavar="OPTIONS",
                    help="a third configuration in every round: --workers 2 with these run options as well "
                         "(e.g. '--reuse off'), interleaved with the other two")
    ap.add_argument("--cold", type=int, default=0, metavar="ROUNDS",
                    help="instead: ROUNDS first runs with empty caches (two workers; wall and CPU time)")
    ap.add_argument("--against", default=None, metavar="CHECKOUT",
                    help="another checkout's runs alternate with this one's (e.g. main's): with --cold the cold "
                         "runs, else --repeat rounds of warm runs with one and two workers (no profile)")
    ap.add_argument("extra", nargs="*", help="more warpshade run options (after --)")
    args = ap.parse_args(argv)
    if args.cold or args.against:
        rounds = (cold_rounds(args.cold, args.against, args.frames, args.extra) if args.cold
                  else warm_rounds(args.repeat, args.against, args.frames, args.extra))
        out = {**rounds, "machine": "shared 2-core VM, other jobs running (loaded)"}
        if args.json:
            with open(args.json, "w") as f:
                json.dump(out, f, indent=2)
            print(f"wrote {args.json}")
        return 0
    warm = one_run(2, args.frames, args.extra)  # warms the kernel cache (and is timed, for the record)
    print(f"first run (kernel cache maybe cold): {warm['wall_seconds']:.1f} s wall {warm['stages']}", flush=True)
    also = args.also.split() if args.also else []
    runs = []
    for r in range(args.repeat):
        for w in (1, 2):
            runs.append(one_run(w, args.frames, args.extra))
            print(f"round {r} workers {w}: {runs[-1]['wall_seconds']:.1f} s wall {runs[-1]['stages']}", flush=True)
        if also:
            runs.append({**one_run(2, args.frames, args.extra + also), "also": args.also})
            print(f"round {r} workers 2 {args.also}: {runs[-1]['wall_seconds']:.1f} s wall {runs[-1]['stages']}",
                  flush=True)
    med = {}
    for w in (1, 2):
        walls = sorted(x["wall_seconds"] for x in runs if x["workers"] == w and "also" not in x)
        med[w] = walls[len(walls) // 2]
    print(f"median warm wall: 1 worker {med[1]:.1f} s, 2 workers {med[2]:.1f} s, ratio {med[1] / med[2]:.2f}x")
    if also:
        walls = sorted(x["wall_seconds"] for x in runs if "also" in x)
        med["also"] = walls[len(walls) // 2]
        print(f"median warm wall: 2 workers {args.also} {med['also']:.1f} s, {med[2] / med['also']:.2f}x faster "
              f"than 2 workers without")
    out = {"command": "python -m warpshade run --no-progress --workers W " + " ".join(args.extra),
           "frames": args.frames or 120, "first_run": warm, "runs": runs,
           "median_wall_seconds": {str(k): v for k, v in med.items()}, "speedup_two_workers": med[1] / med[2],
           "also": args.also,
           "machine": "shared 2-core VM, other jobs running (loaded)"}
    if not args.no_profile:
        prof = profile_inline(args.frames)
        print(f"inline profile: {prof['wall_seconds']:.1f} s wall, stages {prof['stages']}, "
              f"shade split {prof['shade_split']}")
        print(prof["top_cumulative"])
        out["profile_inline"] = prof
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=2)
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
