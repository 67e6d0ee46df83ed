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

Graded (a :class:`Grading`, what the USD reader gives a shaded Cube or Plane unless
``warpshade:graded`` is false): the transfer at a point varies on a length scale of about its
distance ``d`` to the nearest occluder, so the edge there may be ``GRADE_SLOPE * d``, within [target
edge, :meth:`Grading.most`], ``d`` measured to the region the scene's other objects can occupy (their
bounds; a cloth's :func:`cloth_region`). Each face keeps those of its uniform grid's rows that the
rule allows (:func:`_graded_rows`: dyadic levels, so a face is fine where rows and columns pass over
the region and coarse elsewhere; a face with nothing in front of it, a floor slab's bottom and sides,
is coarsest), the rows along a rim are the union of both faces' (cells with extra rows on a side are
fans about their centre), so the surface stays closed vertex to vertex. The curved gprims and
:mod:`warpshade.script`'s shapes (made without a scene) stay uniform.

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

GRADE_SLOPE = 0.25
"""Graded tessellation (:class:`Grading`): the edge at distance ``d`` from the region the other objects
of the scene can occupy is ``GRADE_SLOPE * d``, within [target edge, :func:`Grading.most`]. The
transfer at a point varies on a length scale of about its distance to the nearest occluder (the
occluder's solid angle changes by its own size over that distance), so an edge of a quarter of it
keeps the linear interpolation between vertices close to the function; measured on the pedestal
scene (``benchmarks/gprim_grading.py``, docs/benchmarks)."""

GRADE_LEVELS = 3
"""Most doublings of the target edge a graded tessellation makes (the coarsest edge is at most
``2**GRADE_LEVELS`` times the target edge)."""

GRADE_MOST_DIVISIONS = 20
"""The coarsest graded edge is also at most the scene's diagonal / 20: the receiver refinement
(diagonal / 12, :mod:`warpshade.pipeline.refine`) then never subdivides a graded gprim (a cell's
diagonal, sqrt(2) / 20 of the scene's, is shorter)."""

GRADE_CLOTH_MARGIN = 0.1
"""The region a simulated cloth can occupy: its rest bounds swept down along gravity to the scene's
lowest point, widened on every side by this fraction of their diagonal (a draped cloth's hanging
parts stay within its rest footprint; the margin covers folds that land outside it and sliding)."""

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


class Grading:
    """Where a graded tessellation of a gprim must be fine: ``boxes`` (B, 2, 3), the lower and upper
    corners of boxes bounding the region the scene's other objects can occupy, in the shape's frame
    (its local axes, built along +Z and centred as :func:`box_shape` and :func:`plane_shape` build it,
    in world lengths: see :func:`frame_boxes`), and the scene's bounding-box ``diagonal`` (which
    bounds the coarsest edge, :meth:`most`)."""

    def __init__(self, boxes, diagonal: float):
        self.boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 2, 3)
        self.diagonal = float(diagonal)

    def most(self, edge: float) -> float:
        """The coarsest edge for a target ``edge``: ``2**GRADE_LEVELS`` times it, at most the diagonal /
        :data:`GRADE_MOST_DIVISIONS`, at least ``edge``."""
        return max(edge, min(edge * 2 ** GRADE_LEVELS, self.diagonal / GRADE_MOST_DIVISIONS))

    def spacing(self, t: np.ndarray, axis: int, edge: float, normal: int = 2, plane: float = 0.0,
                side: int = 0) -> np.ndarray:
        """The edge the rule asks for along ``axis`` at coordinates ``t`` [world lengths] on a face in the
        plane ``x[normal] = plane``: ``GRADE_SLOPE`` times the distance from the line x[axis] = t of the
        face to the nearest box in front of it (``side`` +1: the boxes reaching beyond the plane
        along +normal, -1: along -normal, 0: on either side), clamped to [``edge``, :meth:`most`]; the
        coarsest where no box is in front (a floor slab's bottom and sides). The distance ignores the
        face's other axis, so rows and columns through the region stay fine across the whole face."""
        most = self.most(edge)
        b = self.boxes
        if side:
            far, near = (b[:, 1], b[:, 0]) if side > 0 else (b[:, 0], b[:, 1])
            front = side * (far[:, normal] - plane) > 1e-6 * self.diagonal  # touching from behind: not in front
            height = np.maximum(side * (near[front, normal] - plane), 0.0)
            b = b[front]
        else:
            height = np.maximum(np.maximum(b[:, 0, normal] - plane, plane - b[:, 1, normal]), 0.0)
        if not len(b):
            return np.full(len(t), most)
        t = np.asarray(t, dtype=np.float64)[:, None]
        along = np.maximum(np.maximum(b[None, :, 0, axis] - t, t - b[None, :, 1, axis]), 0.0)
        d = np.hypot(along, height[None, :]).min(axis=1)
        return np.clip(GRADE_SLOPE * d, edge, most)


def cloth_region(box, up: int, lowest: float) -> np.ndarray:
    """The world box ((2, 3) lower and upper corners) a simulated cloth can occupy, from its rest bounds
    ``box``: widened on every side by :data:`GRADE_CLOTH_MARGIN` of the rest bounds' diagonal and swept
    down along the ``up`` axis to ``lowest`` (the scene's lowest point: it falls onto the colliders
    below)."""
    box = np.array(box, dtype=np.float64)
    box += GRADE_CLOTH_MARGIN * float(np.linalg.norm(box[1] - box[0])) * np.array([[-1.0], [1.0]])
    box[0, up] = lowest
    return box


def frame_boxes(boxes, to_world: np.ndarray) -> np.ndarray:
    """World axis-aligned ``boxes`` (B, 2, 3) as boxes in a shape's frame (:class:`Grading`):
    ``to_world`` (4, 4, acting on column vectors) takes the shape as built (along +Z) to the world;
    the frame is its local axes scaled to world lengths (the boxes there bound the world boxes' corners)."""
    boxes = np.asarray(boxes, dtype=np.float64).reshape(-1, 2, 3)
    lin = np.asarray(to_world, dtype=np.float64)[:3, :3]
    scale = np.linalg.norm(lin, axis=0)
    corners = np.stack([np.where(np.array([(i >> k) & 1 for k in range(3)], dtype=bool), boxes[:, 1], boxes[:, 0])
                        for i in range(8)], axis=1)  # (B, 8, 3)
    local = np.linalg.solve(lin, (corners - np.asarray(to_world)[:3, 3]).reshape(-1, 3).T).T * scale
    local = local.reshape(-1, 8, 3)
    return np.stack([local.min(axis=1), local.max(axis=1)], axis=1)


def _graded_rows(n: int, spacing: np.ndarray, base_edge: float, most: float) -> np.ndarray:
    """Which of the ``n + 1`` evenly spaced rows along a side (``base_edge`` apart) a graded grid keeps,
    for the ``spacing`` the rule asks for at each: row ``i`` is kept when ``i`` is a multiple of
    ``2**l``, ``l`` the most doublings of ``base_edge`` within its spacing (at most those within
    ``most``); the first and last are always kept. So a gap between kept rows is at most the spacing
    asked for at a row inside it, and the rows of a finer spacing include those of a coarser one."""
    top = int(np.floor(np.log2(max(most / base_edge, 1.0)) + 1e-9))
    level = np.clip(np.floor(np.log2(np.maximum(spacing / base_edge, 1.0)) + 1e-9), 0, top).astype(np.int64)
    i = np.arange(n + 1)
    keep = i % (1 << level) == 0
    keep[-1] = True
    return np.flatnonzero(keep)


def _graded_face(bu: np.ndarray, bw: np.ndarray, gu: np.ndarray, gw: np.ndarray, rims):
    """A rectangle's graded grid in the (u, w) plane: the rows ``gu`` x ``gw`` (indices into the
    coordinates ``bu``, ``bw`` of evenly spaced rows) and, along its four sides, the rows ``rims`` =
    (w = min side, w = max side, u = min side, u = max side; each a superset of ``gu`` or ``gw``)
    that the faces it meets there have: a square with extra rows on its sides is a fan about a vertex
    at its centre, so the sides meet their neighbours vertex to vertex (no T-junctions). The
    ``(u, w)`` coordinates of its vertices and its triangles, wound for +u x +w."""
    nu, nw = len(gu) - 1, len(gw) - 1
    a, b = np.meshgrid(bu[gu], bw[gw])
    coords = [np.stack([a.ravel(), b.ravel()], axis=1)]
    count = (nu + 1) * (nw + 1)
    grid_of = (gu, gu, gw, gw)
    extra = []  # per side: base indices of its extra rows, their vertex ids, the cell each lies on
    for side, rim in enumerate(rims):
        ex = np.setdiff1d(rim, grid_of[side])
        fixed = (bw[gw[0]], bw[gw[-1]], bu[gu[0]], bu[gu[-1]])[side]
        along = (bu if side < 2 else bw)[ex]
        coords.append(np.stack([along, np.full(len(ex), fixed)] if side < 2 else [np.full(len(ex), fixed), along], axis=1))
        cell = np.searchsorted(grid_of[side], ex, side="right") - 1
        extra.append((ex, count + np.arange(len(ex)), cell))
        count += len(ex)
    i, j = np.meshgrid(np.arange(nu), np.arange(nw))
    corner = (j * (nu + 1) + i).ravel()
    quad = np.stack([corner, corner + 1, corner + nu + 2, corner + nu + 1], axis=1)
    flagged = np.zeros((nw, nu), dtype=bool)
    for side, (_, _, cell) in enumerate(extra):
        if side == 0:
            flagged[0, cell] = True
        elif side == 1:
            flagged[nw - 1, cell] = True
        elif side == 2:
            flagged[cell, 0] = True
        else:
            flagged[cell, nu - 1] = True
    tris = [quad[~flagged.ravel()][:, [0, 1, 2, 0, 2, 3]].reshape(-1, 3)]
    centres = []
    for cj, ci in zip(*np.nonzero(flagged)):
        bl, br, tr, tl = quad[cj * nu + ci]
        ring = [bl]
        if cj == 0:
            ring += list(extra[0][1][extra[0][2] == ci])
        ring.append(br)
        if ci == nu - 1:
            ring += list(extra[3][1][extra[3][2] == cj])
        ring.append(tr)
        if cj == nw - 1:
            ring += list(extra[1][1][extra[1][2] == ci][::-1])
        ring.append(tl)
        if ci == 0:
            ring += list(extra[2][1][extra[2][2] == cj][::-1])
        c = count + len(centres)
        centres.append(((bu[gu[ci]] + bu[gu[ci + 1]]) / 2, (bw[gw[cj]] + bw[gw[cj + 1]]) / 2))
        ring = np.asarray(ring)
        tris.append(np.stack([np.full(len(ring), c), ring, np.roll(ring, -1)], axis=1))
    if centres:
        coords.append(np.asarray(centres))
    return np.concatenate(coords), np.concatenate(tris).astype(np.int64)


def graded_box_shape(extents, segments, scale, edge: float, grading: Grading) -> tuple[np.ndarray, np.ndarray]:
    """:func:`box_shape`'s box graded: each face's rows are those of ``segments`` evenly spaced rows that
    :func:`_graded_rows` keeps for the spacing :meth:`Grading.spacing` asks for on that face (world
    lengths: ``scale`` = world length of a unit along each axis); the rows along a rim are the union
    of its two faces' rows (both faces have them there: the surface stays closed where faces meet,
    vertex to vertex). Rims and rows are at :func:`box_shape`'s positions."""
    ext = np.asarray(extents, dtype=np.float64)
    world = ext * np.asarray(scale, dtype=np.float64)
    n = [int(k) for k in segments]
    most = grading.most(edge)
    base = [np.linspace(-ext[k] / 2, ext[k] / 2, n[k] + 1) for k in range(3)]
    rows = {}
    for axis in range(3):
        for sign in (1, -1):
            for along in range(3):
                if along != axis:
                    h = grading.spacing(base[along] * scale[along], along, edge, axis, sign * world[axis] / 2, sign)
                    rows[axis, sign, along] = _graded_rows(n[along], h, world[along] / n[along], most)
    points, triangles = [], []
    for axis in range(3):
        u, w = (axis + 1) % 3, (axis + 2) % 3
        for sign in (1.0, -1.0):
            own_u, own_w = rows[axis, int(sign), u], rows[axis, int(sign), w]
            rims = (np.union1d(own_u, rows[w, -1, u]), np.union1d(own_u, rows[w, 1, u]),
                    np.union1d(own_w, rows[u, -1, w]), np.union1d(own_w, rows[u, 1, w]))
            ab, tri = _graded_face(base[u], base[w], own_u, own_w, rims)
            p = np.zeros((len(ab), 3))
            p[:, axis], p[:, u], p[:, w] = sign * ext[axis] / 2, ab[:, 0], ab[:, 1]
            triangles.append(sum(len(q) for q in points) + (tri if sign > 0 else tri[:, ::-1]))
            points.append(p)
    return np.concatenate(points), np.concatenate(triangles)


def graded_plane_shape(width: float, length: float, segments, scale, edge: float, grading: Grading):
    """:func:`plane_shape` graded as one face of :func:`graded_box_shape` seen from both sides (the
    boxes on either side of the plane count)."""
    n = [int(k) for k in segments]
    dims = (float(width), float(length))
    most = grading.most(edge)
    base = [np.linspace(-dims[k] / 2, dims[k] / 2, n[k] + 1) for k in range(2)]
    rows = [_graded_rows(n[k], grading.spacing(base[k] * scale[k], k, edge), dims[k] * scale[k] / n[k], most)
            for k in range(2)]
    ab, tri = _graded_face(base[0], base[1], rows[0], rows[1], (rows[0], rows[0], rows[1], rows[1]))
    return np.stack([ab[:, 0], ab[:, 1], np.zeros(len(ab))], axis=1), tri


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


GRADED_KINDS = ("cube", "plane")
"""The gprims :func:`gprim_shape` grades when given a :class:`Grading`; the others (curved: their
rings and sections follow their curvature as much as the shading) are uniform."""


def gprim_shape(kind: str, dims: dict, scale, edge: float, grading: Grading | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The tessellation of a gprim in its local frame (along +Z for the axial shapes and the plane)
    for a target ``edge`` [world units].

    Args:
        kind: ``"cube"``, ``"sphere"``, ``"plane"``, ``"cylinder"``, ``"cone"`` or ``"capsule"``.
        dims: Its USD attributes: ``size``; ``radius``; ``width``, ``length``; ``radius``, ``height``.
        scale: World length of a unit along its local x, y, z (the columns of its world transform).
        edge: Target edge length [world units].
        grading: None: every edge at most ``edge`` (uniform). Else, for a Cube or Plane
            (:data:`GRADED_KINDS`), ``edge`` near the grading's boxes, coarser away from them
            (:func:`graded_box_shape`, :func:`graded_plane_shape`); the other kinds stay uniform.
    """
    s = np.asarray(scale, dtype=np.float64)
    if kind == "cube":
        ext = [dims["size"]] * 3
        segments = box_segments(np.asarray(ext) * s, edge)
        return box_shape(ext, segments) if grading is None else graded_box_shape(ext, segments, s, edge, grading)
    if kind == "plane":
        segments = box_segments([dims["width"] * s[0], dims["length"] * s[1]], edge)
        if grading is not None:
            return graded_plane_shape(dims["width"], dims["length"], segments, s, edge, grading)
        return plane_shape(dims["width"], dims["length"], segments)
    if kind == "sphere":
        return sphere_shape(dims["radius"], sphere_subdivisions(dims["radius"] * s.max(), edge))
    return axial_shape(kind, dims["radius"], dims["height"], edge, (max(s[0], s[1]), s[2]))


def gprim_vertex_count(kind: str, dims: dict, scale, edge: float, grading: Grading | None = None) -> int:
    """The number of vertices :func:`gprim_shape` makes with these arguments (without making them,
    except graded ones)."""
    if grading is not None and kind in GRADED_KINDS:
        return len(gprim_shape(kind, dims, scale, edge, grading)[0])
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
    """The target edge for ``shapes`` (``(kind, dims, scale)`` or ``(kind, dims, scale, grading)``
    each) within ``budget`` vertices in all: ``edge`` if they fit, else the shortest longer edge that
    fits (to 1 %; or, if even the coarsest tessellations exceed it, the edge at which they are reached)."""
    def total(e):
        return sum(gprim_vertex_count(*shape[:3], e, *shape[3:]) for shape in shapes)

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
