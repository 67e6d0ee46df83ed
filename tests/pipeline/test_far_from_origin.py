"""A scene far from the world origin shades as the same geometry at the origin: the shading groups' visibility
methods (and the sphere sets between groups) work in coordinates about the scene's own centre
(``rays.local_origin``, ``pipeline.shading._Group.local``)."""

import dataclasses
import warnings

import numpy as np
import pytest
from pxr import Usd

import warpshade as ws
from warpshade.geometry.shapes import box_segments, box_shape


def _placed(points, offset, back):
    """``points`` stored at ``offset`` in float32 (as a USD file holds them), and with ``back`` moved back to the
    origin exactly (float64): the same geometry, bit for bit, in both places."""
    p = (np.asarray(points, dtype=np.float64) + offset).astype(np.float32).astype(np.float64)
    return p - offset if back else p


def _grid(n, size, y):
    xs = np.linspace(-size / 2, size / 2, n)
    pts = np.array([[x, y, z] for z in xs for x in xs])
    faces = [[j * n + i, (j + 1) * n + i, j * n + i + 1] for j in range(n - 1) for i in range(n - 1)]
    faces += [[j * n + i + 1, (j + 1) * n + i, (j + 1) * n + i + 1] for j in range(n - 1) for i in range(n - 1)]
    return pts, np.array(faces)


def _scene(offset, back, method):
    """A box (shaded by ``method``: with another than hemiraster, a shading group of its own) on a ground, under a
    two-sided cloth (hemiraster; its back side has a method of its own), at ``offset``."""
    ground, gf = _grid(9, 2.0, 0.0)
    sheet, sf = _grid(5, 1.0, 0.8)
    ext = np.array([0.6, 0.6, 0.6])
    bv, bf = box_shape(ext, box_segments(ext, 0.3))
    box = ws.mesh("Box", _placed(bv + [0.0, 0.3, 0.0], offset, back), bf)
    return ws.make_scene(ws.mesh("Ground", _placed(ground, offset, back), gf), dataclasses.replace(box, method=method),
                         ws.cloth("Sheet", _placed(sheet, offset, back), sf), ws.sky(), frames=1)


def _colors(path):
    stage = Usd.Stage.Open(str(path))
    t = stage.GetStartTimeCode()
    return {n: np.array(stage.GetPrimAtPath(f"/World/{n}").GetAttribute("primvars:displayColor").Get(t))
            for n in ("Ground", "Box", "Sheet")}


@pytest.mark.parametrize("distance, method", [(1e4, "hemiraster"), (1e3, "spheres")])
def test_a_scene_far_away_shades_as_at_the_origin(tmp_path, distance, method):
    """Measured before (a finer box on a finer ground, docs/benchmarks/history.md): max radiance difference 0.72 %
    (1 km) and 1.6 % (10 km) of the brightest vertex with hemiraster alone, 0.08 % and 1.55 % with spheres; after,
    0 (exact: the shift to the local origin is exact). With spheres, the box is a group of its own, so the sphere
    sets between groups are in play."""
    offset = np.array([distance, 0.0, distance])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # nothing moves in one frame
        far, near = (ws.run(_scene(offset, back, method), str(tmp_path / f"{'near' if back else 'far'}.usda"), frames=1,
                            refine_receivers="off", workers=0).path for back in (False, True))
    a, b = _colors(far), _colors(near)
    assert {n: float(np.abs(a[n] - b[n]).max()) for n in a} == {n: 0.0 for n in a}
    assert min(c.max() for c in b.values()) > 0.05  # lit (a black scene would compare equal too)
