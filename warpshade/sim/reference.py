"""Small, obviously-correct NumPy references for the simulation kernels (tests compare against them)."""

from __future__ import annotations

import numpy as np


def dihedral_angle_np(x1, x2, x3, x4) -> np.ndarray:
    """Signed dihedral angle [rad] of hinges with wings x1, x2 and shared edge x3-x4, shape (H,).

    Zero when flat. With triangle normals n1 = (x1 - x3) x (x1 - x4) and n2 = (x2 - x4) x (x2 - x3),
    the angle is atan2((n1 x n2) . e_hat, n1 . n2), e = x4 - x3, as in the Warp ``dihedral_angle``.
    """
    x1, x2, x3, x4 = (np.atleast_2d(np.asarray(a, dtype=np.float64)) for a in (x1, x2, x3, x4))
    e = x4 - x3
    n1 = np.cross(x1 - x3, x1 - x4)
    n2 = np.cross(x2 - x4, x2 - x3)
    le = np.linalg.norm(e, axis=1)
    s = np.einsum("ij,ij->i", np.cross(n1, n2), e) / np.where(le > 0, le, 1.0)
    c = np.einsum("ij,ij->i", n1, n2)
    return np.where(le > 0, np.arctan2(s, c), 0.0)


def triangle_closest_point_np(p, a, b, c) -> np.ndarray:
    """Closest point of triangle abc to p by brute force over interior projection, edges and corners."""
    p, a, b, c = (np.asarray(v, dtype=np.float64) for v in (p, a, b, c))
    cands = [a, b, c]
    for u, w in ((a, b), (b, c), (c, a)):
        d = w - u
        t = np.clip(np.dot(p - u, d) / max(np.dot(d, d), 1e-300), 0.0, 1.0)
        cands.append(u + t * d)
    n = np.cross(b - a, c - a)
    if np.dot(n, n) > 0:
        q = p - np.dot(p - a, n) / np.dot(n, n) * n
        m = np.array([[*(a - c)], [*(b - c)]]).T
        lam, *_ = np.linalg.lstsq(m, q - c, rcond=None)
        if lam.min() >= 0 and lam.sum() <= 1:
            cands.append(q)
    cands = np.array(cands)
    return cands[np.argmin(np.linalg.norm(cands - p, axis=1))]


def skin_points_np(rest: np.ndarray, indices: np.ndarray, weights: np.ndarray,
                   transforms: np.ndarray) -> np.ndarray:
    """Linear blend skinning: x_v = sum_k w_vk (M_{j_vk} [rest_v, 1])[:3].

    Args:
        rest: Rest positions, shape (V, 3).
        indices: Joint index per influence, shape (V, K), int.
        weights: Influence weights, shape (V, K) (not renormalised here).
        transforms: Skinning matrices (joint world x inverse bind), shape (J, 4, 4), column-vector
            convention (translation in the last column).

    Returns:
        Skinned positions, shape (V, 3), float64.
    """
    rest = np.asarray(rest, dtype=np.float64)
    h = np.concatenate([rest, np.ones((len(rest), 1))], axis=1)
    m = np.asarray(transforms, dtype=np.float64)[np.asarray(indices)]  # (V, K, 4, 4)
    moved = np.einsum("vkij,vj->vki", m, h)[..., :3]
    return np.einsum("vk,vki->vi", np.asarray(weights, dtype=np.float64), moved)
