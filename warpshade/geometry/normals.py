"""Angle-weighted vertex normals (Thürmer & Wüthrich 1998, libigl's default weighting).

Angle weighting makes a vertex normal independent of how the surrounding faces are split into
triangles, which matters for meshes that mix n-gon fans and quads. A NumPy reference and a Warp
kernel compute the same thing; tests compare them.
"""

from __future__ import annotations

import numpy as np
import warp as wp


def vertex_normals_np(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """Angle-weighted unit vertex normals.

    Args:
        points: Vertex positions [m], shape (V, 3).
        faces: Triangle indices, shape (F, 3).

    Returns:
        Unit normals, shape (V, 3), float64. Vertices touching only degenerate triangles (or none)
        get +z so that downstream frames stay finite.
    """
    p = np.asarray(points, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    a, b, c = p[f[:, 0]], p[f[:, 1]], p[f[:, 2]]
    fn = np.cross(b - a, c - a)
    ln = np.linalg.norm(fn, axis=1, keepdims=True)
    fn = np.where(ln > 0, fn / np.where(ln > 0, ln, 1), 0.0)
    out = np.zeros_like(p)
    for k in range(3):
        e1 = p[f[:, (k + 1) % 3]] - p[f[:, k]]
        e2 = p[f[:, (k + 2) % 3]] - p[f[:, k]]
        ang = np.arctan2(np.linalg.norm(np.cross(e1, e2), axis=1), np.einsum("ij,ij->i", e1, e2))
        np.add.at(out, f[:, k], fn * ang[:, None])
    ln = np.linalg.norm(out, axis=1, keepdims=True)
    ok = ln[:, 0] > 0
    out[ok] /= ln[ok]
    out[~ok] = (0.0, 0.0, 1.0)
    return out


@wp.func
def corner_angle(a: wp.vec3, b: wp.vec3, c: wp.vec3) -> float:
    """Interior angle at ``a`` of triangle (a, b, c) [rad]; 0 for degenerate corners."""
    e1 = b - a
    e2 = c - a
    return wp.atan2(wp.length(wp.cross(e1, e2)), wp.dot(e1, e2))


@wp.kernel
def accumulate_vertex_normals(points: wp.array[wp.vec3], faces: wp.array2d[wp.int32], normals: wp.array[wp.vec3]):
    f = wp.tid()
    i = faces[f, 0]
    j = faces[f, 1]
    k = faces[f, 2]
    a = points[i]
    b = points[j]
    c = points[k]
    n = wp.cross(b - a, c - a)
    ln = wp.length(n)
    if ln == 0.0:
        return
    n = n / ln
    wp.atomic_add(normals, i, n * corner_angle(a, b, c))
    wp.atomic_add(normals, j, n * corner_angle(b, c, a))
    wp.atomic_add(normals, k, n * corner_angle(c, a, b))


@wp.kernel
def normalize_vertex_normals(normals: wp.array[wp.vec3]):
    i = wp.tid()
    n = normals[i]
    ln = wp.length(n)
    if ln > 0.0:
        normals[i] = n / ln
    else:
        normals[i] = wp.vec3(0.0, 0.0, 1.0)


def vertex_normals(points: wp.array, faces: wp.array, out: wp.array | None = None) -> wp.array:
    """Angle-weighted unit vertex normals on the device (same result as :func:`vertex_normals_np`).

    Args:
        points: Vertex positions [m], shape (V,), dtype vec3.
        faces: Triangle indices, shape (F, 3), dtype int32.
        out: Optional output, shape (V,), dtype vec3; allocated when None.

    Returns:
        ``out``, unit normals, shape (V,), dtype vec3.
    """
    if out is None:
        out = wp.zeros(points.shape[0], dtype=wp.vec3, device=points.device)
    else:
        out.zero_()
    wp.launch(accumulate_vertex_normals, dim=faces.shape[0], inputs=[points, faces], outputs=[out], device=points.device)
    wp.launch(normalize_vertex_normals, dim=points.shape[0], inputs=[], outputs=[out], device=points.device)
    return out
