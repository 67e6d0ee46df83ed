"""Triangle meshes: loading, validation and vertex normals.

Shapes follow one notation everywhere: V vertices, F triangles.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .normals import vertex_normals_np


class MeshError(ValueError):
    """Invalid mesh input. The message names the file (and prim, vertex or face) at fault."""


@dataclass
class TriMesh:
    """A triangle mesh on the host.

    Attributes:
        points: Vertex positions [m], shape (V, 3), dtype float32.
        faces: Triangle vertex indices, shape (F, 3), dtype int32.
        normals: Unit vertex normals (angle-weighted), shape (V, 3), dtype float32.
        name: Where the mesh came from (file and prim), for error messages.
    """

    points: np.ndarray
    faces: np.ndarray
    normals: np.ndarray = None
    name: str = "<mesh>"
    info: dict = field(default_factory=dict)

    def __post_init__(self):
        self.points = np.ascontiguousarray(self.points, dtype=np.float32)
        self.faces = np.ascontiguousarray(self.faces, dtype=np.int32)
        validate_mesh(self.points, self.faces, self.name)
        if self.normals is None:
            self.normals = vertex_normals_np(self.points, self.faces).astype(np.float32)
        else:
            self.normals = np.ascontiguousarray(self.normals, dtype=np.float32)

    @property
    def num_vertices(self) -> int:
        return len(self.points)

    @property
    def num_faces(self) -> int:
        return len(self.faces)

    def bbox_diagonal(self) -> float:
        """Length of the axis-aligned bounding-box diagonal [m]."""
        return float(np.linalg.norm(self.points.max(axis=0) - self.points.min(axis=0)))


def first_nonfinite(rows: np.ndarray) -> int | None:
    """Index of the first row of ``rows`` (shape (N, k)) with a NaN or infinite entry; None when all are finite."""
    finite = np.isfinite(rows)
    if finite.all():
        return None
    return int(np.flatnonzero(~finite.all(axis=1))[0])


def check_finite(points: np.ndarray, name: str = "<mesh>") -> None:
    """Raise :class:`MeshError` naming ``name``, the first vertex with a non-finite position, its position
    and how many such vertices there are."""
    v = first_nonfinite(points)
    if v is not None:
        bad = int((~np.isfinite(points).all(axis=1)).sum())
        raise MeshError(f"{name}: vertex {v} has a non-finite position {points[v].tolist()} ({bad} such vertices)")


def validate_mesh(points: np.ndarray, faces: np.ndarray, name: str = "<mesh>") -> None:
    """Check shapes, finiteness and index ranges.

    Degenerate (zero-area or repeated-index) triangles are allowed: they carry no area and are
    ignored by normals and visibility.

    Raises:
        MeshError: naming ``name`` and the first offending vertex or face.
    """
    if points.ndim != 2 or points.shape[1] != 3:
        raise MeshError(f"{name}: points must have shape (V, 3), got {points.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise MeshError(f"{name}: faces must have shape (F, 3), got {faces.shape}")
    if len(points) == 0 or len(faces) == 0:
        raise MeshError(f"{name}: empty mesh ({len(points)} vertices, {len(faces)} triangles)")
    check_finite(points, name)
    out = (faces < 0) | (faces >= len(points))
    if out.any():
        f = int(np.flatnonzero(out.any(axis=1))[0])
        raise MeshError(f"{name}: face {f} has vertex index out of range 0..{len(points) - 1}: "
                        f"{faces[f].tolist()}")


def vertex_indices(indices, count: int, what: str, error: type[ValueError] = ValueError) -> np.ndarray:
    """``indices`` (a sequence or array of integers, any shape) as a flat int64 array of indices into a mesh
    of ``count`` vertices: the one check of every vertex selection (pinned, attached vertices) in the script
    API, the USD reader, the cloth pipeline and :class:`~warpshade.sim.ClothBuilder`.

    Raises:
        error: (a ValueError subclass: the caller's, e.g. ``SceneError``) naming ``what`` (the caller's
            prefix: the file, prim, attribute or method) for indices that are not integers (``"<what>:
            vertex indices must be integers, got float64"``) and for the first index out of range
            (``"<what> vertex 7 out of range 0..2"``).
    """
    idx = np.asarray(indices).reshape(-1)
    if idx.size and not np.issubdtype(idx.dtype, np.integer):
        raise error(f"{what}: vertex indices must be integers, got {idx.dtype}")
    idx = idx.astype(np.int64)
    bad = idx[(idx < 0) | (idx >= count)]
    if len(bad):
        raise error(f"{what} vertex {int(bad[0])} out of range 0..{count - 1}")
    return idx


def weld_indices(points: np.ndarray) -> np.ndarray:
    """For each vertex, the first vertex at exactly the same position, shape (V,).

    DCC tools split a mesh's vertices along hard edges (a box exported with per-face normals has
    each face's own copy of its corners). Welded, the faces on both sides of such an edge are
    neighbours again, so the edge is a sharp edge between two faces, not two open borders, and a
    box made of separate faces is closed. Edge topology is fixed at construction: welded vertices
    are assumed to move together (as split copies of one vertex do). -0.0 and 0.0 are one position."""
    p = np.ascontiguousarray(np.asarray(points) + 0.0)  # + 0.0 turns -0.0 into 0.0
    rows = p.view(np.dtype((np.void, p.dtype.itemsize * p.shape[1]))).reshape(-1)  # one key per row
    _, first, inverse = np.unique(rows, return_index=True, return_inverse=True)
    return first[inverse.reshape(-1)].astype(np.int64)


def mesh_edges(faces: np.ndarray) -> np.ndarray:
    """The undirected edges of triangles ``faces`` (F, 3), each once, shape (E, 2) int64, lower index first."""
    e = np.sort(np.asarray(faces, dtype=np.int64)[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    return np.unique(e, axis=0) if len(e) else e


def vertex_neighbours(faces: np.ndarray, num_vertices: int) -> tuple[np.ndarray, np.ndarray]:
    """The vertices one edge away from each vertex, as CSR ``(start (V+1,), adj)`` int64, each row sorted."""
    e = mesh_edges(faces)
    both = np.concatenate([e, e[:, ::-1]])
    both = both[np.lexsort((both[:, 1], both[:, 0]))]
    return np.searchsorted(both[:, 0], np.arange(num_vertices + 1)), both[:, 1]


def fill_from_neighbours(values: np.ndarray, edges: np.ndarray, holes: np.ndarray) -> np.ndarray:
    """``values`` (V, ...) with the rows ``holes`` (V,) bool filled inward from the others over ``edges``
    (E, 2): in rounds, each hole row next to filled rows takes the mean of those (as they were at the
    start of the round) and is filled from then on. Rows not in ``holes`` are returned unchanged; hole rows
    with no path to a filled row (a part made only of holes) keep their values. Returns a new array."""
    out = np.array(values, copy=True)
    filled = ~np.asarray(holes, dtype=bool)
    if filled.all() or not filled.any():
        return out
    e = edges[holes[edges[:, 0]] | holes[edges[:, 1]]]  # only edges touching a hole carry anything
    a, b = np.concatenate([e[:, 0], e[:, 1]]), np.concatenate([e[:, 1], e[:, 0]])  # b's value flows to a
    flat = out.reshape(len(out), -1)
    while True:
        take = filled[b] & ~filled[a]
        if not take.any():
            return out
        dst, src = a[take], b[take]
        count = np.bincount(dst, minlength=len(out))
        rows = np.flatnonzero(count)
        # the sums over the edges into each row, in float64 and in edge order (as np.add.at adds them, at
        # a fraction of its cost): one bincount over (row, column) cells
        k = flat.shape[1]
        cells = (dst[:, None] * k + np.arange(k)).ravel()
        total = np.bincount(cells, weights=flat[src].astype(np.float64).ravel(), minlength=len(out) * k)
        total = total.reshape(len(out), k)
        flat[rows] = (total[rows] / count[rows, None]).astype(flat.dtype)
        filled[rows] = True


def stitched_faces(points: np.ndarray, faces: np.ndarray) -> np.ndarray:
    """``faces`` (F, 3) with the vertices on open borders (ends of an edge of one triangle only) that lie
    at exactly the same position made one (the lowest index, :func:`weld_indices`): the surface of a
    mesh whose faces have vertices of their own along sharp edges (a box split at its rims,
    :mod:`warpshade.geometry.shapes`), while separate parts that touch at a vertex inside them (a ball
    resting on a ground vertex) stay apart. Returns int64; ``faces`` as they are when nothing is
    stitched."""
    f = np.asarray(faces, dtype=np.int64)
    if not len(f):
        return f
    e = np.sort(f[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    keys, counts = np.unique(e[:, 0] * len(points) + e[:, 1], return_counts=True)
    once = keys[counts == 1]
    border = np.unique(np.concatenate([once // len(points), once % len(points)]))
    if not len(border):
        return f
    index = np.arange(len(points))
    index[border] = border[weld_indices(np.asarray(points)[border])]
    return index[f]


def surface_neighbours(points: np.ndarray, faces: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The vertices one edge away from each vertex on the surface :func:`stitched_faces` makes (a box split at its
    rims is one surface), and the other copies of it there (a split rim's vertices at the same position), as
    CSR ``(start (V+1,), adj)`` int64, each row sorted: :func:`vertex_neighbours` when nothing is stitched."""
    f = np.asarray(faces, dtype=np.int64)
    n = len(points)
    weld = np.arange(n)
    s = stitched_faces(points, f)
    weld[f.ravel()] = s.ravel()
    start, adj = vertex_neighbours(s, n)
    deg = np.diff(start)
    # each vertex's welded targets: its own welded vertex and that one's neighbours
    v = np.repeat(np.arange(n), deg[weld])
    first = np.repeat(start[weld] - np.concatenate([[0], np.cumsum(deg[weld])[:-1]]), deg[weld])
    pairs_v = np.concatenate([np.arange(n), v])
    pairs_t = np.concatenate([weld, adj[first + np.arange(len(v))]])
    # every vertex welded into each target
    order = np.argsort(weld, kind="stable")
    mstart = np.searchsorted(weld[order], np.arange(n + 1))
    cnt = np.diff(mstart)[pairs_t]
    out_v = np.repeat(pairs_v, cnt)
    base = np.repeat(mstart[pairs_t] - np.concatenate([[0], np.cumsum(cnt)[:-1]]), cnt)
    out_u = order[base + np.arange(len(out_v))]
    keep = out_u != out_v
    key = np.unique(out_v[keep] * n + out_u[keep])
    return np.searchsorted(key // n, np.arange(n + 1)), key % n


def closed_orientation(points: np.ndarray, faces: np.ndarray) -> int:
    """+1 for a closed mesh with outward-facing triangles, -1 for inward, 0 if not closed or not consistent.

    Closed and consistent: every directed edge appears once and its reverse once, on the surface
    (:func:`stitched_faces`: a box whose faces have vertices of their own is closed).
    """
    f = np.asarray(faces, dtype=np.int64)
    side = _closed_orientation(points, f)
    if side == 0 and len(f):
        side = _closed_orientation(points, stitched_faces(points, f))
    return side


def _closed_orientation(points: np.ndarray, f: np.ndarray) -> int:
    """:func:`closed_orientation` with vertices told apart by index (``f`` int64)."""
    e = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    if (e[:, 0] == e[:, 1]).any():
        return 0
    key = e[:, 0] * (int(e.max()) + 1) + e[:, 1]
    rkey = e[:, 1] * (int(e.max()) + 1) + e[:, 0]
    if len(np.unique(key)) != len(key) or not np.isin(rkey, key).all():
        return 0
    p = np.asarray(points, dtype=np.float64)
    p = p - p.mean(axis=0)
    vol = np.einsum("ij,ij->i", p[f[:, 0]], np.cross(p[f[:, 1]], p[f[:, 2]])).sum()
    return 0 if vol == 0 else (1 if vol > 0 else -1)


def ulp_jitter(points, seed: int) -> np.ndarray:
    """``points`` rounded to float32 with each coordinate then moved by -1, 0 or +1 ulp at random
    (``numpy.random.default_rng(seed)``): the same geometry as another file or tool might round it,
    for checking that a result does not hang on the last bit. Returns float32, same shape."""
    p = np.asarray(points, dtype=np.float32)
    step = np.random.default_rng(seed).integers(-1, 2, size=p.shape)
    return np.where(step > 0, np.nextafter(p, np.float32(np.inf)),
                    np.where(step < 0, np.nextafter(p, np.float32(-np.inf)), p)).astype(np.float32)
