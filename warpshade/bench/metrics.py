"""Error metrics shared by tests, benchmarks and the planner (one definition everywhere).

Relative L2 transfer error: per vertex ``e_v = ||T_v - R_v||_2`` over the SH coefficients, divided by
the mean reference magnitude ``mean_v ||R_v||_2``. Normalising by the mean rather than per vertex
keeps fully occluded vertices (``R_v ≈ 0``) from dividing by zero while still weighting every
vertex equally.
"""

from __future__ import annotations

import numpy as np


def transfer_errors(transfer: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Per-vertex relative L2 errors, shape (V,).

    Args:
        transfer: Transfer to judge, shape (V, N*N).
        reference: Ground truth, shape (V, M*M); compared on the first ``min(N*N, M*M)`` coefficients.
    """
    t = np.asarray(transfer, dtype=np.float64)
    r = np.asarray(reference, dtype=np.float64)
    n = min(t.shape[1], r.shape[1])
    scale = np.linalg.norm(r[:, :n], axis=1).mean()
    if scale == 0.0:
        raise ValueError("reference transfer is zero everywhere; relative error undefined")
    return np.linalg.norm(t[:, :n] - r[:, :n], axis=1) / scale


def error_summary(transfer: np.ndarray, reference: np.ndarray) -> dict:
    """``{"error_mean", "error_p95", "error_max"}`` of :func:`transfer_errors`."""
    e = transfer_errors(transfer, reference)
    return {"error_mean": float(e.mean()), "error_p95": float(np.percentile(e, 95)), "error_max": float(e.max())}


def radiance_error(radiance: np.ndarray, reference: np.ndarray) -> float:
    """Mean relative radiance error: ``mean_v ||L_v - L*_v|| / mean_v ||L*_v||`` over RGB, shape (V, 3) inputs."""
    a = np.asarray(radiance, dtype=np.float64)
    b = np.asarray(reference, dtype=np.float64)
    scale = np.linalg.norm(b, axis=1).mean()
    if scale == 0.0:
        raise ValueError("reference radiance is zero everywhere; relative error undefined")
    return float(np.linalg.norm(a - b, axis=1).mean() / scale)


RECEIVER_CLASSES = ("contact", "fold", "open")
"""The receiver classes of :func:`receiver_classes`, in the order benchmarks print them."""


def receiver_classes(points: np.ndarray, faces: np.ndarray, gap: float = 1.5, rings: int = 4,
                     fold_degrees: float = 60.0) -> dict[str, np.ndarray]:
    """Split a posed surface's vertices (receivers) into *contact*, *fold* and *open* ones.

    * ``contact``: another part of the surface comes within ``gap`` mean edge lengths (of this pose) of
      the vertex: a vertex of it more than ``rings`` edges away along the mesh (layers touching, a cloth
      on itself). Vertices closer along the mesh are the receiver's own neighbourhood, not contact.
    * ``fold``: not contact, and one of the vertex's own triangles turns more than ``fold_degrees``
      from its (angle-weighted) normal: a crease, where the receiver's own fan blocks part of its sky.
    * ``open``: the rest.

    Args:
        points: Vertex positions, shape (V, 3).
        faces: Triangle indices, shape (F, 3).

    Returns:
        ``{name: boolean mask of shape (V,)}`` for the names of :data:`RECEIVER_CLASSES`; each vertex
        is in exactly one.
    """
    import scipy.sparse as sp
    from scipy.spatial import cKDTree

    from ..geometry.normals import vertex_normals_np

    p = np.asarray(points, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    nv = len(p)
    edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    edge = float(np.linalg.norm(p[edges[:, 0]] - p[edges[:, 1]], axis=1).mean())
    adj = sp.csr_matrix((np.ones(2 * len(edges)), (np.r_[edges[:, 0], edges[:, 1]], np.r_[edges[:, 1], edges[:, 0]])),
                        shape=(nv, nv)) + sp.identity(nv, format="csr")
    reach = adj
    for _ in range(rings - 1):
        reach = (reach @ adj).astype(bool).astype(np.float64)
    pairs = cKDTree(p).query_pairs(gap * edge, output_type="ndarray")
    contact = np.zeros(nv, dtype=bool)
    if len(pairs):
        apart = np.asarray(reach[pairs[:, 0], pairs[:, 1]]).ravel() == 0
        contact[pairs[apart].ravel()] = True
    n = vertex_normals_np(p, f)
    fn = np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]])
    fn /= np.maximum(np.linalg.norm(fn, axis=1, keepdims=True), 1e-300)
    cos_min = np.ones(nv)
    for k in range(3):
        np.minimum.at(cos_min, f[:, k], np.einsum("ij,ij->i", fn, n[f[:, k]]))
    fold = ~contact & (cos_min < np.cos(np.radians(fold_degrees)))
    return {"contact": contact, "fold": fold, "open": ~contact & ~fold}
