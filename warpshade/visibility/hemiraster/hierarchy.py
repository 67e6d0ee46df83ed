"""Static blocker structures of hemispherical rasterization (Kautz et al. 2004 §3.2), built once on the host.

* **k-ring lists**: per receiver vertex, the full-resolution triangles touching a vertex at most ``k``
  edges away, minus the triangles incident to the receiver (they contain it, so they subtend no
  solid angle, and rasterizing them would only add quantisation noise).
* **Coarse mesh** by quadric decimation (``fast_simplification``). Each coarse vertex is bound to
  its closest fine triangle (barycentrics + offset along that triangle's normal), so it follows the
  deforming fine mesh every frame with no re-decimation.
* **Coarse-to-fine map**: each fine triangle belongs to the coarse triangle nearest to it at rest,
  so every coarse triangle knows the fine triangles it stands for. Per frame, a coarse triangle whose
  refitted bounds (its own and its fine triangles') come near a receiver, relative to their size, is
  replaced by its fine triangles (spatial near-field refinement): where surfaces touch or fold,
  the receiver sees the exact surface, never a coarse triangle cutting through it.
* **Topological near field**: with refinement, per receiver the coarse triangles standing for fine
  triangles of its k-ring, as a bitset: always refined, so the k-ring is rasterized exactly, at the
  granularity of coarse triangles. Without refinement (the paper's scheme), the k-ring's own
  triangle lists plus an exclusion bitset of the coarse triangles closer (rest pose) than the
  receiver's k-ring radius, which fails where another part of the mesh was near at rest (a
  shoulder next to the torso) or where the coarse surface cuts through the fine one.
* **Clusters**: blocker triangles sorted along a Morton curve of their rest centroids and cut into
  clusters of ``G`` triangles, clusters grouped into super-clusters; bounding boxes are refitted
  per frame and tested against the tangent plane (two-level hierarchical culling).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from ...geometry.mesh import stitched_faces, vertex_neighbours


def vertex_faces(faces: np.ndarray, num_vertices: int) -> list[np.ndarray]:
    """Triangles incident to each vertex."""
    order = np.argsort(faces.ravel(), kind="stable")
    owner = faces.ravel()[order]
    starts = np.searchsorted(owner, np.arange(num_vertices + 1))
    tri = order // 3
    return [tri[starts[v]:starts[v + 1]] for v in range(num_vertices)]


def interpolation_subset(faces: np.ndarray, num_vertices: int, levels: int = 1):
    """Receivers to compute and, level by level, receivers to interpolate from their neighbours.

    Level 0 is the vertex graph: a greedy maximal independent set of it (in index order) is kept,
    every other vertex is interpolated from its kept 1-ring neighbours, or kept itself when fewer
    than two of them are (boundaries, irregular spots). Each further level does the same on the
    kept vertices, two of them adjacent when they were adjacent or shared a neighbour on the level
    below (so a level's neighbours lie about twice as far apart as the level below's): about half
    the receivers are computed with one level, a quarter with two, an eighth with three on a smooth
    closed mesh. The receivers computed are the last level's kept vertices; a level's targets read
    the transfers of the level above (computed, or interpolated there), coarsest level first.

    Returns:
        ``(selected, split)``: ``selected`` int32, the receivers computed; ``split`` one
        ``(targets, start, nbrs)`` per level, coarsest first, int32: the level's interpolated
        receivers and per vertex (CSR, ``start`` shape (V+1,)) the neighbours each of them reads
        (empty rows for the others).
    """
    from scipy import sparse

    start, adj = vertex_neighbours(faces, num_vertices)
    active = np.ones(num_vertices, dtype=bool)
    split = []
    for _ in range(int(levels)):
        chosen = np.zeros(num_vertices, dtype=bool)
        blocked = ~active
        for v in np.flatnonzero(active):
            if not blocked[v]:
                chosen[v] = True
                blocked[adj[start[v]:start[v + 1]]] = True
        lists = [adj[start[v]:start[v + 1]][chosen[adj[start[v]:start[v + 1]]]] if active[v] and not chosen[v]
                 else np.zeros(0, np.int64) for v in range(num_vertices)]
        few = np.array([active[v] and not chosen[v] and len(lists[v]) < 2 for v in range(num_vertices)], dtype=bool)
        chosen |= few
        lists = [np.zeros(0, np.int64) if chosen[v] else x for v, x in enumerate(lists)]
        nstart = np.concatenate([[0], np.cumsum([len(x) for x in lists])])
        nbrs = np.concatenate(lists) if nstart[-1] else np.zeros(1, np.int64)
        split.append((np.flatnonzero(active & ~chosen).astype(np.int32), nstart.astype(np.int32), nbrs.astype(np.int32)))
        # the next level's graph: kept vertices adjacent or sharing a neighbour on this one
        g = sparse.csr_matrix((np.ones(len(adj), np.int8), adj, start), shape=(num_vertices, num_vertices))
        g = (g + sparse.identity(num_vertices, dtype=np.int8, format="csr")).astype(np.int32)
        keep = sparse.diags(chosen.astype(np.int32), dtype=np.int32)
        g2 = (keep @ (g @ g) @ keep).tocsr()
        g2.setdiag(0)
        g2.eliminate_zeros()
        g2.sort_indices()
        start, adj = g2.indptr.astype(np.int64), g2.indices.astype(np.int64)
        active = chosen
    return np.flatnonzero(active).astype(np.int32), split[::-1]


def ring_triangles(faces: np.ndarray, num_vertices: int, k: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-vertex k-ring blocker triangles (CSR) and k-ring vertex sets.

    Args:
        faces: Triangles, shape (F, 3).
        num_vertices: V.
        k: Ring depth (>= 1): triangles touching a vertex within ``k`` edges of the receiver.

    Returns:
        ``(offsets, tris, ring_vertices)``: offsets shape (V+1,) int32, tris int32 (incident triangles
        excluded), ring_vertices a list of int arrays (the k-ring vertices, receiver included).
    """
    from scipy import sparse

    faces = np.asarray(faces, dtype=np.int64)
    nf = len(faces)
    # vertex-triangle incidence, and the vertices within one edge (a shared triangle) of each vertex
    inc = sparse.csr_matrix((np.ones(3 * nf, np.int32), (faces.ravel(), np.repeat(np.arange(nf), 3))),
                            shape=(num_vertices, nf))
    inc.sum_duplicates()
    inc.data[:] = 1  # a triangle listing a vertex twice (degenerate) is incident once
    step = (inc @ inc.T + sparse.identity(num_vertices, dtype=np.int32, format="csr")).tocsr()
    ring = sparse.identity(num_vertices, dtype=np.int32, format="csr")
    for _ in range(k):
        ring = (ring @ step).tocsr()
        ring.data[:] = 1  # keep the counts small: only the pattern matters
    # the triangles touching a ring vertex, less those incident to the receiver (entry counts > 0 alike)
    near = (ring @ inc).tocsr()
    near.data[:] = 1
    near = (near - inc).tocsr()
    near.eliminate_zeros()
    near.sort_indices()
    ring.sort_indices()
    rings = np.split(ring.indices.astype(np.int64), ring.indptr[1:-1])
    return near.indptr.astype(np.int32), near.indices.astype(np.int32), rings


def closest_points_on_triangles(p: np.ndarray, a: np.ndarray, b: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Closest point on triangles (a, b, c) to points p (Ericson, Real-Time Collision Detection §5.1.5).

    All arrays broadcast to (..., 3). Returns ``(point, barycentric)`` with shapes (..., 3) and (..., 3).
    Degenerate triangles fall back to their closest corner.
    """
    p, a, b, c = np.broadcast_arrays(*(np.asarray(x, dtype=np.float64) for x in (p, a, b, c)))
    ab, ac, ap = b - a, c - a, p - a
    d1 = np.einsum("...i,...i", ab, ap)
    d2 = np.einsum("...i,...i", ac, ap)
    bp = p - b
    d3 = np.einsum("...i,...i", ab, bp)
    d4 = np.einsum("...i,...i", ac, bp)
    cp = p - c
    d5 = np.einsum("...i,...i", ab, cp)
    d6 = np.einsum("...i,...i", ac, cp)
    va = d3 * d6 - d5 * d4
    vb = d5 * d2 - d1 * d6
    vc = d1 * d4 - d3 * d2
    denom = va + vb + vc
    with np.errstate(divide="ignore", invalid="ignore"):
        v = np.where(denom != 0, vb / denom, 0.0)
        w = np.where(denom != 0, vc / denom, 0.0)
        bary = np.stack([1 - v - w, v, w], axis=-1)
        # region tests in Ericson's order, last assignment wins for the earliest region
        t_ab = np.where(d1 - d3 != 0, d1 / (d1 - d3), 0.0)
        t_ac = np.where(d2 - d6 != 0, d2 / (d2 - d6), 0.0)
        t_bc = np.where((d4 - d3) + (d5 - d6) != 0, (d4 - d3) / ((d4 - d3) + (d5 - d6)), 0.0)
    z = np.zeros_like(d1)
    o = np.ones_like(d1)
    cases = [
        ((va <= 0) & (d4 - d3 >= 0) & (d5 - d6 >= 0), np.stack([z, 1 - t_bc, t_bc], -1)),
        ((vb <= 0) & (d2 >= 0) & (d6 <= 0), np.stack([1 - t_ac, z, t_ac], -1)),
        ((d6 >= 0) & (d5 <= d6), np.stack([z, z, o], -1)),
        ((vc <= 0) & (d1 >= 0) & (d3 <= 0), np.stack([1 - t_ab, t_ab, z], -1)),
        ((d3 >= 0) & (d4 <= d3), np.stack([z, o, z], -1)),
        ((d1 <= 0) & (d2 <= 0), np.stack([o, z, z], -1)),
    ]
    for cond, val in cases:
        bary = np.where(cond[..., None], val, bary)
    bary = np.where(np.isfinite(bary).all(axis=-1, keepdims=True), bary, np.array([1.0, 0.0, 0.0]))
    point = bary[..., :1] * a + bary[..., 1:2] * b + bary[..., 2:] * c
    return point, bary


def decimate(points: np.ndarray, faces: np.ndarray, target: int, border: bool = False) -> tuple[np.ndarray, np.ndarray]:
    """Quadric decimation to about ``target`` triangles (``fast_simplification``); degenerate faces dropped.
    With ``border``, no edge touching a vertex of an open boundary collapses (the outline is kept)."""
    import fast_simplification

    points = np.asarray(points, dtype=np.float64)
    if target >= len(faces):
        return points, faces.astype(np.int64)
    # fast_simplification's collapse thresholds are absolute: decimate a copy normalised to a unit
    # bounding-box diagonal so the coarse mesh does not depend on the mesh's scale or position
    lo = points.min(axis=0)
    scale = float(np.linalg.norm(points.max(axis=0) - lo)) or 1.0
    # (snapped to a 2^-20 grid: float32 inputs at different scales differ in the last bits, and the
    # greedy collapse order would amplify that into a different coarse mesh)
    unit = np.round((points - lo) / scale * 2.0**20) / 2.0**20
    pts, tris = fast_simplification.simplify(unit, faces.astype(np.int32), target_count=int(target),
                                               preserve_border=bool(border))
    pts = np.asarray(pts) * scale + lo
    tris = tris[(tris[:, 0] != tris[:, 1]) & (tris[:, 1] != tris[:, 2]) & (tris[:, 0] != tris[:, 2])]
    return np.asarray(pts, dtype=np.float64), np.asarray(tris, dtype=np.int64)


def bind_to_surface(query: np.ndarray, points: np.ndarray, faces: np.ndarray, neighbours: int = 16):
    """Bind query points to their closest triangle of (points, faces).

    Candidates are the triangles incident to the ``neighbours`` nearest vertices (a KD-tree), which
    contain the closest triangle on any mesh whose triangles are not far larger than their
    neighbours'.

    Returns:
        ``(face, bary, offset)``: face (Q,) int32, bary (Q, 3) float32, offset (Q,) float32: signed
        distance along that triangle's unit normal, so
        ``q = Σ bary_k p[f_k] + offset · n̂_f`` reproduces the query point at rest.
    """
    from scipy.spatial import cKDTree

    points = np.asarray(points, dtype=np.float64)
    query = np.asarray(query, dtype=np.float64)
    a, b, c = (points[faces[:, k]] for k in range(3))
    fn = np.cross(b - a, c - a)
    ln = np.linalg.norm(fn, axis=1, keepdims=True)
    fn = np.where(ln > 0, fn / np.where(ln > 0, ln, 1.0), 0.0)
    vf = vertex_faces(faces, len(points))
    _, near = cKDTree(points).query(query, k=min(neighbours, len(points)))
    near = np.atleast_2d(near)
    face = np.zeros(len(query), np.int32)
    bary = np.zeros((len(query), 3))
    off = np.zeros(len(query))
    for i, q in enumerate(query):
        cand = np.unique(np.concatenate([vf[v] for v in near[i]]))
        cp, bc = closest_points_on_triangles(q[None], a[cand], b[cand], c[cand])
        best = int(np.argmin(((cp - q) ** 2).sum(-1)))
        face[i] = cand[best]
        bary[i] = bc[best]
        off[i] = np.dot(q - cp[best], fn[cand[best]])
    return face, bary.astype(np.float32), off.astype(np.float32)


def part_borders(border, num_parts: int) -> tuple[bool, ...]:
    """``border`` of :func:`far_field` as one flag per part: a single bool stands for every part."""
    if isinstance(border, (bool, np.bool_)):
        return (bool(border),) * num_parts
    flags = tuple(bool(b) for b in border)
    if len(flags) != num_parts:
        raise ValueError(f"hemiraster: {len(flags)} border flags for {num_parts} far-field parts")
    return flags


def far_field(parts: list[tuple[np.ndarray, np.ndarray]], targets: list[int], mid_targets: list[int] | None = None,
              border: bool | Sequence[bool] = False):
    """Coarse blocker mesh of several parts (receiver mesh, static occluders), each decimated alone.

    Each part is decimated to its target (kept whole when the target reaches its triangle count),
    its coarse vertices are bound to its own fine triangles (a coarse ground vertex must not follow
    a cloth lying on the ground) and its fine triangles are assigned to its own coarse triangles.

    Args:
        parts: ``(points (Vp, 3), faces (Fp, 3))`` per part, in scene order (the scene's fine
            vertices and faces are the parts' concatenated in this order).
        targets: Coarse triangle target per part.
        border: Keep the open boundary vertices in both decimations (:func:`decimate`): one flag for every
            part, or one per part (:func:`part_borders`).

    Returns:
        dict with ``points`` (Vc, 3) float64, ``faces`` (Fc, 3) int64, ``bind_face`` (Vc,) int32 (scene
        face index), ``bind_bary`` (Vc, 3) float32, ``bind_offset`` (Vc,) float32, ``owner`` (F,)
        int64: the primary coarse triangle of each scene face, ``extra`` (P, 2) int64: further
        (scene face, coarse triangle) pairs (:func:`assign_to_coarse`). With ``mid_targets`` (mid
        level triangle target per part), also ``mid``: a dict of the same keys for the mid mesh (a
        second decimation of each part, bound to and assigned over its fine triangles the same way)
        plus ``coarse_owner`` (Fm,) int64, the primary coarse triangle of each mid triangle, and
        ``coarse_extra`` (Q, 2) int64, further (mid triangle, coarse triangle) pairs: the coarse
        triangles assigned over the mid mesh as over a fine one; ``outline`` (Fm,) float32, the
        least deviation of each mid triangle (:func:`outline_deviation`).
    """
    borders = part_borders(border, len(parts))

    def level(pts, faces, surface, target, fbase, keep, fans=True):
        cp, cf = decimate(pts, surface, target, keep)
        f, b, o = bind_to_surface(cp, pts, faces)
        prim, extra = assign_to_coarse(pts, faces, cp, cf, fans=fans)
        return cp, cf, f + fbase, b, o, prim, extra

    out = {"points": [], "faces": [], "bind_face": [], "bind_bary": [], "bind_offset": [], "owner": [], "extra": []}
    mid = {k: [] for k in (*out, "coarse_owner", "coarse_extra", "outline")} if mid_targets is not None else None
    fbase = cbase = cfbase = mbase = mfbase = 0
    for k, ((pts, faces), target) in enumerate(zip(parts, targets)):
        pts = np.asarray(pts, dtype=np.float64)
        faces = np.asarray(faces, dtype=np.int64)
        # the surface is decimated (:func:`stitched_faces`): faces with vertices of their own along
        # sharp edges (a box's rims) decimated apart let light through their seams
        surface = stitched_faces(pts, faces)
        cp, cf, bf, bb, bo, prim, extra = level(pts, faces, surface, target, fbase, borders[k])
        for key, val in zip(out, (cp, cf + cbase, bf, bb, bo, prim + cfbase, extra + np.array([fbase, cfbase]))):
            out[key].append(val)
        if mid is not None:
            # seam cover without the fan rule at both mid seams (coarse/mid, mid/fine): at a few fine
            # triangles per mid triangle it tripled their extras (docs/benchmarks/history.md)
            mp, mf, mbf, mbb, mbo, mprim, mextra = level(pts, faces, surface, mid_targets[k], fbase, borders[k], fans=False)
            # the mid mesh is to the coarse one what the fine mesh is to it
            cprim, cextra = assign_to_coarse(mp, mf, cp, cf, fans=False)
            outline = outline_deviation(pts, faces, mp, mf, mprim)
            for key, val in zip(mid, (mp, mf + mbase, mbf, mbb, mbo, mprim + mfbase, mextra + np.array([fbase, mfbase]),
                                      cprim + cfbase, cextra + np.array([mfbase, cfbase]), outline)):
                mid[key].append(val)
            mbase += len(mp)
            mfbase += len(mf)
        fbase += len(faces)
        cbase += len(cp)
        cfbase += len(cf)
    res = {k: np.concatenate(v) for k, v in out.items()}
    res["bind_face"] = res["bind_face"].astype(np.int32)
    if mid is not None:
        res["mid"] = {k: np.concatenate(v) for k, v in mid.items()}
        res["mid"]["bind_face"] = res["mid"]["bind_face"].astype(np.int32)
    return res


def assign_to_coarse(points: np.ndarray, faces: np.ndarray, cpoints: np.ndarray, cfaces: np.ndarray,
                     candidates: int = 8, reach: float = 0.5, tol: float = 0.05,
                     fans: bool = True) -> tuple[np.ndarray, np.ndarray]:
    """Which coarse triangles each fine triangle belongs to (rest pose).

    *Primary*: the coarse triangle nearest to the fine triangle's centroid (each fine triangle has
    one); the bounds and deviation that decide refinement are taken over those, so they stay tight.
    *Extras* make a refined coarse triangle's fine triangles cover everything it stands in for, so
    no light leaks where a refined coarse triangle meets unrefined ones (a closed shell stays closed;
    in a thin fold decimated into one layer, both layers): every fine triangle with its centroid or
    a corner inside the coarse triangle's prism (projection inside its outline, widened by ``tol``
    of its barycentric range, and nearer to its plane than ``reach`` times its radius) or nearest
    to it; and around each coarse vertex, the fine triangles at the fine vertex nearest to it
    belong to every coarse triangle of the coarse vertex's fan (nearest regions meet ambiguously).
    Candidates are the ``candidates`` coarse triangles with the nearest centroids (a KD-tree).

    Returns:
        ``(primary, extra)``: primary shape (F,) int64; extra shape (P, 2) int64 unique (fine, coarse)
        pairs that are not primary.
    """
    from scipy.spatial import cKDTree

    pts = np.asarray(points, dtype=np.float64)
    cp_ = np.asarray(cpoints, dtype=np.float64)
    query = np.concatenate([pts[faces].mean(axis=1)[:, None, :], pts[faces]], axis=1).reshape(-1, 3)
    a, b, c = (cp_[cfaces[:, k]] for k in range(3))
    cen = (a + b + c) / 3.0
    radius = np.maximum(np.maximum(np.linalg.norm(a - cen, axis=1), np.linalg.norm(b - cen, axis=1)),
                        np.linalg.norm(c - cen, axis=1))
    k = min(candidates, len(cfaces))
    _, cand = cKDTree(cen).query(query, k=k)
    cand = cand.reshape(len(query), k)
    primary = np.zeros(len(faces), np.int64)
    fine_all, coarse_all = [], []
    for s0 in range(0, len(query), 65536):
        q = query[s0:s0 + 65536, None, :]
        cc = cand[s0:s0 + 65536]
        qa, qb, qc = a[cc], b[cc], c[cc]
        cp, _ = closest_points_on_triangles(q, qa, qb, qc)
        dist = ((cp - q) ** 2).sum(-1)
        rows = np.arange(s0, s0 + len(cc))
        is_cent = rows % 4 == 0
        primary[rows[is_cent] // 4] = cc[is_cent, np.argmin(dist[is_cent], axis=1)]
        # prism test: barycentrics of the projection onto the coarse plane, and the height
        e1, e2, d = qb - qa, qc - qa, q - qa
        nrm = np.cross(e1, e2)
        area2 = np.einsum("...i,...i", nrm, nrm)
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.einsum("...i,...i", np.cross(d, e2), nrm) / area2
            w = np.einsum("...i,...i", np.cross(e1, d), nrm) / area2
            h = np.abs(np.einsum("...i,...i", d, nrm)) / np.sqrt(area2)
        inside = (u >= -tol) & (w >= -tol) & (u + w <= 1 + tol) & (h <= reach * radius[cc]) & (area2 > 0)
        r_i, c_i = np.nonzero(inside)
        fine_all.append(rows[r_i] // 4)
        coarse_all.append(cc[r_i, c_i])
        # the coarse triangle nearest to each corner (seams between coarse triangles)
        fine_all.append(rows // 4)
        coarse_all.append(cc[np.arange(len(cc)), np.argmin(dist, axis=1)])
    # around each coarse vertex, the fine triangles at the fine vertex nearest to it belong to every
    # coarse triangle of its fan (nearest-triangle regions meet ambiguously there)
    vf = vertex_faces(faces, len(pts))
    cvf = vertex_faces(cfaces, len(cp_))
    _, nearest_fine = cKDTree(pts).query(cp_)
    for cv in range(len(cp_) if fans else 0):
        if len(cvf[cv]) and len(vf[nearest_fine[cv]]):
            fan = np.stack(np.meshgrid(vf[nearest_fine[cv]], cvf[cv], indexing="ij"), -1).reshape(-1, 2)
            fine_all.append(fan[:, 0])
            coarse_all.append(fan[:, 1])
    pairs = np.unique(np.stack([np.concatenate(fine_all), np.concatenate(coarse_all)], 1), axis=0)
    extra = pairs[pairs[:, 1] != primary[pairs[:, 0]]]
    return primary, extra


def group_bits(start: np.ndarray, mid: np.ndarray, tris: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
    """The groups of :func:`groups_in_order` as bit rows over the listed items (``count`` of them).

    Returns:
        ``(cover, primary)``, each shape (groups, ceil(count/64)) uint64: bit ``i`` of row ``t`` is set
        when group ``t`` lists item ``i`` (``cover``: primaries and extras; ``primary``: primaries only).
    """
    groups, words = len(start) - 1, (count + 63) // 64
    cover = np.zeros((groups, words), np.uint64)
    primary = np.zeros((groups, words), np.uint64)
    row = np.repeat(np.arange(groups), np.diff(start))
    is_primary = np.arange(len(row)) < np.asarray(mid)[row]
    bit = np.left_shift(np.uint64(1), (tris[:len(row)] % 64).astype(np.uint64))
    np.bitwise_or.at(cover, (row, tris[:len(row)] // 64), bit)
    np.bitwise_or.at(primary, (row[is_primary], tris[:len(row)][is_primary] // 64), bit[is_primary])
    return cover, primary


def groups_in_order(primary: np.ndarray, extra: np.ndarray, perm: np.ndarray):
    """CSR of the fine triangles each reordered coarse triangle stands for: primary ones, then extras.

    Args:
        primary: Primary coarse triangle (original index) of each fine triangle, shape (F,).
        extra: Further (fine, coarse) pairs, shape (P, 2) (:func:`assign_to_coarse`).
        perm: Coarse triangle order (``faces[perm]``), shape (Fc,).

    Returns:
        ``(start (Fc+1,), mid (Fc,), tris, owner, run_end)`` int32: reordered coarse triangle ``t`` stands for
        ``tris[start[t]:mid[t]]`` (primary) and also covers ``tris[mid[t]:start[t+1]]`` (extras);
        ``owner`` (same length as ``tris``) is each entry's primary coarse triangle (reordered);
        extras are sorted by it, and ``run_end`` (same length) is the end of each entry's run of
        equal (coarse, owner) entries.
    """
    new_index = np.empty(len(perm), np.int64)
    new_index[perm] = np.arange(len(perm))
    fine = np.concatenate([np.arange(len(primary)), extra[:, 0]])
    coarse = new_index[np.concatenate([primary, extra[:, 1]])]
    is_extra = np.concatenate([np.zeros(len(primary), np.int64), np.ones(len(extra), np.int64)])
    # each entry's primary coarse triangle (reordered): an extra is skipped when that one is refined
    # too, so a group's extras are sorted by it (one test per run of the same primary)
    owner_all = new_index[primary][fine]
    order = np.lexsort((fine, owner_all, is_extra, coarse))
    start = np.searchsorted(coarse[order], np.arange(len(perm) + 1))
    mid = np.searchsorted(coarse[order] * 2 + is_extra[order], np.arange(len(perm)) * 2 + 1)
    owner = owner_all[order]
    # end of each entry's run of equal (coarse, owner): the kernel jumps there past a refined owner
    key = coarse[order] * (len(perm) + 1) + owner
    change = np.flatnonzero(np.diff(key) != 0) + 1
    bounds = np.concatenate([change, [len(key)]])
    run_end = bounds[np.searchsorted(bounds, np.arange(len(key)), side="right")]
    return (start.astype(np.int32), mid.astype(np.int32), fine[order].astype(np.int32), owner.astype(np.int32),
            run_end.astype(np.int32))


def ring_groups(ring_start: np.ndarray, ring_tris: np.ndarray, faces: np.ndarray, owner: np.ndarray,
                num_coarse: int) -> np.ndarray:
    """Per receiver, the coarse triangles that stand for (``owner``: primary, shape (F,)) at least
    one fine triangle of its k-ring (or one touching it), as bits: they are always replaced by their fine triangles, so the near field
    is exact (a superset of the k-ring, with no triangle twice) in every pose.

    Returns:
        shape (V, ceil(Fc/32)) uint32; bit t of row v set = refine coarse triangle t (original index).
    """
    nv = len(ring_start) - 1
    nw = (num_coarse + 31) // 32
    bits = np.zeros((nv, nw * 32), dtype=bool)
    # (receiver, fine triangle) pairs: its k-ring's triangles, and those incident to it
    faces = np.asarray(faces, dtype=np.int64)
    bits[np.repeat(np.arange(nv), np.diff(ring_start)), owner[ring_tris[:ring_start[-1]]]] = True
    bits[faces.ravel(), owner[np.repeat(np.arange(len(faces)), faces.shape[1])]] = True
    words = bits.reshape(nv, nw, 32).astype(np.uint64) << np.arange(32, dtype=np.uint64)
    return words.sum(axis=-1, dtype=np.uint64).astype(np.uint32)


def near_exclusion(points: np.ndarray, rings: list[np.ndarray], cpoints: np.ndarray, cfaces: np.ndarray,
                   scale: float = 1.0, chunk: int = 128) -> np.ndarray:
    """Per receiver, the coarse triangles nearer than ``scale ×`` its k-ring radius (rest pose), as bits.

    Returns:
        shape (V, ceil(Fc/32)) uint32; bit t of row v set = skip coarse triangle t for receiver v.
    """
    nv = len(points)
    radius = np.array([np.linalg.norm(points[r] - points[v], axis=1).max() for v, r in enumerate(rings)]) * scale
    a, b, c = (cpoints[cfaces[:, k]] for k in range(3))
    nw = (len(cfaces) + 31) // 32
    bits = np.zeros((nv, nw * 32), dtype=bool)
    for s in range(0, nv, chunk):
        q = points[s:s + chunk, None, :].astype(np.float64)
        cp, _ = closest_points_on_triangles(q, a[None], b[None], c[None])
        d = np.linalg.norm(cp - q, axis=-1)
        bits[s:s + chunk, :len(cfaces)] = d < radius[s:s + chunk, None]
    words = bits.reshape(nv, nw, 32).astype(np.uint64) << np.arange(32, dtype=np.uint64)
    return words.sum(axis=-1, dtype=np.uint64).astype(np.uint32)


def morton_order(centroids: np.ndarray) -> np.ndarray:
    """Permutation sorting points along a 3D Morton curve (10 bits per axis) of their bounding cube.

    One scale for all axes: per-axis scaling would stretch a nearly flat sheet's tiny thickness to
    the full 10 bits, and the interleaved z bits of its wrinkles would scatter neighbours across
    the curve (cluster boxes of a cloth spanned half the sheet).
    """
    lo, hi = centroids.min(axis=0), centroids.max(axis=0)
    ext = float((hi - lo).max())
    q = ((centroids - lo) / (ext if ext > 0 else 1.0) * 1023).astype(np.int64)
    code = np.zeros(len(centroids), dtype=np.int64)
    for bit in range(10):
        for ax in range(3):
            code |= ((q[:, ax] >> bit) & 1) << (3 * bit + ax)
    return np.argsort(code, kind="stable")


def build_clusters(points: np.ndarray, faces: np.ndarray, size: int, super_size: int):
    """Reorder blocker triangles into clusters of ``size`` and super-clusters of ``super_size`` clusters.

    Returns:
        ``(perm, cluster_start, super_start)``: perm (F,) the new triangle order (faces[perm]);
        cluster_start (C+1,) int32 offsets into the reordered triangles; super_start (S+1,) int32
        offsets into the clusters.
    """
    cent = points[faces].mean(axis=1)
    perm = morton_order(cent)
    nf = len(faces)
    cluster_start = np.arange(0, nf + size, size, dtype=np.int64)
    cluster_start[-1] = nf
    cluster_start = np.unique(cluster_start)
    nc = len(cluster_start) - 1
    super_start = np.arange(0, nc + super_size, super_size, dtype=np.int64)
    super_start[-1] = nc
    super_start = np.unique(super_start)
    return perm, cluster_start.astype(np.int32), super_start.astype(np.int32)


def ring_lists(ring_start: np.ndarray, ring_tris: np.ndarray, faces: np.ndarray, owner: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per receiver, the blockers (``owner``: the primary blocker of each fine triangle, shape (F,))
    standing for at least one fine triangle of its k-ring or touching it, as CSR lists: the sets of
    :func:`ring_groups` for a level too large for a bit row per receiver (the mid level).

    Returns:
        ``(start (V+1,), items)`` int32, each receiver's blockers sorted and unique.
    """
    nv = len(ring_start) - 1
    vf = vertex_faces(faces, nv)
    lists = [np.unique(owner[np.concatenate([ring_tris[ring_start[v]:ring_start[v + 1]], vf[v]]).astype(np.int64)])
             for v in range(nv)]
    start = np.concatenate([[0], np.cumsum([len(x) for x in lists])])
    items = np.concatenate(lists) if start[-1] else np.zeros(1, np.int64)
    return start.astype(np.int32), items.astype(np.int32)


def outline_deviation(points: np.ndarray, faces: np.ndarray, cpoints: np.ndarray, cfaces: np.ndarray,
                      owner: np.ndarray) -> np.ndarray:
    """Per coarse triangle, how far the fine mesh's boundary (an outline no neighbour covers) lies
    from it: the largest distance of a fine boundary vertex from the coarse triangles owning its
    triangles (``owner``: primary, shape (F,)); 0 for triangles away from the boundary.

    The per-frame deviation (:func:`.kernels.refit_blocker_boxes`) is measured across the surface
    only; along it, a fine triangle sticking out past a coarse edge lies on the neighbour's plane.
    At the mesh boundary there is no neighbour: decimation rounds off corners (a 2 cm fold's corner
    lost 1.2 cm at 400 triangles), and a receiver near them sees through the missing part.

    Returns:
        shape (Fc,) float32 [m], at the pose of ``points`` / ``cpoints``.
    """
    f = np.asarray(faces, dtype=np.int64)
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    uniq, counts = np.unique(e, axis=0, return_counts=True)
    out = np.zeros(len(cfaces), np.float64)
    border = np.unique(uniq[counts == 1].ravel())
    if len(border) == 0:
        return out.astype(np.float32)
    vf = vertex_faces(f, len(points))
    pairs = np.unique(np.concatenate([np.stack([np.full(len(vf[v]), v), owner[vf[v]]], 1) for v in border]), axis=0)
    cp = np.asarray(cpoints, dtype=np.float64)
    a, b, c = (cp[cfaces[pairs[:, 1], k]] for k in range(3))
    q = np.asarray(points, dtype=np.float64)[pairs[:, 0]]
    near, _ = closest_points_on_triangles(q, a, b, c)
    np.maximum.at(out, pairs[:, 1], np.linalg.norm(near - q, axis=1))
    return out.astype(np.float32)
