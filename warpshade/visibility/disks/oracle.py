"""NumPy oracle of the disk kernels (tests compare :mod:`.kernels` against it).

Brute force over every vertex disk (no hierarchy), single pass: the value the Warp tree walk must
reproduce when ``lod`` is so large that no node stands for its subtree.
"""

from __future__ import annotations

import numpy as np

from ..rays import FRAME_AXIS

GRID = 4
_FRAME_AXIS = np.array(FRAME_AXIS, np.float64)


def disk_areas_np(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """A third of each incident triangle's area per vertex, shape (V,)."""
    p = np.asarray(points, np.float64)
    f = np.asarray(faces, np.int64)
    a = 0.5 * np.linalg.norm(np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]]), axis=1) / 3.0
    out = np.zeros(len(p))
    for c in range(3):
        np.add.at(out, f[:, c], a)
    return out


def frame_np(n: np.ndarray) -> np.ndarray:
    """Columns (t, b, n) around unit n, as the kernels' :func:`~warpshade.visibility.rays.orthonormal_basis`
    (``t`` along ``FRAME_AXIS × n``), shape (3, 3)."""
    n = np.asarray(n, np.float64)
    t = np.cross(_FRAME_AXIS, n)
    if np.linalg.norm(t) < 1e-4:
        t = np.cross((1.0, 0.0, 0.0), n)
    t = t / np.linalg.norm(t)
    return np.stack([t, np.cross(n, t), n], axis=1)


def concentric_inverse_np(x: float, y: float) -> tuple[float, float]:
    """Unit disk -> [0,1]² (inverse Shirley–Chiu)."""
    r = np.hypot(x, y)
    if r == 0.0:
        return 0.5, 0.5
    phi = np.arctan2(y, x)
    q = np.pi / 4
    if phi < -q:
        phi += 2 * np.pi
    if phi < q:
        a, b = r, phi * r / q
    elif phi < 3 * q:
        b = r
        a = -(phi - 2 * q) * b / q
    elif phi < 5 * q:
        a = -r
        b = (phi - 4 * q) * a / q
    else:
        b = -r
        a = -(phi - 6 * q) * b / q
    return 0.5 * (a + 1), 0.5 * (b + 1)


def bin_occlusion_np(points, normals, faces, back_weight: float) -> np.ndarray:
    """Single-pass, unclamped bin occlusion of every vertex by every other vertex disk, shape (V, 16)."""
    p = np.asarray(points, np.float64)
    nrm = np.asarray(normals, np.float64)
    area = disk_areas_np(p, faces)
    out = np.zeros((len(p), GRID * GRID))
    for v in range(len(p)):
        fr = frame_np(nrm[v])
        for e in range(len(p)):
            if e == v or area[e] <= 0:
                continue
            d = p[e] - p[v]
            dist = np.linalg.norm(d)
            if dist == 0:
                continue
            w = d / dist
            rho = np.sqrt(area[e] / np.pi)
            z = nrm[v] @ d
            if z <= -rho:
                continue
            cp = z / dist if z >= rho else (z + rho) ** 2 / (4 * rho * dist)
            ce = -(nrm[e] @ w)
            if ce < 0:
                ce = -ce * back_weight
            ff = area[e] * ce * cp / (np.pi * dist * dist + area[e])
            if ff <= 0:
                continue
            loc = fr.T @ w
            u, vv = concentric_inverse_np(loc[0], loc[1])
            half = max(0.5 * np.sqrt(area[e] / (np.pi * dist * dist + area[e])), 1e-4)
            u0, u1, v0, v1 = max(0, u - half), min(1, u + half), max(0, vv - half), min(1, vv + half)
            norm = (u1 - u0) * (v1 - v0)
            for i in range(GRID):
                ou = max(0.0, min(u1, (i + 1) / GRID) - max(u0, i / GRID))
                for j in range(GRID):
                    ov = max(0.0, min(v1, (j + 1) / GRID) - max(v0, j / GRID))
                    out[v, i * GRID + j] += ff * GRID * GRID / norm * ou * ov
    return out
