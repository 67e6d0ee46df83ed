"""Warp kernels of the penetration-free self-contact: edge-edge contacts, the velocity filter and
per-vertex motion bounds (orchestrated by :mod:`warpshade.sim.solver_xpbd`).

Motion bounds (after Offset Geometric Contact, Chen et al. 2025, and VBD, Chen et al. 2024,
taken relative to each vertex's inertial motion): at every detection, for every candidate pair
(vertex-triangle or edge-edge, i.e. swept boxes that overlap) at distance D whose vertices'
relative motion over the interval H is at most c = max |v_i - v_k| H, each vertex of the pair may
deviate from its inertial path x0 + v tau by at most b = gamma (D - c), gamma < 1/2. The
relative displacement of any two points of the pair then stays below c + 2 b < D, so the pair
cannot meet; pairs whose boxes do not overlap cannot meet either, because every vertex is also
kept in its own swept box. Pairs predicted to close (c > beta D) first get an inelastic velocity
filter (Bridson et al. 2002) that removes the part of their relative velocity beyond beta D / H.
"""

from __future__ import annotations

import warp as wp

from .kernels import closest_on_triangle, dihedral_angle

# ---------------------------------------------------------------------------------------------
# Geometry
# ---------------------------------------------------------------------------------------------


@wp.func
def closest_segments(p1: wp.vec3, q1: wp.vec3, p2: wp.vec3, q2: wp.vec3) -> wp.vec2:
    """Parameters (s, t) in [0, 1] of the closest points p1 + s (q1 - p1), p2 + t (q2 - p2) (Ericson 5.1.9)."""
    d1 = q1 - p1
    d2 = q2 - p2
    r = p1 - p2
    a = wp.dot(d1, d1)
    e = wp.dot(d2, d2)
    f = wp.dot(d2, r)
    s = float(0.0)
    t = float(0.0)
    if a <= 1.0e-20 and e <= 1.0e-20:
        return wp.vec2(0.0, 0.0)
    if a <= 1.0e-20:
        t = wp.clamp(f / e, 0.0, 1.0)
    else:
        c = wp.dot(d1, r)
        if e <= 1.0e-20:
            s = wp.clamp(-c / a, 0.0, 1.0)
        else:
            b = wp.dot(d1, d2)
            den = a * e - b * b
            if den > 1.0e-12 * a * e:
                s = wp.clamp((b * f - c * e) / den, 0.0, 1.0)
            t = (b * s + f) / e
            if t < 0.0:
                t = 0.0
                s = wp.clamp(-c / a, 0.0, 1.0)
            elif t > 1.0:
                t = 1.0
                s = wp.clamp((b - c) / a, 0.0, 1.0)
    return wp.vec2(s, t)


@wp.func
def edge_orientation(a: wp.vec3, b: wp.vec3, c: wp.vec3, d: wp.vec3) -> float:
    """Sign of det[b - a, d - c, c - a] scaled: which side of edge ab edge cd passes (0 if parallel)."""
    n = wp.cross(b - a, d - c)
    ln = wp.length(n)
    if ln < 1.0e-12:
        return 0.0
    s = wp.dot(n, c - a)
    if s > 0.0:
        return 1.0
    if s < 0.0:
        return -1.0
    return 0.0


# ---------------------------------------------------------------------------------------------
# Edge-edge self-contact
# ---------------------------------------------------------------------------------------------


@wp.kernel
def compute_edge_bounds(
    x: wp.array[wp.vec3],
    v: wp.array[wp.vec3],
    edges: wp.array2d[int],
    horizon: float,
    pad: wp.array[float],
    lower: wp.array[wp.vec3],
    upper: wp.array[wp.vec3],
):
    """Box around an edge now and after `horizon` seconds of its current velocity, each end
    padded by its own pad."""
    e = wp.tid()
    p0 = x[edges[e, 0]]
    p1 = x[edges[e, 1]]
    q0 = p0 + v[edges[e, 0]] * horizon
    q1 = p1 + v[edges[e, 1]] * horizon
    r0 = wp.vec3(pad[edges[e, 0]])
    r1 = wp.vec3(pad[edges[e, 1]])
    lower[e] = wp.min(wp.min(p0, q0) - r0, wp.min(p1, q1) - r1)
    upper[e] = wp.max(wp.max(p0, q0) + r0, wp.max(p1, q1) + r1)


@wp.kernel
def mark_crease_edges(
    x: wp.array[wp.vec3],
    hinges: wp.array2d[int],
    hinge_edge: wp.array[int],
    min_angle: float,
    active: wp.array[int],
):
    """active[edge] = 1 for the shared edge of every hinge bent by more than min_angle [rad]
    (a fold's crease: with the border, where edge-edge contact can happen without a vertex
    meeting a triangle first)."""
    h = wp.tid()
    theta = dihedral_angle(x[hinges[h, 0]], x[hinges[h, 1]], x[hinges[h, 2]], x[hinges[h, 3]])
    if wp.abs(theta) > min_angle:
        active[hinge_edge[h]] = 1


@wp.kernel
def find_edge_contacts(
    bvh: wp.uint64,
    x: wp.array[wp.vec3],
    v: wp.array[wp.vec3],
    horizon: float,
    edges: wp.array2d[int],
    active: wp.array[int],
    ring_offsets: wp.array[int],
    ring: wp.array[int],
    lower: wp.array[wp.vec3],
    upper: wp.array[wp.vec3],
    thickness: float,
    keep_all: int,
    max_contacts: int,
    prev_edge: wp.array2d[int],
    prev_side: wp.array2d[float],
    prev_count: wp.array[int],
    contact_edge: wp.array2d[int],
    contact_side: wp.array2d[float],
    contact_count: wp.array[int],
    overflow: wp.array[int],
):
    """Edge-edge candidates (e, f) of the active edges e (borders and creases, against every
    edge f; a pair of two active edges is kept once, f > e) whose swept boxes overlap and (unless ``keep_all``) that
    may come within 1.5 thicknesses (as :func:`warpshade.sim.kernels.find_self_contacts`); edges
    sharing a vertex are skipped. The side (orientation sign of the edge pair) is stored,
    kept from the previous detection while the pair is in contact."""
    e = wp.tid()
    if active[e] == 0:
        contact_count[e] = 0
        return
    i0 = edges[e, 0]
    i1 = edges[e, 1]
    count = int(0)
    query = wp.bvh_query_aabb(bvh, lower[e], upper[e])
    f = int(0)
    while wp.bvh_query_next(query, f):
        if f <= e and active[f] != 0:
            continue  # the pair is found from f
        j0 = edges[f, 0]
        j1 = edges[f, 1]
        if i0 == j0 or i0 == j1 or i1 == j0 or i1 == j1:
            continue
        a = x[i0]
        b = x[i1]
        c = x[j0]
        d = x[j1]
        st = closest_segments(a, b, c, d)
        dist = wp.length((a + (b - a) * st[0]) - (c + (d - c) * st[1]))
        if keep_all == 0:
            close = wp.max(pair_closure(v, i0, j0, j1, -1, horizon), pair_closure(v, i1, j0, j1, -1, horizon))
            if dist > 1.5 * (thickness + close):
                continue
        if count < max_contacts:
            side = edge_orientation(a, b, c, d)
            if dist < thickness:
                for r in range(prev_count[e]):
                    if prev_edge[e, r] == f and prev_side[e, r] != 0.0:
                        side = prev_side[e, r]
            contact_edge[e, count] = f
            contact_side[e, count] = side
            count += 1
        else:
            wp.atomic_add(overflow, 0, 1)
    contact_count[e] = count


@wp.kernel
def solve_edge_contacts(
    x: wp.array[wp.vec3],
    x_prev: wp.array[wp.vec3],
    inv_mass: wp.array[float],
    edges: wp.array2d[int],
    contact_edge: wp.array2d[int],
    contact_side: wp.array2d[float],
    contact_count: wp.array[int],
    thickness: float,
    friction: float,
    delta: wp.array[wp.vec3],
    delta_count: wp.array[float],
):
    """Edge-edge separation: the closest points of two edges (both strictly inside their edges)
    are kept `thickness` apart along the edges' common normal, on the stored side, with
    position-based Coulomb friction on their relative tangential motion over the substep."""
    e = wp.tid()
    i0 = edges[e, 0]
    i1 = edges[e, 1]
    for k in range(contact_count[e]):
        f = contact_edge[e, k]
        s0 = contact_side[e, k]
        j0 = edges[f, 0]
        j1 = edges[f, 1]
        a = x[i0]
        b = x[i1]
        c = x[j0]
        d = x[j1]
        st = closest_segments(a, b, c, d)
        s = st[0]
        t = st[1]
        if s <= 0.0 or s >= 1.0 or t <= 0.0 or t >= 1.0:
            continue  # an endpoint is closest: vertex-triangle contacts hold it
        nn = wp.cross(b - a, d - c)
        ln = wp.length(nn)
        if ln < 1.0e-9 * wp.length(b - a) * wp.length(d - c):
            continue
        n = nn / ln
        side = s0
        if side == 0.0:
            side = edge_orientation(a, b, c, d)
            if side == 0.0:
                continue
            contact_side[e, k] = side
        # side > 0: edge cd lies on the +n side of edge ab
        p = a + (b - a) * s
        q = c + (d - c) * t
        gap = side * wp.dot(q - p, n)
        if gap >= thickness or gap < -4.0 * thickness:
            continue
        wa = inv_mass[i0] * (1.0 - s)
        wb = inv_mass[i1] * s
        wc = inv_mass[j0] * (1.0 - t)
        wd = inv_mass[j1] * t
        denom = wa * (1.0 - s) + wb * s + wc * (1.0 - t) + wd * t
        if denom == 0.0:
            continue
        depth = thickness - gap
        lam = depth / denom
        g = n * (side * lam)
        # friction: relative tangential displacement of the two closest points over the substep
        pp = x_prev[i0] * (1.0 - s) + x_prev[i1] * s
        qp = x_prev[j0] * (1.0 - t) + x_prev[j1] * t
        rel = (q - qp) - (p - pp)
        rt = rel - n * wp.dot(rel, n)
        lt = wp.length(rt)
        ft = wp.vec3(0.0)
        if lt > 0.0:
            ft = rt * (wp.min(1.0, friction * depth / lt) / denom)
        wp.atomic_add(delta, i0, (-g + ft) * wa)
        wp.atomic_add(delta, i1, (-g + ft) * wb)
        wp.atomic_add(delta, j0, (g - ft) * wc)
        wp.atomic_add(delta, j1, (g - ft) * wd)
        wp.atomic_add(delta_count, i0, 1.0)
        wp.atomic_add(delta_count, i1, 1.0)
        wp.atomic_add(delta_count, j0, 1.0)
        wp.atomic_add(delta_count, j1, 1.0)


# ---------------------------------------------------------------------------------------------
# Velocity filter and motion bounds
# ---------------------------------------------------------------------------------------------


@wp.func
def pair_closure(v: wp.array[wp.vec3], i: int, a: int, b: int, c: int, horizon: float) -> float:
    """Upper bound of the relative motion of vertex i and triangle (or edge, c = -1) abc over horizon."""
    vi = v[i]
    m = wp.max(wp.length(vi - v[a]), wp.length(vi - v[b]))
    if c >= 0:
        m = wp.max(m, wp.length(vi - v[c]))
    return m * horizon


@wp.func
def filter_pair(v: wp.array[wp.vec3], inv_mass: wp.array[float], i: int, k: int, dist: float, beta: float,
                horizon: float, dv: wp.array[wp.vec3], dv_count: wp.array[float]):
    """Remove the part of the relative velocity of vertices i, k beyond beta dist / horizon."""
    r = v[i] - v[k]
    lr = wp.length(r) * horizon
    allowed = beta * dist
    wi = inv_mass[i]
    wk = inv_mass[k]
    if lr > allowed and wi + wk > 0.0:
        f = 1.0 - allowed / lr
        wp.atomic_add(dv, i, -r * (f * wi / (wi + wk)))
        wp.atomic_add(dv, k, r * (f * wk / (wi + wk)))
        wp.atomic_add(dv_count, i, 1.0)
        wp.atomic_add(dv_count, k, 1.0)


@wp.kernel
def filter_vertex_triangle(
    x: wp.array[wp.vec3],
    v: wp.array[wp.vec3],
    inv_mass: wp.array[float],
    tris: wp.array2d[int],
    contact_tri: wp.array2d[int],
    contact_count: wp.array[int],
    beta: float,
    horizon: float,
    dv: wp.array[wp.vec3],
    dv_count: wp.array[float],
):
    """Velocity filter over the vertex-triangle candidates of vertex i."""
    i = wp.tid()
    p = x[i]
    for k in range(contact_count[i]):
        t = contact_tri[i, k]
        a = tris[t, 0]
        b = tris[t, 1]
        c = tris[t, 2]
        bc = closest_on_triangle(p, x[a], x[b], x[c])
        dist = wp.length(p - (x[a] * bc[0] + x[b] * bc[1] + x[c] * bc[2]))
        if pair_closure(v, i, a, b, c, horizon) > beta * dist:
            filter_pair(v, inv_mass, i, a, dist, beta, horizon, dv, dv_count)
            filter_pair(v, inv_mass, i, b, dist, beta, horizon, dv, dv_count)
            filter_pair(v, inv_mass, i, c, dist, beta, horizon, dv, dv_count)


@wp.kernel
def filter_edge_edge(
    x: wp.array[wp.vec3],
    v: wp.array[wp.vec3],
    inv_mass: wp.array[float],
    edges: wp.array2d[int],
    contact_edge: wp.array2d[int],
    contact_count: wp.array[int],
    beta: float,
    horizon: float,
    dv: wp.array[wp.vec3],
    dv_count: wp.array[float],
):
    """Velocity filter over the edge-edge candidates of edge e."""
    e = wp.tid()
    i0 = edges[e, 0]
    i1 = edges[e, 1]
    for k in range(contact_count[e]):
        f = contact_edge[e, k]
        j0 = edges[f, 0]
        j1 = edges[f, 1]
        st = closest_segments(x[i0], x[i1], x[j0], x[j1])
        dist = wp.length((x[i0] + (x[i1] - x[i0]) * st[0]) - (x[j0] + (x[j1] - x[j0]) * st[1]))
        close = wp.max(pair_closure(v, i0, j0, j1, -1, horizon), pair_closure(v, i1, j0, j1, -1, horizon))
        if close > beta * dist:
            filter_pair(v, inv_mass, i0, j0, dist, beta, horizon, dv, dv_count)
            filter_pair(v, inv_mass, i0, j1, dist, beta, horizon, dv, dv_count)
            filter_pair(v, inv_mass, i1, j0, dist, beta, horizon, dv, dv_count)
            filter_pair(v, inv_mass, i1, j1, dist, beta, horizon, dv, dv_count)


@wp.kernel
def apply_velocity_filter(
    v_start: wp.array[wp.vec3],
    pad: wp.array[float],
    horizon: float,
    dv: wp.array[wp.vec3],
    dv_count: wp.array[float],
    v: wp.array[wp.vec3],
):
    """v += dv / count (Jacobi average of the filter's corrections), then clear them. The total
    change stays below pad / horizon, so the filtered inertial path stays in the swept box."""
    i = wp.tid()
    n = dv_count[i]
    if n > 0.0:
        nv = v[i] + dv[i] / n
        ch = nv - v_start[i]
        lim = pad[i] / horizon
        lc = wp.length(ch)
        if lc > lim:
            nv = v_start[i] + ch * (lim / lc)
        v[i] = nv
        dv[i] = wp.vec3(0.0)
        dv_count[i] = 0.0


@wp.kernel
def bound_vertex_triangle(
    x: wp.array[wp.vec3],
    v: wp.array[wp.vec3],
    tris: wp.array2d[int],
    contact_tri: wp.array2d[int],
    contact_count: wp.array[int],
    gamma: float,
    horizon: float,
    bound: wp.array[float],
    unresolved: wp.array[int],
):
    """bound[k] = min(bound[k], gamma (D - c)) over vertex i and the corners of its candidates;
    unresolved[0] counts pairs predicted to close by more than 90 % of their distance."""
    i = wp.tid()
    p = x[i]
    for k in range(contact_count[i]):
        t = contact_tri[i, k]
        a = tris[t, 0]
        b = tris[t, 1]
        c = tris[t, 2]
        bc = closest_on_triangle(p, x[a], x[b], x[c])
        dist = wp.length(p - (x[a] * bc[0] + x[b] * bc[1] + x[c] * bc[2]))
        close = pair_closure(v, i, a, b, c, horizon)
        if close > 0.9 * dist:
            wp.atomic_add(unresolved, 0, 1)
        lim = gamma * wp.max(dist - close, 0.0)
        wp.atomic_min(bound, i, lim)
        wp.atomic_min(bound, a, lim)
        wp.atomic_min(bound, b, lim)
        wp.atomic_min(bound, c, lim)


@wp.kernel
def bound_edge_edge(
    x: wp.array[wp.vec3],
    v: wp.array[wp.vec3],
    edges: wp.array2d[int],
    contact_edge: wp.array2d[int],
    contact_count: wp.array[int],
    gamma: float,
    horizon: float,
    bound: wp.array[float],
    unresolved: wp.array[int],
):
    """bound[k] = min(bound[k], gamma (D - c)) over the four endpoints of every edge-edge candidate
    (unresolved as in :func:`bound_vertex_triangle`)."""
    e = wp.tid()
    i0 = edges[e, 0]
    i1 = edges[e, 1]
    for k in range(contact_count[e]):
        f = contact_edge[e, k]
        j0 = edges[f, 0]
        j1 = edges[f, 1]
        st = closest_segments(x[i0], x[i1], x[j0], x[j1])
        dist = wp.length((x[i0] + (x[i1] - x[i0]) * st[0]) - (x[j0] + (x[j1] - x[j0]) * st[1]))
        close = wp.max(pair_closure(v, i0, j0, j1, -1, horizon), pair_closure(v, i1, j0, j1, -1, horizon))
        if close > 0.9 * dist:
            wp.atomic_add(unresolved, 0, 1)
        lim = gamma * wp.max(dist - close, 0.0)
        wp.atomic_min(bound, i0, lim)
        wp.atomic_min(bound, i1, lim)
        wp.atomic_min(bound, j0, lim)
        wp.atomic_min(bound, j1, lim)


@wp.kernel
def vertex_pads(
    v: wp.array[wp.vec3],
    v_start: wp.array[wp.vec3],
    base: float,
    horizon: float,
    pad: wp.array[float],
    cut: wp.array[float],
):
    """Swept-box pad of each vertex: base, plus the deviation from its inertial path that its last
    velocity change repeated over `horizon` would give, plus twice what its box cut off in the
    last interval (a vertex its box held back gets room to catch up); the cut is then cleared."""
    i = wp.tid()
    pad[i] = base + wp.length(v[i] - v_start[i]) * horizon + 2.0 * cut[i]
    cut[i] = 0.0


@wp.kernel
def start_bounds(
    x: wp.array[wp.vec3],
    v: wp.array[wp.vec3],
    horizon: float,
    pad: wp.array[float],
    x_start: wp.array[wp.vec3],
    v_start: wp.array[wp.vec3],
    lower: wp.array[wp.vec3],
    upper: wp.array[wp.vec3],
    bound: wp.array[float],
):
    """Record each vertex's start, inertial velocity and swept box; bounds start unlimited."""
    i = wp.tid()
    p = x[i]
    q = p + v[i] * horizon
    x_start[i] = p
    v_start[i] = v[i]
    lower[i] = wp.min(p, q) - wp.vec3(pad[i])
    upper[i] = wp.max(p, q) + wp.vec3(pad[i])
    bound[i] = 1.0e30


@wp.kernel
def reset_bounds(bound: wp.array[float], v_start: wp.array[wp.vec3]):
    """Unlimited bounds around a standing reference (the fallback frame)."""
    i = wp.tid()
    bound[i] = 1.0e30
    v_start[i] = wp.vec3(0.0)


@wp.kernel
def clamp_motion(
    x_start: wp.array[wp.vec3],
    v_start: wp.array[wp.vec3],
    lower: wp.array[wp.vec3],
    upper: wp.array[wp.vec3],
    bound: wp.array[float],
    inv_mass: wp.array[float],
    elapsed: float,
    x: wp.array[wp.vec3],
    cut: wp.array[float],
):
    """Keep each free vertex within `bound` of its inertial path x0 + v0 elapsed, then in its
    swept box (which contains x0, so the second projection cannot leave the first's ball when the
    path is in the box); cut records the largest box correction of the interval."""
    i = wp.tid()
    if inv_mass[i] == 0.0:
        return
    ref = x_start[i] + v_start[i] * elapsed
    d = x[i] - ref
    ld = wp.length(d)
    b = bound[i]
    p = x[i]
    if ld > b:
        p = ref + d * (b / ld)
    q = wp.min(wp.max(p, lower[i]), upper[i])
    cut[i] = wp.max(cut[i], wp.length(q - p))
    x[i] = q
