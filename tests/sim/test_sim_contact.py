"""Intersection count (exact triangle-triangle tests against a linear-programming reference) and
the solver's penetration-free contact (self, edge-edge, colliders) on hard cases."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
import warp as wp

from warpshade.sim import ClothBuilder, ColliderSet, IntersectionCounter, XPBDSolver, count_intersections
from warpshade.sim.contact_kernels import segments_cross
from warpshade.sim.intersections import triangles_meet
from warpshade.sim.oracle import triangles_meet_np

DT = 1.0 / 60.0


@wp.kernel
def _meet_kernel(a: wp.array2d[wp.vec3d], b: wp.array2d[wp.vec3d], out: wp.array[int]):
    i = wp.tid()
    out[i] = int(triangles_meet(a[i, 0], a[i, 1], a[i, 2], b[i, 0], b[i, 1], b[i, 2]))


def _meet(a, b) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64).reshape(-1, 3, 3)
    b = np.asarray(b, dtype=np.float64).reshape(-1, 3, 3)
    out = wp.zeros(len(a), dtype=int)
    wp.launch(_meet_kernel, dim=len(a), inputs=[wp.array(a, dtype=wp.vec3d), wp.array(b, dtype=wp.vec3d)],
              outputs=[out])
    return out.numpy().astype(bool)


T0 = [[0, 0, 0], [1, 0, 0], [0, 1, 0]]  # in the z = 0 plane
HAND_MADE = {
    # name: (triangle b, whether it meets T0)
    "crossing": ([[0.2, 0.2, -1], [0.3, 0.2, 1], [0.2, 0.3, 1]], True),
    "piercing edge through the interior": ([[0.25, 0.25, -0.5], [0.25, 0.25, 0.5], [2, 2, 0.2]], True),
    "above": ([[0.2, 0.2, 0.1], [0.3, 0.2, 1], [0.2, 0.3, 1]], False),
    "vertex touching the interior": ([[0.2, 0.2, 0.0], [0.3, 0.2, 1], [0.2, 0.3, 1]], True),
    "edge touching an edge": ([[0.5, 0.5, 0.0], [1.0, 1.0, 0.0], [0.5, 0.5, 1.0]], True),
    "near miss beside an edge": ([[0.51, 0.51, -1], [1, 1, 1], [0.51, 0.51, 1]], False),
    "coplanar overlapping": ([[0.1, 0.1, 0], [0.9, 0.1, 0], [0.1, 0.5, 0]], True),
    "coplanar containing": ([[-1, -1, 0], [3, -1, 0], [-1, 3, 0]], True),
    "coplanar disjoint": ([[1, 1, 0], [2, 1, 0], [1, 2, 0]], False),
    "coplanar edges crossing": ([[0.4, -0.2, 0], [0.4, 0.2, 0], [-0.5, -0.5, 0]], True),
    "shared edge, folded": ([[0, 0, 0], [1, 0, 0], [0.3, -0.5, 0.5]], True),
    "shared edge, coplanar": ([[0, 0, 0], [1, 0, 0], [0.5, -1, 0]], True),
    "shared vertex only": ([[0, 0, 0], [-1, 0, 0.5], [0, -1, 0.5]], True),
    "parallel planes": ([[0, 0, 1e-3], [1, 0, 1e-3], [0, 1, 1e-3]], False),
}


@pytest.mark.parametrize("name", list(HAND_MADE))
def test_triangle_triangle_hand_made_pairs(name):
    tri, expected = HAND_MADE[name]
    assert triangles_meet_np(T0, tri) == expected, f"reference disagrees with the hand-made answer: {name}"
    assert _meet(T0, tri)[0] == expected, name
    assert _meet(tri, T0)[0] == expected, f"{name} (swapped)"


def test_triangle_triangle_random_pairs_match_reference(rng):
    """Random pairs in a unit cube (about a quarter meet): the exact predicate agrees with the LP
    feasibility reference on every pair (a random pair is never within float64 rounding of touching)."""
    a = rng.uniform(0, 1, size=(300, 3, 3))
    b = rng.uniform(0, 1, size=(300, 3, 3))
    got = _meet(a, b)
    ref = np.array([triangles_meet_np(a[i], b[i]) for i in range(len(a))])
    assert 0.1 < ref.mean() < 0.9  # both outcomes well represented
    bad = np.flatnonzero(got != ref)
    assert len(bad) == 0, f"pairs {bad[:5].tolist()} disagree: {a[bad[0]].tolist()} {b[bad[0]].tolist()}"


def _grid(n, size, origin, u=(1, 0, 0), v=(0, 0, 1)):
    b = ClothBuilder()
    b.add_grid(n, n, size, size, origin=origin, u_axis=u, v_axis=v)
    m = b.finalize()
    return m.rest_points_np.astype(np.float64), m.faces


def _brute_force_count(points, faces):
    """Every non-adjacent pair by the LP reference."""
    n = 0
    tri = points[faces]
    for t in range(len(faces)):
        for u in range(t + 1, len(faces)):
            if set(faces[t].tolist()) & set(faces[u].tolist()):
                continue
            lo = np.maximum(tri[t].min(0), tri[u].min(0))
            hi = np.minimum(tri[t].max(0), tri[u].max(0))
            if (lo > hi + 1e-12).any():
                continue
            n += triangles_meet_np(tri[t], tri[u])
    return n


def test_count_of_two_crossing_sheets_matches_brute_force():
    """A horizontal and a vertical 5 x 5 sheet in one mesh, crossing along a line: the BVH count
    equals the all-pairs reference; each sheet alone has none."""
    p1, f1 = _grid(5, 1.0, (-0.5, 0.0, -0.5))
    p2, f2 = _grid(5, 1.0, (-0.43, -0.37, -0.31), u=(1, 0, 0), v=(0, 1, 0.1))
    pts = np.concatenate([p1, p2])
    faces = np.concatenate([f1, f2 + len(p1)])
    ref = _brute_force_count(pts, faces)
    got = count_intersections(pts, faces)
    assert ref > 4 and got["self"] == ref, (got["self"], ref)
    assert got["collider"] == 0 and got["total"] == ref
    assert count_intersections(p1, f1)["self"] == 0  # neighbours sharing a vertex are not counted
    pairs = got["self_pairs"]
    assert (pairs[:, 0] < len(f1)).all() and (pairs[:, 1] >= len(f1)).all()  # every pair is across sheets


def test_count_against_colliders():
    """A flat 8 x 8 sheet at y = 0.1 against solids placed to cut it or to miss it by 1 mm."""
    pts, faces = _grid(8, 1.0, (-0.5, 0.1, -0.5))
    cases = [
        ("plane below", lambda c: c.add_plane((0, 1, 0), 0.099), 0),
        ("plane through", lambda c: c.add_plane((0, 1, 0), 0.1001), 98),
        ("sphere under", lambda c: c.add_sphere((0, 0, 0), 0.099), 0),
        ("sphere cutting", lambda c: c.add_sphere((0.01, 0, 0.01), 0.12), None),
        ("capsule under", lambda c: c.add_capsule((-0.3, 0.0, 0.0), (0.3, 0.0, 0.0), 0.099), 0),
        ("capsule cutting", lambda c: c.add_capsule((-0.3, 0.0, 0.0), (0.3, 0.0, 0.0), 0.11), None),
        ("box under", lambda c: c.add_box((0, 0, 0), (0.2, 0.099, 0.2)), 0),
        # a box whose sharp top edge pokes up through the sheet between vertices
        ("box edge poking", lambda c: c.add_box((0.07, 0.0, 0.0), (0.1, 0.1, 0.2),
                                                 (np.sin(np.pi / 8), 0, 0, np.cos(np.pi / 8))), None),
    ]
    for name, add, expected in cases:
        col = ColliderSet()
        add(col)
        n = count_intersections(pts, faces, col)["collider"]
        if expected is None:
            assert n > 0, name
        else:
            assert n == expected, (name, n)


def test_box_edge_between_vertices_is_counted():
    """A box edge rising 2 mm above a sheet whose vertices all stay outside the box: a vertex
    signed distance sees nothing, the triangle test sees the crossing."""
    pts, faces = _grid(5, 1.0, (-0.5, 0.0, -0.5))  # spacing 0.25 m
    # a 45-degree-rotated box (about z) whose top edge runs along z at x = 0.125, y = 0.002
    c = np.sqrt(0.5)
    col = ColliderSet()
    half = 0.1
    col.add_box((0.125, 0.002 - half * np.sqrt(2), 0.0), (half, half, 0.6), (0, 0, np.sin(np.pi / 8), np.cos(np.pi / 8)))
    ar = col.end_pose_arrays()
    assert ar is not None
    rot = np.array([[c, -c, 0], [c, c, 0], [0, 0, 1]])
    lp = (pts - [0.125, 0.002 - half * np.sqrt(2), 0.0]) @ rot
    q = np.abs(lp) - [half, half, 0.6]
    sd = np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0)
    assert sd.min() > 0.0  # no vertex inside
    assert count_intersections(pts, faces, col)["collider"] > 0


def test_count_against_a_mesh_collider():
    import trimesh

    pts, faces = _grid(9, 1.0, (-0.5, 0.0, -0.5))
    ico = trimesh.creation.icosphere(subdivisions=2, radius=0.2)
    for centre, expect_hit in (((0, 0.1, 0), True), ((0, 0.25, 0), False), ((0, 0.0, 0), True)):
        col = ColliderSet()
        col.add_mesh(np.asarray(ico.vertices) + centre, np.asarray(ico.faces))
        n = count_intersections(pts, faces, col)["collider"]
        assert (n > 0) == expect_hit, (centre, n)
    # a small sheet wholly inside the mesh: no crossing, every triangle counted as inside
    p_in, f_in = _grid(3, 0.1, (-0.05, 0.3, -0.05))
    col = ColliderSet()
    col.add_mesh(np.asarray(ico.vertices) + (0, 0.3, 0), np.asarray(ico.faces))
    res = count_intersections(p_in, f_in, col)
    assert res["collider"] == len(f_in) and (res["collider_pairs"][:, 1] == -1).all()


def test_counter_is_fast_on_a_64_grid():
    """The counter is reused frame after frame: it refits its BVH."""
    pts, faces = _grid(64, 1.0, (-0.5, 0.3, -0.5))
    c = IntersectionCounter(faces)
    assert c.self_pairs(pts)[0] == 0
    folded = pts.copy()
    folded[:, 1] += 0.2 * np.sin(6 * folded[:, 0])
    assert c.self_pairs(folded)[0] == 0
    with pytest.raises(ValueError, match="vertex 3 is not finite"):
        bad = pts.copy()
        bad[3, 0] = np.nan
        c.self_pairs(bad)


def test_fold_across_one_strip_keeps_neighbour_triangle_contacts():
    """A 4 x 3-vertex strip (edge 0.05 m) folded flat about its second vertex column, the far
    layer 4 mm above the near one (below the 10 mm thickness) and shifted by a third of an edge
    in both directions: vertex (column 0, row 1) now lies 4 mm under the inside of a triangle of
    columns 1-2, which holds its edge neighbour and was 0.05 m from it at rest, while every vertex
    of that triangle stays over a third of an edge away from it. The contact must be found (a
    vertex-distance filter cannot see such a fold), and none with a triangle of the vertex's own
    one ring."""
    h, gap = 0.05, 0.004
    b = ClothBuilder(thickness=0.01)
    ids = b.add_grid(4, 3, 3 * h, 2 * h)
    m = b.finalize()
    rest = m.rest_points.numpy()
    x = rest.copy()
    u = rest[:, 0] / h  # column coordinate 0..3
    # fold about column 1: columns 2, 3 are mirrored back over columns 0, 1 (cloth bent by 180 deg)
    far = u > 1.5
    x[far, 0] = 2 * h - rest[far, 0] - h / 3
    x[far, 1] = gap
    x[far, 2] += h / 3
    st = m.state()
    st.set_points(x)
    s = XPBDSolver(m, None, guard=False)
    s._detect_self_contacts(st.points, st.velocities, DT / s.substeps)
    i = int(ids[1, 0])  # ids[row, column]
    tris = m.tris.numpy()
    found = {int(t) for t in s._vt_rows["ids"].numpy()[i, :int(s._contact_count.numpy()[i])]}
    over = {t for t in range(len(tris)) if set(tris[t]) <= {int(v) for v in ids[:, 1:3].ravel()}}
    # the configuration is the one meant: some triangle of `over` has vertex i under its inside
    # and all its corners further than a third of an edge from it
    e = m.edges_np
    ring = set(e[e[:, 0] == i, 1]) | set(e[e[:, 1] == i, 0])
    under = [t for t in over if ring & set(tris[t]) and np.all(np.linalg.norm(x[tris[t]] - x[i], axis=1) > h / 3)
             and np.all(np.linalg.solve(np.c_[(x[tris[t]][:, [0, 2]]), np.ones(3)].T, np.r_[x[i, [0, 2]], 1.0]) > 0)]
    assert under, "test set-up: no triangle of columns 1-2 lies over the vertex"
    assert set(under) & found, (found, under)
    own = {t for t in range(len(tris)) if i in tris[t]}
    assert not (own & found)


def _stack(layers: int, gap: float):
    """`layers` 3 x 3-vertex sheets (0.1 m square) stacked `gap` apart along y, at rest."""
    b = ClothBuilder(thickness=0.01)
    ids = [b.add_grid(3, 3, 0.1, 0.1, origin=(0.0, k * gap, 0.0)) for k in range(layers)]
    return b.finalize(), ids


def _vertex_triangle_distance(x, tris, i, t) -> float:
    """Distance [m] from vertex i to triangle t, by dense barycentric sampling (a NumPy oracle
    accurate to 1e-6 m for these 0.1 m triangles, far below the 1 mm gaps compared)."""
    a, b, c = x[tris[t]]
    s, r = np.meshgrid(np.linspace(0, 1, 201), np.linspace(0, 1, 201))
    keep = s + r <= 1
    p = a + (b - a) * s[keep][:, None] + (c - a) * r[keep][:, None]
    return float(np.linalg.norm(p - x[i], axis=1).min())


def test_contact_rows_grow_until_no_candidate_is_dropped():
    """Nine sheets 1 mm apart (thickness 10 mm): the centre vertex of the bottom sheet has every
    triangle of the eight sheets above within 8 mm, inside the candidate search (boxes padded by
    half a thickness each side) and the 15 mm candidate distance: 64 candidates, over the rows'
    starting width. The rows grow and the detection is repeated: all of them are kept, none is
    counted as dropped."""
    m, ids = _stack(9, 0.001)
    st = m.state()
    s = XPBDSolver(m, None, guard=False, edge_contact=False)
    s._detect_self_contacts(st.points, st.velocities, DT / s.substeps)
    i = int(ids[0][1, 1])
    found = set(s._vt_rows["ids"].numpy()[i, :int(s._contact_count.numpy()[i])].tolist())
    tris = m.tris.numpy()
    above = {t for t in range(len(tris)) if tris[t][0] >= 9}
    assert len(above) > XPBDSolver.CONTACT_ROW_START
    assert found == above
    assert s.stats()["self_contact_overflow"] == 0
    assert s.stats()["self_contact_row_width"] >= len(above)


def test_full_contact_rows_keep_the_nearest_candidates():
    """The same stack with max_contacts=4: the centre vertex keeps the four nearest of its
    candidates (distances from a NumPy oracle; the four nearest are the triangles of the first
    sheet above, 1 mm away, against 2 mm and more for the rest) and counts the rest as dropped."""
    m, ids = _stack(9, 0.001)
    st = m.state()
    s = XPBDSolver(m, None, guard=False, edge_contact=False, max_contacts=4)
    s._detect_self_contacts(st.points, st.velocities, DT / s.substeps)
    i = int(ids[0][1, 1])
    found = s._vt_rows["ids"].numpy()[i, :int(s._contact_count.numpy()[i])].tolist()
    x, tris = m.rest_points.numpy(), m.tris.numpy()
    cand = [t for t in range(len(tris)) if tris[t][0] >= 9]
    dist = {t: _vertex_triangle_distance(x, tris, i, t) for t in cand}
    assert len(found) == 4
    nearest = max(dist[t] for t in found)
    assert nearest < 0.0011, dist
    assert all(dist[t] >= nearest - 1e-6 for t in cand if t not in found)
    assert s.stats()["self_contact_overflow"] > 0


def _split_face_box(half: float, n: int = 3, gap: float = 0.0):
    """A cube of side 2 half centred at 0 as a DCC exports it with per-face normals: each face an
    n x n-vertex grid of its own (corners and rims duplicated, not shared), each face moved `gap`
    outwards along its normal."""
    pts, faces = [], []
    g = np.linspace(-half, half, n)
    for axis in range(3):
        for sign in (-1.0, 1.0):
            u, v = [a for a in range(3) if a != axis]
            base = len(pts)
            for j in range(n):
                for i in range(n):
                    p = np.zeros(3)
                    p[axis], p[u], p[v] = sign * (half + gap), g[i], g[j]
                    pts.append(p)
            for j in range(n - 1):
                for i in range(n - 1):
                    a, b, c, d = (base + j * n + i, base + j * n + i + 1, base + (j + 1) * n + i + 1,
                                  base + (j + 1) * n + i)
                    # outward winding: (u x v) points along +axis for the cyclic order of axes
                    out = np.cross(np.eye(3)[u], np.eye(3)[v])[axis] * sign > 0
                    faces += [[a, b, c], [a, c, d]] if out else [[a, c, b], [a, d, c]]
    return np.array(pts, np.float32), np.array(faces, np.int32)


def test_split_face_box_is_a_closed_solid_with_sharp_rims():
    """Welded by position, a box whose faces have their own vertices is closed and each of its
    12 rims is an edge between two faces; moved 1 mm apart, the faces are open sheets."""
    from warpshade.sim.colliders import MeshCollider

    pts, faces = _split_face_box(0.5)
    m = MeshCollider(pts, faces, 0.5, "cpu")
    assert m.closed
    ef = m.edge_faces.numpy()
    assert (ef[:, 1] >= 0).all()
    nrm = np.cross(pts[faces[:, 1]] - pts[faces[:, 0]], pts[faces[:, 2]] - pts[faces[:, 0]])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    sharp = np.einsum("ij,ij->i", nrm[ef[:, 0]], nrm[ef[:, 1]]) < 0.5
    assert sharp.sum() == 12 * 2  # 12 rims, each 2 edges long at 3 x 3 vertices per face
    apart = MeshCollider(*_split_face_box(0.5, gap=0.001), 0.5, "cpu")
    assert not apart.closed


def _cloth_quad(corners) -> tuple:
    b = ClothBuilder(thickness=0.01)
    c = np.asarray(corners, np.float64)
    b.add_grid(2, 2, 1.0, 1.0)
    m = b.finalize()
    # place the grid's four vertices (ids[j, i] = j * 2 + i) at the given corners
    m.rest_points.assign(wp.array(c.astype(np.float32), dtype=wp.vec3))
    return m, wp.array(c.astype(np.float32), dtype=wp.vec3)


def test_mesh_edges_do_not_lift_cloth_hanging_beside_a_split_face_box():
    """A cloth quad hanging 4 mm off the side of a split-face box (thickness 10 mm), 2-5 cm below
    the top rim, across the ends of the top face's inner edges: no collider edge is cut, so the
    edge pass moves nothing (it lifted such cloth 3-4 cm onto the top when rims counted as open
    borders and the top's flat inner edges as sharp ones). A quad folded over the rim, whose
    edges the rim cuts, is pushed out."""
    half, t = 0.5, 0.01
    col = ColliderSet()
    col.add_mesh(*_split_face_box(half))
    x_side = half + 0.4 * t
    hang, x = _cloth_quad([(x_side, half - 0.05, -0.2), (x_side, half - 0.05, 0.2),
                           (x_side, half - 0.02, -0.2), (x_side, half - 0.02, 0.2)])
    before = x.numpy().copy()
    col.collide_edges(t, hang.inv_mass, hang.edges, x)
    assert np.abs(x.numpy() - before).max() == 0.0
    fold, x = _cloth_quad([(half - 0.02, half + 0.4 * t, -0.2), (half - 0.02, half + 0.4 * t, 0.2),
                           (x_side, half - 0.02, -0.2), (x_side, half - 0.02, 0.2)])
    before = x.numpy().copy()
    col.collide_edges(t, fold.inv_mass, fold.edges, x)
    assert np.abs(x.numpy() - before).max() > 0.1 * t


def test_box_corner_poking_through_a_triangle_is_pushed_behind_it():
    """A cloth quad across a box's corner, perpendicular to its diagonal, the corner 2 mm through
    the inside of one triangle (all four cloth vertices outside the box: every in-plane
    direction from the corner leaves it). No cloth vertex or edge meets the box, so only the
    corner pass can see it: with the triangles given it pushes the triangle until the corner is
    a thickness behind it (within 1e-5 m: the projection is linear in the move, and the 1.2 cm
    uneven move of the three vertices tilts the triangle; measured 7.6e-6 m), without them
    nothing moves (to float32 rounding)."""
    half, t = 0.2, 0.01
    col = ColliderSet()
    col.add_box((0.0, 0.0, 0.0), (half, half, half))
    col.begin_step()
    col.pose_substep(0.0, 1.0)
    corner = np.full(3, half)
    n = np.ones(3) / np.sqrt(3.0)
    e1 = np.array([2.0, -1.0, -1.0]) / np.sqrt(6.0)
    e2 = np.cross(n, e1)
    c0 = corner - 0.002 * n + 0.05 * e1 + 0.02 * e2  # every cloth edge over a thickness from the box
    quad = [c0 + 0.1 * (i * e1 + j * e2) for j in (-1, 1) for i in (-1, 1)]
    assert all((np.abs(q) > half).any() for q in quad)  # the cloth vertices are outside
    for with_tris in (False, True):
        m, x = _cloth_quad(quad)
        col.collide_edges(t, m.inv_mass, m.edges, x, m.tris if with_tris else None)
        p = x.numpy().astype(np.float64)
        tri = [tr for tr in m.tris.numpy() if np.all(np.linalg.solve(
            np.c_[p[tr[1]] - p[tr[0]], p[tr[2]] - p[tr[0]], n], corner - p[tr[0]])[:2] > 0)
            and np.linalg.solve(np.c_[p[tr[1]] - p[tr[0]], p[tr[2]] - p[tr[0]], n], corner - p[tr[0]])[:2].sum() < 1]
        assert len(tri) == 1  # the corner lies over the inside of one triangle
        a, b, c = p[tri[0]]
        nn = np.cross(b - a, c - a)
        nn /= np.linalg.norm(nn) * np.sign(nn @ n)
        h = (corner - a) @ nn  # > 0: the corner is through the cloth
        if with_tris:
            assert abs(h + t) < 1e-5, h
        else:
            assert abs(h - 0.002) < 1e-6, h


def test_contact_launches_are_skipped_only_when_nothing_was_found():
    """With no self-contact candidate anywhere the solver skips the contact launches
    (XPBDSolver._contacts_found), which change nothing then. A sheet falling onto a pinned sheet
    (no candidate in its first frames, then contact) must end bit for bit where a solver that
    always launches them leaves it."""
    def build():
        b = ClothBuilder(thickness=0.01)
        low = b.add_grid(8, 8, 0.4, 0.4, origin=(0.0, 0.0, 0.0))
        b.pin([low[0, 0], low[0, -1], low[-1, 0], low[-1, -1]])
        b.add_grid(6, 6, 0.3, 0.3, origin=(0.05, 0.2, 0.05))
        return b.finalize()

    found = []

    class Spy(XPBDSolver):
        def _detect_self_contacts(self, *args):
            grew = super()._detect_self_contacts(*args)
            found.append(self._contacts_found)
            return grew

    class Always(XPBDSolver):
        def _detect_self_contacts(self, *args):
            grew = super()._detect_self_contacts(*args)
            self._contacts_found = True
            return grew

    states = []
    for cls in (Spy, Always):
        m = build()
        s = cls(m, None)
        a, b = m.state(), m.state()
        for _ in range(40):
            s.step(a, b, DT)
            a, b = b, a
        states.append((a.points.numpy().copy(), a.velocities.numpy().copy()))
    assert False in found[:4] and True in found  # both branches taken: free fall, then contact
    assert np.array_equal(states[0][0], states[1][0]) and np.array_equal(states[0][1], states[1][1])
    assert states[0][0][64:, 1].max() < 0.1  # the upper sheet came down onto the lower one


def test_grouped_vertex_triangle_queries_find_the_same_candidates():
    """The vertex-triangle detection's shared BVH queries (XPBDSolver.DETECTION_GROUP vertices a
    query) give the candidates, sides and order of one query a vertex: a sheet falling onto a
    pinned sheet steps bit for bit alike and fills the same contact rows at every detection with
    one query a vertex, with groups of 4 that always share a query (GROUP_SPAN unbounded) and
    groups of 4 that never do (GROUP_SPAN 0)."""
    def build():
        b = ClothBuilder(thickness=0.01)
        low = b.add_grid(8, 8, 0.4, 0.4, origin=(0.0, 0.0, 0.0))
        b.pin([low[0, 0], low[0, -1], low[-1, 0], low[-1, -1]])
        b.add_grid(7, 7, 0.3, 0.3, origin=(0.05, 0.15, 0.05))
        return b.finalize()

    runs = []
    for group, span in ((1, 0.0), (4, 1.0e9), (4, 0.0)):
        rows = []

        class Spy(XPBDSolver):
            DETECTION_GROUP = group
            GROUP_SPAN = span

            def _detect_self_contacts(self, *args):
                grew = super()._detect_self_contacts(*args)
                count = self._contact_count.numpy()
                ids, sides = self._vt_rows["ids"].numpy(), self._vt_rows["sides"].numpy()
                rows.append([(ids[i, :c].tolist(), sides[i, :c].tolist()) for i, c in enumerate(count)])
                return grew

        m = build()
        s = Spy(m, None)
        a, b = m.state(), m.state()
        for _ in range(40):
            s.step(a, b, DT)
            a, b = b, a
        runs.append((rows, a.points.numpy().copy(), a.velocities.numpy().copy()))
    assert XPBDSolver.DETECTION_GROUP > 1  # the default shares queries
    assert sum(len(r[0]) for r in runs[0][0][-1]) > 0  # the sheets are in contact at the end
    for rows, x, v in runs[1:]:
        assert rows == runs[0][0]
        assert np.array_equal(x, runs[0][1]) and np.array_equal(v, runs[0][2])


def test_sharp_corners_of_mesh_colliders():
    """Pointed convex vertices of closed meshes are corners: a 32-sided cone's apex (its faces'
    angles there sum to 134 degrees), a 4-sided pyramid's 5 (apex and base corners), a box's 8
    corners (270); not a cylinder's rims, any vertex of an icosahedron (300), an icosphere, a UV
    sphere or a capsule; none of an open sheet."""
    from warpshade.sim.colliders import MeshCollider, sharp_corners

    pyramid = trimesh.Trimesh([[0, 0, 0.3], [0.1, 0.1, 0], [-0.1, 0.1, 0], [-0.1, -0.1, 0], [0.1, -0.1, 0]],
                              [[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 1], [1, 3, 2], [1, 4, 3]])
    assert pyramid.is_watertight and pyramid.volume > 0
    cases = [(trimesh.creation.cone(0.12, 0.3, sections=32), 1), (pyramid, 5), (trimesh.creation.box((1, 1, 1)), 8),
             (trimesh.creation.cylinder(0.1, 0.5, sections=24), 0), (trimesh.creation.icosphere(0), 0),
             (trimesh.creation.icosphere(2), 0),
             (trimesh.creation.uv_sphere(0.5, count=[16, 16]), 0), (trimesh.creation.capsule(1.0, 0.2), 0)]
    for mesh, count in cases:
        assert len(sharp_corners(mesh.vertices, mesh.faces)[0]) == count
    cone = trimesh.creation.cone(0.12, 0.3, sections=32)
    apex = int(np.argmax(cone.vertices[:, 2]))
    assert apex in sharp_corners(cone.vertices, cone.faces)[0]
    sheet = MeshCollider(np.array([[0, 0, 0], [1, 0, 0], [0, 0, 1.0]]), np.array([[0, 1, 2]]), 0.5, "cpu")
    assert sheet.corner_vertices.shape[0] == 0


def _tent(peak, half: float = 0.04):
    """A 3 x 3-vertex cloth patch bent into a tent whose middle vertex (4) is at `peak`, its border
    0.03 m lower (a cloth falling onto a cone's apex)."""
    b = ClothBuilder(thickness=0.005)
    b.add_grid(3, 3, 2 * half, 2 * half)
    m = b.finalize()
    g = np.array([(i * half - half, j * half - half) for j in range(3) for i in range(3)])
    drop = np.where(np.abs(g).max(axis=1) > 0, 0.03, 0.0)
    p = np.c_[g[:, 0], g[:, 1], -drop] + np.asarray(peak, np.float64)
    return m, p


@pytest.mark.parametrize("where", ["vertex", "edge", "inside"])
def test_cone_apex_through_a_tent_is_pushed_back(where):
    """A cloth tent falling onto a cone's apex, caught 4 mm through it: at its peak vertex (the
    apex then lies beyond the inside of every triangle), at the middle of an edge from the peak
    (beyond the inside of both triangles on that edge) or under the inside of a triangle. The
    corner contacts, their sides found with the tent still above the apex, push the cloth back
    over it: within float rounding a thickness above it along the cloth's side there, and no
    pair with the cone is left."""
    t = 0.005
    apex = np.array([0.0, 0.0, 0.5])
    col = ColliderSet()
    col.add_cone((0.0, 0.0, 0.2), apex, 0.12)
    offset = {"vertex": (0.0, 0.0), "edge": (0.02, 0.0), "inside": (0.025, 0.01)}[where]
    m, p = _tent(apex + [-offset[0], -offset[1], 0.02])
    x = wp.array(p.astype(np.float32), dtype=wp.vec3)
    col.begin_step()
    col.detect_corner_contacts(x, wp.zeros_like(x), m.tris, 1.0 / 60.0, t)
    col.pose_substep(0.0, 1.0)
    through = p - [0.0, 0.0, 0.024]  # the surface over the apex 4 mm under it
    x.assign(through.astype(np.float32))
    counter = IntersectionCounter(m.faces)
    assert counter.collider_pairs(x, col)[0] > 0
    for _ in range(3):
        col.collide_corners(t, m.inv_mass, m.tris, x)
    out = x.numpy().astype(np.float64)
    assert counter.collider_pairs(out, col)[0] == 0
    q = trimesh.triangles.closest_point(out[m.faces], np.repeat(apex[None], len(m.faces), 0))
    d = np.linalg.norm(q - apex, axis=1)
    assert q[d.argmin(), 2] > apex[2] and d.min() > 0.9 * t, (q[d.argmin()] - apex, d.min())


def test_edges_turning_past_parallel_in_contact_are_not_pulled_through():
    """Two knife edges crossing 9 mm apart (thickness 10 mm): a pinned triangle hanging below
    edge ab (along x, 40 mm) and a free triangle standing on edge cd (100 mm) above it, cd
    turned by 0.05 rad about the vertical through the crossing and spinning back at a rate
    that makes it parallel to ab 1.5 substeps later (1 substep per step, no gravity, no air, the
    guard off so that the contact solve alone is seen). Turning past parallel flips the pair's
    orientation sign with cd still 9 mm above ab and the closest points inside both edges:
    nothing crossed, so with ``follow_edge_sides`` cd must stay above ab (a side kept across the
    flip, as without it, pulls cd down through ab, 17 mm in one step, and the triangles
    intersect)."""
    t, gap, theta = 0.01, 0.009, 0.05
    h = 1.0 / 180.0
    b = ClothBuilder(thickness=t)
    a_ids = b.add_mesh(np.array([[-0.02, 0, 0], [0.02, 0, 0], [0, -0.05, 0]]), np.array([[0, 1, 2]]), name="A")
    c, s = np.cos(theta), np.sin(theta)
    b_ids = b.add_mesh(np.array([[-0.05 * c, gap, -0.05 * s], [0.05 * c, gap, 0.05 * s], [0, gap + 0.05, 0]]),
                       np.array([[0, 1, 2]]), name="B")
    b.pin(a_ids)
    m = b.finalize()
    solver = XPBDSolver(m, None, substeps=1, gravity=(0, 0, 0), air_density=0.0, guard=False,
                        follow_edge_sides=True)
    x = m.rest_points.numpy().astype(np.float64)
    v = np.zeros_like(x)
    omega = theta / (1.5 * h)  # about +y, turning cd's angle atan2(dz, dx) down through 0
    v[b_ids] = np.cross([0.0, omega, 0.0], x[b_ids] - [0.0, gap, 0.0])
    st, out = m.state(), m.state()
    st.set_points(x.astype(np.float32), v.astype(np.float32))
    counter = IntersectionCounter(m.faces)
    for _ in range(4):
        solver.step(st, out, h)
        st, out = out, st
        p = st.points.numpy()
        # ab lies on y = 0 (pinned); cd's middle stays over it on the +y side, at least the 9 mm
        # it started at less the 1 mm a thickness' push can leave unfinished
        assert 0.5 * (p[b_ids[0], 1] + p[b_ids[1], 1]) > gap - 0.001, p[b_ids]
        assert counter.self_pairs(st.points)[0] == 0
    # the set-up is the one meant: cd did turn past parallel
    assert np.arctan2(p[b_ids[1], 2] - p[b_ids[0], 2], p[b_ids[1], 0] - p[b_ids[0], 0]) < 0


@wp.kernel
def _segments_cross_kernel(p0: wp.array2d[wp.vec3], p1: wp.array2d[wp.vec3], tol: float, out: wp.array[int]):
    i = wp.tid()
    out[i] = int(segments_cross(p0[i, 0], p0[i, 1], p0[i, 2], p0[i, 3], p1[i, 0], p1[i, 1], p1[i, 2], p1[i, 3], tol))


def _rotated(theta: float, y: float) -> list:
    """Edge cd of length 0.1 m at height y, turned by theta about the vertical through its middle."""
    c, s = np.cos(theta), np.sin(theta)
    return [[-0.05 * c, y, -0.05 * s], [0.05 * c, y, 0.05 * s]]


@pytest.mark.parametrize("name, start, end, crossed", [
    # ab along x on y = 0; cd crossing over it at 5 mm drops to 5 mm under it: passes through
    ("through", [[-0.05, 0, 0], [0.05, 0, 0]] + _rotated(1.0, 0.005),
     [[-0.05, 0, 0], [0.05, 0, 0]] + _rotated(1.0, -0.005), True),
    # cd 5 mm above ab turns from +0.1 to -0.1 rad: parallel (and coplanar) halfway, 5 mm apart
    ("past parallel", [[-0.05, 0, 0], [0.05, 0, 0]] + _rotated(0.1, 0.005),
     [[-0.05, 0, 0], [0.05, 0, 0]] + _rotated(-0.1, 0.005), False),
    # ab short (x in [-0.02, 0.02]); cd, at x = 0.04 (beyond b) and across it, drops from 5 mm above
    # to 5 mm below ab's line: the lines pass through each other 20 mm beyond b
    ("beside an end", [[-0.02, 0, 0], [0.02, 0, 0], [0.04, 0.005, -0.05], [0.04, 0.005, 0.05]],
     [[-0.02, 0, 0], [0.02, 0, 0], [0.04, -0.005, -0.05], [0.04, -0.005, 0.05]], False),
])
def test_segments_cross_over_a_linear_motion(name, start, end, crossed):
    """Continuous edge-edge crossing test (the stored side of an edge contact follows a sign flip
    without a crossing): expected outcomes from the constructions, tolerance 10 um."""
    p0 = wp.array(np.array([start], np.float32), dtype=wp.vec3)
    p1 = wp.array(np.array([end], np.float32), dtype=wp.vec3)
    out = wp.zeros(1, dtype=int)
    wp.launch(_segments_cross_kernel, dim=1, inputs=[p0, p1, 1.0e-5], outputs=[out])
    assert bool(out.numpy()[0]) == crossed
