"""The fault-injection probes of issue 16, one by one: each injects its fault into a real
``python -m warpshade`` process (or the Python API where the probe is about the API) and prints
PASS or FAIL with what it observed.

The probes are the bullet list of issue 16 ("Nothing lost, nothing written where it does not
belong"), in its order. Each one checks the outcome the issue asks for (files kept, files not
written, processes gone, message text, time to answer), not only the exit code. The tests in
``tests/cli/test_faults.py``, ``tests/parallel/test_scheduler.py``, ``tests/cli/test_cli_errors.py`` and
``tests/visibility/test_extremes.py`` pin the same behaviour; this script re-runs the issue's list as a user
would meet it, on small inputs, in a few minutes.

How to run::

    python benchmarks/fault_probes.py                       # all probes
    python benchmarks/fault_probes.py --only disk sigint    # probes whose name contains a word
    python benchmarks/fault_probes.py --json benchmarks/results/fault_probes.json

Disk full uses a real 2 MB tmpfs when ``mount`` works (root), else a per-file size limit
(``RLIMIT_FSIZE``, the ``ulimit -f`` of the shell: a write past it fails with EFBIG, as a full
disk fails with ENOSPC). Times are wall times on whatever machine runs it; the bounds they are
checked against (a few seconds) are the issue's, not speed targets.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import re
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
import traceback

HERE = os.path.dirname(os.path.abspath(__file__))
REPO = os.path.dirname(HERE)
sys.path.insert(0, REPO)
ENV = dict(os.environ, PYTHONPATH=REPO + os.pathsep + os.environ.get("PYTHONPATH", ""), MPLBACKEND="Agg")
SCENE = os.path.join(REPO, "usd_scenes", "cloth_sphere.usda")
COMMON = ["--method", "reference", "--rays", "4", "--order", "2", "--chunk", "2", "--no-progress"]
FRAMES = 6
TIMEOUT = 600
PY = [sys.executable, "-m", "warpshade"]

PROBES = []


def probe(name: str):
    """Register ``fn(tmp) -> (ok, observed)`` under the issue's wording ``name``."""
    def deco(fn):
        PROBES.append((name, fn))
        return fn
    return deco


def ws(*args, env=None, timeout=TIMEOUT, **kw) -> subprocess.CompletedProcess:
    return subprocess.run(PY + [str(a) for a in args], capture_output=True, text=True, env=env or ENV,
                          timeout=timeout, **kw)


def run_scene(out, *extra, scene=SCENE, frames=FRAMES, **kw):
    return ws("run", scene, "--frames", frames, "--out", out, "--workers", "0", *COMMON, *extra, **kw)


def last_line(text: str) -> str:
    lines = [ln for ln in text.strip().splitlines() if ln.strip()]
    return lines[-1] if lines else ""


def litter(root) -> list[str]:
    out = []
    for d, _dirs, files in os.walk(root):
        out += [os.path.join(d, f) for f in files if ".partial" in f or f.endswith(".lock")]
    return sorted(out)


def frames_of(path) -> dict:
    """{prim: [(points, colors) per frame]} read back by warpshade.usd.ShadedStage (value clips resolved)."""
    from warpshade.usd import ShadedStage

    stage = ShadedStage(path)
    out = {}
    for f in range(int(stage.start), int(stage.end) + 1):
        for name, points, _, colors in stage.frame(f):
            out.setdefault(name, []).append((points, colors))
    return out


def same_frames(a: dict, b: dict) -> bool:
    import numpy as np

    return a.keys() == b.keys() and all(
        len(a[k]) == len(b[k]) and all(np.array_equal(pa, pb) and np.array_equal(ca, cb)
                                       for (pa, ca), (pb, cb) in zip(a[k], b[k])) for k in a)


def end_frame(path) -> int:
    from pxr import Usd

    return int(Usd.Stage.Open(str(path)).GetEndTimeCode()) if os.path.exists(path) else -1


def live_processes() -> dict[int, list[str]]:
    """``{pid: /proc/PID/stat fields after the name}`` of live, non-zombie processes ([1] ppid, [3] session)."""
    out = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            with contextlib.suppress(OSError):
                with open(f"/proc/{d}/stat") as f:
                    fields = f.read().rsplit(")", 1)[1].split()
                if fields[0] != "Z":
                    out[int(d)] = fields
    return out


def descendants(pid: int) -> set[int]:
    procs, found, todo = live_processes(), set(), [pid]
    while todo:
        p = todo.pop()
        kids = {q for q, f in procs.items() if int(f[1]) == p} - found
        found |= kids
        todo += kids
    return found


def wait_gone(pids, seconds: float) -> set[int]:
    deadline = time.monotonic() + seconds
    while (left := set(pids) & set(live_processes())) and time.monotonic() < deadline:
        time.sleep(0.1)
    return left


def start(args, **kw) -> subprocess.Popen:
    return subprocess.Popen(PY + [str(a) for a in args], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            text=True, env=ENV, **kw)


@contextlib.contextmanager
def group_killed_on_exit(proc: subprocess.Popen):
    """The probe's process group is SIGKILLed when the block ends with it still running."""
    try:
        yield proc
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def ctrl_c(proc: subprocess.Popen) -> tuple[str, float]:
    """SIGINT to the process group, as a terminal sends Ctrl-C: (stderr, seconds until it exited)."""
    t = time.monotonic()
    os.killpg(proc.pid, signal.SIGINT)
    err = proc.communicate(timeout=120)[1]
    return err, time.monotonic() - t


def until(cond, seconds: float, proc=None, step: float = 0.1) -> bool:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        if cond():
            return True
        if proc is not None and proc.poll() is not None:
            return bool(cond())
        time.sleep(step)
    return False


def edited_scene(tmp, name: str, old: str, new: str) -> str:
    text = open(SCENE).read()
    assert old in text, old
    path = os.path.join(tmp, name)
    with open(path, "w") as f:
        f.write(text.replace(old, new, 1))
    return path


_UNINTERRUPTED = {}


def uninterrupted() -> dict:
    """The frames of an uninterrupted ``--workers 0`` run of SCENE with COMMON (computed once)."""
    if not _UNINTERRUPTED:
        d = tempfile.mkdtemp(prefix="ws-probe-full-")
        r = run_scene(os.path.join(d, "full.usda"))
        assert r.returncode == 0, r.stderr
        _UNINTERRUPTED["frames"] = frames_of(os.path.join(d, "full.usda"))
        _UNINTERRUPTED["sizes"] = {f: os.path.getsize(os.path.join(dp, f)) for dp, _, fs in os.walk(d) for f in fs}
        shutil.rmtree(d)
    return _UNINTERRUPTED["frames"]


# ------------------------------------------------------------------------------------------------ probes
@probe("disk full: one message naming the file, no crash, no litter, committed frames kept, --resume completes")
def disk_full(tmp):
    full = uninterrupted()
    disk = os.path.join(tmp, "disk")
    os.mkdir(disk)
    mounted = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", disk], capture_output=True).returncode == 0
    try:
        out = os.path.join(disk, "o.usda")
        if mounted:  # leave room for the top file and a clip or two (~0.14 MB + ~0.2 MB per clip)
            st = os.statvfs(disk)
            with open(os.path.join(disk, "fill"), "wb") as f:
                f.write(b"\0" * (st.f_bavail * st.f_frsize - 560_000))
            how, limit = "2 MB tmpfs filled to 560 kB free", None
        else:  # per-file limit between the first clip file's size and the next one's
            sizes = _UNINTERRUPTED["sizes"]
            limit = (sizes["chunk_000000.usdc"] + sizes["chunk_000002.usdc"]) // 2
            how = f"RLIMIT_FSIZE {limit} bytes"

        def limited():
            if limit:
                resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

        r = run_scene(out, preexec_fn=limited)
        kept = end_frame(out) + 1
        left = litter(disk)
        msg = [ln for ln in r.stderr.splitlines() if "error" in ln]
        if mounted:
            os.unlink(os.path.join(disk, "fill"))
        r2 = run_scene(out, "--resume")
        same = r2.returncode == 0 and same_frames(frames_of(out), full)
        ok = (r.returncode == 1 and "Traceback" not in r.stderr and len(msg) == 1 and ".usd" in msg[0]
              and ("No space left" in msg[0] or "File too large" in msg[0]) and not left
              and 0 < kept < FRAMES and f"{kept} complete frames kept" in r.stderr and same and not litter(disk))
        return ok, (f"{how}: rc {r.returncode}, {msg[0] if msg else 'no error line'!r}; {kept} frames kept, "
                    f"litter {len(left)}; --resume rc {r2.returncode}, frames identical to an uninterrupted run: {same}")
    finally:
        if mounted:
            subprocess.run(["umount", "-l", disk], check=False)


@probe("--out X.usdc beside an existing X.usda keeps X.usda's clips")
def usdc_beside_usda(tmp):
    a, c = os.path.join(tmp, "X.usda"), os.path.join(tmp, "X.usdc")
    r1 = run_scene(a, frames=3)
    before = frames_of(a)
    r2 = run_scene(c, frames=2)
    after = frames_of(a)
    ok = r1.returncode == 0 and r2.returncode == 0 and same_frames(before, after) and end_frame(c) == 1
    return ok, (f"X.usda rc {r1.returncode}, X.usdc rc {r2.returncode}; X.usda still has its {end_frame(a) + 1} frames "
                f"unchanged: {same_frames(before, after)}; folders {sorted(d for d in os.listdir(tmp) if d.endswith('frames'))}")


@probe("--out equal to the input scene is refused and the scene is unchanged")
def out_is_input(tmp):
    scene = os.path.join(tmp, "scene.usda")
    shutil.copy(SCENE, scene)
    before = open(scene, "rb").read()
    r = run_scene(scene, scene=scene, frames=2)
    ok = r.returncode == 1 and "is an input of the scene" in r.stderr and open(scene, "rb").read() == before \
        and os.listdir(tmp) == ["scene.usda"]
    return ok, f"rc {r.returncode}, {last_line(r.stderr)!r}; scene unchanged: {open(scene, 'rb').read() == before}"


def scene_without_lights(tmp) -> str:
    text = open(SCENE).read()
    path = os.path.join(tmp, "nolights.usda")
    with open(path, "w") as f:
        f.write(text[:text.index('    def "Lights"')].rstrip() + "\n}\n")
    return path


@probe("two runs on one output: the second is refused, the first keeps its DomeLight texture")
def two_runs(tmp):
    from pxr import Usd

    scene = scene_without_lights(tmp)  # a run then writes the default sky texture beside its clips
    out = os.path.join(tmp, "X.usda")
    first = start(["run", scene, "--frames", 2000, "--out", out, "--workers", "0"] + COMMON)
    try:
        until(lambda: os.path.exists(out), 300, first)
        second = run_scene(out, scene=scene, frames=2)
        first.send_signal(signal.SIGTERM)
        err = first.communicate(timeout=60)[1]
    finally:
        if first.poll() is None:
            first.kill()
    stage = Usd.Stage.Open(out)
    dome = next(p for p in stage.Traverse() if p.GetTypeName() == "DomeLight")
    tex = dome.GetAttribute("inputs:texture:file").Get().resolvedPath
    refused = f"is being written by another run (pid {first.pid} " in second.stderr
    ok = second.returncode == 1 and refused and first.returncode == 143 and bool(tex) and os.path.isfile(tex) \
        and not litter(tmp)
    return ok, (f"second run rc {second.returncode}: {last_line(second.stderr)!r}; first run rc {first.returncode} "
                f"({last_line(err)!r}); its texture exists: {bool(tex) and os.path.isfile(tex)}")


def refused_light(tmp, old, new, expect):
    scene = edited_scene(tmp, "hot.usda", old, new)
    out = os.path.join(tmp, "o.usda")
    r = run_scene(out, scene=scene, frames=2)
    ok = r.returncode == 1 and expect in r.stderr and sorted(os.listdir(tmp)) == ["hot.usda"]
    return ok, f"rc {r.returncode}, {last_line(r.stderr)!r}, nothing written: {sorted(os.listdir(tmp)) == ['hot.usda']}"


@probe("DistantLight at 1e38 x 2^200 is refused up front, naming the light")
def hot_sun(tmp):
    return refused_light(tmp, "float inputs:intensity = 3",
                         "float inputs:intensity = 1e38\n            float inputs:exposure = 200",
                         "/World/Lights/Sun: irradiance overflows float32")


@probe("DomeLight at 3e38 is refused up front, naming the light")
def hot_dome(tmp):
    return refused_light(tmp, "float inputs:intensity = 0.6", "float inputs:intensity = 3e38",
                         "/World/Lights/Sky: its SH radiance reaches")


@probe("ConstantEnvironment(3e38) and DirectionalLight(irradiance=-1) are refused in the Python API")
def api_lights(tmp):
    from warpshade.lighting import ConstantEnvironment, DirectionalLight

    seen = []
    for make in (lambda: ConstantEnvironment(radiance=3e38, name="sky").sh(2),
                 lambda: DirectionalLight(direction=(0, 1, 0), irradiance=-1, name="sun")):
        try:
            make()
            seen.append("accepted")
        except ValueError as exc:
            seen.append(f"ValueError: {exc}")
    ok = seen[0].startswith("ValueError: sky: its SH radiance") and \
        seen[1].startswith("ValueError: sun: irradiance must not be negative")
    return ok, "; ".join(seen)


def signal_run(tmp, sig):
    out = os.path.join(tmp, "o.usda")
    proc = start(["run", SCENE, "--frames", 2000, "--out", out, "--workers", "2"] + COMMON)
    kids = set()
    try:
        def shading():
            kids.update(descendants(proc.pid))
            return end_frame(out) >= 3

        until(shading, 300, proc, step=0.2)
        kids |= descendants(proc.pid)
        seen = end_frame(out)
        t = time.monotonic()
        proc.send_signal(sig)
        err = proc.communicate(timeout=60)[1]
        answered = time.monotonic() - t
    finally:
        if proc.poll() is None:
            proc.kill()
    left = wait_gone(kids, 5.0)
    return proc, err, kids, left, seen, end_frame(out), answered


@probe("SIGKILL with --workers 2: no process left behind")
def sigkill(tmp):
    proc, err, kids, left, seen, end, _ = signal_run(tmp, signal.SIGKILL)
    ok = len(kids) >= 3 and not left and seen >= 3
    return ok, f"{len(kids)} child processes (2 workers + resource tracker); alive 5 s after SIGKILL: {len(left)}"


@probe("SIGTERM with --workers 2: finished frames committed, one line, no process left behind")
def sigterm(tmp):
    proc, err, kids, left, seen, end, answered = signal_run(tmp, signal.SIGTERM)
    ok = proc.returncode == 143 and not left and seen <= end and f"{end + 1} complete frames kept" in err \
        and "Traceback" not in err and not litter(tmp)
    return ok, (f"rc {proc.returncode} after {answered:.1f} s, {last_line(err)!r}; frames {end + 1} (>= {seen + 1} "
                f"seen before the signal); {len(kids)} children, alive after 5 s: {len(left)}")


@probe("Ctrl-C with --scheduler local --workers 2 (a LocalCluster): no worker traceback, no process left behind")
def local_cluster_sigint(tmp):
    out = os.path.join(tmp, "o.usda")
    proc = start(["run", SCENE, "--frames", 2000, "--out", out, "--scheduler", "local", "--workers", "2"] + COMMON,
                 start_new_session=True)
    with group_killed_on_exit(proc):
        until(lambda: end_frame(out) >= 3, 300, proc, step=0.3)
        kids = descendants(proc.pid)
        err, answered = ctrl_c(proc)
    left = wait_gone(kids, 10.0)
    ok = proc.returncode == 130 and "Traceback" not in err and "KeyboardInterrupt" not in err and not left \
        and "complete frames kept" in last_line(err)
    return ok, (f"rc {proc.returncode} after {answered:.1f} s; tracebacks {err.count('Traceback')}; stderr lines "
                f"{len(err.strip().splitlines())}; last {last_line(err)[:70]!r}; processes left {len(left)}"
                + (f"; stderr: {err!r}" if not ok else ""))


@probe('scene knob warpshade:knobs:lut_dir = "../../../x" writes nothing there')
def lut_dir(tmp):
    deep = os.path.join(tmp, "a", "b", "c")
    os.makedirs(deep)
    text = open(SCENE).read().replace('        custom token warpshade:kind = "cloth"',
                                      '        custom token warpshade:kind = "cloth"\n'
                                      '        custom string warpshade:knobs:lut_dir = "../../../x"', 1)
    scene = os.path.join(deep, "steer.usda")
    with open(scene, "w") as f:
        f.write(text)
    r = ws("run", scene, "--frames", 1, "--out", os.path.join(deep, "o.usda"), "--workers", "0", "--method",
           "hemiraster", "--order", "2", "--no-progress", cwd=deep)
    made = [p for p in ("x", "a/x", "a/b/x") if os.path.exists(os.path.join(tmp, p))]
    warned = "lut_dir ignored" in r.stderr
    ok = r.returncode == 0 and warned and not made
    return ok, f"rc {r.returncode}; warning: {warned}; directories created by the scene's path: {made or 'none'}"


@probe("hand-edited clip manifestAssetPath + --resume touches nothing outside OUT_frames/")
def manifest_resume(tmp):
    from pxr import Sdf

    out = os.path.join(tmp, "o.usda")
    r0 = run_scene(out, frames=2)
    decoy = os.path.join(tmp, "precious", "run-x")
    os.makedirs(decoy)
    for f in ("chunk_000000.usdc", "manifest.usda", "keep.partial.usdc"):
        with open(os.path.join(decoy, f), "wb") as fh:
            fh.write(b"precious")
    layer = Sdf.Layer.FindOrOpen(out)
    d = dict(dict(layer.GetPrimAtPath("/World").GetInfo("clips"))["default"])
    d["manifestAssetPath"] = Sdf.AssetPath("./precious/run-x/manifest.usda")
    d["assetPaths"] = Sdf.AssetPathArray([Sdf.AssetPath("./precious/run-x/chunk_000000.usdc")])
    layer.GetPrimAtPath("/World").SetInfo("clips", {"default": d})
    layer.Save()
    del layer
    r = run_scene(out, "--resume", frames=4)
    intact = sorted(os.listdir(decoy)) == ["chunk_000000.usdc", "keep.partial.usdc", "manifest.usda"] and all(
        open(os.path.join(decoy, f), "rb").read() == b"precious" for f in os.listdir(decoy))
    ok = r0.returncode == 0 and r.returncode == 1 and "cannot resume" in r.stderr and intact
    return ok, f"rc {r.returncode}, {last_line(r.stderr)!r}; decoy files intact: {intact}"


@probe("--scheduler to a non-loopback address without TLS warns in one line")
def scheduler_warning(tmp):
    env = dict(ENV, DASK_DISTRIBUTED__COMM__TIMEOUTS__CONNECT="2s")
    r = ws("run", SCENE, "--frames", 2, "--out", os.path.join(tmp, "o.usda"), "--scheduler", "tcp://0.0.0.0:1",
           *COMMON, env=env)
    warn = [ln for ln in r.stderr.splitlines() if "warning" in ln]
    ok = r.returncode == 1 and len(warn) == 1 and "not encrypted" in warn[0] and "Traceback" not in r.stderr
    return ok, f"rc {r.returncode}; warning lines {len(warn)}: {warn[0][:90] + '...' if warn else ''}"


@probe("cluster path end to end: dask scheduler + dask worker --nworkers 2, frames identical to --workers 1")
def cluster(tmp):
    from warpshade.parallel.cluster import stop_sessions

    dask = os.path.join(os.path.dirname(sys.executable), "dask")
    dask = [dask] if os.path.exists(dask) else [sys.executable, "-m", "dask"]
    one = os.path.join(tmp, "one.usda")
    r1 = ws("run", SCENE, "--frames", FRAMES, "--out", one, "--workers", "1", *COMMON)
    sched_file = os.path.join(tmp, "scheduler.json")
    log = open(os.path.join(tmp, "cluster.log"), "wb")
    procs = [subprocess.Popen(dask + ["scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                                      "--scheduler-file", sched_file], stdout=log, stderr=log, env=ENV,
                              start_new_session=True)]
    members: set[int] = set()
    try:
        until(lambda: os.path.exists(sched_file) and open(sched_file).read().strip(), 120)
        time.sleep(0.2)
        address = json.load(open(sched_file))["address"]
        procs.append(subprocess.Popen(dask + ["worker", "--scheduler-file", sched_file, "--nworkers", "2",
                                              "--nthreads", "1", "--no-dashboard", "--host", "127.0.0.1"],
                                      stdout=log, stderr=log, env=ENV, start_new_session=True))
        out = os.path.join(tmp, "cluster.usda")
        r = ws("run", SCENE, "--frames", FRAMES, "--out", out, "--scheduler", address, *COMMON)
        members = {p for p, f in live_processes().items() if int(f[3]) in [q.pid for q in procs]}
    finally:
        stop_sessions(procs)
        log.close()
    left = wait_gone(members, 10.0)
    same = r.returncode == 0 and r1.returncode == 0 and same_frames(frames_of(out), frames_of(one))
    return same and not left, (f"run rc {r.returncode} ({last_line(r.stderr)[:80]!r}); frames bit-identical to "
                               f"--workers 1: {same}; cluster processes left: {len(left)}")


@probe("hemiraster (and every method) scale-invariant vertex by vertex at x1e-2 / x1e4 (max over vertices)")
def scale_invariance(tmp):
    import numpy as np

    sys.path.insert(0, os.path.join(REPO, "tests"))
    from test_extremes import SCALE_TOL, UNOCCLUDED_DC, bumpy_scene, make  # the tests' scene and knobs

    from warpshade.geometry import TriMesh
    from warpshade.visibility import METHODS

    from warpshade.parallel.runtime import init_warp

    init_warp()
    m, worst, bad = bumpy_scene(), {}, []
    for name in sorted(METHODS):
        base = make(name, m).update().numpy()
        for s in (1e-4, 1e-2, 1e4):
            got = make(name, TriMesh(m.points.astype(np.float32) * np.float32(s), m.faces)).update().numpy()
            d = float(np.abs(got - base).max() / UNOCCLUDED_DC)
            worst[name] = max(worst.get(name, 0.0), d)
            if d * UNOCCLUDED_DC > SCALE_TOL:
                bad.append(f"{name} x{s:g}")
    return not bad, ("largest change of any coefficient of any vertex, of the DC, over x1e-4, x1e-2, x1e4: "
                     + ", ".join(f"{k} {v:.1e}" for k, v in worst.items()) + (f"; over 1e-4: {bad}" if bad else ""))


def big_scene(tmp, n: int) -> str:
    """An n x n vertex ground (static) under the cloth_sphere scene's light: n*n vertices to shade."""
    import numpy as np
    from pxr import Usd, UsdGeom, Vt

    path = os.path.join(tmp, f"big{n}.usda")
    stage = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageUpAxis(stage, "Z")
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    x = np.linspace(-5, 5, n, dtype=np.float32)
    gx, gy = np.meshgrid(x, x)
    pts = np.stack([gx.ravel(), gy.ravel(), np.zeros(n * n, np.float32)], 1)
    i = np.arange(n * n).reshape(n, n)
    quads = np.stack([i[:-1, :-1], i[:-1, 1:], i[1:, 1:], i[1:, :-1]], -1).reshape(-1, 4)
    mesh = UsdGeom.Mesh.Define(stage, "/World/Ground")
    mesh.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(pts))
    mesh.GetFaceVertexCountsAttr().Set(Vt.IntArray.FromNumpy(np.full(len(quads), 4, np.int32)))
    mesh.GetFaceVertexIndicesAttr().Set(Vt.IntArray.FromNumpy(quads.ravel().astype(np.int32)))
    stage.GetRootLayer().Save()
    return path


@probe("a 1M-vertex scene shows the setup estimate and setup progress, and Ctrl-C answers at once with one line")
def million(tmp):
    scene = big_scene(tmp, 1000)
    out = os.path.join(tmp, "o.usda")
    proc = subprocess.Popen(PY + ["run", scene, "--frames", "4", "--out", out, "--workers", "0",
                                  "--refine-receivers", "off"], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            env=ENV, start_new_session=True)
    os.set_blocking(proc.stderr.fileno(), False)
    err = b""

    def read():
        nonlocal err
        with contextlib.suppress(BlockingIOError, TypeError):
            err += proc.stderr.read() or b""
        return err.decode(errors="replace")

    try:
        t0 = time.monotonic()
        announced = until(lambda: "setup estimated at" in read(), 180, proc, step=0.2)
        seen_at = time.monotonic() - t0
        time.sleep(5.0)  # into the setup
        progress = read()
        t = time.monotonic()
        os.killpg(proc.pid, signal.SIGINT)
        proc.wait(120)
        answered = time.monotonic() - t
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()
    os.set_blocking(proc.stderr.fileno(), True)
    text = read()
    est = re.search(r"setup estimated at ([\d.]+) s", text)
    bars = re.findall(r"setting up[^\r\n]*", progress)
    tail = [ln for ln in re.split(r"[\r\n]+", text) if ln.strip()][-1:]
    ok = announced and proc.returncode == 130 and answered < 3.0 and "Traceback" not in text and \
        tail == ["warpshade run: interrupted; previous output (if any) left untouched"] and len(set(bars)) > 1
    return ok, (f"estimate {est.group(1) + ' s' if est else 'none'} shown after {seen_at:.1f} s; setup bar states "
                f"{len(set(bars))} (last {bars[-1][:70]!r} ) ; SIGINT answered in {answered:.1f} s, rc {proc.returncode}, "
                f"last line {tail[0][:80] if tail else ''!r}")


@probe("SIGINT during a long `warpshade transfer` is answered quickly with one line")
def transfer_sigint(tmp):
    path = os.path.join(tmp, "grid.obj")
    n = 200
    with open(path, "w") as f:
        for y in range(n):
            for x in range(n):
                f.write(f"v {x / n} {y / n} {0.05 * ((x * 7 + y * 13) % 5) / 5}\n")
        for y in range(n - 1):
            for x in range(n - 1):
                a = y * n + x + 1
                f.write(f"f {a} {a + 1} {a + n + 1}\nf {a} {a + n + 1} {a + n}\n")
    proc = subprocess.Popen(PY + ["transfer", path, "--method", "reference", "--rays", "2048", "--save",
                                  os.path.join(tmp, "t.npz"), "--repeat", "20"], stdout=subprocess.DEVNULL,
                            stderr=subprocess.PIPE, text=True, env=ENV, start_new_session=True)
    with group_killed_on_exit(proc):
        time.sleep(12.0)  # past startup, into the transfer's kernels
        alive_then = proc.poll() is None
        err, answered = ctrl_c(proc)
    ok = alive_then and proc.returncode == 130 and err.strip().splitlines() == ["warpshade transfer: interrupted"] \
        and answered < 3.0
    return ok, f"rc {proc.returncode} after {answered:.1f} s; stderr {err.strip()[-200:]!r}"


@probe("Ctrl-C while `import warpshade` runs: one line, exit code 130")
def import_sigint(tmp):
    hook = os.path.join(tmp, "hook")
    os.mkdir(hook)
    with open(os.path.join(hook, "sitecustomize.py"), "w") as f:
        f.write(SIGINT_ON_IMPORT)
    env = dict(ENV, PYTHONPATH=hook + os.pathsep + ENV["PYTHONPATH"], WS_PROBE_SIGINT_AT="warpshade.sim")
    r = subprocess.run(PY + ["run", "--help"], capture_output=True, text=True, env=env, timeout=120)
    ok = r.returncode == 130 and r.stderr.strip().splitlines() == ["warpshade: interrupted"]
    return ok, f"rc {r.returncode}; stderr {r.stderr.strip()[-160:]!r}"


SIGINT_ON_IMPORT = '''
import os, signal, sys

class _SigintAt:
    """Sends SIGINT to this process when the module named in WS_PROBE_SIGINT_AT starts importing."""
    def find_spec(self, name, path=None, target=None):
        if name == os.environ.get("WS_PROBE_SIGINT_AT"):
            sys.meta_path.remove(self)
            os.kill(os.getpid(), signal.SIGINT)
        return None

sys.meta_path.insert(0, _SigintAt())
'''


@probe("`--rays -5` names --rays, and errors in `run` say `warpshade run`")
def rays(tmp):
    r1 = ws("run", SCENE, "--method", "reference", "--rays", "-5", "--out", os.path.join(tmp, "o.usda"))
    r2 = ws("run", "--method", "reference", "--rays", "-5", SCENE, "--out", os.path.join(tmp, "o.usda"))
    want = "warpshade run: error: argument --rays: must be an integer >= 1, got -5"
    got = [last_line(r1.stderr), last_line(r2.stderr)]
    ok = got == [want, want] and r1.returncode == r2.returncode == 2 and os.listdir(tmp) == []
    return ok, f"rc {r1.returncode}/{r2.returncode}: {got[0]!r} (knob before and after the scene)"


@probe("a garbled .usda keeps pxr's line:column")
def garbled(tmp):
    path = os.path.join(tmp, "g.usda")
    with open(path, "w") as f:
        f.write('#usda 1.0\n(\n    defaultPrim = "World"\n)\n\ndef Xform "World"\n{\n    int x = }\n')
    r = ws("run", path, "--frames", 1, "--out", os.path.join(tmp, "o.usda"), "--no-progress")
    line = last_line(r.stderr)
    ok = r.returncode == 1 and f"{path}:8:" in line and "Traceback" not in r.stderr
    return ok, f"rc {r.returncode}: {line!r}"


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--only", nargs="*", default=None, help="run the probes whose name or function contains a word")
    ap.add_argument("--json", default=None, metavar="OUT.json", help="write the results")
    args = ap.parse_args(argv)
    rows = []
    for name, fn in PROBES:
        if args.only and not any(w in name or w in fn.__name__ for w in args.only):
            continue
        tmp = tempfile.mkdtemp(prefix=f"ws-probe-{fn.__name__}-")
        t = time.perf_counter()
        try:
            ok, observed = fn(tmp)
        except Exception as exc:  # noqa: BLE001 - a probe that breaks is a FAIL with its cause
            ok, observed = False, f"probe raised {type(exc).__name__}: {exc} | {traceback.format_exc(limit=-2)!r}"
        seconds = time.perf_counter() - t
        rows.append({"probe": fn.__name__, "issue": name, "pass": bool(ok), "observed": observed, "seconds": seconds})
        print(f"{'PASS' if ok else 'FAIL'} {fn.__name__:18s} {seconds:6.1f} s  {observed}", flush=True)
        shutil.rmtree(tmp, ignore_errors=True)
    print(f"{sum(r['pass'] for r in rows)}/{len(rows)} probes pass")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"machine": os.uname().nodename, "cpus": os.cpu_count(), "probes": rows}, f, indent=2)
    return 0 if all(r["pass"] for r in rows) else 1


if __name__ == "__main__":
    sys.exit(main())
