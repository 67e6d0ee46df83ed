"""Polygons on the unit sphere, in NumPy (float64): the projected solid angle of a polygon light."""

from __future__ import annotations

import math

import numpy as np


def projected_solid_angle_np(poly: np.ndarray) -> float:
    """Projected solid angle (``∫ cos θ dω``) of a convex spherical polygon on or above the horizon.

    Lambert's formula: ``Φ = ½ Σ_edges θ_e (ĝ_e · z)`` with ``θ_e`` the angle an edge subtends and
    ``ĝ_e`` the unit normal of the plane through the origin and the edge, pointing inwards.

    Args:
        poly: Polygon corners in the tangent frame (normal +z), shape (K, 3), all with z >= 0,
            convex as seen from the origin, either winding.
    """
    a = np.asarray(poly, dtype=np.float64)
    if (a[:, 2] < 0).any():
        raise ValueError("projected_solid_angle_np needs a polygon on or above the horizon (z >= 0)")
    u = a / np.linalg.norm(a, axis=1, keepdims=True)
    if np.dot(u.mean(axis=0), np.cross(u[0], u[1])) < 0:
        u = u[::-1]
    total = 0.0
    for e in range(len(u)):
        p, q = u[e], u[(e + 1) % len(u)]
        g = np.cross(p, q)
        total += math.acos(np.clip(np.dot(p, q), -1, 1)) * g[2] / np.linalg.norm(g)
    return 0.5 * total
