"""Bounding sphere sets, sphere hierarchies and receiver clusters (thesis §4.1; Wang et al. 2006 [43]).

Host-side builder (NumPy/SciPy), run once per object: the result, :class:`SphereTree`, is the static
model the Warp kernels read. Following a deforming mesh does not re-run the fit: every leaf keeps the
vertices it was fitted to and :func:`refit_np` (NumPy reference of the Warp kernels in
``kernels.py``) moves each sphere rigidly with its vertices (Kabsch) and grows or shrinks it with their
spread; parents re-bound their children.

Outside volume (eq. 4.1) is measured on a regular grid: cells inside the mesh (winding number > 0.5)
are *inner points*, the rest *outside points*; a sphere's outside volume is the number of outside
points it covers times the cell volume. For an open mesh (cloth) there is no inside and the fit
minimises the covered volume (analytic, no grid), i.e. tight spheres around the surface.

The fit runs in a unit frame (bounding-box diagonal 1, see :func:`_unit_frame`), so a scaled or moved
mesh gets the scaled or moved spheres.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize
from scipy.spatial import ConvexHull, QhullError, cKDTree

from ...geometry.mesh import stitched_faces


@dataclass
class SphereTree:
    """A sphere hierarchy bounding one object, level 0 = leaves.

    Attributes:
        centers: Rest-pose centres [m], shape (S, 3), float64 (all levels, leaves first).
        radii: Rest-pose radii [m], shape (S,).
        level: Hierarchy level of each sphere (0 = leaf), shape (S,), int.
        parent: Parent sphere index or -1, shape (S,), int.
        vert_start: CSR offsets into :attr:`vert_index` per sphere, shape (S+1,), int. A leaf lists
            the mesh vertices assigned to it; a parent lists the union of its leaves' vertices.
        vert_index: Mesh vertex indices, int.
        closed: Whether the fitted mesh was closed (inner points existed).
        outside_volume: Outside volume of the leaf set [m^3] (eq. 4.1), grid estimate.
    """

    centers: np.ndarray
    radii: np.ndarray
    level: np.ndarray
    parent: np.ndarray
    vert_start: np.ndarray
    vert_index: np.ndarray
    closed: bool = True
    outside_volume: float = 0.0

    @property
    def num_spheres(self) -> int:
        return len(self.radii)

    @property
    def num_leaves(self) -> int:
        return int((self.level == 0).sum())

    @property
    def num_levels(self) -> int:
        return int(self.level.max()) + 1

    def children(self, s: int) -> np.ndarray:
        return np.flatnonzero(self.parent == s)

    def leaf_descendants(self, s: int) -> np.ndarray:
        """Leaf indices under sphere ``s`` (``[s]`` for a leaf)."""
        out, stack = [], [s]
        while stack:
            t = stack.pop()
            if self.level[t] == 0:
                out.append(t)
            else:
                stack.extend(self.children(t).tolist())
        return np.array(sorted(out), dtype=np.int64)

    def vertices_of(self, s: int) -> np.ndarray:
        return self.vert_index[self.vert_start[s]:self.vert_start[s + 1]]


def _grid_points(points: np.ndarray, faces: np.ndarray, closed: bool, cells: int, device: str):
    lo, hi = points.min(axis=0), points.max(axis=0)
    ext = np.maximum(hi - lo, 1e-9 * max(float(np.max(hi - lo)), 1e-30))
    h = float(np.cbrt(np.prod(ext) / cells))
    h = max(h, float(ext.max()) / 200.0)
    if not closed:
        # no inside: every covered point is outside, so the outside volume is the spheres' volume,
        # computed analytically (the grid, 200x200x5 points for a flat cloth, dominated the build)
        return np.zeros((0, 3)), np.zeros((0, 3)), h
    pad = 2.0 * h
    axes = [np.arange(lo[i] - pad, hi[i] + pad + 0.5 * h, h) for i in range(3)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    if closed:
        from .kernels import winding_inside

        inside = winding_inside(points, faces, grid, device)
    else:
        inside = np.zeros(len(grid), dtype=bool)
    return grid[inside], grid[~inside], h


def _sample_surface(points: np.ndarray, faces: np.ndarray, n: int, rng) -> np.ndarray:
    """Area-weighted surface samples plus every vertex (so the leaves bound the vertices)."""
    a, b, c = (points[faces[:, i]].astype(np.float64) for i in range(3))
    area = 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1)
    if area.sum() <= 0:
        return points.astype(np.float64)
    f = rng.choice(len(faces), size=n, p=area / area.sum())
    u, v = rng.random(n), rng.random(n)
    flip = u + v > 1
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    return a[f] + u[:, None] * (b[f] - a[f]) + v[:, None] * (c[f] - a[f])


class _Fitter:
    """Lloyd-style minimisation of the outside volume (assignment, centre optimisation, teleportation)."""

    def __init__(self, surface, inner, outside, h):
        self.surface, self.inner, self.outside, self.h = surface, inner, outside, h
        self.pts = np.concatenate([surface, inner]) if len(inner) else surface
        self.surf_tree = cKDTree(surface)
        self.out_tree = cKDTree(outside) if len(outside) else None
        self.cell = h ** 3

    def clearance(self, c):
        """Radius a sphere at ``c`` can have for free: distance to the nearest outside point."""
        if self.out_tree is None:
            return np.zeros(len(c))
        d, _ = self.out_tree.query(c)
        return np.maximum(d - self.h, 0.0)

    def assign(self, c):
        # Point goes to the sphere whose bound grows least beyond its free (fully inside) radius: a
        # vectorised stand-in for the flood fill "least increase of outside volume" of [43].
        cost = np.linalg.norm(self.pts[:, None, :] - c[None], axis=2) - self.clearance(c)[None]
        lab = np.argmin(cost, axis=1)
        r = np.zeros(len(c))
        for i in range(len(c)):
            m = lab == i
            if m.any():
                r[i] = np.linalg.norm(self.pts[m] - c[i], axis=1).max()
        return lab, r

    def sphere_outside(self, c, r):
        if self.out_tree is None:
            return (4.0 / 3.0) * math.pi * r ** 3
        return len(self.out_tree.query_ball_point(c, r)) * self.cell

    def energy(self, c, r):
        return float(sum(self.sphere_outside(c[i], r[i]) for i in range(len(r))))

    def optimise_center(self, c0, pts):
        if len(pts) == 0:
            return c0
        if len(pts) > 64:
            # the farthest point of a set from any centre is a vertex of its convex hull: same r, less work
            try:
                pts = pts[ConvexHull(pts).vertices]
            except QhullError:  # flat or degenerate set: keep every point
                pass
        near = self.outside
        r0 = np.linalg.norm(pts - c0, axis=1).max()
        if self.out_tree is not None:
            near = self.outside[self.out_tree.query_ball_point(c0, 2.0 * r0 + 2 * self.h)]
        h = self.h

        def outside_volume(c):
            r = np.linalg.norm(pts - c, axis=1).max()
            if self.out_tree is None or len(near) == 0:
                return r ** 3
            # smooth count (logistic over one cell) so Powell sees a slope, not steps
            t = np.clip((r - np.linalg.norm(near - c, axis=1)) / h, -40, 40)
            return float(np.sum(1.0 / (1.0 + np.exp(-t)))) + 1e-3 * (r / h) ** 3

        # In the unit frame (diagonal 1): line searches start from a 0.2-diagonal bracket and stop at a
        # relative tolerance of 100 * 2.5 h. Chosen so the mean outside volume over seeds 0..5 matches
        # the fit before the unit frame on bunny and bear (whose brackets were 1 m: 0.38 and 0.08 diagonals).
        res = minimize(outside_volume, c0, method="Powell",
                       options={"maxfev": 36, "xtol": 2.5 * h, "direc": 0.2 * np.eye(3)})
        return res.x

    def lloyd(self, c, iterations):
        e_best, best = math.inf, None
        for _ in range(iterations):
            lab, r = self.assign(c)
            e = self.energy(c, r)
            if e < e_best - 1e-9 * self.cell:
                e_best, best = e, (c.copy(), r.copy(), lab)
            elif e >= e_best * 0.995:
                break
            c = np.array([self.optimise_center(c[i], self.pts[lab == i]) for i in range(len(c))])
        lab, r = self.assign(c)
        e = self.energy(c, r)
        if e < e_best:
            e_best, best = e, (c, r, lab)
        return best[0], best[1], best[2], e_best

    def teleport(self, c, r, lab):
        """Move the most redundant sphere to split the one with the largest outside volume (Bradshaw [5])."""
        covered = np.zeros(len(self.pts), dtype=int)
        for i in range(len(c)):
            covered += np.linalg.norm(self.pts - c[i], axis=1) <= r[i]
        redundancy = []
        for i in range(len(c)):
            inside = np.linalg.norm(self.pts - c[i], axis=1) <= r[i]
            redundancy.append((covered[inside] > 1).mean() if inside.any() else 1.0)
        s_o = int(np.argmax(redundancy))
        outside = np.array([self.sphere_outside(c[i], r[i]) for i in range(len(c))])
        outside[s_o] = -1
        s_e = int(np.argmax(outside))
        pe = self.pts[lab == s_e]
        if len(pe) < 2:
            return None
        # the two mutually farthest points of S_E (approximate: farthest from a point, then from it)
        a = pe[np.argmax(np.linalg.norm(pe - pe.mean(axis=0), axis=1))]
        b = pe[np.argmax(np.linalg.norm(pe - a, axis=1))]
        c2 = c.copy()
        c2[s_e] = a + 0.25 * (b - a)
        c2[s_o] = b + 0.25 * (a - b)
        return c2


def _unit_frame(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Origin and length unit of the fit: bounding-box minimum and diagonal [m].

    The fit runs on ``(points - origin) / unit`` so every tolerance, step and threshold in it (grid
    spacing, Powell's unit line-search bracket and tolerances, energy comparisons, Lloyd convergence)
    is relative to the mesh size: the spheres of a scaled or moved mesh are the scaled or moved spheres.
    """
    lo = points.min(axis=0)
    unit = float(np.linalg.norm(points.max(axis=0) - lo))
    if not np.isfinite(unit) or unit <= 0.0:
        raise ValueError(f"mesh points must be finite and not all coincident (bounding-box diagonal {unit})")
    return lo, unit


UNIT_QUANTUM = 2.0 ** -14
"""Lattice step of the unit-frame points the fit sees (6e-5 of the bounding-box diagonal, far below the
grid spacing of ~5e-3). The fit (Lloyd assignment, Powell, teleportation) is chaotic: float32 rounding
of a scaled mesh (relative 6e-8) changed the spheres by up to 75 % of a radius. Snapped to this lattice a
scaled mesh gives bitwise the same fit unless a coordinate lies within ~1e-7 of a lattice midpoint."""


def _to_unit(points: np.ndarray, lo: np.ndarray, unit: float) -> np.ndarray:
    return np.round((points - lo) / (unit * UNIT_QUANTUM)) * UNIT_QUANTUM


def fit_leaf_spheres(points, faces, spheres: int = 30, seed: int = 0, iterations: int = 4, teleports: int = 2,
                     grid_cells: int = 12000, surface_samples: int = 3000, device: str = "cpu",
                     restarts: int = 2):
    """Bounding leaf spheres of a mesh minimising the outside volume (thesis §4.1, [43]).

    Args:
        points: Vertex positions [m], shape (V, 3).
        faces: Triangles, shape (F, 3).
        spheres: Number of leaf spheres.
        seed: Random seed (initial centres, surface samples).
        iterations: Lloyd iterations per round (stops early when the outside volume stalls).
        teleports: Teleportation attempts (each accepted only if the outside volume drops; the first
            rejected one ends the round).
        restarts: Independent rounds from different random initial centres; the lowest outside volume
            wins (the fit is chaotic: one round landed 3-5x above the others on an icosphere).
        grid_cells: Grid cells in the bounding box for inner/outside points.
        surface_samples: Area-weighted surface samples (on top of every vertex).

    Returns:
        ``(centers (S,3), radii (S,), vertex_labels (V,), closed, outside_volume)``; every vertex lies in
        its leaf (``||p_v - c|| <= r``).
    """
    points = np.asarray(points, dtype=np.float64)
    lo, unit = _unit_frame(points)
    c, r, lab, closed, e = _fit_leaf_unit(_to_unit(points, lo, unit), faces, spheres, seed, iterations, teleports,
                                          grid_cells, surface_samples, device, restarts)
    c = lo + unit * c
    # the snapped points moved by <= 3.5e-5 diagonals: re-bound the true vertices (exactly, in metres)
    r = unit * r
    for i in range(len(c)):
        m = lab == i
        if m.any():
            r[i] = max(r[i], float(np.linalg.norm(points[m] - c[i], axis=1).max()))
    return c, r, lab, closed, e * unit ** 3


def _fit_leaf_unit(points, faces, spheres, seed, iterations, teleports, grid_cells, surface_samples, device,
                   restarts):
    """:func:`fit_leaf_spheres` on a mesh of bounding-box diagonal 1 (see :func:`_unit_frame`)."""
    import trimesh

    faces = np.asarray(faces, dtype=np.int64)
    if spheres < 1:
        raise ValueError(f"spheres must be >= 1, got {spheres}")
    rng = np.random.default_rng(seed)
    closed = bool(trimesh.Trimesh(points, stitched_faces(points, faces), process=False).is_watertight)
    inner, outside, h = _grid_points(points, faces, closed, grid_cells, device)
    closed = closed and len(inner) > 0
    surf = _sample_surface(points, faces, surface_samples, rng)
    verts = points if len(points) <= 4000 else points[rng.choice(len(points), 4000, replace=False)]
    surface = np.concatenate([surf, verts])
    fitter = _Fitter(surface, inner, outside, h)
    spheres = min(spheres, len(fitter.pts))
    pool = inner if len(inner) >= spheres else fitter.pts
    best = None
    for _ in range(max(1, restarts)):
        c = pool[rng.choice(len(pool), spheres, replace=False)]
        c, r, lab, e = fitter.lloyd(c, iterations)
        for _ in range(teleports if spheres > 1 else 0):
            c2 = fitter.teleport(c, r, lab)
            if c2 is None:
                break
            cc, rr, ll, ee = fitter.lloyd(c2, iterations)
            if ee >= e:
                break  # teleport() is deterministic: retrying from the same spheres repeats this move
            c, r, lab, e = cc, rr, ll, ee
        if best is None or e < best[3]:
            best = (c, r, lab, e)
    c, r, lab, e = best
    # every mesh vertex is bounded by the leaf that claims it (cost rule), so receivers on the surface
    # sit inside a leaf, the configuration the tangent-plane rules of §4.2 expect
    cost = np.linalg.norm(points[:, None, :] - c[None], axis=2) - fitter.clearance(c)[None]
    vlab = np.argmin(cost, axis=1)
    for i in range(len(c)):
        m = vlab == i
        if m.any():
            r[i] = max(r[i], np.linalg.norm(points[m] - c[i], axis=1).max())
    keep = np.flatnonzero(np.bincount(vlab, minlength=len(c)) > 0)
    remap = -np.ones(len(c), dtype=np.int64)
    remap[keep] = np.arange(len(keep))
    return c[keep], r[keep], remap[vlab], closed, fitter.energy(c[keep], r[keep])


def _bounding_sphere_of_spheres(c, r):
    """Centre and radius of a small sphere bounding spheres ``(c_j, r_j)`` (min of max ||c_j - x|| + r_j)."""
    if len(c) == 1:
        return c[0], r[0]
    f = lambda x: float(np.max(np.linalg.norm(c - x, axis=1) + r))  # noqa: E731
    x0 = c.mean(axis=0)
    step = 0.05 * float(np.max(np.linalg.norm(c - x0, axis=1) + r))
    # explicit initial simplex sized by the spheres (scipy's default steps are 5 % of each coordinate,
    # or 2.5e-4 m for a zero coordinate: not scale or translation invariant)
    simplex = np.vstack([x0, x0 + step * np.eye(3)])
    x = minimize(f, x0, method="Nelder-Mead", options={"xatol": 1e-9 * step, "fatol": 1e-9 * step,
                                                        "initial_simplex": simplex}).x
    return x, f(x)


def build_sphere_tree(points, faces, spheres: int = 30, levels: int = 3, branching: int | None = None, seed: int = 0,
                      device: str = "cpu", **fit_kwargs) -> SphereTree:
    """Fit leaves, then parents by Lloyd clustering of child centres with a branching factor (thesis §4.1).

    Args:
        points, faces: The mesh (rest pose). Vertices in no triangle belong to no sphere.
        spheres: Leaf spheres.
        levels: Hierarchy levels including the leaves (1 = leaves only).
        branching: Children per parent; default ``ceil(spheres ** (1/(levels-1)))`` so the top level has
            about one sphere.
        seed: Random seed.
    """
    if levels < 1:
        raise ValueError(f"levels must be >= 1, got {levels}")
    points = np.asarray(points, dtype=np.float64)
    faces = np.asarray(faces, dtype=np.int64)
    used = np.unique(faces)
    if len(used) < len(points):
        # vertices in no triangle (receivers that cast no shadows, warpshade:castsShadows = false) are not
        # bounded: fit the triangles' vertices only, then list the spheres' vertices in the caller's indices
        tree = build_sphere_tree(points[used], np.searchsorted(used, faces), spheres, levels, branching, seed,
                                 device, **fit_kwargs)
        tree.vert_index = used[tree.vert_index]
        return tree
    # fit and cluster in the unit frame (bounding-box diagonal 1) so the tree is scale invariant
    c, r, vlab, closed, e = fit_leaf_spheres(points, faces, spheres, seed=seed, device=device, **fit_kwargs)
    # cluster in the unit frame too (Nelder-Mead and k-means tolerances), then back to metres
    lo, unit = _unit_frame(points)
    c, r, e = (c - lo) / unit, r / unit, e / unit ** 3
    n = len(r)
    if branching is None:
        branching = max(2, math.ceil(n ** (1.0 / (levels - 1)))) if levels > 1 else 2
    centers, radii, level, parent = [c], [r], [np.zeros(n, int)], [-np.ones(n, int)]
    rng = np.random.default_rng(seed + 1)
    child_lo, cur_c, cur_r = 0, c, r
    for lev in range(1, levels):
        k = max(1, math.ceil(len(cur_r) / branching))
        if k >= len(cur_r):
            break
        lab = _kmeans(cur_c, k, rng)
        pc, pr = [], []
        for j in range(k):
            m = lab == j
            x, rad = _bounding_sphere_of_spheres(cur_c[m], cur_r[m])
            pc.append(x)
            pr.append(rad)
        base = child_lo + len(cur_r)
        parent[-1][:] = base + lab
        cur_c, cur_r = np.array(pc), np.array(pr)
        centers.append(cur_c)
        radii.append(cur_r)
        level.append(np.full(k, lev))
        parent.append(-np.ones(k, int))
        child_lo = base
    centers = np.concatenate(centers)
    radii = np.concatenate(radii)
    level = np.concatenate(level)
    parent = np.concatenate(parent)
    # vertex lists: leaves own their vertices; parents the union of their leaves'
    owner = vlab.copy()
    lists = [[] for _ in range(len(radii))]
    for v, s in enumerate(owner):
        while s >= 0:
            lists[s].append(v)
            s = parent[s]
    start = np.zeros(len(radii) + 1, dtype=np.int64)
    start[1:] = np.cumsum([len(x) for x in lists])
    index = np.array([v for x in lists for v in x], dtype=np.int64)
    return SphereTree(lo + unit * centers, unit * radii, level, parent, start, index, closed, e * unit ** 3)


def _kmeans(x, k, rng, iterations: int = 30):
    """Lloyd clustering (thesis §4.1 "Parent sphere construction", "Receiver point clusters")."""
    x = np.asarray(x, dtype=np.float64)
    if k >= len(x):
        return np.arange(len(x))
    c = x[rng.choice(len(x), k, replace=False)]
    lab = -np.ones(len(x), dtype=np.int64)
    for _ in range(iterations):
        prev, lab = lab, cKDTree(c).query(x)[1]
        if np.array_equal(lab, prev):  # converged; a label test has no length scale (np.allclose has)
            break
        c = np.array([x[lab == j].mean(axis=0) if (lab == j).any() else x[rng.integers(len(x))] for j in range(k)])
    # drop empty clusters, keep labels dense
    return np.unique(lab, return_inverse=True)[1]


def cluster_receivers(points, clusters: int, seed: int = 0) -> np.ndarray:
    """Receiver clusters by Lloyd clustering of positions (thesis §4.1); labels (V,), dense 0..K-1."""
    if clusters < 1:
        raise ValueError(f"clusters must be >= 1, got {clusters}")
    return _kmeans(np.asarray(points), clusters, np.random.default_rng(seed))


def refit_np(tree: SphereTree, rest_points: np.ndarray, points: np.ndarray):
    """NumPy reference of the per-frame refit (kernels ``refit_spheres`` + ``bound_parents``).

    Each sphere moves rigidly with its vertices (Kabsch rotation of the rest offset centre − centroid)
    and its radius changes by the change of its vertices' farthest distance; parents then re-bound
    their children. At the rest pose it returns the fitted spheres unchanged.

    Returns:
        ``(centers (S,3), radii (S,), rotations (S,3,3))``.
    """
    p0 = np.asarray(rest_points, dtype=np.float64)
    p1 = np.asarray(points, dtype=np.float64)
    S = tree.num_spheres
    cen = np.zeros((S, 3))
    rad = np.zeros(S)
    rot = np.tile(np.eye(3), (S, 1, 1))
    for s in range(S):
        idx = tree.vertices_of(s)
        a, b = p0[idx], p1[idx]
        ma, mb = a.mean(axis=0), b.mean(axis=0)
        u, _, vt = np.linalg.svd((a - ma).T @ (b - mb))
        d = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
        R = vt.T @ np.diag([1, 1, d]) @ u.T
        rot[s] = R
        cen[s] = mb + R @ (tree.centers[s] - ma)
        spread0 = np.linalg.norm(a - tree.centers[s], axis=1).max()
        spread1 = np.linalg.norm(b - cen[s], axis=1).max()
        rad[s] = max(tree.radii[s] + spread1 - spread0, spread1)
    for lev in range(1, tree.num_levels):
        for s in np.flatnonzero(tree.level == lev):
            ch = tree.children(s)
            rad[s] = max(rad[s], float(np.max(np.linalg.norm(cen[ch] - cen[s], axis=1) + rad[ch])))
    return cen, rad, rot


def tree_from_spheres(centers, radii) -> tuple[SphereTree, np.ndarray]:
    """A leaves-only :class:`SphereTree` of given spheres, for analytic scenes and tests.

    Each sphere owns the 4 vertices of a regular tetrahedron inscribed in it (so :func:`refit_np` and
    the refit kernel reproduce it exactly and move it rigidly with them).

    Returns:
        ``(tree, rest_points (4S, 3))``: pass both as a blocker ``(tree, rest_points)``.
    """
    c = np.atleast_2d(np.asarray(centers, dtype=np.float64))
    r = np.atleast_1d(np.asarray(radii, dtype=np.float64))
    if c.shape != (len(r), 3) or (r <= 0).any() or not np.isfinite(c).all():
        raise ValueError(f"need (S,3) finite centres and (S,) positive radii, got {c.shape}, {r.shape}")
    tet = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], dtype=np.float64) / math.sqrt(3)
    pts = (c[:, None, :] + r[:, None, None] * tet[None]).reshape(-1, 3)
    S = len(r)
    tree = SphereTree(c.copy(), r.copy(), np.zeros(S, int), -np.ones(S, int),
                      np.arange(0, 4 * S + 1, 4, dtype=np.int64), np.arange(4 * S, dtype=np.int64), True, 0.0)
    return tree, pts


def halfspace_blocker(point, normal, scale: float, ratio: float = 1000.0) -> tuple[SphereTree, np.ndarray]:
    """A ground plane as a blocker: one sphere of radius ``ratio * scale`` tangent to the plane from below.

    Seen from a receiver within ``scale`` of ``point`` it subtends ``π/2 - O(1/ratio)``: the half-space
    behind the plane (a ground box casts no spheres in the thesis; this lets it shadow the objects on it).

    Args:
        point: A point on the plane [m], (3,).
        normal: Plane normal pointing to the open side, (3,).
        scale: Size of the region where receivers live [m] (e.g. the scene's bounding-box diagonal).
        ratio: Sphere radius over ``scale`` (float32 positions keep ``1/ratio`` above their precision).

    Returns:
        ``(tree, rest_points)`` to pass in ``blockers``.
    """
    n = np.asarray(normal, dtype=np.float64)
    n = n / np.linalg.norm(n)
    r = ratio * float(scale)
    return tree_from_spheres([np.asarray(point, dtype=np.float64) - n * r], [r])
