"""Warp kernels of the XPBD cloth solver (orchestrated by :mod:`warpshade.sim.solver_xpbd`).

Method: extended position-based dynamics (XPBD, Macklin, Müller & Chentanez 2016) in the
small-steps regime (Macklin et al. 2019): many substeps with one Gauss-Seidel sweep each. Stretch
and bending constraints are graph-coloured so that each launch updates disjoint vertices in place
(Gauss-Seidel on every device, no atomics); contacts are solved Jacobi-style with averaged
corrections (Macklin et al. 2014, "Unified particle physics", §4.2).

Conventions: positions in metres, velocities in m/s, ``inv_mass`` in 1/kg (0 = kinematic).
The per-substep kernels take their index tuples as one-dimensional arrays of vectors (``vec2i``
edges, ``vec3i`` triangles, ``vec4i`` hinges: zero-copy views of the model's (n, k) arrays): on
the CPU, Warp runs a kernel whose arrays are all one-dimensional without the per-thread index
division and stride arithmetic of the general path.
"""

from __future__ import annotations

import warp as wp

wp.set_module_options({"enable_backward": False})

# ---------------------------------------------------------------------------------------------
# Small geometric helpers
# ---------------------------------------------------------------------------------------------


@wp.func
def edge_axis(xi: wp.vec3, xj: wp.vec3) -> wp.vec4:
    """Unit direction from xj to xi and the edge length: vec4(nx, ny, nz, length); zero when degenerate."""
    d = xi - xj
    length = wp.length(d)
    if length < 1.0e-12:
        return wp.vec4(0.0)
    n = d / length
    return wp.vec4(n[0], n[1], n[2], length)


@wp.func
def closest_on_triangle(p: wp.vec3, a: wp.vec3, b: wp.vec3, c: wp.vec3) -> wp.vec3:
    """Barycentric coordinates (u, v, w) of the point of triangle abc closest to p (Ericson 5.1.5)."""
    ab = b - a
    ac = c - a
    ap = p - a
    d1 = wp.dot(ab, ap)
    d2 = wp.dot(ac, ap)
    if d1 <= 0.0 and d2 <= 0.0:
        return wp.vec3(1.0, 0.0, 0.0)
    bp = p - b
    d3 = wp.dot(ab, bp)
    d4 = wp.dot(ac, bp)
    if d3 >= 0.0 and d4 <= d3:
        return wp.vec3(0.0, 1.0, 0.0)
    vc = d1 * d4 - d3 * d2
    if vc <= 0.0 and d1 >= 0.0 and d3 <= 0.0:
        t = d1 / (d1 - d3)
        return wp.vec3(1.0 - t, t, 0.0)
    cp = p - c
    d5 = wp.dot(ab, cp)
    d6 = wp.dot(ac, cp)
    if d6 >= 0.0 and d5 <= d6:
        return wp.vec3(0.0, 0.0, 1.0)
    vb = d5 * d2 - d1 * d6
    if vb <= 0.0 and d2 >= 0.0 and d6 <= 0.0:
        t = d2 / (d2 - d6)
        return wp.vec3(1.0 - t, 0.0, t)
    va = d3 * d6 - d5 * d4
    if va <= 0.0 and (d4 - d3) >= 0.0 and (d5 - d6) >= 0.0:
        t = (d4 - d3) / ((d4 - d3) + (d5 - d6))
        return wp.vec3(0.0, 1.0 - t, t)
    den = 1.0 / (va + vb + vc)
    v = vb * den
    w = vc * den
    return wp.vec3(1.0 - v - w, v, w)


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
def stored_side(prev_id: wp.array2d[int], prev_side: wp.array2d[float], prev_count: wp.array[int], row: int,
                other: int, side: float) -> float:
    """The side a contact pair (row, other) had at the previous detection, else `side`: a pair
    already in contact keeps its side (inside the contact layer the current one may be wrong, a
    correction left unfinished, and re-reading it would lock a crossing in)."""
    out = side
    for r in range(prev_count[row]):
        if prev_id[row, r] == other and prev_side[row, r] != 0.0:
            out = prev_side[row, r]
    return out


@wp.kernel
def save_rows(
    count: wp.array[int],
    ids: wp.array2d[int],
    sides: wp.array2d[float],
    prev_count: wp.array[int],
    prev_ids: wp.array2d[int],
    prev_sides: wp.array2d[float],
):
    """Keep a detection's candidate rows for the next one's :func:`stored_side`: prev_count =
    count and the rows' first count ids and sides (the rest of a row is never read; copying
    only those spares copying whole rows, most of them empty)."""
    i = wp.tid()
    c = count[i]
    prev_count[i] = c
    for r in range(c):
        prev_ids[i, r] = ids[i, r]
        prev_sides[i, r] = sides[i, r]


@wp.func
def push_candidate(ids: wp.array2d[int], sides: wp.array2d[float], dists: wp.array2d[float], row: int, count: int,
                   other: int, side: float, dist: float, overflow: wp.array[int]) -> int:
    """Store contact candidate `other`, its side and distance in slot `count` of `row`; returns
    the new count. A full row keeps the nearest candidates: `other` replaces the farthest one
    stored if it is nearer, and one candidate dropped is counted in overflow[0] either way."""
    if count < ids.shape[1]:
        ids[row, count] = other
        sides[row, count] = side
        dists[row, count] = dist
        return count + 1
    far = int(0)
    for r in range(1, count):
        if dists[row, r] > dists[row, far]:
            far = r
    if dist < dists[row, far]:
        ids[row, far] = other
        sides[row, far] = side
        dists[row, far] = dist
    wp.atomic_add(overflow, 0, 1)
    return count


@wp.func
def dihedral_angle(x1: wp.vec3, x2: wp.vec3, x3: wp.vec3, x4: wp.vec3) -> float:
    """Signed dihedral angle [rad] of the hinge with shared edge x3-x4 and wings x1, x2.

    Zero for a flat hinge; atan2 keeps it accurate near 0 and +-pi, where acos loses precision.
    """
    e = x4 - x3
    n1 = wp.cross(x1 - x3, x1 - x4)
    n2 = wp.cross(x2 - x4, x2 - x3)
    le = wp.length(e)
    if le == 0.0:
        return 0.0
    s = wp.dot(wp.cross(n1, n2), e) / le
    c = wp.dot(n1, n2)
    return wp.atan2(s, c)


# ---------------------------------------------------------------------------------------------
# Integration
# ---------------------------------------------------------------------------------------------


@wp.kernel
def predict_positions(
    x: wp.array[wp.vec3],
    v: wp.array[wp.vec3],
    inv_mass: wp.array[float],
    lift: wp.array[wp.vec3],
    air_drag: wp.array[float],
    wind: wp.vec3,
    gravity: wp.vec3,
    drag: float,
    dt: float,
    x_prev: wp.array[wp.vec3],
    x_out: wp.array[wp.vec3],
    v_out: wp.array[wp.vec3],
):
    """Symplectic Euler prediction (XPBD Alg. 1, line 3); kinematic vertices keep their velocity.

    Aerodynamic drag -D (v - wind) is integrated implicitly (stable for any D dt / m); the lift
    impulse is capped at the vertex's speed relative to the air, which it could at most redirect.
    """
    i = wp.tid()
    x0 = x[i]
    x_prev[i] = x0
    w = inv_mass[i]
    v1 = v[i]
    if w > 0.0:
        u = v1 - wind
        dv = lift[i] * (w * dt)
        ldv = wp.length(dv)
        lu = wp.length(u)
        if ldv > lu:
            dv = dv * (lu / ldv)
        a = air_drag[i] * w * dt
        v1 = (v1 + gravity * dt + dv + wind * a) / (1.0 + a)
        # exact exponential decay of a linear drag, unconditionally stable for any drag * dt
        # (none without drag: exp(-0) is exactly 1)
        if drag != 0.0:
            v1 = v1 * wp.exp(-drag * dt)
    v_out[i] = v1
    x_out[i] = x0 + v1 * dt


@wp.kernel
def drive_attachments(
    indices: wp.array[int],
    start: wp.array[wp.vec3],
    target: wp.array[wp.vec3],
    alpha: float,
    x: wp.array[wp.vec3],
):
    """Kinematic attachments follow their target: linear interpolation over the step's substeps."""
    k = wp.tid()
    x[indices[k]] = wp.lerp(start[k], target[k], alpha)


@wp.kernel
def gather_points(
    indices: wp.array[int],
    x: wp.array[wp.vec3],
    out: wp.array[wp.vec3],
):
    """out[k] = x[indices[k]]."""
    k = wp.tid()
    out[k] = x[indices[k]]


@wp.kernel
def update_velocities(
    x: wp.array[wp.vec3],
    x_prev: wp.array[wp.vec3],
    dt: float,
    v: wp.array[wp.vec3],
):
    """XPBD Alg. 1, line 11: velocities from the position change of the substep."""
    i = wp.tid()
    v[i] = (x[i] - x_prev[i]) / dt


# ---------------------------------------------------------------------------------------------
# Elastic constraints (graph-coloured Gauss-Seidel)
# ---------------------------------------------------------------------------------------------


@wp.kernel
def solve_stretch(
    edges: wp.array[wp.vec2i],
    rest_length: wp.array[float],
    compliance: wp.array[float],
    inv_mass: wp.array[float],
    offset: int,
    dt: float,
    relaxation: float,
    lam: wp.array[float],
    x: wp.array[wp.vec3],
):
    """Distance constraints C = |xi - xj| - L (XPBD eq. 18), over-relaxed by `relaxation`.

    Damping is not folded in here (XPBD eq. 26): with one sweep per substep its (1 + gamma)
    factor only slows convergence; :func:`damp_stretch` damps velocities instead.
    """
    e = wp.tid() + offset
    ij = edges[e]
    i = ij[0]
    j = ij[1]
    wi = inv_mass[i]
    wj = inv_mass[j]
    wsum = wi + wj
    axis = edge_axis(x[i], x[j])
    if wsum == 0.0 or axis[3] < 1.0e-12:
        return
    n = wp.vec3(axis[0], axis[1], axis[2])
    c = axis[3] - rest_length[e]
    alpha = compliance[e] / (dt * dt)
    dlam = -relaxation * (c + alpha * lam[e]) / (wsum + alpha)
    lam[e] = lam[e] + dlam
    x[i] = x[i] + n * (wi * dlam)
    x[j] = x[j] - n * (wj * dlam)


@wp.func
def dihedral_gradients(x1: wp.vec3, x2: wp.vec3, x3: wp.vec3, x4: wp.vec3) -> wp.mat33:
    """Rows: d theta / d x1, x2, x3 of :func:`dihedral_angle` (d/dx4 is minus their sum).

    The exact gradients of Bridson, Marino & Fedkiw 2003 (eq. 8, the "bending modes"); zero for a
    degenerate hinge (zero-length edge or zero-area wing).
    """
    e = x4 - x3
    le = wp.length(e)
    n1 = wp.cross(x1 - x3, x1 - x4)
    n2 = wp.cross(x2 - x4, x2 - x3)
    a1 = wp.length_sq(n1)
    a2 = wp.length_sq(n2)
    if le < 1.0e-12 or a1 < 1.0e-24 or a2 < 1.0e-24:
        return wp.mat33(0.0)
    # with these normals the bending modes point down the gradient of atan2(sin, cos)
    u1 = -n1 * (le / a1)
    u2 = -n2 * (le / a2)
    u3 = -(n1 * (wp.dot(x1 - x4, e) / (le * a1)) + n2 * (wp.dot(x2 - x4, e) / (le * a2)))
    return wp.matrix_from_rows(u1, u2, u3)


@wp.kernel
def solve_bending(
    hinges: wp.array[wp.vec4i],
    rest_angle: wp.array[float],
    compliance: wp.array[float],
    inv_mass: wp.array[float],
    offset: int,
    dt: float,
    lam: wp.array[float],
    x: wp.array[wp.vec3],
):
    """Dihedral-angle bending constraints C = theta - theta0, at XPBD step ``dt``.

    Hinge (x1, x2, x3, x4): wings x1, x2, shared edge x3-x4. The angle gradients are the exact
    ones of Bridson, Marino & Fedkiw 2003 (eq. 8, the "bending modes" u1..u4), not Müller 2007's
    approximation; they sum to zero, so the correction conserves linear momentum.
    """
    h = wp.tid() + offset
    ids = hinges[h]
    i1 = ids[0]
    i2 = ids[1]
    i3 = ids[2]
    i4 = ids[3]
    w1 = inv_mass[i1]
    w2 = inv_mass[i2]
    w3 = inv_mass[i3]
    w4 = inv_mass[i4]
    if w1 + w2 + w3 + w4 == 0.0:
        return
    x1 = x[i1]
    x2 = x[i2]
    x3 = x[i3]
    x4 = x[i4]
    g = dihedral_gradients(x1, x2, x3, x4)
    u1 = g[0]
    u2 = g[1]
    u3 = g[2]
    u4 = -(u1 + u2 + u3)  # the gradients of an angle sum to zero (translation invariance)
    theta = dihedral_angle(x1, x2, x3, x4)
    c = theta - rest_angle[h]
    # keep the error in (-pi, pi] so a hinge passing through +-pi does not flip its correction
    if c > wp.pi:
        c = c - 2.0 * wp.pi
    if c < -wp.pi:
        c = c + 2.0 * wp.pi
    denom = w1 * wp.length_sq(u1) + w2 * wp.length_sq(u2) + w3 * wp.length_sq(u3) + w4 * wp.length_sq(u4)
    if denom < 1.0e-20:
        return
    alpha = compliance[h] / (dt * dt)
    dlam = -(c + alpha * lam[h]) / (denom + alpha)
    lam[h] = lam[h] + dlam
    x[i1] = x1 + u1 * (w1 * dlam)
    x[i2] = x2 + u2 * (w2 * dlam)
    x[i3] = x3 + u3 * (w3 * dlam)
    x[i4] = x4 + u4 * (w4 * dlam)


@wp.kernel
def add_moved(x: wp.array[wp.vec3], before: wp.array[wp.vec3], moved: wp.array[wp.vec3]):
    """moved += x - before: adds the displacement since ``before`` was taken."""
    i = wp.tid()
    moved[i] = moved[i] + (x[i] - before[i])


@wp.kernel
def discount_moved(scale: float, moved: wp.array[wp.vec3], v: wp.array[wp.vec3]):
    """v -= scale * moved, then moved = 0: takes back the part of a correction's velocity that belongs to a step
    longer than the substep (``XPBDSolver(bend_interval=k)``: a bending sweep every k substeps is
    an XPBD step of k substeps, whose correction gives the velocity 1/k of what the substep's
    velocity update makes of it)."""
    i = wp.tid()
    v[i] = v[i] - moved[i] * scale
    moved[i] = wp.vec3(0.0, 0.0, 0.0)


@wp.kernel
def damp_stretch(
    edges: wp.array[wp.vec2i],
    compliance: wp.array[float],
    inv_mass: wp.array[float],
    x: wp.array[wp.vec3],
    offset: int,
    dt: float,
    damping: float,
    v: wp.array[wp.vec3],
):
    """Stiffness-proportional damper along each edge, k_d = damping * k, integrated implicitly.

    The relative normal velocity u of the edge decays as u' = u / (1 + h k_d (wi + wj)) (implicit
    Euler of the 1-D damper), stable for any k_d; an inextensible edge (k = inf) loses all of it.
    """
    e = wp.tid() + offset
    ij = edges[e]
    i = ij[0]
    j = ij[1]
    wi = inv_mass[i]
    wj = inv_mass[j]
    wsum = wi + wj
    axis = edge_axis(x[i], x[j])
    if wsum == 0.0 or axis[3] < 1.0e-12:
        return
    n = wp.vec3(axis[0], axis[1], axis[2])
    u = wp.dot(v[i] - v[j], n)
    c = compliance[e]
    # fraction of u removed: h kd wsum / (1 + h kd wsum), written with kd = damping / c
    frac = float(1.0)
    if c > 0.0:
        a = dt * damping * wsum
        frac = a / (c + a)
    p = -u * frac / wsum
    v[i] = v[i] + n * (wi * p)
    v[j] = v[j] - n * (wj * p)


@wp.kernel
def damp_bending(
    hinges: wp.array[wp.vec4i],
    compliance: wp.array[float],
    inv_mass: wp.array[float],
    x: wp.array[wp.vec3],
    offset: int,
    dt: float,
    damping: float,
    v: wp.array[wp.vec3],
):
    """Stiffness-proportional damper on each hinge's angular velocity, integrated implicitly.

    With theta_dot = sum_k u_k . v_k and D = sum_k w_k |u_k|^2, the angular velocity decays as
    theta_dot' = theta_dot / (1 + h k_d D), k_d = damping * k (as :func:`damp_stretch`).
    """
    h = wp.tid() + offset
    c = compliance[h]
    ids = hinges[h]
    i1 = ids[0]
    i2 = ids[1]
    i3 = ids[2]
    i4 = ids[3]
    g = dihedral_gradients(x[i1], x[i2], x[i3], x[i4])
    u1 = g[0]
    u2 = g[1]
    u3 = g[2]
    u4 = -(u1 + u2 + u3)
    w1 = inv_mass[i1]
    w2 = inv_mass[i2]
    w3 = inv_mass[i3]
    w4 = inv_mass[i4]
    denom = w1 * wp.length_sq(u1) + w2 * wp.length_sq(u2) + w3 * wp.length_sq(u3) + w4 * wp.length_sq(u4)
    if denom < 1.0e-20:
        return
    rate = wp.dot(u1, v[i1]) + wp.dot(u2, v[i2]) + wp.dot(u3, v[i3]) + wp.dot(u4, v[i4])
    frac = float(1.0)
    if c > 0.0:
        a = dt * damping * denom
        frac = a / (c + a)
    p = -rate * frac / denom
    v[i1] = v[i1] + u1 * (w1 * p)
    v[i2] = v[i2] + u2 * (w2 * p)
    v[i3] = v[i3] + u3 * (w3 * p)
    v[i4] = v[i4] + u4 * (w4 * p)


@wp.kernel
def solve_tethers(
    anchor: wp.array[int],
    max_length: wp.array[float],
    per_vertex: int,
    inv_mass: wp.array[float],
    x: wp.array[wp.vec3],
):
    """Long-range attachments (Kim, Chentanez & Müller 2012, eq. 3): |x - x_anchor| <= L.

    L bounds the rest geodesic distance to a kinematic vertex, so a tether only acts on stretch:
    it removes in one projection the sag that Gauss-Seidel sweeps leave in long hanging cloth
    (their error grows with the square of the number of vertices along the hang). ``anchor`` and
    ``max_length`` are the model's (V, per_vertex) arrays flattened.
    """
    i = wp.tid()
    if inv_mass[i] == 0.0:
        return
    for c in range(per_vertex):
        a = anchor[i * per_vertex + c]
        if a >= 0:
            d = x[i] - x[a]
            length = wp.length(d)
            lmax = max_length[i * per_vertex + c]
            if length > lmax and length > 0.0:
                x[i] = x[i] - d * ((length - lmax) / length)


@wp.kernel
def flag_moved(before: wp.array[wp.vec3], x: wp.array[wp.vec3], flag: wp.array[int]):
    """flag[i] = 1 where the contact projections moved vertex i (x differs from ``before``), else 0."""
    i = wp.tid()
    d = x[i] - before[i]
    flag[i] = wp.where(wp.dot(d, d) > 0.0, 1, 0)


@wp.kernel
def solve_limits(
    pairs: wp.array[wp.vec2i],
    max_length: wp.array[float],
    inv_mass: wp.array[float],
    max_move: float,
    contacts: wp.array[int],
    touched: wp.array[int],
    offset: int,
    x: wp.array[wp.vec3],
):
    """Stretch limits |xi - xj| <= L between distant vertices
    (:func:`~warpshade.sim.model.stretch_limits`), projected with inverse-mass weights; a limit
    never pushes apart, moves neither vertex by more than ``max_move``, and is skipped while
    ``contacts`` or ``touched`` is non-zero at either vertex."""
    p = wp.tid() + offset
    ij = pairs[p]
    i = ij[0]
    j = ij[1]
    wi = inv_mass[i]
    wj = inv_mass[j]
    wsum = wi + wj
    d = x[i] - x[j]
    length = wp.length(d)
    lmax = max_length[p]
    if wsum == 0.0 or length <= lmax or contacts[i] + contacts[j] + touched[i] + touched[j] > 0:
        return
    step = wp.min((length - lmax) / wsum, max_move / wp.max(wi, wj))
    corr = d * (step / length)
    x[i] = x[i] - corr * wi
    x[j] = x[j] + corr * wj


@wp.kernel
def chebyshev_step(omega: float, x: wp.array[wp.vec3], x_last: wp.array[wp.vec3], x_before: wp.array[wp.vec3]):
    """Chebyshev semi-iterative acceleration of a sweep (Wang 2015, eq. 12 with gamma = 1): x, the
    sweep's result from the iterate ``x_last``, becomes omega (x - x_before) + x_before, where
    ``x_before`` is the iterate before ``x_last``; then x_before <- x_last and x_last <- x."""
    i = wp.tid()
    xn = omega * (x[i] - x_before[i]) + x_before[i]
    x_before[i] = x_last[i]
    x_last[i] = xn
    x[i] = xn


@wp.kernel
def record_moved(before: wp.array[wp.vec3], x: wp.array[wp.vec3], moved: wp.array[wp.vec3]):
    """moved[i] = x[i] - before[i]: how the contact projections moved vertex i."""
    i = wp.tid()
    moved[i] = x[i] - before[i]


@wp.func
def slide(dx: wp.vec3, pushed: wp.vec3) -> wp.vec3:
    """dx without its component against ``pushed`` (how the contacts moved the vertex), so a
    correction moves a vertex along the surface that pushed it (a collider's, another layer's)
    rather than into it."""
    if wp.dot(pushed, pushed) > 0.0:
        n = wp.normalize(pushed)
        a = wp.dot(dx, n)
        if a < 0.0:
            return dx - n * a
    return dx


@wp.kernel
def mark_parents(offsets: wp.array[int], parents: wp.array[int], contacts: wp.array[int], marked: wp.array[int]):
    """marked[j] = 1 for a coarse level's vertex j that has self-contact candidates (``contacts``) or is
    a parent of a vertex that has (rows ``offsets[i]:offsets[i + 1]`` of ``parents``, as
    :func:`prolong_moves` reads them; ``marked`` zeroed before): a coarse constraint there would move
    cloth that lies against another layer. Threads write only ones."""
    i = wp.tid()
    if contacts[i] > 0:
        marked[i] = 1
        for k in range(offsets[i], offsets[i + 1]):
            marked[parents[k]] = 1


@wp.kernel
def prolong_moves(
    offsets: wp.array[int],
    parents: wp.array[int],
    weights: wp.array[float],
    inv_mass: wp.array[float],
    contacts: wp.array[int],
    touched: wp.array[int],
    pushed: wp.array[wp.vec3],
    sliding: int,
    x_before: wp.array[wp.vec3],
    x: wp.array[wp.vec3],
):
    """Carry a coarse level's moves (x - x_before at its vertices) to the vertices it drops: vertex i
    moves by the weighted sum of its parents' moves (Müller 2008's prolongation; rows
    ``offsets[i]:offsets[i + 1]`` of ``parents`` and ``weights``, empty for the level's own vertices,
    which are never a row's vertex, so no thread reads a position another writes). Skipped, as the
    limits are (:func:`solve_limits`, :func:`solve_limits_sliding`), at kinematic vertices and while
    ``contacts`` is non-zero, and while ``touched`` is unless ``sliding`` (then the move slides along
    ``pushed``, :func:`slide`)."""
    i = wp.tid()
    a = offsets[i]
    b = offsets[i + 1]
    if a == b or inv_mass[i] == 0.0 or contacts[i] > 0:
        return
    if sliding == 0 and touched[i] > 0:
        return
    dx = wp.vec3(0.0, 0.0, 0.0)
    for k in range(a, b):
        p = parents[k]
        dx = dx + weights[k] * (x[p] - x_before[p])
    if sliding != 0:
        dx = slide(dx, pushed[i])
    x[i] = x[i] + dx


@wp.kernel
def solve_limits_sliding(
    pairs: wp.array[wp.vec2i],
    max_length: wp.array[float],
    inv_mass: wp.array[float],
    max_move: float,
    contacts: wp.array[int],
    pushed: wp.array[wp.vec3],
    offset: int,
    x: wp.array[wp.vec3],
):
    """Stretch limits as :func:`solve_limits`, skipped only while either vertex has self-contact
    candidates (``contacts``): a vertex the contact projections moved in the last substep
    (``pushed``, their displacement of it) takes its share of the correction without the
    component against that push (:func:`slide`)."""
    p = wp.tid() + offset
    ij = pairs[p]
    i = ij[0]
    j = ij[1]
    wi = inv_mass[i]
    wj = inv_mass[j]
    wsum = wi + wj
    d = x[i] - x[j]
    length = wp.length(d)
    lmax = max_length[p]
    if wsum == 0.0 or length <= lmax or contacts[i] + contacts[j] > 0:
        return
    step = wp.min((length - lmax) / wsum, max_move / wp.max(wi, wj))
    corr = d * (step / length)
    x[i] = x[i] + slide(-corr * wi, pushed[i])
    x[j] = x[j] + slide(corr * wj, pushed[j])


# ---------------------------------------------------------------------------------------------
# Aerodynamics
# ---------------------------------------------------------------------------------------------


@wp.kernel
def accumulate_aero_forces(
    x: wp.array[wp.vec3],
    v: wp.array[wp.vec3],
    tris: wp.array[wp.vec3i],
    wind: wp.vec3,
    air_density: float,
    drag_coefficient: float,
    lift_coefficient: float,
    lift: wp.array[wp.vec3],
    drag: wp.array[float],
):
    """Per-triangle aerodynamic drag and lift, a third to each corner.

    With relative air velocity u = v_tri - wind, unit normal n and cos(t) = u.n / |u| (flat-plate
    model): drag = -D u with D = 1/2 rho Cd A |cos t| |u| (projected area), lift = -1/2 rho Cl A
    |u|^2 cos t (n - cos t u_hat), perpendicular to the flow with magnitude ~ sin 2t as for a flat
    plate. Drag is returned as the coefficient D [kg/s] so that :func:`predict_positions` can
    integrate it implicitly (explicit drag on light cloth overshoots and blows up).
    """
    t = wp.tid()
    ijk = tris[t]
    i = ijk[0]
    j = ijk[1]
    k = ijk[2]
    nn = wp.cross(x[j] - x[i], x[k] - x[i])
    ln = wp.length(nn)
    if ln == 0.0:
        return
    area = 0.5 * ln
    n = nn / ln
    u = (v[i] + v[j] + v[k]) / 3.0 - wind
    speed = wp.length(u)
    if speed == 0.0:
        return
    uh = u / speed
    cs = wp.dot(uh, n)
    q = 0.5 * air_density * area * speed
    d = q * drag_coefficient * wp.abs(cs) / 3.0
    fl = -(n - uh * cs) * (q * speed * lift_coefficient * cs / 3.0)
    wp.atomic_add(drag, i, d)
    wp.atomic_add(drag, j, d)
    wp.atomic_add(drag, k, d)
    wp.atomic_add(lift, i, fl)
    wp.atomic_add(lift, j, fl)
    wp.atomic_add(lift, k, fl)


# ---------------------------------------------------------------------------------------------
# Self-collision: vertex-triangle, swept-box broad phase once per detection, Jacobi solve
# ---------------------------------------------------------------------------------------------


@wp.kernel
def compute_triangle_bounds(
    x: wp.array[wp.vec3],
    v: wp.array[wp.vec3],
    tris: wp.array[wp.vec3i],
    horizon: float,
    pad: wp.array[float],
    lower: wp.array[wp.vec3],
    upper: wp.array[wp.vec3],
):
    """Box around a triangle now and after `horizon` seconds of its current velocity, each corner
    padded by its own pad."""
    t = wp.tid()
    lo = wp.vec3(1.0e30)
    hi = wp.vec3(-1.0e30)
    ids = tris[t]
    for c in range(3):
        vc = ids[c]
        p = x[vc]
        q = p + v[vc] * horizon
        r = wp.vec3(pad[vc])
        lo = wp.min(lo, wp.min(p, q) - r)
        hi = wp.max(hi, wp.max(p, q) + r)
    lower[t] = lo
    upper[t] = hi


@wp.func
def in_one_ring(i: int, j: int, ring_offsets: wp.array[int], ring: wp.array[int]) -> bool:
    """Whether vertex j is vertex i or one of its edge neighbours (CSR adjacency)."""
    if i == j:
        return True
    for k in range(ring_offsets[i], ring_offsets[i + 1]):
        if ring[k] == j:
            return True
    return False


NEIGHBOUR_FOLD = wp.constant(0.5)
"""A vertex's contact with a triangle of one of its edge neighbours is kept when the vertex is
closer to the triangle than this fraction of its rest distance to it (a fold)."""


@wp.func
def boxes_overlap(a_lo: wp.vec3, a_hi: wp.vec3, b_lo: wp.vec3, b_hi: wp.vec3) -> bool:
    """Closed boxes a and b overlap (the test of Warp's BVH box query)."""
    return not (a_lo[0] > b_hi[0] or a_lo[1] > b_hi[1] or a_lo[2] > b_hi[2] or a_hi[0] < b_lo[0]
                or a_hi[1] < b_lo[1] or a_hi[2] < b_lo[2])


@wp.func
def neighbour_flat(i: int, a: int, b: int, c: int, dist: float, rest_x: wp.array[wp.vec3],
                   ring_offsets: wp.array[int], ring: wp.array[int]) -> bool:
    """Triangle abc is one of vertex i's neighbours' and no fold brings it to i: the vertex is
    not closer to it (dist) than NEIGHBOUR_FOLD of its distance to it at rest (a fold across one
    strip of triangles; vertex-vertex distances cannot see it, the neighbour stays an edge length
    away). Such a pair is no contact candidate."""
    if (in_one_ring(i, a, ring_offsets, ring) or in_one_ring(i, b, ring_offsets, ring)
            or in_one_ring(i, c, ring_offsets, ring)):
        rb = closest_on_triangle(rest_x[i], rest_x[a], rest_x[b], rest_x[c])
        rest = wp.length(rest_x[i] - (rest_x[a] * rb[0] + rest_x[b] * rb[1] + rest_x[c] * rb[2]))
        return dist > NEIGHBOUR_FOLD * rest
    return False


@wp.func
def vertex_query_box(x: wp.array[wp.vec3], v: wp.array[wp.vec3], pad: wp.array[float], i: int, ahead: float) -> wp.mat33:
    """Rows: lower and upper corner of vertex i's box swept over ``ahead`` seconds and padded by
    its pad (the box it looks up the triangles with), and its position."""
    p = x[i]
    qa = p + v[i] * ahead
    return wp.matrix_from_rows(wp.min(p, qa) - wp.vec3(pad[i]), wp.max(p, qa) + wp.vec3(pad[i]), p)


@wp.func
def vertex_triangle_candidate(
    i: int,
    t: int,
    count: int,
    x: wp.array[wp.vec3],
    rest_x: wp.array[wp.vec3],
    v: wp.array[wp.vec3],
    tris: wp.array2d[int],
    ring_offsets: wp.array[int],
    ring: wp.array[int],
    horizon: float,
    later: float,
    lower: wp.array[wp.vec3],
    upper: wp.array[wp.vec3],
    pad: wp.array[float],
    thickness: float,
    prev_tri: wp.array2d[int],
    prev_side: wp.array2d[float],
    prev_count: wp.array[int],
    contact_tri: wp.array2d[int],
    contact_side: wp.array2d[float],
    contact_dist: wp.array2d[float],
    overflow: wp.array[int],
    near: wp.array[int],
) -> int:
    """The test of :func:`find_self_contacts` for vertex i and triangle t, whose boxes swept over
    the look-ahead overlap: pushes the pair into row i when it is a candidate (returns the row's
    new count) and sets near[0] when the look-ahead foresees it."""
    a = tris[t, 0]
    b = tris[t, 1]
    c = tris[t, 2]
    if i == a or i == b or i == c:
        return count
    p = x[i]
    vi = v[i]
    q = p + vi * horizon
    lo = wp.min(p, q) - wp.vec3(pad[i])
    hi = wp.max(p, q) + wp.vec3(pad[i])
    now = boxes_overlap(lo, hi, lower[t], upper[t])
    look = later > 0.0 and near[0] == 0
    if not now and not look:
        return count
    speed = wp.max(wp.max(wp.length(vi - v[a]), wp.length(vi - v[b])), wp.length(vi - v[c]))
    close = speed * horizon
    reach = 1.5 * (thickness + speed * later)
    # (the pair's distance changes by at most `close` until the next detection, and is at
    # least the vertex's distance to the triangle's box, which holds it)
    if not now and wp.length(wp.max(wp.max(lower[t] - p, p - upper[t]), wp.vec3(0.0))) - close > reach:
        return count
    bc = closest_on_triangle(p, x[a], x[b], x[c])
    dist = wp.length(p - (x[a] * bc[0] + x[b] * bc[1] + x[c] * bc[2]))
    if look and dist - close <= reach:
        ta = x[a] + v[a] * horizon
        tb = x[b] + v[b] * horizon
        tc = x[c] + v[c] * horizon
        bt = closest_on_triangle(q, ta, tb, tc)
        dist_next = wp.length(q - (ta * bt[0] + tb * bt[1] + tc * bt[2]))
        if dist_next <= reach and not neighbour_flat(i, a, b, c, dist_next, rest_x, ring_offsets, ring):
            near[0] = 1
    if not now or dist > 1.5 * (thickness + close):
        return count  # (tested first: it rejects most triangles, and the neighbour test costs more)
    if neighbour_flat(i, a, b, c, dist, rest_x, ring_offsets, ring):
        return count
    xa = x[a]
    nn = wp.cross(x[b] - xa, x[c] - xa)
    d = wp.dot(p - xa, nn)
    side = float(0.0)
    # an in-plane vertex has no side yet: the solve decides at first contact
    if d > 1.0e-9 * wp.length_sq(nn):
        side = 1.0
    elif d < -1.0e-9 * wp.length_sq(nn):
        side = -1.0
    if wp.abs(d) < thickness * wp.sqrt(wp.length_sq(nn)):
        side = stored_side(prev_tri, prev_side, prev_count, i, t, side)
    return push_candidate(contact_tri, contact_side, contact_dist, i, count, t, side, dist, overflow)


@wp.kernel
def find_self_contacts(
    bvh: wp.uint64,
    x: wp.array[wp.vec3],
    rest_x: wp.array[wp.vec3],
    v: wp.array[wp.vec3],
    tris: wp.array2d[int],
    ring_offsets: wp.array[int],
    ring: wp.array[int],
    horizon: float,
    ahead: float,
    lower: wp.array[wp.vec3],
    upper: wp.array[wp.vec3],
    pad: wp.array[float],
    thickness: float,
    bvh_lower: wp.array[wp.vec3],
    bvh_upper: wp.array[wp.vec3],
    group: int,
    max_span: float,
    query_lower: wp.array[wp.vec3],
    query_upper: wp.array[wp.vec3],
    prev_tri: wp.array2d[int],
    prev_side: wp.array2d[float],
    prev_count: wp.array[int],
    contact_tri: wp.array2d[int],
    contact_side: wp.array2d[float],
    contact_count: wp.array[int],
    contact_dist: wp.array2d[float],
    overflow: wp.array[int],
    near: wp.array[int],
):
    """Vertex-triangle candidate pairs whose swept boxes overlap and that
    are, or may come within one interval, closer than 1.5 thicknesses: distance <= 1.5 (thickness
    + c), c = max |v_i - v_k| horizon the relative motion of the pair's vertices (a flat sheet's
    own neighbours, a few edge lengths away, are not stored).

    Only the triangles of the vertex itself are skipped (a topological test, so it also holds for
    garments whose rest shape is folded): a tight fold brings triangles of the one-ring's
    neighbours against the vertex, and they must be kept apart too. The side of
    the triangle the vertex is on now is stored; the solve keeps it there, which is what stops
    folds from passing through (the cloth is assumed free of intersections at detection time).

    The look-ahead, for ``ahead`` > ``horizon``: the next detection comes after ``horizon``
    seconds and looks ``ahead - horizon`` seconds on. ``bvh`` holds the triangles' boxes swept
    over ``ahead`` (``lower``/``upper``: over ``horizon``, the boxes the candidates are found
    with; the BVH's leaf order is the same for both, so the candidates and their order are those
    of a search over the ``horizon`` boxes alone), and near[0] is set to 1 when some pair, moved
    on with its velocities to the next detection, would be a candidate of it.

    A thread takes ``group`` consecutive vertices (the launch has ceil(V / group) threads). When
    the box around their look-up boxes is at most ``max_span`` wide, it makes one BVH query
    with it and passes each triangle found to the vertices whose own boxes overlap the
    triangle's BVH box (``bvh_lower``/``bvh_upper``, the BVH's items): the same pairs, in the
    same order (the BVH's), as one query per vertex, which it makes otherwise.
    """
    n = x.shape[0]
    first = wp.tid() * group
    last = wp.min(first + group, n)
    later = ahead - horizon
    glo = wp.vec3(1.0e30)
    ghi = wp.vec3(-1.0e30)
    for i in range(first, last):
        box = vertex_query_box(x, v, pad, i, ahead)
        query_lower[i] = box[0]
        query_upper[i] = box[1]
        glo = wp.min(glo, box[0])
        ghi = wp.max(ghi, box[1])
        contact_count[i] = 0
    span = ghi - glo
    if last - first > 1 and wp.max(wp.max(span[0], span[1]), span[2]) <= max_span:
        query = wp.bvh_query_aabb(bvh, glo, ghi)
        t = int(0)
        while wp.bvh_query_next(query, t):
            tlo = bvh_lower[t]
            thi = bvh_upper[t]
            for i in range(first, last):
                if boxes_overlap(query_lower[i], query_upper[i], tlo, thi):
                    contact_count[i] = vertex_triangle_candidate(
                        i, t, contact_count[i], x, rest_x, v, tris, ring_offsets, ring, horizon, later, lower, upper,
                        pad, thickness, prev_tri, prev_side, prev_count, contact_tri, contact_side, contact_dist,
                        overflow, near)
    else:
        for i in range(first, last):
            count = int(0)
            query = wp.bvh_query_aabb(bvh, query_lower[i], query_upper[i])
            t = int(0)
            while wp.bvh_query_next(query, t):
                count = vertex_triangle_candidate(
                    i, t, count, x, rest_x, v, tris, ring_offsets, ring, horizon, later, lower, upper, pad, thickness,
                    prev_tri, prev_side, prev_count, contact_tri, contact_side, contact_dist, overflow, near)
            contact_count[i] = count


@wp.kernel
def solve_self_contacts(
    x: wp.array[wp.vec3],
    x_prev: wp.array[wp.vec3],
    inv_mass: wp.array[float],
    tris: wp.array2d[int],
    contact_tri: wp.array2d[int],
    contact_side: wp.array2d[float],
    contact_count: wp.array[int],
    thickness: float,
    friction: float,
    delta: wp.array[wp.vec3],
    delta_count: wp.array[float],
):
    """Vertex-triangle separation, with position-based Coulomb friction (Macklin et al. 2014,
    eq. 24-25) on the relative tangential motion of p and its triangle point over the substep
    (x_prev: positions at its start). Corrections are accumulated for averaging (eq. 11).

    C = s n.(p - q) - thickness >= 0 on the stored side s, q the projection of p, only for
    projections inside the triangle (near edges a neighbouring triangle holds it).
    """
    i = wp.tid()
    wp_ = inv_mass[i]
    p = x[i]
    for k in range(contact_count[i]):
        t = contact_tri[i, k]
        a = tris[t, 0]
        b = tris[t, 1]
        c = tris[t, 2]
        xa = x[a]
        xb = x[b]
        xc = x[c]
        nn = wp.cross(xb - xa, xc - xa)
        ln2 = wp.length_sq(nn)
        if ln2 < 1.0e-24:
            continue
        n = nn / wp.sqrt(ln2)
        s = contact_side[i, k]
        dn = wp.dot(p - xa, n)
        if s == 0.0:
            s = wp.sign(dn)
            if dn == 0.0:
                s = 1.0
            contact_side[i, k] = s
        d = s * dn
        # respond within the contact layer and a few thicknesses past it (fast layers overshoot
        # within one substep); deeper "penetrations" are tangles or stale pairs whose huge
        # corrections would only inject energy
        if d >= thickness or d < -4.0 * thickness:
            continue
        # barycentric coordinates of the projection of p onto the triangle's plane
        pp = p - n * dn
        bw = wp.dot(wp.cross(xb - xa, pp - xa), n) / wp.sqrt(ln2)
        bv = wp.dot(wp.cross(pp - xa, xc - xa), n) / wp.sqrt(ln2)
        bu = 1.0 - bv - bw
        # a small tolerance: a vertex right above a shared edge or corner (aligned layers) would
        # otherwise fall between its triangles through round-off
        if bu < -0.01 or bv < -0.01 or bw < -0.01:
            continue
        bu = wp.max(bu, 0.0)
        bv = wp.max(bv, 0.0)
        bw = wp.max(bw, 0.0)
        bs = bu + bv + bw
        bu = bu / bs
        bv = bv / bs
        bw = bw / bs
        n = n * s
        wa = inv_mass[a]
        wb = inv_mass[b]
        wc = inv_mass[c]
        denom = wp_ + bu * bu * wa + bv * bv * wb + bw * bw * wc
        if denom == 0.0:
            continue
        depth = thickness - d
        lam = depth / denom
        g = n * lam
        if friction > 0.0:
            rel = (p - x_prev[i]) - ((xa - x_prev[a]) * bu + (xb - x_prev[b]) * bv + (xc - x_prev[c]) * bw)
            rt = rel - n * wp.dot(rel, n)
            lt = wp.length(rt)
            if lt > 0.0:
                g = g - rt * (wp.min(1.0, friction * depth / lt) / denom)
        wp.atomic_add(delta, i, g * wp_)
        wp.atomic_add(delta_count, i, 1.0)
        wp.atomic_add(delta, a, -g * (bu * wa))
        wp.atomic_add(delta_count, a, 1.0)
        wp.atomic_add(delta, b, -g * (bv * wb))
        wp.atomic_add(delta_count, b, 1.0)
        wp.atomic_add(delta, c, -g * (bw * wc))
        wp.atomic_add(delta_count, c, 1.0)


@wp.kernel
def apply_averaged_deltas(
    delta: wp.array[wp.vec3],
    delta_count: wp.array[float],
    x: wp.array[wp.vec3],
):
    """x += delta / count, then clear the accumulators for the next use."""
    i = wp.tid()
    n = delta_count[i]
    if n > 0.0:
        x[i] = x[i] + delta[i] / n
        delta[i] = wp.vec3(0.0)
        delta_count[i] = 0.0


# ---------------------------------------------------------------------------------------------
# Health check
# ---------------------------------------------------------------------------------------------


@wp.kernel
def find_nonfinite(
    x: wp.array[wp.vec3],
    v: wp.array[wp.vec3],
    first: wp.array[int],
):
    """first[0] = smallest index of a vertex whose position or velocity is not finite."""
    i = wp.tid()
    p = x[i]
    u = v[i]
    ok = wp.isfinite(p[0]) and wp.isfinite(p[1]) and wp.isfinite(p[2])
    ok = ok and wp.isfinite(u[0]) and wp.isfinite(u[1]) and wp.isfinite(u[2])
    if not ok:
        wp.atomic_min(first, 0, i)


# ---------------------------------------------------------------------------------------------
# Linear blend skinning
# ---------------------------------------------------------------------------------------------


@wp.kernel
def skin_points(
    rest: wp.array[wp.vec3],
    joint_index: wp.array2d[int],
    joint_weight: wp.array2d[float],
    transforms: wp.array[wp.mat44],
    out: wp.array[wp.vec3],
):
    """Linear blend skinning x = sum_k w_k (M_{j_k} [rest, 1])[:3] (column-vector matrices).

    Evaluated as x = rest + sum_k w_k ((M_k - I) [rest, 1])[:3], the same sum when the weights add
    up to 1, but exact for vertices whose joints do not move: their float32 weights need not sum
    to exactly 1 for the rest pose to come back bit for bit.
    """
    i = wp.tid()
    m = wp.mat44(0.0)
    for k in range(joint_index.shape[1]):
        w = joint_weight[i, k]
        if w != 0.0:
            m = m + (transforms[joint_index[i, k]] - wp.identity(n=4, dtype=float)) * w
    p = rest[i]
    out[i] = p + wp.vec3(m[0, 0] * p[0] + m[0, 1] * p[1] + m[0, 2] * p[2] + m[0, 3],
                         m[1, 0] * p[0] + m[1, 1] * p[1] + m[1, 2] * p[2] + m[1, 3],
                         m[2, 0] * p[0] + m[2, 1] * p[1] + m[2, 2] * p[2] + m[2, 3])
