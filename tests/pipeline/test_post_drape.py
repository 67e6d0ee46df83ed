"""A user's scene from issue 19: a sheet pinned at two corners (or along an edge) falls 10 cm onto
a Cylinder post and drapes over its rim. Nothing moves but the cloth, and the sheet can drape
there unstretched; before the cylinder's rim was kept out of the cloth triangles in the substeps
(``ColliderSet.collide_edges``' face pass), the rim cut the triangles lying over it at the end of
almost every step, the intersection guard held those vertices at their start positions for 30
steps in a row while the rest fell, and the edges between stretched to 3x their rest length
(``ClothSimulation`` warned).

Each case asserts 0 intersecting pairs (cloth-cloth and cloth-collider, exact count) at the end
of every frame, no strain warning, guard holds of at most :data:`HOLD` steps, and the p99 and
worst edge strain over all frames under :data:`P99` and :data:`WORST`. Measured on the branch
that brought the face pass (the three cases): holds of 0-1 steps, p99 12-25 %, worst 30-69 % (the
stretch the edge sweeps leave where the cloth bends over the rim); on main: holds of 30-31 steps,
p99 34-54 %, worst 98-222 %."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from warpshade.geometry import ulp_jitter
from warpshade.pipeline.cloth import ClothSimulation
from warpshade.scene import SceneWarning
from warpshade.sim import IntersectionCounter
from warpshade.usd.scene_io import read_scene

HOLD = 3
"""Longest guard hold allowed [steps] (measured 0-1; main 30-31)."""
P99 = 0.35
"""p99 edge strain allowed over all frames (measured 0.12-0.25; main 0.34-0.54)."""
WORST = 0.9
"""Worst edge strain allowed (measured 0.30-0.69; main 0.98-2.22)."""


def post_scene(path, n=25, pins="corners", yup=False, jitter=None):
    """The Houdini-style stage of issue 19: Z up in centimetres (or Y up in metres), time codes
    1001-1036 at 24 fps, an n x n sheet 120 cm wide at 80 cm pinned at two corners or along an
    edge (float vertex primvar ``warpshade_pinned``), a Cylinder post (radius 8, height 70, its
    axis 10 cm off the sheet's centre) and a ground mesh."""
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
    sheet = UsdGeom.Mesh.Define(st, "/World/Sheet")
    sheet.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(points))
    sheet.CreateFaceVertexCountsAttr([4] * len(quads))
    sheet.CreateFaceVertexIndicesAttr([i for q in quads for i in (q[::-1] if yup else q)])
    sheet.GetPrim().CreateAttribute("warpshade:kind", Sdf.ValueTypeNames.Token).Set("cloth")
    pin = np.zeros(n * n, np.float32)
    pin[[0, n - 1] if pins == "corners" else slice(0, n)] = 1.0
    UsdGeom.PrimvarsAPI(sheet).CreatePrimvar("warpshade_pinned", Sdf.ValueTypeNames.FloatArray,
                                             UsdGeom.Tokens.vertex).Set(Vt.FloatArray.FromNumpy(pin))
    post = UsdGeom.Cylinder.Define(st, "/World/Post")
    post.CreateRadiusAttr(8.0 * s)
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


@pytest.mark.parametrize("case", [{}, {"n": 17, "pins": "edge", "yup": True}, {"n": 17, "jitter": 1}],
                         ids=["z_up_cm_25", "edge_pinned_y_up_m_17", "jittered_17"])
def test_sheet_drapes_over_a_post_unheld_and_unstretched(tmp_path, case):
    sim = ClothSimulation(read_scene(post_scene(tmp_path / "post.usda", **case)))
    solver, model = sim.solver, sim.model
    counter = IntersectionCounter(model.faces)
    edges = model.edges_np
    rest = model.edge_rest_length.numpy().astype(np.float64)
    pairs, strain = [], []
    with warnings.catch_warnings():
        warnings.simplefilter("error", SceneWarning)
        for f in range(1, sim.frames):
            sim.advance(f, {})
            x = sim.state.points
            pairs.append(counter.self_pairs(x)[0] + counter.collider_pairs(x, solver.colliders)[0])
            p = x.numpy().astype(np.float64)
            strain.append(np.linalg.norm(p[edges[:, 0]] - p[edges[:, 1]], axis=1) / rest - 1.0)
    strain = np.concatenate(strain)
    stats = solver.stats()
    assert not any(pairs), f"intersecting pairs at frames {[f + 1 for f, n in enumerate(pairs) if n]}: {stats}"
    # the sheet drapes over the post: some of it lies on the cap (within 2 cm above its 70 cm), most hangs below
    p = sim.state.points.numpy().astype(np.float64) * 100.0  # [cm]
    up, across = (p[:, 1], np.stack([p[:, 0], -p[:, 2]], 1)) if case.get("yup") else (p[:, 2], p[:, :2])
    on_cap = (np.linalg.norm(across - (0.0, 10.0), axis=1) < 8.0) & (up > 70.0) & (up < 72.0)
    assert on_cap.any() and np.median(up) < 60.0, (on_cap.sum(), np.median(up))
    assert stats["guard_longest_hold"] <= HOLD, stats
    assert np.percentile(strain, 99) < P99 and strain.max() < WORST, (np.percentile(strain, 99), strain.max(), stats)
