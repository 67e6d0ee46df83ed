"""Fault injection (issue 16): write errors and full disks, signals, concurrent runs, hostile
scenes and outputs, non-finite values. Each test injects the fault and checks what is left behind,
not only the exit code."""

from __future__ import annotations

import errno
import glob
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom

from helpers import COMMON, FRAMES, REPO, SCENE, assert_same_frames, frames_of, live_processes
from warpshade.cli import main
from warpshade.usd import AnimationWriter
from warpshade.usd.writer import OutputLockedError, OutputWriteError

ENV = dict(os.environ, PYTHONPATH=REPO + os.pathsep + os.environ.get("PYTHONPATH", ""))


def litter(root) -> list[str]:
    """Temporary and lock files a run may leave behind."""
    return sorted(p for p in glob.glob(os.path.join(str(root), "**", "*"), recursive=True)
                  if ".partial" in os.path.basename(p) or p.endswith(".lock"))


class DiskFull:
    """Patch ``Sdf.Layer.Export`` so that, from the ``after``-th call writing a file whose name ends
    in ``suffix`` on, it writes half a file and fails with ENOSPC, as a full disk does."""

    def __init__(self, monkeypatch, suffix: str, after: int = 0):
        self.calls, self.suffix, self.after = 0, suffix, after
        self.real = real = Sdf.Layer.Export

        def export(layer, path, *a, **kw):
            if not path.endswith(suffix):
                return real(layer, path, *a, **kw)
            self.calls += 1
            if self.calls <= after:
                return real(layer, path, *a, **kw)
            with open(path, "wb") as f:
                f.write(b"PXR-USDC" + b"\0" * 100)
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

        monkeypatch.setattr(Sdf.Layer, "Export", export)


def tri_frames(n):
    return [np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32) + f for f in range(n)]


# -- 1. write errors -------------------------------------------------------------------------------
@pytest.mark.parametrize("failing", [".usdc", ".usda"], ids=["clip-file", "top-level-file"])
def test_write_error_keeps_committed_frames_and_resume_completes(tmp_path, monkeypatch, failing):
    out = tmp_path / "o.usda"
    frames = tri_frames(8)
    w = AnimationWriter(str(out), chunk=2)
    name = w.add_mesh("tri", np.array([[0, 1, 2]]))
    # the third clip file / the third top-level rewrite (frames 4-5) meets a full disk
    fault = DiskFull(monkeypatch, failing, after=2)
    with pytest.raises(OutputWriteError, match="No space left on device") as err:
        for f, pts in enumerate(frames):
            w.write_frame(f, name, pts)
    assert err.value.errno == errno.ENOSPC
    what = "chunk_000004.usdc" if failing == ".usdc" else str(out)
    assert what in str(err.value), err.value
    assert ".partial" not in str(err.value)  # the user's file name, not the temporary one
    assert w.abort() == str(out)  # no second save of the failed layer, no crash
    assert w.frames_committed == 4
    assert litter(tmp_path) == []
    assert Usd.Stage.Open(str(out)).GetEndTimeCode() == 3
    monkeypatch.setattr(Sdf.Layer, "Export", fault.real)  # space freed
    w = AnimationWriter(str(out), chunk=2, resume=True)
    assert w.resume_frame == 4
    name = w.add_mesh("tri", np.array([[0, 1, 2]]))
    for f in range(4, 8):
        w.write_frame(f, name, frames[f])
    w.close()
    stage = Usd.Stage.Open(str(out))
    pts = UsdGeom.Mesh(stage.GetPrimAtPath("/World/tri")).GetPointsAttr()
    assert [np.asarray(pts.Get(f)).tolist() for f in range(8)] == [p.tolist() for p in frames]
    assert litter(tmp_path) == []


def test_write_error_on_the_first_chunk_leaves_the_previous_output(tmp_path, monkeypatch):
    out = tmp_path / "o.usda"
    w = AnimationWriter(str(out), chunk=2)
    name = w.add_mesh("tri", np.array([[0, 1, 2]]))
    for f, pts in enumerate(tri_frames(3)):
        w.write_frame(f, name, pts)
    w.close()
    before = out.read_bytes()
    DiskFull(monkeypatch, ".usdc")
    w = AnimationWriter(str(out), chunk=2)
    name = w.add_mesh("tri", np.array([[0, 1, 2]]))
    with pytest.raises(OutputWriteError):
        for f, pts in enumerate(tri_frames(5)):
            w.write_frame(f, name, pts + 10)
    assert w.abort() is None
    assert out.read_bytes() == before
    assert len(os.listdir(tmp_path / "o_frames")) == 1  # this run's empty run folder is gone
    assert litter(tmp_path) == []


def test_run_out_of_space_one_message_then_resume(tmp_path, monkeypatch, capsys, uninterrupted):
    """``warpshade run`` meets a full disk at its second clip file: one line naming the file and the
    cause, exit code 1, committed frames kept; --resume (space freed) gives the uninterrupted result."""
    out = tmp_path / "o.usda"
    fault = DiskFull(monkeypatch, ".usdc", after=1)
    args = ["run", SCENE, "--frames", str(FRAMES), "--out", str(out), "--workers", "0"] + COMMON
    assert main(args) == 1
    err = capsys.readouterr().err
    assert "Traceback" not in err
    lines = [ln for ln in err.splitlines() if "error" in ln]
    assert len(lines) == 1 and "chunk_000002.usdc" in lines[0] and "No space left on device" in lines[0], err
    assert "2 complete frames kept" in err
    assert litter(tmp_path) == []
    monkeypatch.setattr(Sdf.Layer, "Export", fault.real)
    assert main(args + ["--resume"]) == 0
    assert_same_frames(frames_of(out), uninterrupted)
    assert litter(tmp_path) == []


@pytest.fixture
def small_tmpfs(tmp_path):
    """A 2 MB tmpfs (a disk that really fills up); needs root and mount(8)."""
    mnt = tmp_path / "disk"
    mnt.mkdir()
    r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=2m", "tmpfs", str(mnt)], capture_output=True, text=True)
    if r.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs here ({r.stderr.strip() or r.returncode}); "
                    "test_run_out_of_space_one_message_then_resume covers this with a patched writer")
    try:
        yield mnt
    finally:
        subprocess.run(["umount", "-l", str(mnt)], check=False)


def test_real_full_disk_no_crash_no_litter_then_resume(small_tmpfs, uninterrupted):
    out = small_tmpfs / "o.usda"
    fill = small_tmpfs / "fill"
    # a 6-frame output of this scene takes ~0.5 MB (0.1 MB top file, ~0.13 MB per 2-frame clip file):
    # leave room for the top file and a clip or two, not for all of it
    free = os.statvfs(small_tmpfs).f_bavail * os.statvfs(small_tmpfs).f_frsize
    fill.write_bytes(b"\0" * (free - 420_000))
    cmd = [sys.executable, "-m", "warpshade", "run", SCENE, "--frames", str(FRAMES), "--out", str(out),
           "--workers", "0"] + COMMON
    r = subprocess.run(cmd, capture_output=True, text=True, env=ENV, timeout=600)
    assert r.returncode == 1, (r.returncode, r.stderr)  # not 139 (segfault)
    assert "No space left on device" in r.stderr and "Traceback" not in r.stderr, r.stderr
    assert litter(small_tmpfs) == []
    kept = Usd.Stage.Open(str(out)).GetEndTimeCode() if out.exists() else -1
    assert 0 <= kept < FRAMES - 1, "the disk did not fill up: nothing was tested"
    fill.unlink()
    r = subprocess.run(cmd + ["--resume"], capture_output=True, text=True, env=ENV, timeout=600)
    assert r.returncode == 0, r.stderr
    assert_same_frames(frames_of(out), uninterrupted)
    assert litter(small_tmpfs) == []


# -- 2. signals and worker lifetime ----------------------------------------------------------------
ORPHAN_SCRIPT = '''
import os, sys, time
from warpshade.parallel import shade_frames

class Slow:
    def build(self):
        def shade(frame, geometry):
            time.sleep(0.2)
            return frame
        return shade

if __name__ == "__main__":
    for f, r in shade_frames(Slow(), ((f, {}) for f in range(10**6)), workers=2):
        if f == 2:
            print("shading", flush=True)
'''


def children_of(pid: int) -> set[int]:
    """Live child processes of ``pid`` (from /proc)."""
    return {p for p, fields in live_processes().items() if int(fields[1]) == pid}


def alive(pids) -> set[int]:
    out = set()
    for p in pids:
        try:
            with open(f"/proc/{p}/stat") as f:
                if f.read().rsplit(")", 1)[1].split()[0] != "Z":
                    out.add(p)
        except OSError:
            pass
    return out


def wait_gone(pids, seconds: float) -> set[int]:
    deadline = time.monotonic() + seconds
    while alive(pids) and time.monotonic() < deadline:
        time.sleep(0.1)
    return alive(pids)


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGTERM], ids=["SIGKILL", "SIGTERM"])
def test_workers_and_resource_tracker_exit_when_the_parent_dies(tmp_path, sig):
    script = tmp_path / "orphan.py"
    script.write_text(ORPHAN_SCRIPT)
    proc = subprocess.Popen([sys.executable, str(script)], stdout=subprocess.PIPE, stderr=subprocess.DEVNULL,
                            env=ENV, text=True)
    try:
        assert proc.stdout.readline().strip() == "shading"
        kids = children_of(proc.pid)
        # two spawn workers and multiprocessing's resource tracker
        assert len(kids) >= 3, kids
        proc.send_signal(sig)
        proc.wait(30)
        # the watchdog polls every 0.5 s; 5 s leaves room for a loaded machine
        assert wait_gone(kids, 5.0) == set(), "processes outlived their parent"
    finally:
        if proc.poll() is None:
            proc.kill()
        for p in alive(children_of(proc.pid)):
            os.kill(p, signal.SIGKILL)


def children_until_frames(proc: subprocess.Popen, out, end: int, seconds: float = 300.0) -> set[int]:
    """Wait until the run's output holds frames up to ``end`` (or the run ends, or ``seconds`` pass);
    returns the child processes seen meanwhile."""
    kids = set()
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline and proc.poll() is None:
        kids |= children_of(proc.pid)
        if out.exists() and Usd.Stage.Open(str(out)).GetEndTimeCode() >= end:
            break
        time.sleep(0.1)
    return kids


def test_sigterm_commits_finished_frames_like_ctrl_c(tmp_path):
    out = tmp_path / "o.usda"
    cmd = [sys.executable, "-m", "warpshade", "run", SCENE, "--frames", "2000", "--out", str(out),
           "--workers", "2"] + COMMON
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=ENV, text=True)
    kids = set()
    try:
        kids = children_until_frames(proc, out, 3)
        assert proc.poll() is None, "the run ended before it could be terminated"
        seen = Usd.Stage.Open(str(out)).GetEndTimeCode()
        proc.send_signal(signal.SIGTERM)
        err = proc.communicate(timeout=60)[1]
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 128 + signal.SIGTERM, err
    assert "Traceback" not in err, err
    end = Usd.Stage.Open(str(out)).GetEndTimeCode()
    assert f"terminated (SIGTERM); {int(end) + 1} complete frames kept in {out}" in err, err
    assert seen <= end < 2000 - 1
    assert wait_gone(kids, 5.0) == set()
    assert litter(tmp_path) == []


def test_ctrl_c_with_a_local_dask_cluster_is_one_line_and_leaves_no_process(tmp_path):
    # the run's own LocalCluster: its workers' warnings about cancelled tasks must not follow the
    # run's last line (they did in about half the runs), and its processes end with the run
    out = tmp_path / "o.usda"
    cmd = [sys.executable, "-m", "warpshade", "run", SCENE, "--frames", "2000", "--out", str(out),
           "--scheduler", "local", "--workers", "2"] + COMMON
    proc = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, env=ENV, text=True,
                            start_new_session=True)
    kids = set()
    try:
        kids = children_until_frames(proc, out, 3)
        assert proc.poll() is None, "the run ended before it could be interrupted"
        kids |= children_of(proc.pid)
        os.killpg(proc.pid, signal.SIGINT)  # as a terminal sends Ctrl-C: to the whole group
        err = proc.communicate(timeout=60)[1]
    finally:
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait(10)
    assert proc.returncode == 130, err
    end = Usd.Stage.Open(str(out)).GetEndTimeCode()
    assert err.splitlines() == [f"warpshade run: interrupted; {int(end) + 1} complete frames kept in {out} "
                                "(--resume continues it)"], err
    assert kids and wait_gone(kids, 10.0) == set()
    assert litter(tmp_path) == []


def test_a_signal_during_a_commit_waits_until_the_commit_is_in_place(tmp_path, monkeypatch):
    """The CI flake this replaces: SIGTERM landing between a top-level file's write and its rename
    left ``o.partialPID.usda`` behind. Here the signal is sent from inside every write of a commit
    (the worst moment); the commit must finish, leave no temporary file, and only then raise."""
    out = tmp_path / "o.usda"
    w = AnimationWriter(str(out), chunk=2)
    name = w.add_mesh("tri", np.array([[0, 1, 2]]))
    real = Sdf.Layer.Export
    sent = []

    def export(layer, path, *a, **kw):
        ok = real(layer, path, *a, **kw)
        if ".partial" in path and w.frames_committed == 0:
            sent.append(path)
            os.kill(os.getpid(), signal.SIGTERM)
        return ok

    def on_term(signum, frame):
        raise KeyboardInterrupt(signum)

    monkeypatch.setattr(Sdf.Layer, "Export", export)
    previous = signal.signal(signal.SIGTERM, on_term)
    try:
        with pytest.raises(KeyboardInterrupt):
            for f, pts in enumerate(tri_frames(4)):
                w.write_frame(f, name, pts)
    finally:
        signal.signal(signal.SIGTERM, previous)
    assert sent, "no commit wrote a temporary file"
    assert w.frames_committed == 2  # frames 0-1, the commit the signal interrupted, are in the file
    assert all(p.endswith(".lock") for p in litter(tmp_path))  # only the live run's lock
    assert w.abort() == str(out)
    assert litter(tmp_path) == []
    assert Usd.Stage.Open(str(out)).GetEndTimeCode() == 1


# -- 3. one run per output, outputs and inputs kept apart -------------------------------------------
def scene_without_lights(tmp_path) -> str:
    """cloth_sphere without its lights: a run then writes the default sky texture into its clip folder."""
    text = open(SCENE).read()
    cut = text.index('    def "Lights"')
    path = tmp_path / "nolights.usda"
    path.write_text(text[:cut].rstrip() + "\n}\n")
    return str(path)


def dome_texture(out) -> str:
    stage = Usd.Stage.Open(str(out))
    dome = next(p for p in stage.Traverse() if p.GetTypeName() == "DomeLight")
    return dome.GetAttribute("inputs:texture:file").Get().resolvedPath


def test_second_run_on_an_output_is_refused_and_other_formats_are_kept_apart(tmp_path, capsys):
    scene = scene_without_lights(tmp_path)
    out = tmp_path / "X.usda"
    proc = subprocess.Popen([sys.executable, "-m", "warpshade", "run", scene, "--frames", "2000", "--out", str(out),
                             "--workers", "0"] + COMMON, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                            env=ENV, text=True)
    try:
        deadline = time.monotonic() + 300
        while not out.exists() and time.monotonic() < deadline and proc.poll() is None:
            time.sleep(0.1)
        assert proc.poll() is None, "the first run ended too early"
        # a second run on the same output: refused, naming the owner
        assert main(["run", scene, "--frames", "2", "--out", str(out), "--workers", "0"] + COMMON) == 1
        err = capsys.readouterr().err
        assert f"{out} is being written by another run (pid {proc.pid} " in err, err
        # the same name in another format is another output with its own clip folder
        other = tmp_path / "X.usdc"
        assert main(["run", scene, "--frames", "3", "--out", str(other), "--workers", "0"] + COMMON) == 0
        assert Usd.Stage.Open(str(other)).GetEndTimeCode() == 2
        assert (tmp_path / "X_usdc_frames").is_dir()
        assert proc.poll() is None
        proc.send_signal(signal.SIGTERM)
        proc.communicate(timeout=60)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 128 + signal.SIGTERM
    # each output's sky texture is still where its stage points
    for o in (out, other):
        tex = dome_texture(o)
        assert tex and os.path.isfile(tex), (o, tex)
        assert os.path.dirname(os.path.dirname(tex)) == str(tmp_path / ("X_frames" if o == out else "X_usdc_frames"))
    assert litter(tmp_path) == []


def test_stale_lock_of_a_dead_run_is_taken_over(tmp_path):
    out = tmp_path / "o.usda"
    lock = tmp_path / "o_frames.lock"
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    lock.write_text(f"pid {dead.pid} on {os.uname().nodename}\n")  # its flock died with it
    assert main(["run", SCENE, "--frames", "2", "--out", str(out), "--workers", "0"] + COMMON) == 0
    assert Usd.Stage.Open(str(out)).GetEndTimeCode() == 1
    assert not lock.exists()


def test_lock_held_by_another_process_refuses_the_writer(tmp_path):
    out = tmp_path / "o.usda"
    holder = subprocess.Popen([sys.executable, "-c", "import sys, time\n"
                               "from warpshade.usd import AnimationWriter\n"
                               f"w = AnimationWriter({str(out)!r})\nprint('held', flush=True)\ntime.sleep(60)"],
                              stdout=subprocess.PIPE, env=ENV, text=True)
    try:
        assert holder.stdout.readline().strip() == "held"
        with pytest.raises(OutputLockedError, match=f"pid {holder.pid} "):
            AnimationWriter(str(out))
        holder.kill()
        holder.wait(30)
        AnimationWriter(str(out)).close()  # the dead holder's lock is taken over
    finally:
        if holder.poll() is None:
            holder.kill()


def test_out_equal_to_the_input_scene_is_refused(tmp_path, capsys):
    scene = tmp_path / "scene.usda"
    scene.write_bytes(open(SCENE, "rb").read())
    before = scene.read_bytes()
    assert main(["run", str(scene), "--frames", "2", "--out", str(scene), "--workers", "0"] + COMMON) == 1
    assert "is an input of the scene" in capsys.readouterr().err
    assert scene.read_bytes() == before
    assert sorted(os.listdir(tmp_path)) == ["scene.usda"]


# -- 4. nothing non-finite is written; lights that overflow are refused -----------------------------
def test_a_frame_with_a_non_finite_value_is_not_committed(tmp_path):
    out = tmp_path / "o.usda"
    w = AnimationWriter(str(out), chunk=2)
    name = w.add_mesh("tri", np.array([[0, 1, 2]]))
    frames = tri_frames(6)
    for f in range(4):
        w.write_frame(f, name, frames[f], colors=np.ones((3, 3), np.float32))
    bad = np.ones((3, 3), np.float32)
    bad[1, 2] = np.inf
    with pytest.raises(ValueError, match=r"mesh 'tri' frame 4: colors of vertex 1 are not finite"):
        w.write_frame(4, name, frames[4], colors=bad)
    w.abort()
    stage = Usd.Stage.Open(str(out))
    assert stage.GetEndTimeCode() == 3
    col = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/World/tri")).GetPrimvar("displayColor")
    assert all(np.isfinite(np.asarray(col.Get(f))).all() for f in range(4))


def edited_scene(tmp_path, name: str, old: str, new: str) -> str:
    text = open(SCENE).read()
    assert old in text
    path = tmp_path / name
    path.write_text(text.replace(old, new, 1))
    return str(path)


@pytest.mark.parametrize("old,new,light", [
    ("float inputs:intensity = 3", "float inputs:intensity = 1e38\n            float inputs:exposure = 200",
     "/World/Lights/Sun: irradiance overflows float32"),
    ("float inputs:intensity = 0.6", "float inputs:intensity = 3e38",
     "/World/Lights/Sky: its SH radiance reaches 8.51e+38, beyond float32"),
], ids=["DistantLight-1e38x2^200", "DomeLight-3e38"])
def test_a_light_that_overflows_float32_is_refused_up_front(tmp_path, capsys, old, new, light):
    scene = edited_scene(tmp_path, "hot.usda", old, new)
    out = tmp_path / "o.usda"
    assert main(["run", scene, "--frames", "2", "--out", str(out), "--workers", "0"] + COMMON) == 1
    assert light in capsys.readouterr().err
    assert sorted(os.listdir(tmp_path)) == ["hot.usda"]  # refused before anything was written


def test_python_lights_refuse_negative_and_overflowing_emission():
    from warpshade.lighting import ConstantEnvironment, DirectionalLight, PointLight

    with pytest.raises(ValueError, match="sun: irradiance must not be negative"):
        DirectionalLight(direction=(0, 1, 0), irradiance=-1, name="sun")
    with pytest.raises(ValueError, match="bulb: intensity must not be negative"):
        PointLight(position=(0, 1, 0), intensity=(1, -0.1, 1), name="bulb")
    with pytest.raises(ValueError, match="sun: irradiance overflows float32"):
        DirectionalLight(direction=(0, 1, 0), irradiance=1e38 * 2.0**200, name="sun")
    # 3e38 fits in float32, its SH L00 = sqrt(4 pi) * 3e38 = 1.06e39 does not
    with pytest.raises(ValueError, match="sky: its SH radiance reaches 1.06e\\+39"):
        ConstantEnvironment(radiance=3e38, name="sky").sh(2)


# -- 5. nothing read from a scene or an output chooses where files are written ----------------------
def test_scene_knob_lut_dir_is_ignored_with_a_warning(tmp_path):
    target = tmp_path / "elsewhere" / "lut"
    scene = edited_scene(tmp_path, "steer.usda", '        custom token warpshade:kind = "cloth"',
                         '        custom token warpshade:kind = "cloth"\n'
                         f'        custom string warpshade:knobs:lut_dir = "{target}"')
    from warpshade.scene import SceneWarning
    from warpshade.usd import read_scene

    with pytest.warns(SceneWarning, match="warpshade:knobs:lut_dir ignored: a scene cannot choose where files"):
        sc = read_scene(scene)
    assert all("lut_dir" not in o.knobs for o in sc.objects)
    out = tmp_path / "o.usda"
    with pytest.warns(SceneWarning):
        assert main(["run", scene, "--frames", "1", "--out", str(out), "--workers", "0", "--method", "hemiraster",
                     "--order", "2", "--no-progress"]) == 0
    assert not (tmp_path / "elsewhere").exists()


def test_resume_never_touches_files_outside_the_outputs_frame_folder(tmp_path, capsys):
    out = tmp_path / "o.usda"
    assert main(["run", SCENE, "--frames", "2", "--out", str(out), "--workers", "0"] + COMMON) == 0
    # a decoy run folder elsewhere, with a file a resume would delete (a .partial chunk)
    decoy = tmp_path / "precious" / "run-x"
    decoy.mkdir(parents=True)
    for f in ("chunk_000000.usdc", "manifest.usda", "keep.partial.usdc"):
        (decoy / f).write_bytes(b"precious")
    layer = Sdf.Layer.FindOrOpen(str(out))
    clips = dict(layer.GetPrimAtPath("/World").GetInfo("clips"))
    d = dict(clips["default"])
    d["manifestAssetPath"] = Sdf.AssetPath("./precious/run-x/manifest.usda")
    d["assetPaths"] = Sdf.AssetPathArray([Sdf.AssetPath("./precious/run-x/chunk_000000.usdc")])
    layer.GetPrimAtPath("/World").SetInfo("clips", {"default": d})
    layer.Save()
    del layer
    assert main(["run", SCENE, "--frames", "4", "--out", str(out), "--workers", "0", "--resume"] + COMMON) == 1
    assert "cannot resume: clip file ./precious/run-x/manifest.usda is not in a run folder of" in capsys.readouterr().err
    assert sorted(os.listdir(decoy)) == ["chunk_000000.usdc", "keep.partial.usdc", "manifest.usda"]
    assert all((decoy / f).read_bytes() == b"precious" for f in os.listdir(decoy))
