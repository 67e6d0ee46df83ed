"""A sheet draped over a thin post (issue 19): the 36-variation matrix of the user's stage.

What it measures: issue 19's Houdini-style stage (:func:`post_scene`: a sheet 120 cm wide at 80 cm, pinned at
two corners or along its near edge, falling onto a `Cylinder` post 70 cm high whose axis is 10 cm off the sheet's
centre, over a floor; time codes 1001-1036 at 24 fps) for every post radius x sheet resolution x pinning x stage
convention asked for (default: radius 4/8/15 cm x 17/25/41 vertices a side x corners/edge x Z up in centimetres /
Y up in metres, 36 cases), each stepped through ``ClothSimulation`` as ``warpshade run`` steps it. Per case: the
frames ending with intersecting triangle pairs and the most pairs (exact count, cloth-cloth and cloth-collider,
after every frame), the guard's steps, unresolved steps and longest hold, the p99 and worst edge strain over all
frames, the strain warnings ``ClothSimulation`` raised, and the wall seconds of the run (shared machine: rough).

Success criteria (issue 19): 0 pairs at the end of every frame of every case; no strain warning (an edge past 3x
its rest length); guard holds of at most 3 steps.

Run:  python benchmarks/post_drape.py --json benchmarks/results/post_drape.json
      python benchmarks/post_drape.py --radii 4 --grids 41 --frames 20      (one corner of the matrix)
"""

from __future__ import annotations

import argparse
import itertools
import json
import os
import sys
import tempfile
import time
import warnings

import numpy as np

sys.path.insert(0, os.path.abspath(os.path.join(os.path.dirname(__file__), "..")))

from warpshade.geometry import ulp_jitter

RADII = (4.0, 8.0, 15.0)
"""Post radii [cm]."""
GRIDS = (17, 25, 41)
"""Sheet vertices a side (7.5, 5 and 3 cm edges)."""


def post_scene(path, n=25, pins="corners", yup=False, jitter=None, radius=8.0, diagonal="test"):
    """Issue 19's Houdini-style stage, written to ``path``: Z up in centimetres (or Y up in metres), time codes
    1001-1036 at 24 fps, an n x n sheet 120 cm wide at 80 cm pinned at two corners or along an edge (float vertex
    primvar ``warpshade_pinned``), a Cylinder post (``radius`` cm, height 70, its axis 10 cm off the sheet's
    centre) and a ground mesh. ``jitter``: the sheet's coordinates moved by an ulp (seed). ``diagonal``: where the
    Y-up stage's reversed quads start (so which diagonal a quad is split along): ``"test"`` at the quad's last
    corner, ``"matrix"`` at its first (the Z-up sheets' diagonal, as the 36-variation matrix of history.md)."""
    from pxr import Gf, Sdf, Usd, UsdGeom, Vt

    s = 0.01 if yup else 1.0
    st = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(st, UsdGeom.Tokens.y if yup else UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(st, 1.0 if yup else 0.01)
    st.SetStartTimeCode(1001)
    st.SetEndTimeCode(1036)
    st.SetTimeCodesPerSecond(24)
    st.SetFramesPerSecond(24)
    st.SetDefaultPrim(UsdGeom.Xform.Define(st, "/World").GetPrim())

    def stage(p):  # Z-up centimetres -> the stage's axes and unit
        p = np.asarray(p, dtype=np.float64)
        return p[..., [0, 2, 1]] * np.array([s, s, -s]) if yup else p

    xs = np.linspace(-60.0, 60.0, n)
    points = stage([(x, y, 80.0) for y in xs for x in xs]).astype(np.float32)
    if jitter is not None:
        points = ulp_jitter(points, jitter)
    quads = [(j * n + i, j * n + i + 1, (j + 1) * n + i + 1, (j + 1) * n + i) for j in range(n - 1) for i in range(n - 1)]
    if yup:  # the other winding (the stage's z is the sheet's -y)
        quads = [q[::-1] if diagonal == "test" else (q[0], q[3], q[2], q[1]) for q in quads]
    sheet = UsdGeom.Mesh.Define(st, "/World/Sheet")
    sheet.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(points))
    sheet.CreateFaceVertexCountsAttr([4] * len(quads))
    sheet.CreateFaceVertexIndicesAttr([i for q in quads for i in q])
    sheet.GetPrim().CreateAttribute("warpshade:kind", Sdf.ValueTypeNames.Token).Set("cloth")
    pin = np.zeros(n * n, np.float32)
    pin[[0, n - 1] if pins == "corners" else slice(0, n)] = 1.0
    UsdGeom.PrimvarsAPI(sheet).CreatePrimvar("warpshade_pinned", Sdf.ValueTypeNames.FloatArray,
                                             UsdGeom.Tokens.vertex).Set(Vt.FloatArray.FromNumpy(pin))
    post = UsdGeom.Cylinder.Define(st, "/World/Post")
    post.CreateRadiusAttr(radius * s)
    post.CreateHeightAttr(70.0 * s)
    post.CreateAxisAttr("Y" if yup else "Z")
    UsdGeom.XformCommonAPI(post).SetTranslate(Gf.Vec3d(*stage((0.0, 10.0, 35.0)).tolist()))
    post.GetPrim().CreateAttribute("warpshade:collider", Sdf.ValueTypeNames.Token).Set("cylinder")
    floor = UsdGeom.Mesh.Define(st, "/World/Floor")
    corners = stage([(-200, -200, 0), (200, -200, 0), (200, 200, 0), (-200, 200, 0)]).astype(np.float32)
    floor.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(corners))
    floor.CreateFaceVertexCountsAttr([4])
    floor.CreateFaceVertexIndicesAttr([0, 3, 2, 1] if yup else [0, 1, 2, 3])
    floor.GetPrim().CreateAttribute("warpshade:collider", Sdf.ValueTypeNames.Token).Set("ground")
    st.GetRootLayer().Save()
    return str(path)


def drape(path, frames=None) -> dict:
    """Step the stage at ``path`` through ``ClothSimulation`` (all its frames, or the first ``frames``) and meter
    every frame's end: the exact intersecting pairs, the edge strain, the warnings."""
    from warpshade.pipeline.cloth import ClothSimulation
    from warpshade.sim import IntersectionCounter
    from warpshade.usd.scene_io import read_scene

    t0 = time.perf_counter()
    sim = ClothSimulation(read_scene(path))
    solver, model = sim.solver, sim.model
    counter = IntersectionCounter(model.faces)
    edges = model.edges_np
    rest = model.edge_rest_length.numpy().astype(np.float64)
    pairs, strain, warned = [], [], []
    last = sim.frames if frames is None else min(sim.frames, frames + 1)
    for f in range(1, last):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            sim.advance(f, {})
        warned += [str(w.message) for w in caught if "stretched" in str(w.message)]
        x = sim.state.points
        pairs.append(counter.self_pairs(x)[0] + counter.collider_pairs(x, solver.colliders)[0])
        p = x.numpy().astype(np.float64)
        strain.append(np.linalg.norm(p[edges[:, 0]] - p[edges[:, 1]], axis=1) / rest - 1.0)
    s = np.concatenate(strain)
    st = solver.stats()
    return {"frames": len(pairs), "frames_with_pairs": int(sum(n > 0 for n in pairs)), "max_pairs": int(max(pairs)),
            "guard_steps": st["guard_steps"], "guard_unresolved": st["guard_unresolved"],
            "longest_hold": st["guard_longest_hold"], "p99_strain": float(np.percentile(s, 99)),
            "worst_strain": float(s.max()), "warnings": len(warned), "seconds": time.perf_counter() - t0}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--radii", type=float, nargs="+", default=list(RADII), help="post radii [cm]")
    ap.add_argument("--grids", type=int, nargs="+", default=list(GRIDS), help="sheet vertices a side")
    ap.add_argument("--pins", nargs="+", default=["corners", "edge"], choices=["corners", "edge"])
    ap.add_argument("--up", nargs="+", default=["z", "y"], choices=["z", "y"], help="Z up in cm, Y up in m")
    ap.add_argument("--diagonal", default="matrix", choices=["matrix", "test"],
                    help="Y-up quads' diagonal: the Z-up sheets' (matrix) or tests/pipeline/test_post_drape.py's")
    ap.add_argument("--seeds", type=int, nargs="*", default=None, help="also runs jittered by an ulp, per seed")
    ap.add_argument("--frames", type=int, default=None, help="frames to step (default: the stage's 35)")
    ap.add_argument("--json", help="write the rows to this file")
    args = ap.parse_args(argv)
    import warp as wp

    wp.config.quiet = True
    wp.config.log_level = wp.LOG_WARNING
    rows = []
    head = (f"{'radius':>6}{'grid':>5}{'pins':>8}{'up':>3}{'seed':>5}{'pair fr':>8}{'pairs':>6}{'guard':>6}"
            f"{'unres':>6}{'hold':>5}{'p99':>7}{'worst':>7}{'warn':>5}{'s':>6}")
    print(head)
    with tempfile.TemporaryDirectory() as tmp:
        for r, n, pins, up, seed in itertools.product(args.radii, args.grids, args.pins, args.up,
                                                      [None] + list(args.seeds or [])):
            path = post_scene(os.path.join(tmp, f"post_{len(rows)}.usda"), n=n, pins=pins, yup=up == "y",
                              jitter=seed, radius=r, diagonal=args.diagonal)
            row = {"radius_cm": r, "grid": n, "pins": pins, "up": up, "seed": seed, **drape(path, args.frames)}
            rows.append(row)
            print(f"{r:6.0f}{n:5d}{pins:>8}{up:>3}{'-' if seed is None else seed:>5}{row['frames_with_pairs']:8d}"
                  f"{row['max_pairs']:6d}{row['guard_steps']:6d}{row['guard_unresolved']:6d}{row['longest_hold']:5d}"
                  f"{row['p99_strain']:7.1%}{row['worst_strain']:7.0%}{row['warnings']:5d}{row['seconds']:6.1f}",
                  flush=True)
    bad = [r for r in rows if r["max_pairs"] or r["warnings"] or r["longest_hold"] > 3]
    print(f"{len(rows)} cases: {sum(r['max_pairs'] > 0 for r in rows)} with pairs, "
          f"{sum(r['warnings'] > 0 for r in rows)} warned, {sum(r['longest_hold'] > 3 for r in rows)} hold > 3 steps; "
          f"{'criteria met' if not bad else 'criteria not met'}")
    if args.json:
        with open(args.json, "w") as fh:
            json.dump({"diagonal": args.diagonal, "frames": args.frames, "rows": rows}, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
