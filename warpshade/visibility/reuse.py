"""Temporal reuse of transfer: recompute a receiver cluster only when the scene moved, seen from it.

:class:`TemporalReuse` wraps any :class:`~.base.TransferMethod`. Receivers are grouped into small
spatial clusters (median splits of the rest pose, :func:`kd_clusters`). Every frame, each cluster
``c`` adds to its account what the step from the previous frame changed in what it sees:

* its own normals: ``2 s_c / h`` [rad], where ``s_c`` is the largest deviation of one of its
  vertices' displacement from the cluster's mean displacement ``m_c`` and ``h`` the mesh's median
  edge length (a vertex moved by ``s`` among neighbours ``h`` away turns their normals by about
  ``s / h``);
* every other cluster ``b``: the angle it moved as seen from ``c``, ``(|m_b - m_c| + s_b + s_c) / d``
  with ``d`` the gap between the two clusters' bounding spheres (at least ``h``), weighted by the
  share of the view it can fill, ``min(1, (r_b + h)² / d²)`` (``r_b``: its bounding radius).

A cluster whose account exceeds ``tolerance`` is recomputed and its account reset; the others keep
the transfer of their last computation. So the tolerance is a budget in radians of view-weighted
motion: a neighbour turning the normals by 0.05 rad spends 0.05, a small distant blocker moving by
the same angle far less. Only relative motion counts: a rigid translation of the whole mesh spends
nothing (the transfer is unchanged by it). ``tolerance = 0`` recomputes every receiver whenever
anything moved, which is the method itself, value for value. Methods with a ``compute_rows(rows, later)``
(hemiraster in its diffuse mode without ``interpolate``) compute only the receivers due (``later``: the
receivers read, which later frames may compute); others
compute all of them when any is due, and the reuse saves time only on frames where none is.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from .base import TransferMethod

MAX_CLUSTERS = 512
"""Receiver clusters at most (the per-frame test is over cluster pairs: 512² of them)."""

MIN_CLUSTER = 16
"""Receivers per cluster at least."""


def kd_clusters(points: np.ndarray, size: int) -> tuple[np.ndarray, np.ndarray]:
    """Vertices split into compact clusters of at most ``size``: halved at the median of the longest
    axis of their bounding box, recursively.

    Returns:
        ``(order, start)``: vertex indices cluster by cluster, int64 (V,); cluster ``k`` holds
        ``order[start[k]:start[k+1]]``, ``start`` int64 (K+1,).
    """
    p = np.asarray(points, dtype=np.float64)
    size = max(1, int(size))
    leaves, todo = [], [np.arange(len(p))]
    while todo:
        idx = todo.pop()
        if len(idx) <= size:
            leaves.append(idx)
            continue
        q = p[idx]
        axis = int(np.argmax(np.ptp(q, axis=0)))
        half = np.argsort(q[:, axis], kind="stable")
        mid = len(idx) // 2
        todo += [idx[half[mid:]], idx[half[:mid]]]
    order = np.concatenate(leaves) if leaves else np.zeros(0, np.int64)
    start = np.concatenate([[0], np.cumsum([len(x) for x in leaves])]).astype(np.int64)
    return order.astype(np.int64), start


def median_edge(points: np.ndarray, faces: np.ndarray) -> float:
    """Median edge length of a triangle mesh (0 for a mesh without a proper edge)."""
    f = np.asarray(faces, dtype=np.int64)
    p = np.asarray(points, dtype=np.float64)
    e = np.linalg.norm(p[f] - p[np.roll(f, 1, axis=1)], axis=2).ravel()
    e = e[e > 0]
    return float(np.median(e)) if len(e) else 0.0


def check_tolerance(tolerance) -> float:
    """``tolerance`` as a float [rad].

    Raises:
        ValueError: it is negative or not finite.
    """
    value = float(tolerance)
    if not (value >= 0.0 and np.isfinite(value)):
        raise ValueError(f"reuse tolerance must be a finite angle >= 0 [rad], got {tolerance}")
    return value


def _row_norms(v: np.ndarray) -> np.ndarray:
    """Euclidean norm of each row of ``v`` (n, 3), summed ``(x² + y²) + z²`` as ``np.linalg.norm(v, axis=1)``
    sums it (the same values bit for bit), without its temporaries."""
    x, y, z = v[:, 0], v[:, 1], v[:, 2]
    out = x * x
    out += y * y
    out += z * z
    return np.sqrt(out, out=out)


def _pair_distances(p: np.ndarray) -> np.ndarray:
    """``|p_i - p_j|`` for every pair of rows of ``p`` (K, 3), (K, K): the values of
    ``np.linalg.norm(p[:, None] - p[None], axis=2)`` bit for bit, coordinate by coordinate (about five
    times faster at K = 256)."""
    out = np.zeros((len(p), len(p)))
    for k in range(3):
        d = p[:, k, None] - p[None, :, k]
        d *= d
        out += d
    return np.sqrt(out, out=out)


class TemporalReuse:
    """``method`` with its transfer reused where nothing moved by more than ``tolerance`` (see module doc).

    Args:
        method: The visibility method (built; its mesh gives topology and rest pose).
        tolerance: Budget [rad] of view-weighted motion seen from a receiver cluster before it is
            recomputed (module doc; >= 0, 0 recomputes whenever anything moved).
        cluster: Receivers per cluster (default: :data:`MIN_CLUSTER`, more on meshes with more than
            :data:`MAX_CLUSTERS` times that many vertices).

    Attributes:
        transfer: The transfer as reused and recomputed, (V, N*N) float32 ``wp.array``.
        labels: The cluster of each receiver, int64 (V,).
    """

    def __init__(self, method: TransferMethod, tolerance: float, cluster: int | None = None):
        self.method, self.tolerance = method, check_tolerance(tolerance)
        self.mesh, self.order, self.device = method.mesh, method.order, method.device
        nv = self.mesh.num_vertices
        size = int(cluster) if cluster else max(MIN_CLUSTER, -(-nv // MAX_CLUSTERS))
        if size < 1:
            raise ValueError(f"reuse cluster must be >= 1 receivers, got {cluster}")
        self._order, self._start = kd_clusters(self.mesh.points, size)
        self.labels = np.empty(nv, dtype=np.int64)
        self.labels[self._order] = np.repeat(np.arange(len(self._start) - 1), np.diff(self._start))
        self._count = np.diff(self._start).astype(np.float64)
        self._h = median_edge(self.mesh.points, self.mesh.faces) or 1.0
        self._account = np.zeros(len(self._start) - 1)
        self._all = np.arange(nv, dtype=np.int32)
        self._previous = None
        self._values = None
        self.transfer = wp.zeros_like(method.transfer)
        self.frames = 0
        self.computed = 0
        """Receivers computed over all updates (``computed / (frames * V)``: the fraction computed)."""
        self.last_computed = 0

    @property
    def name(self) -> str:
        return self.method.name

    @property
    def points(self) -> wp.array:
        return self.method.points

    @property
    def normals(self) -> wp.array:
        return self.method.normals

    def knobs(self) -> dict:
        return {**self.method.knobs(), "reuse": self.tolerance}

    def stats(self) -> dict:
        nv = self.mesh.num_vertices
        return {**self.method.stats(), "reuse_computed_fraction": self.computed / max(1, self.frames * nv),
                "reuse_last_computed_fraction": self.last_computed / nv}

    def transfer_numpy(self) -> np.ndarray:
        return self.transfer.numpy()

    def reset(self) -> None:
        """Forget the frames seen: the next :meth:`update` computes every receiver, as the first one does.
        The counters (``frames``, ``computed``) go on."""
        self._account[:] = 0.0
        self._previous = None
        self._values = None

    def due(self, points: np.ndarray) -> np.ndarray:
        """Advance the clusters' accounts by the step from the previous frame to ``points`` (module doc);
        returns the receivers due for recomputation, sorted int32 (all of them on the first frame)."""
        nv = self.mesh.num_vertices
        if self._previous is None:
            return np.arange(nv, dtype=np.int32)
        step = (points - self._previous).astype(np.float64)
        if not step.any():
            return np.zeros(0, dtype=np.int32)
        lab, cnt, starts = self.labels, self._count, self._start[:-1]
        o = self._order
        mean = np.add.reduceat(step[o], starts, axis=0) / cnt[:, None]
        spread = np.maximum.reduceat(_row_norms(step - mean[lab])[o], starts)
        pts = points.astype(np.float64)
        centre = np.add.reduceat(pts[o], starts, axis=0) / cnt[:, None]
        radius = np.maximum.reduceat(_row_norms(pts - centre[lab])[o], starts)
        gap = _pair_distances(centre)
        gap -= radius[:, None]
        gap -= radius[None, :]
        np.maximum(gap, self._h, out=gap)
        rel = _pair_distances(mean)
        rel += spread[:, None]
        rel += spread[None, :]
        seen = (radius[None, :] + self._h) / gap  # the share of the view the other cluster can fill: its
        seen *= seen                                # squared angular radius, at most 1; times the angle it moved
        np.minimum(1.0, seen, out=seen)
        seen *= rel
        seen /= gap
        np.fill_diagonal(seen, 2.0 * spread / self._h)
        self._account += seen.sum(axis=1)
        due = self._account > self.tolerance
        return np.flatnonzero(due[lab]).astype(np.int32)

    def update(self, points=None, normals=None, needed=None) -> wp.array:
        """Positions (and normals) of this frame; recomputes the receivers due, keeps the others.

        Args:
            needed: Receivers whose transfer will be read (None: all). Others are not recomputed
                (their rows keep whatever they held) when the method can compute rows.

        Returns:
            :attr:`transfer`.
        """
        m = self.method
        pts = np.asarray(self.mesh.points if points is None else points, dtype=np.float32)
        rows = self.due(pts)
        nv = self.mesh.num_vertices
        can_rows = hasattr(m, "compute_rows")
        if needed is not None and can_rows:
            needed = np.asarray(needed, dtype=np.int32)
            rows = np.intersect1d(rows, needed).astype(np.int32)
        if len(rows) and (not can_rows or (needed is None and len(rows) == nv)):
            values = m.update(pts, normals).numpy()
            rows = np.arange(nv, dtype=np.int32)
            self._values = values.copy()
        else:
            m.set_points(pts, normals)  # normals stay current everywhere, reused or not
            if self._values is None:
                self._values = np.zeros((nv, self.order * self.order), dtype=np.float32)
            if len(rows):  # later frames may compute any receiver read (hemiraster keeps its static part for them)
                values = m.compute_rows(rows, later=self._all if needed is None else needed).numpy()
                self._values[rows] = values[rows]
        self.transfer.assign(self._values)
        self._account[np.unique(self.labels[rows])] = 0.0
        self._previous = pts.copy()
        self.frames += 1
        self.computed += len(rows)
        self.last_computed = len(rows)
        return self.transfer


def update_rows(method, points, normals, rows) -> wp.array:
    """``method``'s transfer for ``points`` where only the receivers ``rows`` will be read: computed
    there alone when the method can (``compute_rows``, or a :class:`TemporalReuse` of such a method),
    else everywhere. The rows read are the same as a full ``update`` gives."""
    if isinstance(method, TemporalReuse):
        return method.update(points, normals, needed=rows)
    if hasattr(method, "compute_rows"):
        method.set_points(points, normals)
        return method.compute_rows(rows)
    return method.update(points, normals)


def with_reuse(method, tolerance: float | None):
    """``method`` wrapped in :class:`TemporalReuse` at ``tolerance``, or ``method`` itself for None."""
    return method if tolerance is None or method is None else TemporalReuse(method, tolerance)


__all__ = ["MAX_CLUSTERS", "MIN_CLUSTER", "TemporalReuse", "check_tolerance", "kd_clusters", "median_edge", "update_rows", "with_reuse"]
