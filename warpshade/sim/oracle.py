"""Small, obviously-correct NumPy oracles for the simulation kernels (tests compare against them)."""

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


def point_triangle_distance_np(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Unsigned distance of every point to every triangle, shape (N, M).

    Args:
        p: Points, shape (N, 3). a, b, c: Triangle corners, shape (M, 3).

    The closest point is the projection onto the plane when it falls inside the triangle, else the
    closest point of the three edges (a segment clamp): the textbook case split, vectorised.
    """
    p = np.asarray(p, dtype=np.float64)[:, None, :]
    a, b, c = (np.asarray(v, dtype=np.float64)[None] for v in (a, b, c))
    n = np.cross(b - a, c - a)
    nn = np.einsum("...i,...i", n, n)
    safe = np.where(nn > 0, nn, 1.0)
    dpl = np.einsum("...i,...i", p - a, n) / safe
    q = p - dpl[..., None] * n
    # inside test with signed sub-areas
    inside = ((np.einsum("...i,...i", np.cross(b - a, q - a), n) >= 0)
              & (np.einsum("...i,...i", np.cross(c - b, q - b), n) >= 0)
              & (np.einsum("...i,...i", np.cross(a - c, q - c), n) >= 0) & (nn > 0))
    best = np.where(inside, np.linalg.norm(p - q, axis=-1), np.inf)
    for u, w in ((a, b), (b, c), (c, a)):
        d = w - u
        t = np.clip(np.einsum("...i,...i", p - u, d) / np.maximum(np.einsum("...i,...i", d, d), 1e-300), 0.0, 1.0)
        best = np.minimum(best, np.linalg.norm(p - (u + t[..., None] * d), axis=-1))
    return best


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


def triangles_meet_np(a, b, tol: float = 1e-12) -> bool:
    """Whether closed triangles a and b (each shape (3, 3)) share a point, by linear programming.

    They meet iff barycentric weights alpha, beta >= 0 with sum 1 exist such that
    sum alpha_i a_i = sum beta_j b_j: a feasibility problem (no geometry case analysis), solved
    with scipy's HiGHS; ``tol`` is the allowed residual of the equality [m].
    """
    from scipy.optimize import linprog

    a = np.asarray(a, dtype=np.float64)
    b = np.asarray(b, dtype=np.float64)
    # variables: alpha (3), beta (3), slack s >= 0 bounding |A alpha - B beta| <= s; minimise s
    a_eq = np.zeros((2, 7))
    a_eq[0, :3] = 1.0
    a_eq[1, 3:6] = 1.0
    diff = np.concatenate([a.T, -b.T], axis=1)  # (3, 6)
    a_ub = np.concatenate([np.concatenate([diff, -np.ones((3, 1))], 1), np.concatenate([-diff, -np.ones((3, 1))], 1)])
    res = linprog(np.r_[np.zeros(6), 1.0], A_ub=a_ub, b_ub=np.zeros(6), A_eq=a_eq, b_eq=[1.0, 1.0],
                  bounds=[(0, None)] * 7, method="highs")
    return bool(res.status == 0 and res.fun <= tol)
