"""NumPy oracle of GEARS masks: brute-force segment–triangle tests for every light sample.

Obviously correct and slow (V × F × k² work): tests compare the rasterized masks and the grid
against it on small scenes.
"""

from __future__ import annotations

import numpy as np

from .base import LightRect


def blocked_samples_np(points, normals, faces, light: LightRect, k: int, offset_abs: float) -> np.ndarray:
    """Blocked flags of the k×k cell-centre light samples per vertex, shape (V, k, k) bool, [v, row j, col i].

    A sample is blocked when the segment from the (offset) vertex to the light point crosses a
    triangle (Möller–Trumbore, parameter strictly inside the segment).
    """
    p = np.asarray(points, np.float64) + offset_abs * np.asarray(normals, np.float64)
    pts = np.asarray(points, np.float64)
    f = np.asarray(faces, np.int64)
    a, b, c = pts[f[:, 0]], pts[f[:, 1]], pts[f[:, 2]]
    e1, e2 = b - a, c - a
    centres = -1.0 + (2.0 * np.arange(k) + 1.0) / k
    t_grid, s_grid = np.meshgrid(centres, centres, indexing="ij")
    q = light.point(s_grid, t_grid)  # (k, k, 3)
    out = np.zeros((len(p), k, k), bool)
    for v in range(len(p)):
        d = q - p[v]  # (k, k, 3) segment directions, length = distance to the light point
        h = np.cross(d[..., None, :], e2)  # (k, k, F, 3)
        det = np.einsum("fc,ijfc->ijf", e1, h)
        ok = np.abs(det) > 1e-20
        inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
        s = p[v] - a  # (F, 3)
        uu = np.einsum("fc,ijfc->ijf", s, h) * inv
        qv = np.cross(s, e1)  # (F, 3)
        vv = np.einsum("ijc,fc->ijf", d, qv) * inv
        tt = np.einsum("fc,fc->f", e2, qv)[None, None, :] * inv
        hit = ok & (uu >= 0) & (vv >= 0) & (uu + vv <= 1) & (tt > 1e-9) & (tt < 1.0 - 1e-6)
        out[v] = hit.any(axis=-1)
    return out


def masks_to_bool(masks: np.ndarray, k: int) -> np.ndarray:
    """uint32 row masks (V, k) -> bool (V, k, k) [v, row j, col i]."""
    m = np.asarray(masks, np.uint32)
    return ((m[:, :, None] >> np.arange(k, dtype=np.uint32)[None, None, :]) & 1).astype(bool)
