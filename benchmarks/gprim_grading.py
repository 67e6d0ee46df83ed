"""Graded gprim tessellation on a hand-made scene: vertices, shading time and the floor's error against
the ray-traced truth, graded against uniform.

What it measures: a scene as a user writes it with pxr (Z up, metres, 24 fps, frames 1-48): a 3 x 3 x
0.05 m floor slab that is a scaled unit ``Cube``, a ``Cylinder`` pedestal (radius 0.25 m, 0.6 m tall)
on it, both with ``UsdPhysics.CollisionAPI``, a 40 x 40 quad cloth 1 m across 0.75 m up, a
``DistantLight`` (10 degrees, turned 30/20 degrees) and a ``DomeLight``. It is run with ``warpshade
run --workers 0`` (hemiraster, the default) twice: graded (the reader's default) and uniform
(``warpshade:graded = false`` on the default prim: every gprim edge at most the target edge, as
before grading). At each ``--compare`` frame a still snapshot of the scene (the cloth's points of
the uniform run at that frame, as a static mesh; the sim does not depend on the tessellation: the
floor and pedestal collide as their exact box and cylinder) is run with ``--method reference`` on
the uniform floor: the truth at the uniform floor's vertices; and on the graded floor: the graded
tessellation's own error, without the method's.

The error is that of the floor's top face as rendered: luminance of ``displayColor``, a tessellation's
per-vertex values interpolated over its own triangles (barycentric) onto the uniform floor's top
vertices, against the truth there; mean, p95 and max |error| over the whole top face and the mean
within ``--near`` m of the pedestal's axis; the floor under the pedestal (within its radius and one edge of
its axis: hidden, its coplanar contact ill-posed) is left out. Shading seconds per frame are the runs' own (``shade``:
worker time; kernel compilation is cached after a first run: run the script twice and read the
second).

How to run::

    python benchmarks/gprim_grading.py [--frames 48] [--compare 1,24,40,48] [--near 1.0] [--json PATH]

Wall and shading times on a shared machine are noisy: the A/B of run time against another version is
``warpshade run`` alternated between checkouts (docs/benchmarks/index.md says how it was measured).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gprim_density import colours, run, sheet, z_up_stage  # noqa: E402  (benchmarks/ is not a package)


EDGE = 0.025
"""The runs' target edge [m]: the cloth's 2.5 cm edge (the reader's rule); a snapshot, whose static
cloth does not set it, sets it with ``warpshade:edgeLength``."""

PEDESTAL_RADIUS = 0.25


def build(path: str, graded: bool, cloth_points=None) -> None:
    """Write the pedestal scene to ``path``: graded or not; with ``cloth_points`` the cloth is a static
    mesh there (a still snapshot, target edge :data:`EDGE`) instead of a simulated sheet at rest."""
    from pxr import Gf, UsdGeom, UsdLux, UsdPhysics

    stage = z_up_stage(path, "/World", 1.0, 24, 48, EDGE if cloth_points is not None else None, graded)
    floor = UsdGeom.Cube.Define(stage, "/World/Floor")
    floor.GetSizeAttr().Set(1.0)
    UsdGeom.XformCommonAPI(floor).SetScale(Gf.Vec3f(3, 3, 0.05))
    UsdGeom.XformCommonAPI(floor).SetTranslate(Gf.Vec3d(0, 0, -0.025))
    UsdPhysics.CollisionAPI.Apply(floor.GetPrim())
    ped = UsdGeom.Cylinder.Define(stage, "/World/Pedestal")
    ped.GetRadiusAttr().Set(PEDESTAL_RADIUS)
    ped.GetHeightAttr().Set(0.6)
    ped.GetAxisAttr().Set("Z")
    UsdGeom.XformCommonAPI(ped).SetTranslate(Gf.Vec3d(0, 0, 0.3))
    UsdPhysics.CollisionAPI.Apply(ped.GetPrim())
    n, size = 40, 1.0
    pts = [Gf.Vec3f(-size / 2 + size * i / n, -size / 2 + size * j / n, 0.75) for j in range(n + 1) for i in range(n + 1)]
    if cloth_points is not None:
        pts = [Gf.Vec3f(*map(float, p)) for p in cloth_points]
    sheet(stage, "/World/Cloth", pts, n, "static" if cloth_points is not None else "cloth", (0.8, 0.15, 0.1))
    sun = UsdLux.DistantLight.Define(stage, "/World/Sun")
    sun.CreateIntensityAttr(3.0)
    sun.CreateAngleAttr(10.0)
    UsdGeom.XformCommonAPI(sun).SetRotate(Gf.Vec3f(30, 20, 0))
    UsdLux.DomeLight.Define(stage, "/World/Sky").CreateIntensityAttr(0.5)
    stage.GetRootLayer().Save()


def top(mesh):
    """The floor's top face: its points, triangles and values (the vertices at the top height)."""
    p, f, v = mesh
    keep = p[:, 2] > p[:, 2].max() - 1e-4
    return p, f[keep[f].all(axis=1)], v, keep


def on(mesh, xy: np.ndarray) -> np.ndarray:
    """A floor's top-face values interpolated over its own triangles (barycentric) at the points ``xy``."""
    import matplotlib.tri as mtri

    p, f, v, _ = top(mesh)
    return np.asarray(mtri.LinearTriInterpolator(mtri.Triangulation(p[:, 0], p[:, 1], f), v)(xy[:, 0], xy[:, 1]))


def stats(err: np.ndarray, near: np.ndarray) -> dict:
    a = np.abs(err)
    return {"mean": float(a.mean()), "p95": float(np.percentile(a, 95)), "max": float(a.max()), "mean_near": float(a[near].mean())}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, default=48, help="frames run (the compare frames must be among them)")
    ap.add_argument("--compare", default="1,24,40,48", help="time codes compared against the reference")
    ap.add_argument("--near", type=float, default=1.0, help="radius [m] about the pedestal's axis of the 'near' mean")
    ap.add_argument("--keep", default=None, metavar="DIR", help="keep the scenes and outputs here")
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        work = os.path.abspath(args.keep or tmp)
        os.makedirs(work, exist_ok=True)
        runs = {}
        for name, graded in (("graded", True), ("uniform", False)):
            scene = os.path.join(work, f"{name}.usda")
            build(scene, graded)
            times = run(scene, os.path.join(work, f"{name}_out.usda"), None, args.frames)
            runs[name] = times
            print(f"{name}: setup {times.get('setup')} s, shade {times.get('shade')} s for {args.frames} frames", flush=True)
        rows = []
        for code in [float(c) for c in args.compare.split(",")]:
            hemi = {name: colours(os.path.join(work, f"{name}_out.usda"), code) for name in runs}
            cloth = hemi["uniform"]["Cloth"][0]
            ref = {}
            for name, graded in (("graded", True), ("uniform", False)):
                snap = os.path.join(work, f"snap_{name}_{code:g}.usda")
                build(snap, graded, cloth)
                out = os.path.join(work, f"snap_{name}_{code:g}_ref.usda")
                ref[name] = (run(snap, out, "reference"), colours(out, 1)["Floor"])
            p, _, truth, keep = top(ref["uniform"][1])
            xy, truth = p[keep, :2], truth[keep]
            r = np.hypot(xy[:, 0], xy[:, 1])
            seen = r > PEDESTAL_RADIUS + EDGE  # under the pedestal: hidden, and its contact is coplanar (ill-posed)
            xy, truth, r = xy[seen], truth[seen], r[seen]
            near = r <= args.near
            row = {"time_code": code, "cloth_lowest_m": float(cloth[:, 2].min()),
                   "floor_vertices": {name: len(hemi[name]["Floor"][0]) for name in runs},
                   "vertices": {name: sum(len(m[0]) for m in hemi[name].values()) for name in runs},
                   "reference_shade_s": {name: ref[name][0].get("shade") for name in ref},
                   "truth_mean": float(truth.mean()), "truth_min": float(truth.min()), "points": int(len(truth)),
                   "hemiraster_vs_truth": {name: stats(on(hemi[name]["Floor"], xy) - truth, near) for name in runs},
                   "reference_vs_truth": {"graded": stats(on(ref["graded"][1], xy) - truth, near)}}
            rows.append(row)
            print(f"time {code:g}: cloth lowest {row['cloth_lowest_m']:.3f} m, floor vertices {row['floor_vertices']}, "
                  f"truth mean {row['truth_mean']:.4f} (min {row['truth_min']:.4f}) over {row['points']} top vertices", flush=True)
            for name, s in [*row["hemiraster_vs_truth"].items(), ("graded, reference", row["reference_vs_truth"]["graded"])]:
                print(f"    {name:18s} |error| mean {s['mean']:.5f} p95 {s['p95']:.5f} max {s['max']:.5f} "
                      f"mean within {args.near:g} m {s['mean_near']:.5f}", flush=True)
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"frames": args.frames, "near": args.near, "runs": runs, "rows": rows}, fh, indent=1)


if __name__ == "__main__":
    main()
