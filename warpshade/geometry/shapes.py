"""Tessellations of the UsdGeom gprims (Cube, Sphere, Capsule, Cylinder, Cone, Plane) shared by the
USD reader and the Python scene API, so that both shade the same triangles, and the rule that
sizes them.

Shading is per vertex, so the tessellation is the shading's resolution. A gprim is tessellated for
a target edge length given in world units (:func:`gprim_shape`): a scaled Cube gets as many squares
along each axis as its world length there holds edges (a 4 m x 4 m x 2 cm slab: many across, one
through its thickness), a Cylinder as many rings along its height, a Sphere the icosphere with at
least one vertex per edge-squared of its area. Curved shapes keep at least :data:`MIN_SECTIONS`
sections around (their silhouettes and normals), every count is at most :data:`MAX_SEGMENTS`. The
scene's target edge (:func:`scene_edge`) and the vertex budget (:func:`fit_budget`) are decided here
too; the USD reader supplies the scene's sizes and the per-prim overrides.

A vertex shared by two faces meeting at a sharp edge would get one normal between them and shade
like neither face (a dark or bright seam along every rim of a cube). So each face of a box and the
caps of a cylinder or cone have vertices of their own, as a renderer shades the gprims (flat faces,
smooth sides); the vertices along a rim of two faces are at the same positions (the same counts on
both), so the surface is closed where they meet.
"""

from __future__ import annotations

import numpy as np

AXIS_FROM_Z = {"Z": np.eye(3), "Y": np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]]),
               "X": np.array([[0, 0, 1.0], [0, 1, 0], [-1, 0, 0]])}
"""Rotations (acting on column vectors) taking a shape built along +Z to a gprim's ``axis``."""



MAX_SEGMENTS = 1024
"""Most squares along a box's axis or a plane's side, rings along a shape's profile, or sections
around it, whatever the target edge (a 1 mm edge on a 10 m floor stops at ~1 cm)."""

MIN_SECTIONS = 48
"""Fewest sections around a Cylinder, Cone or Capsule, and (:data:`SPHERE_SUBDIVISIONS`) about as
many around a Sphere: facets of 7.5 degrees, whatever the target edge, so small curved shapes keep
their silhouettes and smooth normals."""

SPHERE_SUBDIVISIONS = (3, 7)
"""Fewest and most icosphere subdivisions of a Sphere: 642 (about :data:`MIN_SECTIONS` around) to
163 842 vertices."""

BOX_SEGMENTS = 22
"""Squares along the longest side of a shape made without a scene to size it (:mod:`warpshade.script`):
its target edge is its longest extent / 22 (a unit cube: 3174 vertices)."""

EDGE_DIVISIONS = 100
"""The scene's target edge is at most its bounding box's diagonal / 100 (:func:`scene_edge`)."""

VERTEX_BUDGET = 60_000
"""Most vertices of the gprims tessellated by the scene's target edge together (:func:`fit_budget`):
shading cost grows with the vertices (hemiraster receivers and blockers)."""


def scene_edge(diagonal: float, cloth_edges=()) -> float | None:
    """The target edge length of a scene's gprims [scene units]: the finest simulated cloth's edge
    (``cloth_edges``, each cloth's median edge: the shading resolution its author chose), at most the
    scene's bounding-box ``diagonal`` / :data:`EDGE_DIVISIONS`. None for an empty scene."""
    edges = [float(e) for e in cloth_edges if e > 0]
    if diagonal > 0:
        edges.append(float(diagonal) / EDGE_DIVISIONS)
    return min(edges) if edges else None


def _count(length: float, edge: float, least: int = 1) -> int:
    """Pieces of at most ``edge`` along ``length`` (at least ``least``, at most :data:`MAX_SEGMENTS`)."""
    n = int(np.ceil(length / edge * (1.0 - 1e-9))) if edge > 0 else MAX_SEGMENTS
    return int(min(max(n, least), MAX_SEGMENTS))


def _grid(nu: int, nw: int, lu: float, lw: float):
    """A ``lu`` x ``lw`` rectangle centred on the origin of the (u, w) plane as ``nu`` x ``nw`` squares:
    ``(u, w)`` coordinates of its (nu + 1)(nw + 1) vertices and its triangles, wound for +u x +w."""
    a, b = np.meshgrid(np.linspace(-lu / 2, lu / 2, nu + 1), np.linspace(-lw / 2, lw / 2, nw + 1))
    i, j = np.meshgrid(np.arange(nu), np.arange(nw))
    corner = (j * (nu + 1) + i).ravel()
    quad = np.stack([corner, corner + 1, corner + nu + 2, corner + nu + 1], axis=1)
    return a.ravel(), b.ravel(), quad[:, [0, 1, 2, 0, 2, 3]].reshape(-1, 3)


def box_segments(extents, edge: float) -> tuple[int, int, int]:
    """Squares along each axis of a box of world ``extents`` for a target ``edge``."""
    return tuple(_count(float(e), edge) for e in extents)


def box_shape(extents, segments) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) and triangles (F, 3) of a box of ``extents`` centred on the origin, each face a
    grid of its own vertices (its rims not shared: each face shades as itself up to them) of
    ``segments[k]`` squares along axis ``k``, each square two triangles. Rows of vertices run along the
    rims, so a shading that changes towards a rim (a contact shadow) changes smoothly across the rows."""
    ext = np.asarray(extents, dtype=np.float64)
    points, triangles = [], []
    for axis in range(3):
        u, w = (axis + 1) % 3, (axis + 2) % 3  # (u x w) = +axis
        a, b, tri = _grid(int(segments[u]), int(segments[w]), ext[u], ext[w])
        for sign in (1.0, -1.0):
            p = np.zeros((a.size, 3))
            p[:, axis], p[:, u], p[:, w] = sign * ext[axis] / 2, a, b
            triangles.append(sum(len(q) for q in points) + (tri if sign > 0 else tri[:, ::-1]))
            points.append(p)
    return np.concatenate(points), np.concatenate(triangles)


def plane_shape(width: float, length: float, segments) -> tuple[np.ndarray, np.ndarray]:
    """A ``width`` (x) by ``length`` (y) rectangle in z = 0 facing +z, ``segments`` = (along x, along y)
    squares."""
    a, b, tri = _grid(int(segments[0]), int(segments[1]), width, length)
    return np.stack([a, b, np.zeros_like(a)], axis=1), tri


def _profile(kind: str, radius: float, height: float, scale, edge: float):
    """The patches of a ``kind`` shape along +Z as profiles in the (rho, z) plane, each an (K, 2) array
    from its start to its end (a cap from its centre to its rim, the side from bottom to top), pieces
    at most ``edge`` long in world units (``scale`` = (radial, axial) world scales), and the sections
    around."""
    sr, sa = float(scale[0]), float(scale[1])
    r, h = float(radius), float(height)

    def line(p0, p1):
        n = _count(float(np.hypot(sr * (p1[0] - p0[0]), sa * (p1[1] - p0[1]))), edge)
        t = np.linspace(0.0, 1.0, n + 1)[:, None]
        return np.asarray(p0) * (1 - t) + np.asarray(p1) * t

    def arc(z0, a0, a1):  # quarter circle of the capsule's end about (0, z0), angles from the +z axis
        n = _count(abs(a1 - a0) * r * max(sr, sa), edge)
        a = np.linspace(a0, a1, n + 1)
        return np.stack([np.where(np.abs(np.sin(a)) < 1e-12, 0.0, r * np.sin(a)), z0 + r * np.cos(a)], axis=1)

    bottom, top = -h / 2, h / 2
    if kind == "cylinder":
        patches = [line((0.0, bottom), (r, bottom)), line((r, bottom), (r, top)), line((r, top), (0.0, top))]
    elif kind == "cone":  # the apex at +height/2, as USD defines it
        patches = [line((0.0, bottom), (r, bottom)), line((r, bottom), (0.0, top))]
    elif kind == "capsule":
        side = line((r, bottom), (r, top))
        upper = arc(top, np.pi / 2, 0.0)[1 if h == 0 else 0:]  # height 0: the two ends meet at one ring
        patches = [np.concatenate([arc(bottom, np.pi, np.pi / 2), side[1:-1], upper])]
    else:
        raise ValueError(f"axial shape must be capsule, cylinder or cone, got {kind!r}")
    return patches, _count(2 * np.pi * r * sr, edge, MIN_SECTIONS)


def _revolve(profile: np.ndarray, sections: int):
    """Vertices and triangles of ``profile`` ((K, 2) points (rho, z)) turned about +Z in ``sections``
    steps: a point on the axis is one vertex; triangles face the profile's left (outward for a profile
    running from the bottom centre out and up)."""
    theta = 2 * np.pi * np.arange(sections) / sections
    ring_start, points = [], []
    for rho, z in profile:
        ring_start.append(sum(len(p) for p in points))
        if rho <= 0:
            points.append(np.array([[0.0, 0.0, z]]))
        else:
            points.append(np.stack([rho * np.cos(theta), rho * np.sin(theta), np.full(sections, z)], axis=1))
    j = np.arange(sections)
    k = (j + 1) % sections
    tris = []
    for i in range(len(profile) - 1):
        a0, b0 = ring_start[i], ring_start[i + 1]
        on_a, on_b = profile[i][0] <= 0, profile[i + 1][0] <= 0
        if on_a and on_b:
            continue
        if on_a:
            tris.append(np.stack([np.full(sections, a0), b0 + k, b0 + j], axis=1))
        elif on_b:
            tris.append(np.stack([a0 + j, a0 + k, np.full(sections, b0)], axis=1))
        else:
            tris.append(np.stack([a0 + j, a0 + k, b0 + k], axis=1))
            tris.append(np.stack([a0 + j, b0 + k, b0 + j], axis=1))
    return np.concatenate(points), np.concatenate(tris)


def axial_shape(kind: str, radius: float, height: float, edge: float, scale=(1.0, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) and triangles (F, 3) of a ``"capsule"``, ``"cylinder"`` or ``"cone"`` along
    +Z centred on the origin, as USD defines the gprim: a Capsule's ``height`` is its cylindrical
    part (hemispheres of ``radius`` beyond), a Cone's apex is at ``+height/2``. Surfaces of revolution:
    rings along the profile at most ``edge`` apart and ``2 pi radius / edge`` sections around (at
    least :data:`MIN_SECTIONS`), lengths in world units under the world ``scale`` (radial, axial).
    Caps have vertices of their own (their rims are creases), rims at the side's rim positions."""
    patches, sections = _profile(kind, radius, height, scale, edge)
    points, triangles = [], []
    for prof in patches:
        v, f = _revolve(prof, sections)
        triangles.append(f + sum(len(p) for p in points))
        points.append(v)
    return np.concatenate(points), np.concatenate(triangles)


def sphere_subdivisions(radius: float, edge: float) -> int:
    """Icosphere subdivisions of a sphere of world ``radius``: the fewest giving at least one vertex per
    ``edge``² of its area (as a grid of squares of side ``edge``), within :data:`SPHERE_SUBDIVISIONS`."""
    need = 4 * np.pi * radius ** 2 / edge ** 2 if edge > 0 else np.inf
    lo, hi = SPHERE_SUBDIVISIONS
    s = lo
    while s < hi and 10 * 4 ** s + 2 < need:
        s += 1
    return s


SPHERE_CACHE = "icosphere"
"""Kind of the disk cache entries (:mod:`warpshade._cache`) holding :func:`sphere_shape`'s tessellations."""


def sphere_shape(radius: float, subdivisions: int) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (float64) and triangles (int64) of an icosphere of ``radius`` centred on the origin
    (``trimesh.creation.icosphere``, imported on the first call that is not a hit). Kept in the per-user
    disk cache (:mod:`warpshade._cache`), keyed on ``radius``, ``subdivisions``, the trimesh and numpy
    versions and the machine: reading the scene then does not import trimesh (and the scipy modules it
    imports), which is most of the command's start-up cost for a scene with a Sphere."""
    import platform

    from .. import _cache

    radius, subdivisions = float(radius), int(subdivisions)
    nf = 20 * 4 ** subdivisions
    nv = nf // 2 + 2
    key = _cache.Key(SPHERE_CACHE, radius, subdivisions, platform.machine(), *_cache.versions("trimesh", "numpy")).hexdigest()
    hit = _cache.load(SPHERE_CACHE, key, check=lambda a: (
        _cache.has_layout(a, {"points": ((nv, 3), np.float64), "faces": ((nf, 3), np.int64)})
        and 0 <= a["faces"].min() and a["faces"].max() < nv))
    if hit is not None:
        return hit["points"], hit["faces"]
    import trimesh

    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    points, faces = np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int64)
    _cache.save(SPHERE_CACHE, key, {"points": points, "faces": faces})
    return points, faces


def gprim_shape(kind: str, dims: dict, scale, edge: float) -> tuple[np.ndarray, np.ndarray]:
    """The tessellation of a gprim in its local frame (along +Z for the axial shapes and the plane)
    for a target ``edge`` [world units].

    Args:
        kind: ``"cube"``, ``"sphere"``, ``"plane"``, ``"cylinder"``, ``"cone"`` or ``"capsule"``.
        dims: Its USD attributes: ``size``; ``radius``; ``width``, ``length``; ``radius``, ``height``.
        scale: World length of a unit along its local x, y, z (the columns of its world transform).
        edge: Target edge length [world units].
    """
    s = np.asarray(scale, dtype=np.float64)
    if kind == "cube":
        ext = [dims["size"]] * 3
        return box_shape(ext, box_segments(np.asarray(ext) * s, edge))
    if kind == "plane":
        return plane_shape(dims["width"], dims["length"], box_segments([dims["width"] * s[0], dims["length"] * s[1]], edge))
    if kind == "sphere":
        return sphere_shape(dims["radius"], sphere_subdivisions(dims["radius"] * s.max(), edge))
    return axial_shape(kind, dims["radius"], dims["height"], edge, (max(s[0], s[1]), s[2]))


def gprim_vertex_count(kind: str, dims: dict, scale, edge: float) -> int:
    """The number of vertices :func:`gprim_shape` makes with these arguments (without making them)."""
    s = np.asarray(scale, dtype=np.float64)
    if kind == "cube":
        n = box_segments(np.asarray([dims["size"]] * 3) * s, edge)
        return 2 * sum((n[(k + 1) % 3] + 1) * (n[(k + 2) % 3] + 1) for k in range(3))
    if kind == "plane":
        n = box_segments([dims["width"] * s[0], dims["length"] * s[1]], edge)
        return (n[0] + 1) * (n[1] + 1)
    if kind == "sphere":
        return 10 * 4 ** sphere_subdivisions(dims["radius"] * s.max(), edge) + 2
    patches, sections = _profile(kind, dims["radius"], dims["height"], (max(s[0], s[1]), s[2]), edge)
    return int(sum(sum(1 if rho <= 0 else sections for rho, _ in prof) for prof in patches))


def fit_budget(shapes, edge: float, budget: int = VERTEX_BUDGET) -> float:
    """The target edge for ``shapes`` (``(kind, dims, scale)`` each) within ``budget`` vertices in all:
    ``edge`` if they fit, else the shortest longer edge that fits (to 1 %; or, if even the coarsest
    tessellations exceed it, the edge at which they are reached)."""
    def total(e):
        return sum(gprim_vertex_count(k, d, s, e) for k, d, s in shapes)

    if total(edge) <= budget:
        return edge
    lo, hi = edge, edge
    while total(hi) > budget:
        if total(hi * 2) == total(hi):  # every shape at its fewest vertices already
            return hi
        lo, hi = hi, hi * 2
    while hi > lo * 1.01:
        mid = np.sqrt(lo * hi)
        lo, hi = (mid, hi) if total(mid) > budget else (lo, mid)
    return hi
