"""Cloth model: a host-side :class:`ClothBuilder` that ``finalize()``s into an immutable
:class:`ClothModel` on the device (Newton's builder/model split).

Material parameters and their units:

* ``density`` [kg/m^2]: area density; vertex mass = density x (sum of incident triangle areas) / 3.
* ``stretch_stiffness`` [N/m]: spring constant of every mesh edge (stretch and shear). In a 2-D
  spring network the membrane stiffness equals the spring constant whatever the resolution, so the
  value does not need rescaling when the mesh is refined. ``inf`` makes the edges inextensible.
* ``bend_stiffness`` [N m]: bending modulus B. Each interior edge gets the discrete-shell weight
  k = 3 B |e|^2 / (A1 + A2) (Grinspun et al. 2003, eq. 4), again independent of resolution.
* ``damping``, ``bend_damping`` [s]: stiffness-proportional (Rayleigh) damping of stretch and of
  bending, k_d = damping x k, integrated implicitly on velocities.
* ``thickness`` [m]: distance kept from colliders and between cloth layers.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import warp as wp

from ..geometry.mesh import MeshError, TriMesh, validate_mesh, vertex_indices
from .oracle import dihedral_angle_np

if TYPE_CHECKING:  # (state.py imports this module)
    from .state import ClothControl, ClothState


class SimulationError(RuntimeError):
    """The simulation failed (non-finite state, bad step). The message names the step and vertex."""


def check_param(name: str, value: float, low: float = 0.0, low_inclusive: bool = True,
                allow_inf: bool = False) -> float:
    """``value`` as a float, or a ValueError naming ``name`` when it is NaN, infinite (unless ``allow_inf``)
    or below ``low`` (or at it, unless ``low_inclusive``)."""
    v = float(value)
    if np.isnan(v) or (np.isinf(v) and not allow_inf):
        raise ValueError(f"{name} must be finite, got {value}")
    if v < low or (v == low and not low_inclusive):
        op = ">=" if low_inclusive else ">"
        raise ValueError(f"{name} must be {op} {low}, got {value}")
    return v


_DEGENERATE_FIX = ("delete it or dissolve the degenerate faces (Blender: Mesh > Clean Up > Degenerate Dissolve; "
                   "Houdini: Clean SOP, Remove Degenerate Primitives)")
"""How to clean a degenerate triangle in a DCC (the end of the two degenerate-triangle messages)."""


def check_cloth_mesh(points: np.ndarray, faces: np.ndarray, name: str) -> None:
    """Validate a cloth mesh: shapes, finiteness, indices, then, in this order (each defect can look like the
    next one: a duplicate face puts three triangles on its interior edges, a non-manifold edge shows as two
    triangles traversing it the same way), repeated corners, zero area, unused vertices, duplicate faces,
    non-manifold edges and inconsistent orientation.

    Raises:
        MeshError: naming ``name``, the triangles (indices after faces are split into triangles), their
            vertices or edge, and how to clean the mesh in a DCC.
    """
    validate_mesh(points, faces, name)
    f = faces.astype(np.int64)
    nv = len(points)
    rep = (f[:, 0] == f[:, 1]) | (f[:, 1] == f[:, 2]) | (f[:, 0] == f[:, 2])
    if rep.any():
        t = int(np.flatnonzero(rep)[0])
        raise MeshError(f"{name}: triangle {t} {f[t].tolist()} repeats a vertex (degenerate: it has no area; "
                        f"{int(rep.sum())} such triangles): {_DEGENERATE_FIX}")
    p = points.astype(np.float64)
    a, b, c = p[f[:, 0]], p[f[:, 1]], p[f[:, 2]]
    area2 = np.linalg.norm(np.cross(b - a, c - a), axis=1)
    longest = np.max(np.stack([np.linalg.norm(b - a, axis=1), np.linalg.norm(c - b, axis=1),
                               np.linalg.norm(a - c, axis=1)]), axis=0)
    # relative area test: a sliver whose height is below 1e-6 of its longest edge has no usable normal
    degen = area2 <= 1e-6 * longest * longest
    if degen.any():
        t = int(np.flatnonzero(degen)[0])
        raise MeshError(f"{name}: triangle {t} {f[t].tolist()} is degenerate (area {0.5 * area2[t]:.3g} m^2, "
                        f"{int(degen.sum())} such triangles): {_DEGENERATE_FIX}")
    used = np.zeros(nv, dtype=bool)
    used[f.ravel()] = True
    if not used.all():
        v = int(np.flatnonzero(~used)[0])
        raise MeshError(f"{name}: vertex {v} is not used by any triangle (it would have no mass; "
                        f"{int((~used).sum())} such vertices): delete loose vertices (Blender: Mesh > Clean Up > "
                        f"Delete Loose; Houdini: Clean SOP, Remove Unused Points)")
    # duplicate faces: the same three vertices in either winding
    srt = np.sort(f, axis=1)
    _, first, inverse, counts = np.unique(srt, axis=0, return_index=True, return_inverse=True, return_counts=True)
    if (counts > 1).any():
        inverse = inverse.reshape(-1)
        t1 = int(np.flatnonzero((counts[inverse] > 1) & (np.arange(len(f)) != first[inverse]))[0])
        raise MeshError(f"{name}: duplicate face: triangles {int(first[inverse[t1]])} and {t1} have the same "
                        f"vertices {f[t1].tolist()} ({int((counts - 1)[counts > 1].sum())} such duplicates): "
                        f"delete one of each pair (Houdini: Clean SOP, Fix Overlaps)")
    directed = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    tri_of = np.tile(np.arange(len(f)), 3)
    und = np.sort(directed, axis=1)
    ukey = und[:, 0] * nv + und[:, 1]
    keys, counts = np.unique(ukey, return_counts=True)
    if (counts > 2).any():
        k = keys[np.flatnonzero(counts > 2)[0]]
        tris = sorted(int(t) for t in tri_of[ukey == k])
        raise MeshError(f"{name}: edge ({k // nv}, {k % nv}) is shared by {len(tris)} triangles {tris} "
                        f"(non-manifold: a cloth edge joins at most two; {int((counts > 2).sum())} such edges): "
                        f"delete the extra faces or split the edge (Blender: Select > Select All by Trait > "
                        f"Non Manifold shows them; Houdini: Clean SOP, Manifold-Only Topology)")
    # orientation: in a consistently oriented manifold each directed edge occurs once
    key = directed[:, 0] * nv + directed[:, 1]
    order = np.argsort(key, kind="stable")
    dup = np.flatnonzero(key[order][1:] == key[order][:-1])
    if len(dup):
        t0, t1 = sorted((int(tri_of[order[dup[0]]]), int(tri_of[order[dup[0] + 1]])))  # the later one is 'inverted'
        e = directed[order[dup[0]]].tolist()
        raise MeshError(f"{name}: triangle {t1} {f[t1].tolist()} is inverted relative to its neighbour {t0} "
                        f"{f[t0].tolist()} (both traverse edge {e} in the same direction): make the normals "
                        f"consistent (Blender: Mesh > Normals > Recalculate Outside; Houdini: Clean SOP, Orient "
                        f"Polygons)")


def mesh_edges_and_hinges(faces: np.ndarray):
    """Unique edges (E, 2) and bending hinges (H, 4) = (wing1, wing2, edge0, edge1) of a manifold mesh.

    The hinge's shared edge runs (edge0 -> edge1) in wing1's triangle, so the dihedral angle is 0
    for a flat rest shape and its sign is consistent across the mesh.
    """
    f = faces.astype(np.int64)
    nv = int(f.max()) + 1
    directed = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
    opposite = np.concatenate([f[:, 2], f[:, 0], f[:, 1]])
    und = np.sort(directed, axis=1)
    key = und[:, 0] * nv + und[:, 1]
    order = np.argsort(key, kind="stable")
    ks = key[order]
    first = np.ones(len(ks), dtype=bool)
    first[1:] = ks[1:] != ks[:-1]
    edges = und[order][first]
    # pairs: consecutive equal keys (manifold: at most two)
    pair = np.flatnonzero(~first)
    i0 = order[pair - 1]
    i1 = order[pair]
    hinges = np.stack([opposite[i0], opposite[i1], directed[i0, 1], directed[i0, 0]], axis=1)
    return edges.astype(np.int32), hinges.astype(np.int32)


def color_constraints(elements: np.ndarray, num_vertices: int) -> tuple[np.ndarray, list[tuple[int, int]]]:
    """Greedy graph colouring: constraints of one colour share no vertex.

    Returns:
        (order, ranges): a permutation sorting the constraints by colour and (offset, count) per colour.
    """
    used = [0] * num_vertices  # bitmask of colours touching each vertex
    colors = np.empty(len(elements), dtype=np.int64)
    for k, el in enumerate(elements.tolist()):
        mask = 0
        for v in el:
            mask |= used[v]
        c = (~mask & (mask + 1)).bit_length() - 1  # lowest free colour
        colors[k] = c
        bit = 1 << c
        for v in el:
            used[v] |= bit
    order = np.argsort(colors, kind="stable")
    counts = np.bincount(colors) if len(colors) else np.zeros(0, dtype=np.int64)
    offsets = np.concatenate([[0], np.cumsum(counts)[:-1]]) if len(counts) else []
    return order, [(int(o), int(c)) for o, c in zip(offsets, counts) if c > 0]


def tether_anchors(points: np.ndarray, edges: np.ndarray, kinematic: np.ndarray, piece: np.ndarray,
                   convex_flat: np.ndarray, count: int = 2):
    """Nearest kinematic vertices of each vertex and an upper bound of the rest geodesic distance.

    On a flat, convex piece the geodesic distance is the Euclidean rest distance (exact, so a
    tether is taut exactly when the cloth between vertex and anchor is unstretched): the ``count``
    nearest anchors of the same piece by a k-d tree. Elsewhere the shortest edge path, which
    over-estimates the geodesic (a looser but never over-constraining bound), to the single
    nearest anchor (multi-source Dijkstra). Memory stays O(V) for any number of anchors.

    Args:
        points: Rest positions, shape (V, 3).
        edges: Mesh edges, shape (E, 2).
        kinematic: Pinned or attached vertices, shape (V,), bool.
        piece: Piece index of each vertex, shape (V,), int.
        convex_flat: Per piece, whether it is flat and convex, shape (P,), bool.
        count: Anchors per vertex on flat convex pieces.

    Returns:
        (anchor (V, T) int32, -1 for none; length (V, T) float32 [m]), T = min(count, #anchors).
    """
    from scipy.sparse.csgraph import dijkstra
    from scipy.spatial import cKDTree

    v = len(points)
    k = max(1, min(count, int(kinematic.sum())))
    anchor = np.full((v, k), -1, dtype=np.int32)
    length = np.zeros((v, k), dtype=np.float32)
    if not kinematic.any():
        return anchor, length
    curved = np.zeros(v, dtype=bool)
    for pc in range(len(convex_flat)):
        mine = piece == pc
        kin = np.flatnonzero(mine & kinematic)
        free = np.flatnonzero(mine & ~kinematic)
        if len(kin) == 0 or len(free) == 0:
            continue
        if not convex_flat[pc]:
            curved[free] = True
            continue
        kk = min(k, len(kin))
        dist, near = cKDTree(points[kin]).query(points[free], k=kk)
        anchor[free, :kk] = kin[near.reshape(len(free), kk)]
        length[free, :kk] = dist.reshape(len(free), kk)
    if curved.any():
        dist, _, src = dijkstra(_edge_graph(points, edges), directed=False, indices=np.flatnonzero(kinematic), min_only=True,
                                return_predecessors=True)
        ok = np.flatnonzero(curved & np.isfinite(dist))
        anchor[ok, 0] = src[ok]
        length[ok, 0] = dist[ok]
    return anchor, length


def _edge_graph(points: np.ndarray, edges: np.ndarray):
    """The mesh's edges as a symmetric sparse graph weighted by rest length (for scipy's dijkstra)."""
    from scipy.sparse import coo_matrix

    v = len(points)
    w = np.linalg.norm(points[edges[:, 0]] - points[edges[:, 1]], axis=1)
    return coo_matrix((np.concatenate([w, w]), (np.concatenate([edges[:, 0], edges[:, 1]]),
                                             np.concatenate([edges[:, 1], edges[:, 0]]))), shape=(v, v)).tocsr()


STIFF_STRAIN = 1.0e-3
"""Pieces get stretch limits when their full weight hanging from one edge would stretch them by at
most this (density * g * diameter / stretch_stiffness): the limits allow no stretch at all, so a
softer piece (a rubber sheet) is left to its edges."""


def stretch_limits(points: np.ndarray, edges: np.ndarray, piece: np.ndarray, convex_flat: np.ndarray,
                   radius: float = 2.0, max_path: float = 1.5, limited: np.ndarray | None = None):
    """Multi-scale stretch limits: pairs of vertices about 2, 4, 8, ... edges apart and an upper
    bound of their rest geodesic distance, coarsest scale first.

    Level l keeps a subset of the vertices no two of which are closer than ``2**l`` median edge
    lengths (greedy, in index order; each level a subset of the one below) and pairs each kept
    vertex with the kept vertices of its piece within ``radius`` times that spacing. The bound is
    exact on a flat, convex piece (the Euclidean rest distance) and the shortest edge path
    elsewhere (never smaller than the geodesic distance); pairs whose edge path is longer than
    ``max_path`` times their Euclidean distance (across a fold or a gap of the rest shape) are
    left out, as loose bounds that would never act. A limit ``|xi - xj| <= L`` holds in every
    unstretched pose, so it acts on stretch only. It carries in one projection the load that
    sweeps over single edges pass on one edge per sweep: a hanging span of N edges keeps a
    stretch of about N g h^2 per substep of length h without it (the coarse levels of Müller
    2008, hierarchical position based dynamics, act the same way). It moves only the pair's two
    vertices, along the straight line between them.

    Args:
        points: Rest positions, shape (V, 3).
        edges: Mesh edges, shape (E, 2).
        piece: Piece index of each vertex, shape (V,), int.
        convex_flat: Per piece, whether it is flat and convex, shape (P,), bool.
        radius: Neighbourhood of a kept vertex, in units of its level's spacing.
        max_path: Longest edge path kept, relative to the Euclidean distance.
        limited: Per piece, whether it gets limits, shape (P,), bool (None: all).

    Returns:
        (pairs (L, 2) int32, length (L,) float32 [m], levels: (offset, count) of each level's
        pairs, coarsest first).
    """
    from scipy.sparse.csgraph import dijkstra
    from scipy.spatial import cKDTree

    empty = (np.zeros((0, 2), np.int32), np.zeros(0, np.float32), [])
    if len(edges) == 0:
        return empty
    h0 = float(np.median(np.linalg.norm(points[edges[:, 0]] - points[edges[:, 1]], axis=1)))
    if not h0 > 0:
        return empty
    graph = None
    kept = np.arange(len(points))
    levels = []
    lvl = 1
    while len(kept) > 1:
        r = h0 * 2.0 ** lvl
        near = cKDTree(points[kept]).query_ball_point(points[kept], 0.999 * r)
        taken = np.zeros(len(kept), dtype=bool)
        blocked = np.zeros(len(kept), dtype=bool)
        for a in range(len(kept)):
            if not blocked[a]:
                taken[a] = True
                blocked[near[a]] = True
        kept = kept[taken]
        if len(kept) < 2:
            break
        pairs = cKDTree(points[kept]).query_pairs(radius * r, output_type="ndarray")
        pairs = kept[pairs] if len(pairs) else np.zeros((0, 2), np.int64)
        pairs = pairs[piece[pairs[:, 0]] == piece[pairs[:, 1]]]
        if limited is not None:
            pairs = pairs[limited[piece[pairs[:, 0]]]]
        euclid = np.linalg.norm(points[pairs[:, 0]] - points[pairs[:, 1]], axis=1)
        length = euclid.copy()
        curved = ~convex_flat[piece[pairs[:, 0]]]
        if curved.any():
            if graph is None:
                graph = _edge_graph(points, edges)
            cp = pairs[curved]
            src, inv = np.unique(cp[:, 0], return_inverse=True)
            path = np.empty(len(cp))
            chunk = max(1, 2 ** 24 // len(points))  # rows of the dense distance matrix per call
            for c0 in range(0, len(src), chunk):
                dist = dijkstra(graph, directed=False, indices=src[c0:c0 + chunk], limit=max_path * radius * r * 1.001)
                sel = (inv >= c0) & (inv < c0 + chunk)
                path[sel] = dist[inv[sel] - c0, cp[sel, 1]]
            length[curved] = path
        ok = np.isfinite(length) & (length <= max_path * euclid)
        if ok.any():
            levels.append((pairs[ok], length[ok]))
        lvl += 1
    levels = levels[::-1]  # coarsest first: a sweep carries the load down the scales
    if not levels:
        return empty
    pairs = np.concatenate([p for p, _ in levels]).astype(np.int32)
    length = np.concatenate([w for _, w in levels]).astype(np.float32)
    offsets = np.cumsum([0] + [len(p) for p, _ in levels])
    return pairs, length, [(int(o), int(len(p))) for o, (p, _) in zip(offsets, levels)]


def stretch_hierarchy(points: np.ndarray, edges: np.ndarray, mass: np.ndarray, kinematic: np.ndarray,
                      member: np.ndarray, levels: int = 2) -> list[dict]:
    """Coarse levels of the cloth for hierarchical stretch constraints (Müller 2008, hierarchical
    position based dynamics), finest coarse level first.

    Level l + 1 keeps a maximal independent set of level l's graph (kinematic vertices first, then
    in index order; level 0 is the mesh's edges between ``member`` vertices); every level-l vertex
    it drops has as parents its level-l neighbours that it keeps, weighted by the inverse rest path
    length to them and summing to 1, and the kept vertices pair up when they were within two edges
    of level l, with the shortest such path's rest length as bound (never shorter than the
    geodesic distance, so a bound holds in every unstretched pose). The weights compose down to
    the mesh: a level's ``weights`` carry a move of its vertices to every member vertex it drops.
    A coarse vertex weighs what its weights gather, sum_i w_ij m_i.

    Args:
        points: Rest positions, shape (V, 3).
        edges: Mesh edges, shape (E, 2).
        mass: Vertex masses, shape (V,).
        kinematic: Pinned or attached vertices, shape (V,), bool (their coarse inverse mass is 0).
        member: Vertices that take part, shape (V,), bool.
        levels: Coarse levels wanted (fewer when a level has no pair left).

    Returns:
        Per level a dict: ``pairs`` (C, 2) int32 vertex indices, ``length`` (C,) float32 [m],
        ``offsets`` (V + 1,) int32 and ``parents`` / ``weights`` (CSR rows of the mesh's vertices that
        the level drops: the level's vertices and their weights), ``inv_mass`` (V,) float32 (the
        level's vertices' inverse masses, 0 elsewhere).
    """
    from scipy.sparse import coo_matrix, csr_matrix

    v = len(points)
    e = edges[member[edges[:, 0]] & member[edges[:, 1]]]
    rest = np.linalg.norm(points[e[:, 0]] - points[e[:, 1]], axis=1)
    nodes = np.flatnonzero(member)  # level l's vertices (mesh indices)
    g_a, g_b, g_len = e[:, 0], e[:, 1], rest  # level l's graph (each pair once)
    prolong = csr_matrix((np.ones(len(nodes)), (nodes, np.arange(len(nodes)))), shape=(v, len(nodes)))
    out = []
    for _ in range(levels):
        if len(g_a) == 0:
            break
        local = np.full(v, -1, dtype=np.int64)
        local[nodes] = np.arange(len(nodes))
        a, b = local[np.concatenate([g_a, g_b])], local[np.concatenate([g_b, g_a])]
        ln = np.concatenate([g_len, g_len])
        adj = csr_matrix((ln, (a, b)), shape=(len(nodes), len(nodes)))
        # a maximal independent set: kinematic vertices first, then in index order
        order = np.concatenate([np.flatnonzero(kinematic[nodes]), np.flatnonzero(~kinematic[nodes])])
        keep = np.zeros(len(nodes), dtype=bool)
        blocked = np.zeros(len(nodes), dtype=bool)
        for i in order.tolist():
            if not blocked[i]:
                keep[i] = True
                blocked[adj.indices[adj.indptr[i]:adj.indptr[i + 1]]] = True
        coarse = np.flatnonzero(keep)
        cidx = np.full(len(nodes), -1, dtype=np.int64)
        cidx[coarse] = np.arange(len(coarse))
        # parents: a dropped vertex's kept neighbours, weights 1 / rest length, normalised
        to_kept = keep[b] & ~keep[a]
        pw = 1.0 / ln[to_kept]
        p = coo_matrix((pw, (a[to_kept], cidx[b[to_kept]])), shape=(len(nodes), len(coarse))).tocsr()
        p = csr_matrix(p.multiply(1.0 / np.asarray(p.sum(axis=1)).clip(1e-300)))
        p = p + csr_matrix((np.ones(len(coarse)), (coarse, np.arange(len(coarse)))), shape=p.shape)
        prolong = csr_matrix(prolong @ p)
        # coarse pairs within two edges: paths kept - m - kept, the shortest per pair
        via = keep[b]
        m_of, k_of, l_of = a[via], cidx[b[via]], ln[via]
        srt = np.argsort(m_of, kind="stable")
        m_of, k_of, l_of = m_of[srt], k_of[srt], l_of[srt]
        starts = np.searchsorted(m_of, np.arange(len(nodes)))
        cnt = np.diff(np.append(starts, len(m_of)))
        pi, pj, pl = [], [], []
        for c in np.unique(cnt[cnt > 1]).tolist():
            s = starts[cnt == c]
            for x in range(c):
                for y in range(x + 1, c):
                    pi.append(k_of[s + x])
                    pj.append(k_of[s + y])
                    pl.append(l_of[s + x] + l_of[s + y])
        if not pi:
            break
        pi, pj, pl = np.concatenate(pi), np.concatenate(pj), np.concatenate(pl)
        lo, hi = np.minimum(pi, pj), np.maximum(pi, pj)
        key = lo * len(coarse) + hi
        srt = np.lexsort((pl, key))
        first = np.ones(len(srt), dtype=bool)
        first[1:] = key[srt][1:] != key[srt][:-1]
        sel = srt[first]
        lo, hi, pl = lo[sel], hi[sel], pl[sel]
        nodes = nodes[coarse]
        pairs = np.stack([nodes[lo], nodes[hi]], axis=1)
        # the rows of the vertices the level drops (mesh indices), their parents as mesh indices
        rows = prolong
        dropped = np.ones(v, dtype=bool)
        dropped[nodes] = False
        counts = np.where(dropped, np.diff(rows.indptr), 0)
        offsets = np.concatenate([[0], np.cumsum(counts)]).astype(np.int32)
        take = np.repeat(dropped, np.diff(rows.indptr))
        cmass = np.asarray(prolong.T @ mass).reshape(-1)
        inv = np.zeros(v, dtype=np.float32)
        inv[nodes] = np.where(kinematic[nodes], 0.0, 1.0 / cmass.clip(1e-300))
        out.append({"pairs": pairs.astype(np.int32), "length": pl.astype(np.float32), "offsets": offsets,
                    "parents": nodes[rows.indices[take]].astype(np.int32),
                    "weights": rows.data[take].astype(np.float32), "inv_mass": inv})
        g_a, g_b, g_len = nodes[lo], nodes[hi], pl
    return out


def convex_and_flat(points: np.ndarray, faces: np.ndarray) -> bool:
    """Whether a piece is planar (thinnest principal extent < 1e-6 of the widest) and convex
    (its area equals the area of its 2-D convex hull to 1e-6)."""
    from scipy.spatial import ConvexHull

    c = points - points.mean(axis=0)
    _, sv, vt = np.linalg.svd(c, full_matrices=False)
    if sv[-1] > 1e-6 * max(sv[0], 1e-30):
        return False
    uv = c @ vt[:2].T
    a, b, cc = points[faces[:, 0]], points[faces[:, 1]], points[faces[:, 2]]
    area = 0.5 * np.linalg.norm(np.cross(b - a, cc - a), axis=1).sum()
    try:
        hull = ConvexHull(uv).volume  # the "volume" of a 2-D hull is its area
    except Exception:  # degenerate hull (collinear): not a usable flat piece
        return False
    return bool(abs(hull - area) <= 1e-6 * hull)


@dataclass
class _Piece:
    points: np.ndarray
    faces: np.ndarray
    density: float
    stretch_stiffness: float
    bend_stiffness: float
    name: str


class ClothBuilder:
    """Collects cloth pieces, pins and attachments on the host; :meth:`finalize` makes the model.

    Args:
        density: Default area density [kg/m^2] (> 0).
        stretch_stiffness: Default edge spring constant [N/m] (> 0, ``inf`` = inextensible).
        bend_stiffness: Default bending modulus [N m] (>= 0; 0 disables bending).
        damping: Stiffness-proportional damping time [s] of stretch (>= 0).
        bend_damping: The same for bending [s] (>= 0; 0, the default, skips the pass).
        thickness: Contact distance [m] to colliders and between layers (>= 0).

    Raises:
        ValueError: for an out-of-range parameter, naming it.
    """

    def __init__(self, density: float = 0.2, stretch_stiffness: float = 5.0e4, bend_stiffness: float = 5.0e-5,
                 damping: float = 1.0e-3, thickness: float = 0.005, bend_damping: float = 0.0):
        self.density = check_param("density", density, 0.0, low_inclusive=False)
        self.stretch_stiffness = check_param("stretch_stiffness", stretch_stiffness, 0.0, False, allow_inf=True)
        self.bend_stiffness = check_param("bend_stiffness", bend_stiffness, 0.0, allow_inf=True)
        self.damping = check_param("damping", damping)
        self.bend_damping = check_param("bend_damping", bend_damping)
        self.thickness = check_param("thickness", thickness)
        self._pieces: list[_Piece] = []
        self._count = 0
        self._pinned: set[int] = set()
        self._attached: list[int] = []

    @property
    def vertex_count(self) -> int:
        return self._count

    def add_mesh(self, points: np.ndarray, faces: np.ndarray, name: str = "cloth", density: float | None = None,
                 stretch_stiffness: float | None = None, bend_stiffness: float | None = None) -> np.ndarray:
        """Add a cloth piece from a triangle mesh (e.g. ``warpshade.load_mesh(path)``'s arrays).

        Args:
            points: Rest positions [m], shape (V, 3).
            faces: Consistently oriented triangles, shape (F, 3), int.
            name: For error messages.
            density, stretch_stiffness, bend_stiffness: Overrides of the builder defaults.

        Returns:
            The model's vertex indices of this piece, shape (V,), int.

        Raises:
            MeshError: non-finite points, bad indices, degenerate or inverted triangles, unused
                vertices, non-manifold edges (naming the triangle, vertex or edge).
        """
        points = np.ascontiguousarray(points, dtype=np.float64)
        faces = np.ascontiguousarray(faces, dtype=np.int64)
        check_cloth_mesh(points, faces, name)
        piece = _Piece(points, faces,
                       check_param(f"{name}: density", self.density if density is None else density, 0.0, False),
                       check_param(f"{name}: stretch_stiffness",
                                    self.stretch_stiffness if stretch_stiffness is None else stretch_stiffness,
                                    0.0, False, allow_inf=True),
                       check_param(f"{name}: bend_stiffness",
                                    self.bend_stiffness if bend_stiffness is None else bend_stiffness,
                                    0.0, allow_inf=True), name)
        self._pieces.append(piece)
        ids = np.arange(self._count, self._count + len(points))
        self._count += len(points)
        return ids

    def add_trimesh(self, mesh: TriMesh, **kwargs) -> np.ndarray:
        """Add a :class:`~warpshade.geometry.TriMesh` (from ``warpshade.load_mesh``) as cloth."""
        kwargs.setdefault("name", mesh.name)
        return self.add_mesh(mesh.points, mesh.faces, **kwargs)

    def add_grid(self, nu: int, nv: int, width: float, height: float, origin=(0.0, 0.0, 0.0),
                 u_axis=(1.0, 0.0, 0.0), v_axis=(0.0, 0.0, 1.0), **kwargs) -> np.ndarray:
        """Add a rectangular cloth of nu x nv vertices spanning width x height [m].

        Vertex (i, j) sits at origin + u_axis * width * i / (nu - 1) + v_axis * height * j / (nv - 1);
        cells are split along alternating diagonals so the cloth has no preferred shear direction.
        Triangles face u_axis x v_axis.

        Returns:
            Vertex indices, shape (nv, nu): ``ids[j, i]`` is vertex (i, j).
        """
        if int(nu) < 2 or int(nv) < 2:
            raise ValueError(f"grid needs at least 2 x 2 vertices, got {nu} x {nv}")
        if not (np.isfinite(width) and np.isfinite(height) and width > 0 and height > 0):
            raise ValueError(f"grid size must be finite and > 0, got {width} x {height}")
        nu, nv = int(nu), int(nv)
        u = np.asarray(u_axis, dtype=np.float64)
        v = np.asarray(v_axis, dtype=np.float64)
        ii, jj = np.meshgrid(np.arange(nu), np.arange(nv))
        pts = (np.asarray(origin, dtype=np.float64) + (ii * (width / (nu - 1)))[..., None] * u
               + (jj * (height / (nv - 1)))[..., None] * v).reshape(-1, 3)
        i0, j0 = np.meshgrid(np.arange(nu - 1), np.arange(nv - 1))
        i0, j0 = i0.ravel(), j0.ravel()
        a = j0 * nu + i0
        b, c, d = a + 1, a + nu + 1, a + nu
        flip = (i0 + j0) % 2 == 1
        t1 = np.where(flip[:, None], np.stack([a, b, d], 1), np.stack([a, b, c], 1))
        t2 = np.where(flip[:, None], np.stack([b, c, d], 1), np.stack([a, c, d], 1))
        faces = np.concatenate([t1, t2])
        kwargs.setdefault("name", f"grid{len(self._pieces)}")
        return self.add_mesh(pts, faces, **kwargs).reshape(nv, nu)

    def pin(self, indices) -> None:
        """Fix vertices in place (infinite mass)."""
        idx = self._check_indices(indices, "pin")
        self._pinned.update(idx.tolist())

    def attach(self, indices) -> np.ndarray:
        """Make vertices kinematic attachments that follow ``ClothControl.attachment_targets``.

        Returns:
            The attachment slots, shape (len(indices),): target k of the control drives the vertex
            ``indices[k]``.
        """
        idx = self._check_indices(indices, "attach")
        dup = set(idx.tolist()) & set(self._attached)
        if dup or len(set(idx.tolist())) != len(idx):
            raise ValueError(f"attach: vertex {sorted(dup)[0] if dup else idx.tolist()} attached twice")
        slots = np.arange(len(self._attached), len(self._attached) + len(idx))
        self._attached.extend(idx.tolist())
        return slots

    def _check_indices(self, indices, what: str) -> np.ndarray:
        return vertex_indices(indices, self._count, what)

    def finalize(self, device: str = "cpu") -> "ClothModel":
        """Build the immutable device model.

        Raises:
            ValueError: when no cloth was added.
        """
        if not self._pieces:
            raise ValueError("ClothBuilder.finalize: no cloth added (use add_grid / add_mesh)")
        pts, faces, edges, hinges = [], [], [], []
        mass = np.zeros(self._count)
        e_k, h_k, h_rest = [], [], []
        base = 0
        for pc in self._pieces:
            f = pc.faces + base
            p = pc.points
            a, b, c = p[pc.faces[:, 0]], p[pc.faces[:, 1]], p[pc.faces[:, 2]]
            area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
            np.add.at(mass, f.ravel(), np.repeat(area * pc.density / 3.0, 3))
            e, h = mesh_edges_and_hinges(pc.faces)
            edges.append(e + base)
            e_k.append(np.full(len(e), pc.stretch_stiffness))
            if pc.bend_stiffness > 0 and len(h):
                x1, x2, x3, x4 = (p[h[:, k]] for k in range(4))
                el2 = np.sum((x4 - x3) ** 2, axis=1)
                a1 = 0.5 * np.linalg.norm(np.cross(x1 - x3, x1 - x4), axis=1)
                a2 = 0.5 * np.linalg.norm(np.cross(x2 - x4, x2 - x3), axis=1)
                hinges.append(h + base)
                h_k.append(3.0 * pc.bend_stiffness * el2 / (a1 + a2))
                h_rest.append(dihedral_angle_np(x1, x2, x3, x4))
            pts.append(p)
            faces.append(f)
            base += len(p)
        return ClothModel(self, np.concatenate(pts), np.concatenate(faces), mass, np.concatenate(edges),
                          np.concatenate(e_k),
                          np.concatenate(hinges) if hinges else np.zeros((0, 4), np.int32),
                          np.concatenate(h_k) if h_k else np.zeros(0), np.concatenate(h_rest) if h_rest else np.zeros(0),
                          device)


def _compliance(k: np.ndarray) -> np.ndarray:
    with np.errstate(divide="ignore"):
        return np.where(np.isinf(k), 0.0, 1.0 / k).astype(np.float32)


class ClothModel:
    """Immutable cloth description on the device. Build with :class:`ClothBuilder`.

    Attributes:
        particle_count: Number of vertices V.
        rest_points: Rest positions [m], shape (V,), dtype vec3.
        tris: Triangles, shape (F, 3), dtype int32.
        faces: Triangles on the host, shape (F, 3), int32 (for writers and shading).
        mass: Vertex masses [kg] on the host, shape (V,), float64 (before pinning).
        inv_mass: Inverse masses [1/kg], shape (V,), dtype float32; 0 for pinned and attached vertices.
        edges: Stretch/shear edges sorted by colour, shape (E, 2), dtype int32.
        edge_rest_length: Rest lengths [m], shape (E,), dtype float32.
        edge_compliance: 1 / stiffness [m/N], shape (E,), dtype float32.
        edge_colors: (offset, count) of each colour's edges.
        hinges: Bending hinges (wing1, wing2, edge0, edge1) sorted by colour, shape (H, 4), dtype int32.
        hinge_rest_angle: Rest dihedral angles [rad], shape (H,), dtype float32.
        hinge_compliance: 1 / hinge stiffness [1/(N m)], shape (H,), dtype float32.
        hinge_colors: (offset, count) of each colour's hinges.
        tether_anchor: Nearest kinematic vertices per vertex, shape (V, T), dtype int32 (-1: none).
        tether_length: Upper bound of the rest geodesic distance to them [m], shape (V, T), dtype float32.
        limit_pairs: Multi-scale stretch limits (:func:`stretch_limits`), coarsest level first and
            each level sorted by colour, shape (L, 2), dtype int32.
        limit_length: Their upper bounds of the rest geodesic distance [m], shape (L,), dtype float32.
        limit_colors: (offset, count) of each level's colours, in sweep order.
        hierarchy: Coarse levels of hierarchical stretch constraints (:func:`stretch_hierarchy`, built on
            first use), finest first, on the pieces with limits: per level ``pairs`` (C,) vec2i sorted by colour,
            ``length`` (C,), ``colors``, the prolongation rows ``offsets`` (V + 1,), ``parents``,
            ``weights`` and the coarse ``inv_mass`` (V,) on the device; ``hierarchy_np`` the same on
            the host.
        hinge_edge: Index into ``edges`` of every hinge's shared edge, shape (H,), dtype int32.
        edge_border: 1 for edges on the cloth's border (one triangle), shape (E,), dtype int32.
        ring_offsets, ring: One-ring adjacency (CSR): the edge neighbours of vertex i are
            ``ring[ring_offsets[i]:ring_offsets[i + 1]]``, shapes (V + 1,) and (2E,), dtype int32.
        attachment_indices: Attached vertices, shape (A,), dtype int32 (slot k drives vertex [k]).
        pinned: Pinned vertex indices on the host, shape (P,), int64.
        thickness, damping, bend_damping: As given to the builder.
    """

    def __init__(self, builder: ClothBuilder, points, faces, mass, edges, edge_k, hinges, hinge_k, hinge_rest,
                 device):
        self.device = wp.get_device(device)
        v = len(points)
        self.particle_count = v
        self.tri_count = len(faces)
        self.thickness = builder.thickness
        self.damping = builder.damping
        self.bend_damping = builder.bend_damping
        self.faces = faces.astype(np.int32)
        self.rest_points_np = points.astype(np.float32)
        self.mass = mass
        self.pinned = np.array(sorted(builder._pinned), dtype=np.int64)
        attached = np.array(builder._attached, dtype=np.int64)
        kinematic = np.zeros(v, dtype=bool)
        kinematic[self.pinned] = True
        kinematic[attached] = True
        inv = np.where(kinematic, 0.0, 1.0 / mass).astype(np.float32)
        self.inv_mass_np = inv

        order, self.edge_colors = color_constraints(edges, v)
        edges = edges[order]
        rest = np.linalg.norm(points[edges[:, 0]] - points[edges[:, 1]], axis=1)
        horder, self.hinge_colors = color_constraints(hinges, v) if len(hinges) else (np.zeros(0, int), [])
        hinges, hinge_k, hinge_rest = hinges[horder], hinge_k[horder], hinge_rest[horder]
        self.edges_np = edges
        self.hinges_np = hinges
        # edge index of every hinge's shared edge, and the border edges (no hinge)
        key = np.minimum(edges[:, 0], edges[:, 1]).astype(np.int64) * v + np.maximum(edges[:, 0], edges[:, 1])
        order_k = np.argsort(key)
        if len(hinges):
            hk = np.minimum(hinges[:, 2], hinges[:, 3]).astype(np.int64) * v + np.maximum(hinges[:, 2], hinges[:, 3])
            hinge_edge = order_k[np.searchsorted(key[order_k], hk)]
        else:
            hinge_edge = np.zeros(0, dtype=np.int64)
        border = np.ones(len(edges), dtype=bool)
        border[hinge_edge] = False
        piece = np.zeros(v, dtype=np.int64)
        convex_flat = np.zeros(len(builder._pieces), dtype=bool)
        start = 0
        for pi, pc in enumerate(builder._pieces):
            piece[start:start + len(pc.points)] = pi
            convex_flat[pi] = convex_and_flat(pc.points, pc.faces)
            start += len(pc.points)
        anchor, tlen = tether_anchors(points, edges, kinematic, piece, convex_flat)
        # stretch limits only on pieces that barely stretch under their own weight (the sag their
        # full weight would give, density g diameter / k, below STIFF_STRAIN): a limit allows no stretch
        stiff = np.array([np.isinf(pc.stretch_stiffness) or
                          pc.density * 9.81 * float(np.linalg.norm(np.ptp(pc.points, axis=0))) / pc.stretch_stiffness
                          <= STIFF_STRAIN for pc in builder._pieces], dtype=bool)
        lpairs, llen, llevels = stretch_limits(points, edges, piece, convex_flat, limited=stiff)
        # each level coloured on its own, so that a sweep still runs the levels coarsest first
        lorder, self.limit_colors = [], []
        for off, cnt in llevels:
            o, cols = color_constraints(lpairs[off:off + cnt], v)
            self.limit_colors += [(off + co, cc) for co, cc in cols]
            lorder.append(off + o)
        lorder = np.concatenate(lorder) if lorder else np.zeros(0, np.int64)
        self.limit_pairs_np, limit_length = lpairs[lorder], llen[lorder]
        # the coarse levels of hierarchical stretch constraints, on the pieces with limits: built on
        # first use (`hierarchy`), as only XPBDSolver(coarse_levels > 0) reads them
        self._hierarchy_args = (points, edges, mass, kinematic, stiff[piece])
        self._hierarchy = None
        d = self.device
        self.rest_points = wp.array(self.rest_points_np, dtype=wp.vec3, device=d)
        self.tris = wp.array(self.faces, dtype=wp.int32, device=d)
        self.inv_mass = wp.array(inv, dtype=wp.float32, device=d)
        self.edges = wp.array(edges.astype(np.int32), dtype=wp.int32, device=d)
        self.edge_rest_length = wp.array(rest.astype(np.float32), dtype=wp.float32, device=d)
        self.edge_compliance = wp.array(_compliance(edge_k[order]), dtype=wp.float32, device=d)
        self.hinges = wp.array(hinges.astype(np.int32).reshape(-1, 4), dtype=wp.int32, device=d)
        self.hinge_rest_angle = wp.array(hinge_rest.astype(np.float32), dtype=wp.float32, device=d)
        self.hinge_compliance = wp.array(_compliance(hinge_k), dtype=wp.float32, device=d)
        both = np.concatenate([edges, edges[:, ::-1]]).astype(np.int64)
        both = both[np.lexsort((both[:, 1], both[:, 0]))]
        offsets = np.concatenate([[0], np.cumsum(np.bincount(both[:, 0], minlength=v))])
        self.ring_offsets = wp.array(offsets.astype(np.int32), dtype=wp.int32, device=d)
        self.ring = wp.array(both[:, 1].astype(np.int32), dtype=wp.int32, device=d)
        self.tether_anchor = wp.array(anchor, dtype=wp.int32, device=d)
        self.tether_length = wp.array(tlen, dtype=wp.float32, device=d)
        self.limit_pairs = wp.array(self.limit_pairs_np.reshape(-1, 2), dtype=wp.int32, device=d)
        self.limit_length = wp.array(limit_length, dtype=wp.float32, device=d)
        self.attachment_indices = wp.array(attached.astype(np.int32), dtype=wp.int32, device=d)
        self.attachment_count = len(attached)
        self.hinge_edge = wp.array(hinge_edge.astype(np.int32), dtype=wp.int32, device=d)
        self.edge_border = wp.array(border.astype(np.int32), dtype=wp.int32, device=d)

    HIERARCHY_LEVELS = 2
    """Coarse levels built for hierarchical stretch constraints (:func:`stretch_hierarchy`; the
    solver's ``coarse_levels`` uses up to this many)."""

    def _build_hierarchy(self) -> None:
        levels = stretch_hierarchy(*self._hierarchy_args, self.HIERARCHY_LEVELS)
        for lv in levels:
            o, lv["colors"] = color_constraints(lv["pairs"], self.particle_count)
            lv["pairs"], lv["length"] = lv["pairs"][o], lv["length"][o]
        d = self.device
        self._hierarchy = (levels, [{"pairs": wp.array(lv["pairs"], dtype=wp.int32, device=d).view(wp.vec2i),
                                     "length": wp.array(lv["length"], dtype=wp.float32, device=d),
                                     "colors": lv["colors"], "offsets": wp.array(lv["offsets"], dtype=wp.int32, device=d),
                                     "parents": wp.array(lv["parents"], dtype=wp.int32, device=d),
                                     "weights": wp.array(lv["weights"], dtype=wp.float32, device=d),
                                     "inv_mass": wp.array(lv["inv_mass"], dtype=wp.float32, device=d)}
                                    for lv in levels])

    @property
    def hierarchy_np(self) -> list[dict]:
        """The coarse levels on the host (see the class's attributes)."""
        if self._hierarchy is None:
            self._build_hierarchy()
        return self._hierarchy[0]

    @property
    def hierarchy(self) -> list[dict]:
        """The coarse levels on the device (see the class's attributes)."""
        if self._hierarchy is None:
            self._build_hierarchy()
        return self._hierarchy[1]

    @property
    def edge_count(self) -> int:
        return len(self.edges_np)

    @property
    def hinge_count(self) -> int:
        return len(self.hinges_np)

    def edge_strain(self, points) -> np.ndarray:
        """Relative stretch |xi - xj| / L - 1 of every edge for positions (V, 3), shape (E,), float64."""
        x = np.asarray(points, dtype=np.float64)
        e = self.edges_np
        return np.linalg.norm(x[e[:, 0]] - x[e[:, 1]], axis=1) / self.edge_rest_length.numpy().astype(np.float64) - 1.0

    def state(self) -> ClothState:
        """A new state at the rest pose with zero velocity."""
        from .state import ClothState

        return ClothState(self)

    def control(self) -> ClothControl:
        """A new control: attachment targets at their rest positions, no wind."""
        from .state import ClothControl

        return ClothControl(self)
