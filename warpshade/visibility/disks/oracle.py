"""NumPy oracle of the disk kernels (tests compare :mod:`.kernels` against it).

Brute force over every vertex disk (no hierarchy), single pass: the value the Warp tree walk must
reproduce when ``lod`` is so large that no node stands for its subtree, contact rule included
(:func:`contact_normal_np`, :func:`contact_half_space_np`).
"""

from __future__ import annotations

import numpy as np

from ...geometry.mesh import surface_neighbours
from ..rays import FRAME_AXIS
from .kernels import (
    CONTACT,
    CONTACT_FACING,
    CONTACT_LEANING,
    CONTACT_REACH,
    CONTACT_SAMPLES,
)

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


def concentric_disk_np(u: float, v: float) -> tuple[float, float]:
    """[0,1]² -> unit disk (Shirley–Chiu), as the kernels' :func:`~warpshade.visibility.rays.concentric_disk`."""
    a, b = 2.0 * u - 1.0, 2.0 * v - 1.0
    if a == 0.0 and b == 0.0:
        return 0.0, 0.0
    if a * a > b * b:
        r, phi = a, (np.pi / 4.0) * (b / a)
    else:
        r, phi = b, (np.pi / 2.0) - (np.pi / 4.0) * (a / b)
    return r * np.cos(phi), r * np.sin(phi)


def contact_normal_np(v: int, p: np.ndarray, nrm: np.ndarray, area: np.ndarray, neighbours: set) -> np.ndarray | None:
    """The normal of the disk vertex ``v`` stands on (the kernels' ``contact_foot``): among the disks of vertices
    other than ``v`` and its edge ``neighbours``, within :data:`~.kernels.CONTACT` ρ of whose plane ``v`` lies
    (:data:`~.kernels.CONTACT_LEANING` ρ when ``n·N <`` :data:`~.kernels.CONTACT_FACING`) with its foot within
    :data:`~.kernels.CONTACT_REACH` ρ of the centre, the one with the nearest foot (in radii);
    None when there is none. ``neighbours``: :func:`~warpshade.geometry.mesh.surface_neighbours`' row of ``v``."""
    best, normal = CONTACT_REACH, None
    for e in range(len(p)):
        if e == v or e in neighbours or area[e] <= 0:
            continue
        d = p[e] - p[v]
        h = nrm[e] @ d
        rho = np.sqrt(area[e] / np.pi)
        if abs(h) > (CONTACT if nrm[v] @ nrm[e] >= CONTACT_FACING else CONTACT_LEANING) * rho:
            continue
        s = np.linalg.norm(d - nrm[e] * h) / rho
        if s < best:
            best, normal = s, nrm[e]
    return normal


def contact_half_space_np(frame: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Per bin, the share of its cosine measure behind the plane of ``normal`` (``w·N < 0``), by the kernels'
    :data:`~.kernels.CONTACT_SAMPLES`² midpoint rule in the concentric square, shape (16,)."""
    out = np.zeros(GRID * GRID)
    k = CONTACT_SAMPLES
    for i in range(GRID):
        for j in range(GRID):
            hit = 0
            for si in range(k):
                for sj in range(k):
                    x, y = concentric_disk_np((i + (si + 0.5) / k) / GRID, (j + (sj + 0.5) / k) / GRID)
                    w = frame @ np.array([x, y, np.sqrt(max(0.0, 1.0 - x * x - y * y))])
                    hit += w @ normal < 0.0
            out[i * GRID + j] = hit / (k * k)
    return out


def bin_occlusion_np(points, normals, faces, back_weight: float) -> np.ndarray:
    """Single-pass, unclamped bin occlusion of every vertex by every other vertex disk, and by the half-space
    behind a disk it stands on (:func:`contact_normal_np`), shape (V, 16)."""
    p = np.asarray(points, np.float64)
    nrm = np.asarray(normals, np.float64)
    area = disk_areas_np(p, faces)
    ring_start, ring = surface_neighbours(p, np.asarray(faces))
    out = np.zeros((len(p), GRID * GRID))
    for v in range(len(p)):
        fr = frame_np(nrm[v])
        contact = contact_normal_np(v, p, nrm, area, set(ring[ring_start[v]:ring_start[v + 1]].tolist()))
        if contact is not None:
            out[v] += contact_half_space_np(fr, contact)
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
