"""Tessellations of the UsdGeom gprims (Cube, Capsule, Cylinder, Cone) shared by the USD reader
and the Python scene API, so that both shade the same triangles.

Shading is per vertex, so a vertex shared by two faces meeting at a sharp edge would get one
normal between them and shade like neither face (a dark or bright seam along every rim of a
cube). So each face of a box (:func:`box_shape`) and the caps of a cylinder or cone (split at their
creases, :func:`split_creases`) have vertices of their own, as a renderer shades the gprims (flat
faces, smooth sides).
"""

from __future__ import annotations

import numpy as np

AXIS_FROM_Z = {"Z": np.eye(3), "Y": np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]]),
               "X": np.array([[0, 0, 1.0], [0, 1, 0], [-1, 0, 0]])}
"""Rotations (acting on column vectors) taking a shape built along +Z to a gprim's ``axis``."""

CREASE_ANGLE = np.radians(30.0)
"""Two triangles sharing an edge whose normals differ by more than this meet at a crease
[rad]: the 90-degree rims of a cube and the cap rims of a cylinder are creases (a cone's base rim,
90-180 degrees, too); the steps between the facets of a 48-section cylinder (7.5 degrees) or of a
capsule's ends (at most 15 degrees) are not."""


def split_creases(vertices: np.ndarray, faces: np.ndarray, angle: float = CREASE_ANGLE) -> tuple[np.ndarray, np.ndarray]:
    """The same triangles with their vertices unshared across creases.

    The corners of the triangles around a vertex stay one vertex where they are joined through
    edges that are not creases (shared by exactly two triangles whose normals differ by at most
    ``angle``); each further group of corners gets a copy of the vertex. Vertex ``i < V`` of the
    result is vertex ``i`` of the input (for its first group of corners); copies follow, so a
    mesh without creases comes back unchanged.

    Args:
        vertices: Positions, shape (V, 3).
        faces: Triangles, shape (F, 3).
        angle: Crease angle [rad].

    Returns:
        ``(vertices (V', 3), faces (F, 3))``, V' >= V, the same dtypes.
    """
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    v = np.asarray(vertices)
    f = np.asarray(faces)
    nf = len(f)
    p = v.astype(np.float64)
    fn = np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]])
    ln = np.linalg.norm(fn, axis=1, keepdims=True)
    fn = np.divide(fn, ln, out=np.zeros_like(fn), where=ln > 0)
    # directed edges (a -> b) of every triangle; corner index = face * 3 + k
    a = f.reshape(-1).astype(np.int64)
    b = f[:, [1, 2, 0]].reshape(-1).astype(np.int64)
    corner_a = np.arange(3 * nf)
    corner_b = (np.arange(nf)[:, None] * 3 + np.array([1, 2, 0])).reshape(-1)
    key = np.minimum(a, b) * len(v) + np.maximum(a, b)
    order = np.argsort(key, kind="stable")
    _, start, count = np.unique(key[order], return_index=True, return_counts=True)
    two = start[count == 2]  # manifold edges: their two directed halves
    e1, e2 = order[two], order[two + 1]
    smooth = np.einsum("ij,ij->i", fn[e1 // 3], fn[e2 // 3]) >= np.cos(angle)
    e1, e2 = e1[smooth], e2[smooth]
    # join the corners at each end of a smooth edge: the corner at vertex a[e] in one triangle with
    # the corner at the same vertex in the other
    same = a[e1] == a[e2]  # (a consistently wound pair runs the edge in opposite directions)
    i = np.concatenate([corner_a[e1], corner_b[e1]])
    j = np.concatenate([np.where(same, corner_a[e2], corner_b[e2]), np.where(same, corner_b[e2], corner_a[e2])])
    graph = coo_matrix((np.ones(len(i)), (i, j)), shape=(3 * nf, 3 * nf))
    _, label = connected_components(graph, directed=False)
    # one vertex per (vertex, corner group): the first group of each vertex keeps the vertex's index
    pairs = a * (int(label.max()) + 1) + label
    groups, corner_group = np.unique(pairs, return_inverse=True)
    gvert = groups // (int(label.max()) + 1)
    primary = np.r_[True, gvert[1:] != gvert[:-1]]  # groups sorted by vertex, then label
    index = np.empty(len(groups), dtype=np.int64)
    index[primary] = gvert[primary]
    index[~primary] = len(v) + np.arange(int((~primary).sum()))
    new_faces = index[corner_group].reshape(nf, 3).astype(f.dtype)
    new_vertices = np.concatenate([v, v[gvert[~primary]]])
    return new_vertices, new_faces


BOX_SEGMENTS = 22
"""Squares along the longest side of a box's faces (:func:`box_shape`): a unit Cube gets 3174
vertices, fine enough for shadows to land on."""


def box_shape(extents) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) and triangles (F, 3) of a box of ``extents`` centred on the origin: each face a
    grid of its own vertices (its rims not shared: each face shades as itself up to them) of
    squares of side about ``max(extents) / BOX_SEGMENTS``, each square two triangles. Rows of
    vertices run along the rims, so a shading that changes towards a rim (a contact shadow) changes
    smoothly across the rows."""
    ext = np.asarray(extents, dtype=np.float64)
    edge = float(ext.max()) / BOX_SEGMENTS
    points, triangles = [], []
    for axis in range(3):
        u, w = (axis + 1) % 3, (axis + 2) % 3  # (u x w) = +axis
        nu, nw = (max(1, int(np.ceil(ext[k] / edge * (1.0 - 1e-9)))) for k in (u, w))
        a, b = np.meshgrid(np.linspace(-ext[u] / 2, ext[u] / 2, nu + 1), np.linspace(-ext[w] / 2, ext[w] / 2, nw + 1))
        i, j = np.meshgrid(np.arange(nu), np.arange(nw))
        corner = (j * (nu + 1) + i).ravel()
        quad = np.stack([corner, corner + 1, corner + nu + 2, corner + nu + 1], axis=1)
        tri = quad[:, [0, 1, 2, 0, 2, 3]].reshape(-1, 3)
        for sign in (1.0, -1.0):
            p = np.zeros((a.size, 3))
            p[:, axis], p[:, u], p[:, w] = sign * ext[axis] / 2, a.ravel(), b.ravel()
            triangles.append(sum(len(q) for q in points) + (tri if sign > 0 else tri[:, ::-1]))
            points.append(p)
    return np.concatenate(points), np.concatenate(triangles)


def axial_shape(kind: str, radius: float, height: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) and triangles (F, 3) of a ``"capsule"``, ``"cylinder"`` or ``"cone"`` along
    +Z centred on the origin, as USD defines the gprim: a Capsule's ``height`` is its cylindrical
    part (hemispheres of ``radius`` beyond), a Cone's apex is at ``+height/2``. 48 sections around
    (a capsule's ends 24 rings), like the reader's other gprims fine enough for shadows; split at
    the cap rims (:func:`split_creases`)."""
    import trimesh

    if kind == "cylinder":
        m = trimesh.creation.cylinder(radius=radius, height=height, sections=48)
    elif kind == "capsule":
        m = trimesh.creation.capsule(height=height, radius=radius, count=[48, 24])
    elif kind == "cone":  # trimesh puts the base at z = 0
        m = trimesh.creation.cone(radius=radius, height=height, sections=48)
        m.apply_translation([0.0, 0.0, -height / 2])
    else:
        raise ValueError(f"axial shape must be capsule, cylinder or cone, got {kind!r}")
    return split_creases(np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces))
