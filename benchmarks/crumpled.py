"""Hemispherical rasterization on crumpled and draped 64x64 cloths, and Kautz's Table 1 cloth (issue 18).

What it shows: per mesh, the transfer error (mean relative L2 of the order-5 transfer,
:mod:`warpshade.bench.metrics`, against the ray-traced reference at 4096 rays,
:func:`warpshade.bench.reference_cache.ground_truth`) and the process CPU time per frame (median of
``--repeat`` round-robin rounds after a warm-up round, compile excluded, one Warp CPU thread) of
hemiraster configurations, beside the ray-traced reference at 256 rays measured in the same run.
The warm-up round pays the one-off far-field rebuild of ``redecimate`` (reported separately as
``rebuild_seconds``); the timed rounds are frames that follow on the same pose.

Meshes (``warpshade.bench.meshes``): ``cloth``, the benchmark's crumpled 64² cloth (rest: flat);
``crumpled2``, another seed crumpled harder (0.75 compression); ``draped``, a 64² cloth dropped
onto a ball and simulated for 60 frames (cached); ``table1``, the 1378-vertex travelling-wrinkle
cloth of ``benchmarks/hemiraster.py`` (3 frames, rest = frame 0).

Per row the error is also split by receiver class (:func:`warpshade.bench.metrics.receiver_classes`:
contact, fold, open; the mean error within each class), to say where the error sits.

The mid level (``mid``) rows: refined coarse triangles are replaced by mid triangles and only the
nearest of those by fine ones ("fine, mid": refined fine and mid triangles rasterized per vertex).

``--sweep``: instead of those rows, the neighbourhood of the fastest setting within 3 % on the crumpled
cloths (``SWEEP``: one knob at a time from it, and the tiny-image culls together), round-robin as above.

``--alternate "LABEL;LABEL;..."``: the labelled rows (of the table or of ``SWEEP``) each timed in its own
process, the processes alternating (the order reversed every other round) for ``--rounds`` rounds per
mesh, so load drift hits all of them; per process the median of ``--repeat`` frames after two warm-up
frames (compile and the far field's rebuild excluded); the JSON holds every process's median, the
median over rounds, the load average beside each and a SHA-256 of each process's transfer (equal
across rounds: the same pose gives the same output).

Success criteria (issue 18): crumpled and draped cloths <= 3.0 % at <= 50 ms per frame; Table 1
cloth >= 60 frames/s at <= 2.5 %.

How to run::

    OPENBLAS_NUM_THREADS=1 python benchmarks/crumpled.py [--repeat 3] [--meshes cloth,draped] [--json out.json]
    OPENBLAS_NUM_THREADS=1 python benchmarks/crumpled.py --sweep --meshes cloth,crumpled2 --repeat 5 --json out.json
    OPENBLAS_NUM_THREADS=1 python benchmarks/crumpled.py --meshes cloth,crumpled2 --repeat 5 --rounds 4 \
        --alternate "fastest (c5);fastest, fine_image 1.0, min_image 1.5" --json out.json
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))
sys.path.insert(0, HERE)

import warp as wp
from hemiraster import TUNED, scene

from warpshade.bench.meshes import draped_cloth, wrinkled_cloth
from warpshade.bench.metrics import RECEIVER_CLASSES, receiver_classes, transfer_errors
from warpshade.bench.reference_cache import ground_truth
from warpshade.geometry import TriMesh
from warpshade.visibility import get_method

ORDER = 5
PEER_RAYS = 256
CRUMPLED = {"defaults": {}, "redecimate": {"redecimate": 0.1},
            "redecimate, coarse 256, mid 2048": {"redecimate": 0.1, "coarse": 256, "mid": 2048},
            "redecimate, coarse 256, mid 2048, refine 1.5": {"redecimate": 0.1, "coarse": 256, "mid": 2048, "refine": 1.5},
            "redecimate, coarse 192, mid 1024, refine 1.25, lut 64":
                {"redecimate": 0.1, "coarse": 192, "mid": 1024, "refine": 1.25, "lut": 64},
            "redecimate, coarse 256, mid 2048, refine 1.5, interpolate 0.08":
                {"redecimate": 0.1, "coarse": 256, "mid": 2048, "refine": 1.5, "interpolate": 0.08},
            "redecimate, min_image 0": {"redecimate": 0.1, "min_image": 0.0},
            "redecimate, min_image 0, lut 96": {"redecimate": 0.1, "min_image": 0.0, "lut": 96},
            "drape: redecimate, min_image 0, border, coarse 1024, lut 96":
                {"redecimate": 0.1, "min_image": 0.0, "border": True, "coarse": 1024, "lut": 96},
            "redecimate, min_image 0, border, coarse 1536, lut 96":
                {"redecimate": 0.1, "min_image": 0.0, "border": True, "coarse": 1536, "lut": 96},
            "redecimate, min_image 0, border, coarse 1536, lut 96, direct_far":
                {"redecimate": 0.1, "min_image": 0.0, "border": True, "coarse": 1536, "lut": 96, "direct_far": True},
            "redecimate, min_image 0, border, coarse 1536, lut 128, direct_far":
                {"redecimate": 0.1, "min_image": 0.0, "border": True, "coarse": 1536, "lut": 128, "direct_far": True},
            "redecimate, min_image 0, border, coarse 1536, refine 1.5, lut 128, direct_far":
                {"redecimate": 0.1, "min_image": 0.0, "border": True, "coarse": 1536, "refine": 1.5, "lut": 128,
                 "direct_far": True},
            "redecimate, min_image 0, border, coarse 1280, refine 3, lut 128, direct_far":
                {"redecimate": 0.1, "min_image": 0.0, "border": True, "coarse": 1280, "refine": 3.0, "lut": 128,
                 "direct_far": True},
            "redecimate, min_image 0, border, coarse 1280, refine 3, lut 128":
                {"redecimate": 0.1, "min_image": 0.0, "border": True, "coarse": 1280, "refine": 3.0, "lut": 128},
            "redecimate, min_image 0, border, coarse 768, lut 64, mask 64":
                {"redecimate": 0.1, "min_image": 0.0, "border": True, "coarse": 768, "lut": 64, "mask": 64},
            "c6 fastest: redecimate, coarse 192, mid 1024, refine 1.1, lut 56, fine_image 1, min_image 2, direct_far":
                {"redecimate": 0.1, "coarse": 192, "mid": 1024, "refine": 1.1, "lut": 56, "fine_image": 1.0, "min_image": 2.0,
                 "direct_far": True}}
FASTEST = {"redecimate": 0.1, "coarse": 192, "mid": 1024, "refine": 1.25, "lut": 64}
SWEEP = {"fastest (c5)": FASTEST,
         **{f"fastest, {k} {v}": {**FASTEST, k: v} for k, vals in
            (("coarse", (128, 160, 224)), ("mid", (768, 896, 1280)), ("refine", (1.0, 1.1, 1.5)), ("lut", (48, 56, 80)),
             ("min_image", (0.0, 1.0, 1.5, 2.0)), ("fine_image", (0.25, 0.5, 1.0)), ("ring", (0,))) for v in vals},
         **{f"fastest, fine_image {fi}, min_image {mi}{''.join(f', {k} {v}' for k, v in extra.items())}":
            {**FASTEST, "fine_image": fi, "min_image": mi, **extra} for fi, mi, extra in
            ((0.25, 1.0, {}), (0.5, 1.5, {}), (1.0, 1.5, {}), (1.0, 2.0, {}), (1.5, 1.5, {}), (2.0, 2.0, {}),
             (4.0, 2.0, {}), (1.0, 1.5, {"lut": 56}), (1.0, 2.0, {"refine": 1.1}), (1.0, 2.0, {"refine": 1.1, "lut": 56}),
             (1.0, 1.5, {"coarse": 160}), (1.0, 1.5, {"mid": 768}), (1.0, 1.5, {"ring": 0}), (1.0, 2.0, {"ring": 0}),
             (1.0, 1.5, {"refine": 1.5}))}}
TABLE1 = {"defaults": {}, "tuned": TUNED["cloth"], "tuned+interpolate": {**TUNED["cloth"], "interpolate": 0.08},
          "tuned, refine 1.25, interpolate": {**TUNED["cloth"], "refine": 1.25, "interpolate": 0.08},
          "tuned, fan off (main)": {**TUNED["cloth"], "fan": False},
          "coarse 256, mid 1024": {"coarse": 256, "mid": 1024}}


def inputs(name: str):
    """Rest mesh, judged frames and their 4096-ray truths."""
    if name == "table1":
        mesh, frames = scene("cloth")
    else:
        bm = {"cloth": lambda: wrinkled_cloth(64), "crumpled2": lambda: wrinkled_cloth(64, seed=3, compress=0.75),
              "draped": lambda: draped_cloth(64)}[name]()
        mesh, frames = bm.rest, [bm.frame]
    truths = [ground_truth(TriMesh(f, mesh.faces, name=f"{name}-frame"), ORDER, log=print) for f in frames]
    return mesh, frames, truths


def classes_of(mesh, frames) -> list[dict]:
    """Receiver classes (contact, fold, open) of each judged frame."""
    return [receiver_classes(f, mesh.faces) for f in frames]


def frame_cpu(m, f) -> float:
    """Process CPU seconds of one frame's transfer on points ``f`` (normals and the compute, after
    ``set_points``), around ``wp.synchronize()``."""
    m.set_points(f)
    wp.synchronize()
    c0 = time.process_time()
    m._compute()
    wp.synchronize()
    return time.process_time() - c0


def run(methods: list, frames, truths, repeat: int, classes: list[dict]) -> list[dict]:
    """Round-robin CPU time per frame (median of rounds, median over frames), mean error over frames and the
    mean error within each receiver class (over the frames' receivers of that class; None for an empty class)."""
    for m in methods:
        for f in frames:
            m.update(f)
    cpu = np.zeros((len(methods), len(frames), max(1, repeat)))
    for rnd in range(max(1, repeat)):
        for i, m in enumerate(methods):
            for j, f in enumerate(frames):
                cpu[i, j, rnd] = frame_cpu(m, f)
    rows = []
    for i, m in enumerate(methods):
        errs, per_vertex = [], []
        for f, t in zip(frames, truths):
            m.update(f)
            per_vertex.append(transfer_errors(m.transfer_numpy(), t))
            errs.append(per_vertex[-1].mean())
        by_class = {}
        for c in RECEIVER_CLASSES:
            e = np.concatenate([pv[cl[c]] for pv, cl in zip(per_vertex, classes)])
            by_class[c] = float(e.mean()) if len(e) else None
        st = m.stats()
        rows.append({"cpu_seconds": float(np.median(np.median(cpu[i], axis=1))), "error_mean": float(np.mean(errs)),
                     "triangles_per_vertex": st.get("triangles_per_vertex"), "rebuilds": st.get("rebuilds"),
                     "refined_per_vertex": st.get("refined_per_vertex"), "mid_per_vertex": st.get("mid_per_vertex"),
                     "rebuild_seconds": st.get("rebuild_seconds"), "computed_fraction": st.get("computed_fraction"),
                     "error_by_class": by_class})
    return rows


def one(name: str, label: str, repeat: int) -> dict:
    """The row ``label`` on mesh ``name`` in this process (``--alternate``'s child): median process CPU
    per frame of ``repeat`` frames after two warm-up frames, the error and a hash of the transfer."""
    mesh, frames, truths = inputs(name)
    knobs = {**CRUMPLED, **SWEEP, **TABLE1}[label]
    m = get_method("hemiraster")(mesh, order=ORDER, **knobs)
    for _ in range(2):
        for f in frames:
            m.update(f)
    cpu = np.zeros((len(frames), max(1, repeat)))
    for rnd in range(max(1, repeat)):
        for j, f in enumerate(frames):
            cpu[j, rnd] = frame_cpu(m, f)
    digest, errs = hashlib.sha256(), []
    for f, t in zip(frames, truths):
        m.update(f)
        tr = m.transfer_numpy()
        digest.update(np.ascontiguousarray(tr).tobytes())
        errs.append(transfer_errors(tr, t).mean())
    return {"cpu_seconds": float(np.median(np.median(cpu, axis=1))), "error_mean": float(np.mean(errs)),
            "triangles_per_vertex": m.stats().get("triangles_per_vertex"), "transfer_sha256": digest.hexdigest(),
            "load": os.getloadavg()[0]}


def alternate(meshes: list[str], labels: list[str], rounds: int, repeat: int) -> dict:
    """Each label in its own process, alternating for ``rounds`` rounds per mesh (order reversed every
    other round): every process's result and, per label, the median over rounds."""
    out = {"rounds": rounds, "repeat": repeat, "meshes": {}}
    for name in meshes:
        runs = {lb: [] for lb in labels}
        for rnd in range(rounds):
            for lb in (labels if rnd % 2 == 0 else labels[::-1]):
                res = subprocess.run([sys.executable, os.path.abspath(__file__), "--one", name, lb, "--repeat", str(repeat)],
                                     capture_output=True, text=True, check=True)
                runs[lb].append(json.loads(res.stdout.strip().splitlines()[-1]))
                print(f"{name} round {rnd} {lb}: {runs[lb][-1]['cpu_seconds'] * 1e3:.1f} ms, "
                      f"{runs[lb][-1]['error_mean'] * 100:.2f} %, load {runs[lb][-1]['load']:.1f}", flush=True)
        out["meshes"][name] = {lb: {"knobs": {**CRUMPLED, **SWEEP, **TABLE1}[lb],
                                    "median_cpu_seconds": float(np.median([r["cpu_seconds"] for r in rs])),
                                    "error_mean": rs[0]["error_mean"], "triangles_per_vertex": rs[0]["triangles_per_vertex"],
                                    "same_transfer_every_round": len({r["transfer_sha256"] for r in rs}) == 1,
                                    "processes": rs} for lb, rs in runs.items()}
    print("\nSeparate processes alternating; CPU ms per frame (median over rounds of each process's median), error")
    print("| mesh | configuration | ms | error | tris/vertex | per round (ms) |")
    print("|---|---|---|---|---|---|")
    for name, e in out["meshes"].items():
        for lb, r in e.items():
            per = ", ".join(f"{p['cpu_seconds'] * 1e3:.1f}" for p in r["processes"])
            print(f"| {name} | {lb} | {r['median_cpu_seconds'] * 1e3:.1f} | {r['error_mean'] * 100:.2f} % | "
                  f"{r['triangles_per_vertex']:.0f} | {per} |")
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--meshes", default="cloth,crumpled2,draped,table1")
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json", default=None, metavar="PATH")
    ap.add_argument("--sweep", action="store_true", help="the neighbourhood of the fastest setting (SWEEP) instead of the table's rows")
    ap.add_argument("--alternate", default=None, metavar="LABELS",
                    help="';'-separated row labels (of the table or of SWEEP) timed in separate processes, alternating")
    ap.add_argument("--rounds", type=int, default=4, help="--alternate: rounds per mesh")
    ap.add_argument("--one", nargs=2, metavar=("MESH", "LABEL"), help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    wp.config.log_level = wp.LOG_WARNING
    if args.one:
        print(json.dumps(one(*args.one, args.repeat)))
        return 0
    if args.alternate:
        out = alternate(args.meshes.split(","), args.alternate.split(";"), args.rounds, args.repeat)
        if args.json:
            with open(args.json, "w") as f:
                json.dump(out, f, indent=2, default=float)
        return 0
    cls, ref = get_method("hemiraster"), get_method("reference")
    out = {"order": ORDER, "truth_rays": 4096, "peer_rays": PEER_RAYS, "load_average_start": os.getloadavg()[0],
           "meshes": {}}
    for name in args.meshes.split(","):
        mesh, frames, truths = inputs(name)
        configs = TABLE1 if name == "table1" else (SWEEP if args.sweep else CRUMPLED)
        methods = [cls(mesh, order=ORDER, **k) for k in configs.values()]
        methods.append(ref(mesh, order=ORDER, rays=PEER_RAYS, seed=1))
        classes = classes_of(mesh, frames)
        rows = run(methods, frames, truths, args.repeat, classes)
        labels = list(configs) + [f"reference {PEER_RAYS} rays"]
        knobs = list(configs.values()) + [{"rays": PEER_RAYS}]
        out["meshes"][name] = {"vertices": mesh.num_vertices, "frames": len(frames),
                               "class_sizes": {c: int(sum(cl[c].sum() for cl in classes)) for c in RECEIVER_CLASSES},
                               "rows": [{"label": lb, "knobs": k, **r} for lb, k, r in zip(labels, knobs, rows)]}
        del methods
    print("\nOrder 5, one Warp CPU thread; CPU ms per frame (median after warm-up, round-robin), mean error vs 4096 rays")
    print("| mesh | configuration | ms | frames/s | error | tris/vertex (fine, mid) | computed | rebuild |")
    print("|---|---|---|---|---|---|---|---|")
    for name, e in out["meshes"].items():
        for r in e["rows"]:
            tv = (f"{r['triangles_per_vertex']:.0f} ({r['refined_per_vertex']:.0f}, {r['mid_per_vertex']:.0f})"
                  if r["triangles_per_vertex"] is not None else "-")
            cf = f"{r['computed_fraction']:.2f}" if r["computed_fraction"] is not None else "-"
            rb = f"{r['rebuild_seconds']:.2f} s" if r["rebuilds"] else "-"
            print(f"| {name} ({e['vertices']}) | {r['label']} | {r['cpu_seconds'] * 1e3:.1f} | {1 / r['cpu_seconds']:.1f} | "
                  f"{r['error_mean'] * 100:.2f} % | {tv} | {cf} | {rb} |")
    print("\nMean error within each receiver class (warpshade.bench.metrics.receiver_classes; receivers per class)")
    print("| mesh | configuration | " + " | ".join(RECEIVER_CLASSES) + " |")
    print("|---|---|" + "---|" * len(RECEIVER_CLASSES))
    for name, e in out["meshes"].items():
        sizes = ", ".join(f"{c} {n}" for c, n in e["class_sizes"].items())
        for r in e["rows"]:
            cells = ["-" if r["error_by_class"][c] is None else f"{r['error_by_class'][c] * 100:.2f} %" for c in RECEIVER_CLASSES]
            print(f"| {name} ({sizes}) | {r['label']} | " + " | ".join(cells) + " |")
    out["load_average_end"] = os.getloadavg()[0]
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=2, default=float)
    return 0


if __name__ == "__main__":
    sys.exit(main())
