"""Gprim tessellation density on a hand-made scene: vertices, run time and error against the reference.

What it measures: a scene as a DCC writes it (Z up, centimetres: a 400 x 400 x 5 cm floor slab that is a
scaled unit ``Cube``, a 60 cm ``Cube`` crate turned 20 degrees standing on it, a ``Cone``, a 24 x 24 quad
cloth of 5 cm edges 90 cm up, a ``RectLight`` and a ``DomeLight``, all colliders marked with
``UsdPhysics.CollisionAPI`` only) is built with pxr and run with ``warpshade run --frames 1 --workers 0``
(frame 1: the cloth still flat, the crate on the floor) once per target edge given (``warpshade:edgeLength``
on the default prim; ``auto``: none, the reader's rule; ``--grading``: the reader's graded tessellation, on or
``warpshade:graded = false``, the truth always uniform), with hemiraster (the default) and with
``--method reference`` (1024 rays). Per object it prints the vertex count and the mean |luminance
difference| of ``displayColor`` between hemiraster and the reference of the same tessellation (the
method's error), and for the floor's top face near the crate (outside its footprint, within
``--band`` cm of it) the error of the hemiraster floor, interpolated over its own triangles, against a
reference run at ``--truth-edge`` (what a picture shows: the method's and the tessellation's error
together; the jagged contact edge of a coarse floor is in it), and the same for the reference run of
that tessellation (the tessellation's error alone, with the rays' noise). Setup and shading seconds are the run's
own (kernel compilation is cached after the first run; run the script twice and read the second).

How to run::

    python benchmarks/gprim_density.py [--edges auto,2.5] [--grading on,off] [--truth-edge 1.25] [--band 20] [--truth OUT.usda] [--json PATH]

``--truth OUT.usda`` keeps the fine reference run there and reuses it when it exists, so another
version's tessellation (``PYTHONPATH`` set to another checkout: its subprocess runs use that code) can
be judged by the same truth.

Wall times on a shared, loaded machine (±20 % and worse): compare rows of one invocation.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile

import numpy as np

REPO = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..")
LUM = np.array([0.2126, 0.7152, 0.0722])
CRATE_TURN, CRATE_HALF = 20.0, 30.0  # degrees, cm


def build(path: str, edge: float | None, graded: bool = True) -> None:
    """Write the crate scene to ``path`` (``warpshade:edgeLength`` = ``edge`` on the default prim if given;
    ``warpshade:graded = false`` there unless ``graded``)."""
    from pxr import Gf, UsdGeom, UsdLux, UsdPhysics

    stage = z_up_stage(path, "/Scene", 0.01, 30, 30, edge, graded)
    floor = UsdGeom.Cube.Define(stage, "/Scene/Floor")
    floor.CreateSizeAttr(1.0)
    floor.AddTranslateOp().Set(Gf.Vec3d(0, 0, -2.5))
    floor.AddScaleOp().Set(Gf.Vec3f(400, 400, 5))
    crate = UsdGeom.Cube.Define(stage, "/Scene/Crate")
    crate.CreateSizeAttr(2 * CRATE_HALF)
    crate.AddTranslateOp().Set(Gf.Vec3d(0, 0, CRATE_HALF))
    crate.AddRotateZOp().Set(CRATE_TURN)
    cone = UsdGeom.Cone.Define(stage, "/Scene/Cone")
    cone.CreateRadiusAttr(12.0)
    cone.CreateHeightAttr(30.0)
    cone.CreateAxisAttr("Z")
    cone.AddTranslateOp().Set(Gf.Vec3d(-45, 40, 15))
    for g in (floor, crate, cone):
        UsdPhysics.CollisionAPI.Apply(g.GetPrim())
    n, size, h = 24, 120.0, 90.0
    step = size / n
    sheet(stage, "/Scene/Sheet", [Gf.Vec3f(-size / 2 + i * step, -size / 2 + j * step, h) for j in range(n + 1) for i in range(n + 1)],
          n, "cloth", (0.7, 0.15, 0.1))
    rect = UsdLux.RectLight.Define(stage, "/Scene/Softbox")
    rect.CreateWidthAttr(80.0)
    rect.CreateHeightAttr(80.0)
    rect.CreateIntensityAttr(30.0)
    rect.AddTranslateOp().Set(Gf.Vec3d(0, -60, 220))
    rect.AddRotateXOp().Set(-15.0)
    UsdLux.DomeLight.Define(stage, "/Scene/Sky").CreateIntensityAttr(0.4)
    stage.Save()


def z_up_stage(path: str, root: str, meters_per_unit: float, fps: float, last: int, edge: float | None, graded: bool):
    """A new stage at ``path``, Z up, frames 1 to ``last``, default prim the Xform ``root`` carrying
    ``warpshade:edgeLength`` = ``edge`` if given and ``warpshade:graded = false`` unless ``graded``."""
    from pxr import Sdf, Usd, UsdGeom

    stage = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(stage, meters_per_unit)
    stage.SetTimeCodesPerSecond(fps)
    stage.SetStartTimeCode(1)
    stage.SetEndTimeCode(last)
    world = UsdGeom.Xform.Define(stage, root).GetPrim()
    stage.SetDefaultPrim(world)
    if edge is not None:
        world.CreateAttribute("warpshade:edgeLength", Sdf.ValueTypeNames.Float).Set(edge)
    if not graded:
        world.CreateAttribute("warpshade:graded", Sdf.ValueTypeNames.Bool).Set(False)
    return stage


def sheet(stage, path: str, points, n: int, kind: str, colour) -> None:
    """An ``n`` x ``n`` quad mesh at ``path`` (``points`` row by row) of ``warpshade:kind`` ``kind``, with a
    UsdPreviewSurface material of ``colour`` (at its parent's ``Looks/Red``) bound."""
    from pxr import Gf, Sdf, UsdGeom, UsdShade

    root = path.rsplit("/", 1)[0]
    cloth = UsdGeom.Mesh.Define(stage, path)
    cloth.CreatePointsAttr(points)
    cloth.CreateFaceVertexCountsAttr([4] * (n * n))
    cloth.CreateFaceVertexIndicesAttr([v for j in range(n) for i in range(n) for v in
                                       (j * (n + 1) + i, j * (n + 1) + i + 1, (j + 1) * (n + 1) + i + 1, (j + 1) * (n + 1) + i)])
    cloth.GetPrim().CreateAttribute("warpshade:kind", Sdf.ValueTypeNames.Token, custom=True).Set(kind)
    mat = UsdShade.Material.Define(stage, f"{root}/Looks/Red")
    sh = UsdShade.Shader.Define(stage, f"{root}/Looks/Red/PBR")
    sh.CreateIdAttr("UsdPreviewSurface")
    sh.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*colour))
    mat.CreateSurfaceOutput().ConnectToSource(sh.ConnectableAPI(), "surface")
    UsdShade.MaterialBindingAPI.Apply(cloth.GetPrim()).Bind(mat)


def run(scene: str, out: str, method: str | None, frames: int = 1) -> dict:
    """``warpshade run`` of the first ``frames`` frames inline; its setup and shading seconds."""
    cmd = [sys.executable, "-m", "warpshade", "run", scene, "--frames", str(frames), "--workers", "0", "-o", out, "--no-progress"]
    if method:
        cmd += ["--method", method]
    env = dict(os.environ, PYTHONPATH=os.environ.get("PYTHONPATH") or REPO)  # PYTHONPATH set: that code
    # run outside any checkout: python -m puts the working directory first on sys.path
    res = subprocess.run(cmd, capture_output=True, text=True, env=env, check=True, cwd=os.path.dirname(out))
    times = {k: float(v) for k, v in re.findall(r"(setup|shade) ([0-9.]+) s", res.stderr)}
    return times


def colours(path: str, time: float = 1) -> dict:
    """Per mesh: points, triangles and luminance of ``displayColor`` at ``time``."""
    from pxr import Usd, UsdGeom

    out = {}
    stage = Usd.Stage.Open(path)  # held: its prims expire with it
    for p in stage.Traverse():
        if p.IsA(UsdGeom.Mesh):
            m = UsdGeom.Mesh(p)
            out[p.GetName()] = (np.asarray(m.GetPointsAttr().Get(time), dtype=np.float64),
                                np.asarray(m.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3),
                                np.asarray(UsdGeom.PrimvarsAPI(p).GetPrimvar("displayColor").Get(time)) @ LUM)
    return out


def floor_top(mesh):
    """The floor's top face: its points, triangles and values (the vertices at the top height)."""
    p, f, v = mesh
    top = np.isclose(p[:, 2], p[:, 2].max())
    keep = top[f].all(axis=1)
    return p, f[keep], v


def band(points: np.ndarray, width: float) -> np.ndarray:
    """Points outside the crate's footprint and within ``width`` of it (in its turned frame)."""
    c, s = np.cos(np.radians(-CRATE_TURN)), np.sin(np.radians(-CRATE_TURN))
    x = points[:, 0] * c - points[:, 1] * s
    y = points[:, 0] * s + points[:, 1] * c
    d = np.maximum(np.abs(x), np.abs(y)) - CRATE_HALF
    return (d > 0) & (d <= width)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--edges", default="auto,2.5", help="target edges [cm], 'auto' for the reader's rule")
    ap.add_argument("--truth-edge", type=float, default=1.25, help="edge [cm] of the reference run the floor is judged by")
    ap.add_argument("--grading", default="on", help="graded tessellation: on, off or on,off (each edge with each)")
    ap.add_argument("--band", type=float, default=20.0, help="floor band around the crate [cm]")
    ap.add_argument("--truth", default=None, metavar="OUT.usda", help="keep (or reuse) the fine reference run here")
    ap.add_argument("--json", default=None)
    args = ap.parse_args()
    import matplotlib.tri as mtri

    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        truth = args.truth or os.path.join(tmp, "truth_out.usda")
        if not os.path.exists(truth):
            truth_scene = os.path.join(tmp, "truth.usda")
            build(truth_scene, args.truth_edge, graded=False)
            run(truth_scene, os.path.abspath(truth), "reference")
        tp, tf, tv = floor_top(colours(truth)["Floor"])
        tmask = np.isclose(tp[:, 2], tp[:, 2].max())
        near = tmask & band(tp, args.band)
        for edge, grading in [(e, g) for e in args.edges.split(",") for g in args.grading.split(",")]:
            tag = f"{edge}_{grading}"
            scene = os.path.join(tmp, f"crate_{tag}.usda")
            build(scene, None if edge == "auto" else float(edge), graded=grading == "on")
            hemi_t = run(scene, os.path.join(tmp, f"hemi_{tag}.usda"), None)
            ref_t = run(scene, os.path.join(tmp, f"ref_{tag}.usda"), "reference")
            hemi, ref = colours(os.path.join(tmp, f"hemi_{tag}.usda")), colours(os.path.join(tmp, f"ref_{tag}.usda"))
            def on_truth(mesh):  # a floor's values interpolated over its own triangles at the truth's points
                p, f, v = floor_top(mesh)
                interp = mtri.LinearTriInterpolator(mtri.Triangulation(p[:, 0], p[:, 1], f), v)
                return np.asarray(interp(tp[near, 0], tp[near, 1]))

            at, ref_at = on_truth(hemi["Floor"]), on_truth(ref["Floor"])
            row = {"edge": edge, "graded": grading == "on", "hemiraster_setup_s": hemi_t.get("setup"), "hemiraster_shade_s": hemi_t.get("shade"),
                   "reference_shade_s": ref_t.get("shade"),
                   "vertices": {k: len(val[0]) for k, val in hemi.items()},
                   "error_vs_reference": {k: float(np.mean(np.abs(hemi[k][2] - ref[k][2]))) for k in hemi},
                   "reference_mean": {k: float(np.mean(ref[k][2])) for k in hemi},
                   "floor_band_error_vs_fine_reference": float(np.mean(np.abs(at - tv[near]))),
                   "floor_band_p95_vs_fine_reference": float(np.percentile(np.abs(at - tv[near]), 95)),
                   "floor_band_reference_error_vs_fine_reference": float(np.mean(np.abs(ref_at - tv[near]))),
                   "floor_band_points": int(near.sum())}
            rows.append(row)
            print(f"edge {edge}, grading {grading}: vertices {row['vertices']}  hemiraster setup {row['hemiraster_setup_s']} s shade "
                  f"{row['hemiraster_shade_s']} s  reference shade {row['reference_shade_s']} s")
            for k in hemi:
                print(f"    {k:12s} mean |hemiraster - reference| {row['error_vs_reference'][k]:.5f} "
                      f"(reference mean {row['reference_mean'][k]:.4f})")
            print(f"    floor within {args.band:g} cm of the crate: mean |error| against the {args.truth_edge:g} cm "
                  f"reference {row['floor_band_error_vs_fine_reference']:.5f}, p95 {row['floor_band_p95_vs_fine_reference']:.5f} "
                  f"({row['floor_band_points']} points); the reference of this tessellation "
                  f"{row['floor_band_reference_error_vs_fine_reference']:.5f}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"truth_edge": args.truth_edge, "band": args.band, "rows": rows}, fh, indent=1)


if __name__ == "__main__":
    main()
