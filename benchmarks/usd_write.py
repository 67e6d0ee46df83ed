"""Streaming USD export: 10 000 frames, one time-sampled layer vs warpshade's value-clip writer.

What it shows: how write time per frame, peak memory and read-back time behave over a long shot
for (a) ``single``: every time sample in one ``.usdc`` layer, saved at the end (what a naive
exporter does; OpenUSD issue #3249 reports sharp slow-downs there) and (b) ``clips``:
:class:`warpshade.usd.AnimationWriter` (chunks of frames in small crate files stitched with value
clips, commits every chunk). Each mode runs in its own process so peak RSS is its own.

Success criteria: ``clips`` keeps per-frame time flat (last 1000 frames ≈ first 1000) and peak
memory independent of the frame count.

Run:  python benchmarks/usd_write.py [--frames 10000] [--vertices 1024] [--repeat 3] [--json out.json]

Numbers are wall times on a shared, loaded 2-core machine; per-frame time excludes nothing but
the (trivial) generation of the synthetic frame arrays, which is done before the timer starts.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile

CHILD = r"""
import json, os, resource, sys, time
import numpy as np
mode, frames, nv, out = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
# imports before the clock starts (they are not part of writing)
from pxr import Usd, UsdGeom, Vt, Sdf
from warpshade.usd import AnimationWriter
rng = np.random.default_rng(0)
pts = rng.random((nv, 3), dtype=np.float32)
nrm = np.tile(np.float32([0, 0, 1]), (nv, 1))
col = rng.random((nv, 3), dtype=np.float32)
faces = np.stack([np.arange(nv - 2), np.arange(1, nv - 1), np.arange(2, nv)], axis=1)
def rss_mb():
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmHWM"):
                return int(line.split()[1]) / 1024
base = rss_mb()
marks = []
t0 = time.perf_counter()
if mode == "single":
    stage = Usd.Stage.CreateNew(out)
    m = UsdGeom.Mesh.Define(stage, "/World/cloth")
    m.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(faces), 3, np.int32)))
    m.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(faces.reshape(-1).astype(np.int32)))
    pa, na, ea = m.CreatePointsAttr(), m.CreateNormalsAttr(), m.CreateExtentAttr()
    ca = UsdGeom.PrimvarsAPI(m).CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3fArray, "vertex")
    for f in range(frames):
        t = Usd.TimeCode(f)
        p = pts + np.float32(f * 1e-3)
        pa.Set(Vt.Vec3fArray.FromNumpy(p), t)
        na.Set(Vt.Vec3fArray.FromNumpy(nrm), t)
        ea.Set(Vt.Vec3fArray.FromNumpy(np.stack([p.min(0), p.max(0)])), t)
        ca.Set(Vt.Vec3fArray.FromNumpy(col), t)
        if f % 1000 == 999:
            marks.append(time.perf_counter())
    ts = time.perf_counter()
    stage.GetRootLayer().Save()
    save = time.perf_counter() - ts
else:
    w = AnimationWriter(out, chunk=int(mode.split(":")[1]) if ":" in mode else 32)
    name = w.add_mesh("cloth", faces)
    for f in range(frames):
        w.write_frame(f, name, pts + np.float32(f * 1e-3), nrm, col)
        if f % 1000 == 999:
            marks.append(time.perf_counter())
    ts = time.perf_counter()
    w.close()
    save = time.perf_counter() - ts
total = time.perf_counter() - t0
tr = time.perf_counter()
stage = Usd.Stage.Open(out)
m = UsdGeom.Mesh(stage.GetPrimAtPath("/World/cloth"))
last = np.asarray(m.GetPointsAttr().Get(frames - 1))
open_read = time.perf_counter() - tr
assert np.allclose(last, pts + np.float32((frames - 1) * 1e-3)), "read-back mismatch"
per_k = np.diff([t0] + marks) / 1000.0
size = os.path.getsize(out)
d = os.path.splitext(out)[0] + "_frames"
if os.path.isdir(d):
    size += sum(os.path.getsize(os.path.join(r, f)) for r, _, fs in os.walk(d) for f in fs)
print(json.dumps({"mode": mode, "frames": frames, "vertices": nv, "total_s": total, "save_s": save,
                  "ms_per_frame_first1000": per_k[0] * 1e3, "ms_per_frame_last1000": per_k[-1] * 1e3,
                  "peak_rss_mb": rss_mb(), "rss_before_mb": base, "open_and_read_last_s": open_read,
                  "bytes_on_disk": size}))
"""


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--frames", type=int, default=10000)
    p.add_argument("--vertices", type=int, default=1024)
    p.add_argument("--modes", default="single,clips:32,clips:256")
    p.add_argument("--repeat", type=int, default=3, help="runs per mode; the table shows medians")
    p.add_argument("--json", default=None)
    args = p.parse_args(argv)
    if args.frames < 1000:
        p.error("--frames must be >= 1000 (per-frame times are reported per 1000 frames)")
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for mode in args.modes.split(","):
            out = os.path.join(tmp, f"{mode.replace(':', '_')}.usdc" if mode == "single" else f"{mode.replace(':', '_')}.usda")
            env = dict(os.environ, PYTHONPATH=os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
            runs = []
            for _ in range(max(1, args.repeat)):
                r = subprocess.run([sys.executable, "-c", CHILD, mode, str(args.frames), str(args.vertices), out],
                                   capture_output=True, text=True, env=env)
                if r.returncode:
                    print(r.stderr, file=sys.stderr)
                    return 1
                runs.append(json.loads(r.stdout.strip().splitlines()[-1]))
            row = {k: (statistics.median(x[k] for x in runs) if isinstance(v, float) else v) for k, v in runs[0].items()}
            row["repeat"] = len(runs)
            rows.append(row)
    print(f"USD export, {args.frames} frames x {args.vertices} vertices (points, normals, extent, displayColor); "
          f"medians of {args.repeat} runs (each in a fresh process, imports excluded); "
          "wall times on a shared, loaded 2-core machine")
    hdr = (f"{'mode':<11}{'total s':>9}{'ms/frame first 1k':>19}{'ms/frame last 1k':>18}{'save s':>8}"
           f"{'peak RSS MB':>13}{'growth MB':>11}{'open+read s':>13}{'MB on disk':>12}")
    print(hdr)
    for r in rows:
        print(f"{r['mode']:<11}{r['total_s']:>9.2f}{r['ms_per_frame_first1000']:>19.3f}{r['ms_per_frame_last1000']:>18.3f}"
              f"{r['save_s']:>8.2f}{r['peak_rss_mb']:>13.0f}{r['peak_rss_mb'] - r['rss_before_mb']:>11.0f}"
              f"{r['open_and_read_last_s']:>13.3f}{r['bytes_on_disk'] / 1e6:>12.1f}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"note": "shared, loaded 2-core machine", "results": rows}, f, indent=2)
    return 0


if __name__ == "__main__":
    sys.exit(main())
