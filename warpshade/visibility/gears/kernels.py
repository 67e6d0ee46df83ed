"""Kernels of GEARS area-light visibility (Popescu) and its ray-traced reference.

Light parameterisation (shared by every kernel here): a parallelogram light with centre ``c`` and
half-axes ``u``, ``v``; the point with light coordinates ``(s, t) ∈ [-1, 1]²`` is ``c + s u + t v``.
A k×k visibility mask samples the light at cell centres ``s_i = -1 + (2 i + 1) / k`` (row ``j`` holds
``t_j``); bit ``i`` of row ``j`` is set when the sample is *blocked*. Masks are ``uint32`` rows, so
``k <= 32``.
"""

from __future__ import annotations

import warp as wp

from ...geometry.kernels import clip_polygon, mat63
from ..rays import near_faces, ray_eps, trace_surface_ray

wp.set_module_options({"enable_backward": False})


# -- small math ---------------------------------------------------------------------------------
@wp.func
def popcount(x: wp.uint32) -> int:
    """Number of set bits (SWAR)."""
    x = x - ((x >> wp.uint32(1)) & wp.uint32(0x55555555))
    x = (x & wp.uint32(0x33333333)) + ((x >> wp.uint32(2)) & wp.uint32(0x33333333))
    x = (x + (x >> wp.uint32(4))) & wp.uint32(0x0F0F0F0F)
    return int((x * wp.uint32(0x01010101)) >> wp.uint32(24))


@wp.func
def mask_full(masks: wp.array2d[wp.uint32], r: int, k: int, full: wp.uint32) -> bool:
    """Whether every row of receiver ``r``'s mask equals ``full`` (all k samples blocked)."""
    for j in range(k):
        if masks[r, j] != full:
            return False
    return True


@wp.func
def light_point(c: wp.vec3, u: wp.vec3, v: wp.vec3, s: float, t: float) -> wp.vec3:
    return c + u * s + v * t


@wp.func
def light_sample_weight(p: wp.vec3, n: wp.vec3, q: wp.vec3, light_normal: wp.vec3) -> float:
    """Form-factor density ``max(0, n·ω) |n_L·ω| / (π r²)`` of light point ``q`` seen from ``p``.

    The light emits on both sides, hence the absolute value of its cosine.
    """
    d = q - p
    r2 = wp.dot(d, d)
    if r2 == 0.0:
        return 0.0
    r = wp.sqrt(r2)
    w = d / r
    return wp.max(0.0, wp.dot(n, w)) * wp.abs(wp.dot(light_normal, w)) / (wp.pi * r2)


@wp.func
def summarize_mask(
    masks: wp.array2d[wp.uint32],
    r: int,
    k: int,
    p: wp.vec3,
    n: wp.vec3,
    c: wp.vec3,
    u: wp.vec3,
    v: wp.vec3,
    light_normal: wp.vec3,
    dA: float,
) -> wp.vec2:
    """(fraction of samples visible, form factor of the visible samples) of receiver ``r``'s mask."""
    blocked = int(0)
    ff = float(0.0)
    # the light is convex: if all four corners are behind the tangent plane, every point is
    facing = bool(False)
    for q in range(4):
        if wp.dot(light_point(c, u, v, wp.where(q % 2 == 0, -1.0, 1.0), wp.where(q < 2, -1.0, 1.0)) - p, n) > 0.0:
            facing = True
    full = ~wp.uint32(0) >> wp.uint32(32 - k)
    for j in range(k):
        row = masks[r, j]
        blocked += popcount(row)
        if not facing or row == full:
            continue  # nothing visible in this row
        t = -1.0 + (2.0 * float(j) + 1.0) / float(k)
        for i in range(k):
            if (row & (wp.uint32(1) << wp.uint32(i))) == wp.uint32(0):
                s = -1.0 + (2.0 * float(i) + 1.0) / float(k)
                ff += light_sample_weight(p, n, light_point(c, u, v, s, t), light_normal) * dA
    return wp.vec2(1.0 - float(blocked) / float(k * k), ff)


@wp.kernel
def triangle_corners(points: wp.array[wp.vec3], faces: wp.array2d[wp.int32], corners: wp.array[wp.vec3]):
    """``corners[3 f + i] = points[faces[f, i]]``: the triangles' corners side by side, read per receiver."""
    f, i = wp.tid()
    corners[3 * f + i] = points[faces[f, i]]


# -- acceleration grid (the paper's A.1–A.3) -----------------------------------------------------
@wp.kernel
def locate_receivers(
    points: wp.array[wp.vec3],
    normals: wp.array[wp.vec3],
    offset: float,
    c: wp.vec3,
    light_normal: wp.vec3,
    e1: wp.vec3,
    e2: wp.vec3,
    grid_lo: wp.array2d[float],
    grid_cell: wp.array[float],
    grid_res: int,
    cell_of: wp.array[int],
):
    """Grid cell of every receiver (A.2): orthographic projection along the light normal, one grid per side.

    ``grid_lo[side]`` is the (e1, e2) corner of that side's grid and ``grid_cell[side]`` its cell size.
    Receivers in the light's plane get cell -1 (they see the light edge-on).
    """
    r = wp.tid()
    p = points[r] + normals[r] * offset
    h = wp.dot(p - c, light_normal)
    if h == 0.0:
        cell_of[r] = -1
        return
    side = wp.where(h > 0.0, 0, 1)
    x = (wp.dot(p - c, e1) - grid_lo[side, 0]) / grid_cell[side]
    y = (wp.dot(p - c, e2) - grid_lo[side, 1]) / grid_cell[side]
    cx = wp.clamp(int(wp.floor(x)), 0, grid_res - 1)
    cy = wp.clamp(int(wp.floor(y)), 0, grid_res - 1)
    cell_of[r] = (side * grid_res + cy) * grid_res + cx


@wp.kernel
def bound_shadow_volumes(
    points: wp.array[wp.vec3],
    faces: wp.array2d[wp.int32],
    c: wp.vec3,
    u: wp.vec3,
    v: wp.vec3,
    light_normal: wp.vec3,
    e1: wp.vec3,
    e2: wp.vec3,
    side_height: wp.array[float],
    grid_lo: wp.array2d[float],
    grid_cell: wp.array[float],
    grid_res: int,
    boxes: wp.array2d[int],
    near_height: wp.array[float],
):
    """Grid-cell AABB of each triangle's shadow volume, per side of the light (A.3), shape (F, 2) x 4.

    The paper extends each triangle vertex B_i away from light corner L_j by ``|B_i - L_j|``; that
    truncation can miss receivers farther away. Here the part of the triangle on one side of the
    light (0 <= height <= H, H the farthest receiver on that side) is extended from each corner L_j
    up to height H: ``F_ij = L_j + (B_i - L_j) H / h_i``. The shadow volume restricted to heights
    <= H lies in conv{B_i, F_ij} (F is affine in L and projective in B), so the AABB of their
    orthographic projections never misses a receiver. Parts touching the light's plane (h -> 0)
    reach infinitely far and get the whole grid. ``boxes[f*2+side] = (x0, y0, x1, y1)``; x0 = -1: none.
    ``near_height[f*2+side]`` is the clipped triangle's smallest height above the light: it cannot
    block a receiver at that height or lower (the grid is 2-D; this restores the third dimension).
    """
    f, side = wp.tid()
    row = f * 2 + side
    boxes[row, 0] = -1
    H = side_height[side]
    if H <= 0.0:
        return
    sgn = wp.where(side == 0, 1.0, -1.0)
    nrm = light_normal * sgn
    poly = mat63()
    tmp = mat63()
    poly[0] = points[faces[f, 0]]
    poly[1] = points[faces[f, 1]]
    poly[2] = points[faces[f, 2]]
    tmp, m = clip_polygon(poly, 3, nrm, 0.0, c)
    if m == 0:
        return
    poly, m = clip_polygon(tmp, m, -nrm, -H, c)
    if m == 0:
        return
    inf = float(1.0e30)
    xmin = inf
    ymin = inf
    xmax = -inf
    ymax = -inf
    hmin = inf
    whole = bool(False)
    for i in range(m):
        b = poly[i]
        hb = wp.dot(b - c, nrm)
        hmin = wp.min(hmin, hb)
        px = wp.dot(b - c, e1)
        py = wp.dot(b - c, e2)
        xmin = wp.min(xmin, px)
        xmax = wp.max(xmax, px)
        ymin = wp.min(ymin, py)
        ymax = wp.max(ymax, py)
        if hb <= 1.0e-6 * H:
            whole = True
        else:
            for j in range(4):
                sj = wp.where(j % 2 == 0, -1.0, 1.0)
                tj = wp.where(j < 2, -1.0, 1.0)
                lj = light_point(c, u, v, sj, tj)
                fp = lj + (b - lj) * (H / hb)
                qx = wp.dot(fp - c, e1)
                qy = wp.dot(fp - c, e2)
                xmin = wp.min(xmin, qx)
                xmax = wp.max(xmax, qx)
                ymin = wp.min(ymin, qy)
                ymax = wp.max(ymax, qy)
    g = float(grid_res)
    near_height[row] = hmin
    if whole:
        boxes[row, 0] = 0
        boxes[row, 1] = 0
        boxes[row, 2] = grid_res - 1
        boxes[row, 3] = grid_res - 1
        return
    x0 = wp.clamp((xmin - grid_lo[side, 0]) / grid_cell[side], -1.0, g + 1.0)
    x1 = wp.clamp((xmax - grid_lo[side, 0]) / grid_cell[side], -1.0, g + 1.0)
    y0 = wp.clamp((ymin - grid_lo[side, 1]) / grid_cell[side], -1.0, g + 1.0)
    y1 = wp.clamp((ymax - grid_lo[side, 1]) / grid_cell[side], -1.0, g + 1.0)
    # receivers are binned with floor() and clamped into the grid, so clamp the box the same way
    ix0 = wp.clamp(int(wp.floor(x0)), 0, grid_res - 1)
    ix1 = wp.clamp(int(wp.floor(x1)), 0, grid_res - 1)
    iy0 = wp.clamp(int(wp.floor(y0)), 0, grid_res - 1)
    iy1 = wp.clamp(int(wp.floor(y1)), 0, grid_res - 1)
    boxes[row, 0] = ix0
    boxes[row, 1] = iy0
    boxes[row, 2] = ix1
    boxes[row, 3] = iy1


@wp.kernel
def count_cell_triangles(boxes: wp.array2d[int], grid_res: int, cell_count: wp.array[int]):
    """Number of triangles assigned to each grid cell."""
    row = wp.tid()
    if boxes[row, 0] < 0:
        return
    side = row % 2
    for y in range(boxes[row, 1], boxes[row, 3] + 1):
        for x in range(boxes[row, 0], boxes[row, 2] + 1):
            wp.atomic_add(cell_count, (side * grid_res + y) * grid_res + x, 1)


@wp.kernel
def fill_cell_triangles(
    boxes: wp.array2d[int],
    grid_res: int,
    near_height: wp.array[float],
    cell_start: wp.array[int],
    cell_fill: wp.array[int],
    cell_tris: wp.array[int],
    cell_keys: wp.array[float],
):
    """Scatter triangle ids (and their near heights, the sort key) into the per-cell lists."""
    row = wp.tid()
    if boxes[row, 0] < 0:
        return
    side = row % 2
    f = row / 2
    for y in range(boxes[row, 1], boxes[row, 3] + 1):
        for x in range(boxes[row, 0], boxes[row, 2] + 1):
            cell = (side * grid_res + y) * grid_res + x
            slot = wp.atomic_add(cell_fill, cell, 1)
            cell_tris[cell_start[cell] + slot] = f
            cell_keys[cell_start[cell] + slot] = near_height[row]


@wp.kernel
def iota(out: wp.array[int]):
    """``out[i] = i``."""
    i = wp.tid()
    out[i] = i


@wp.kernel
def fill_cells_in_order(
    order: wp.array[int],
    rows: int,
    boxes: wp.array2d[int],
    grid_res: int,
    near_height: wp.array[float],
    cell_start: wp.array[int],
    cell_fill: wp.array[int],
    cell_tris: wp.array[int],
    cell_keys: wp.array[float],
):
    """:func:`fill_cell_triangles` for one thread (launch dim 1): rows taken in the order ``order[:rows]``
    (sorted by near height), so every cell's list comes out sorted without a segmented sort."""
    for i in range(rows):
        row = order[i]
        if boxes[row, 0] >= 0:
            side = row % 2
            f = row / 2
            for y in range(boxes[row, 1], boxes[row, 3] + 1):
                for x in range(boxes[row, 0], boxes[row, 2] + 1):
                    cell = (side * grid_res + y) * grid_res + x
                    slot = cell_start[cell] + cell_fill[cell]
                    cell_fill[cell] = cell_fill[cell] + 1
                    cell_tris[slot] = f
                    cell_keys[slot] = near_height[row]


@wp.kernel
def add_counts(count: wp.array[int], end: wp.array[int]):
    """``end += count`` (segment ends from starts)."""
    i = wp.tid()
    end[i] = end[i] + count[i]


# -- conservative pre-cull (native) ------------------------------------------------------------------
CULL_BATCH = wp.constant(32)
"""Candidate triangles a receiver passes to :func:`cull_batch` at a time (its scratch row length)."""

_CULL_BATCH = r"""
// corners: (3F) contiguous vec3; ids: the cell's triangle list; the walk goes first, first-1, ...
const float* __restrict__ P = (const float*)corners.data;
const int* __restrict__ ids = (const int*)cell_tris.data;
const unsigned int* __restrict__ mrow = (const unsigned int*)((const char*)masks.data + r * masks.strides[0]);
int* __restrict__ out = (int*)((char*)keep.data + r * keep.strides[0]);
const float px = p[0], py = p[1], pz = p[2];
const float nx = nrm[0], ny = nrm[1], nz = nrm[2];
const float ux = du[0], uy = du[1], uz = du[2];
const float vx = dv[0], vy = dv[1], vz = dv[2];
const float fk = (float)k;
// the outermost sample centres are 1/k inside the light's edges: planes half a cell outside them
const float edge = 1.0f - 0.5f / fk;
// S + edge H, S - edge H, T + edge H, T - edge H as planes through the receiver: w·(X - P)
const float w0x = (s0 + edge) * nx + ux, w0y = (s0 + edge) * ny + uy, w0z = (s0 + edge) * nz + uz;
const float w1x = (s0 - edge) * nx + ux, w1y = (s0 - edge) * ny + uy, w1z = (s0 - edge) * nz + uz;
const float w2x = (t0 + edge) * nx + vx, w2y = (t0 + edge) * ny + vy, w2z = (t0 + edge) * nz + vz;
const float w3x = (t0 - edge) * nx + vx, w3y = (t0 - edge) * ny + vy, w3z = (t0 - edge) * nz + vz;
// every term of these planes and of the exact path's S, T, H is at most C |X - P|_1 in magnitude
const float an = wp::max(fabsf(nx), wp::max(fabsf(ny), fabsf(nz)));
const float C = (fabsf(s0) + fabsf(t0) + 2.0f) * an + wp::max(fabsf(ux), wp::max(fabsf(uy), fabsf(uz)))
              + wp::max(fabsf(vx), wp::max(fabsf(vy), fabsf(vz)));
const float ax = fabsf(ux) + fabsf(vx), ay = fabsf(uy) + fabsf(vy), az = fabsf(uz) + fabsf(vz);
const float anx = fabsf(nx), any = fabsf(ny), anz = fabsf(nz);
const float hs = 1.0f + fabsf(s0) + fabsf(t0);
// gather the corners relative to the receiver (structure of arrays, so the next loops vectorize)
float cx[3][32], cy[3][32], cz[3][32];
for (int q = 0; q < n; ++q) {
    const float* t = P + 9 * ids[first - q];
    for (int c = 0; c < 3; ++c) {
        cx[c][q] = t[3 * c] - px;
        cy[c][q] = t[3 * c + 1] - py;
        cz[c][q] = t[3 * c + 2] - pz;
    }
}
// 1. branch-free frustum test (bitwise & and |): outside one of the planes (linear in X, so the
// clipped polygon is outside it too), wholly behind the receiver or beyond the light
int inside[32];
for (int q = 0; q < n; ++q) {
    bool o0 = true, o1 = true, o2 = true, o3 = true, ob = true, of = true;
    float l1 = 0.0f;
    for (int c = 0; c < 3; ++c) {
        const float dx = cx[c][q], dy = cy[c][q], dz = cz[c][q];
        l1 += fabsf(dx) + fabsf(dy) + fabsf(dz);
    }
    const float tau = 1.0e-5f * C * l1;
    for (int c = 0; c < 3; ++c) {
        const float dx = cx[c][q], dy = cy[c][q], dz = cz[c][q];
        const float h = dx * nx + dy * ny + dz * nz;
        o0 &= dx * w0x + dy * w0y + dz * w0z < -tau;
        o1 &= dx * w1x + dy * w1y + dz * w1z > tau;
        o2 &= dx * w2x + dy * w2y + dz * w2z < -tau;
        o3 &= dx * w3x + dy * w3y + dz * w3z > tau;
        ob &= h < -tau;
        of &= h > 1.0f + tau;
    }
    inside[q] = (cull == 0) | !(o0 | o1 | o2 | o3 | ob | of);
}
int sel[32];
int ns = 0;
for (int q = 0; q < n; ++q) {
    sel[ns] = q;
    ns += inside[q];
}
// 2. the survivors wholly in front of the receiver: the box of the corners' projections, as sample
// ranges (branch-free, vectorized)
int row0[32], row1[32], hit[32];
unsigned int span[32];
for (int e = 0; e < ns; ++e) {
    const int q = sel[e];
    float H[3], S[3], T[3];
    float asum = 0.0f;
    for (int c = 0; c < 3; ++c) {
        const float dx = cx[c][q], dy = cy[c][q], dz = cz[c][q];
        const float h = dx * nx + dy * ny + dz * nz;
        H[c] = h;
        S[c] = h * s0 + (dx * ux + dy * uy + dz * uz);
        T[c] = h * t0 + (dx * vx + dy * vy + dz * vz);
        // sum of the magnitudes of the terms: bounds the rounding of H, S, T (here and in the exact path)
        const float b = fabsf(dx) * anx + fabsf(dy) * any + fabsf(dz) * anz;
        asum += (fabsf(h) + b) * hs + fabsf(dx) * ax + fabsf(dy) * ay + fabsf(dz) * az;
    }
    const float hmin = wp::min(H[0], wp::min(H[1], H[2]));
    const bool front = hmin > 1.0e-3f;
    const float ih = front ? 1.0f / hmin : 0.0f;
    const float r0 = front ? 1.0f / H[0] : 0.0f, r1 = front ? 1.0f / H[1] : 0.0f, r2 = front ? 1.0f / H[2] : 0.0f;
    const float s_0 = S[0] * r0, s_1 = S[1] * r1, s_2 = S[2] * r2;
    const float t_0 = T[0] * r0, t_1 = T[1] * r1, t_2 = T[2] * r2;
    // margin: over 1000x the rounding of s = S/H (that of S, and of H times |s|), plus 1e-4
    const float big = wp::max(wp::max(wp::max(fabsf(s_0), fabsf(s_1)), wp::max(fabsf(s_2), fabsf(t_0))),
                              wp::max(fabsf(t_1), fabsf(t_2)));
    const float m = 1.0e-4f * asum * (1.0f + big) * ih + 1.0e-4f;
    const float smin = wp::min(s_0, wp::min(s_1, s_2)) - m, smax = wp::max(s_0, wp::max(s_1, s_2)) + m;
    const float tmin = wp::min(t_0, wp::min(t_1, t_2)) - m, tmax = wp::max(t_0, wp::max(t_1, t_2)) + m;
    // sample index ranges as :func:`scan_kept`'s index_range
    const float lo_c = -2.0f, hi_c = fk + 2.0f;
    const float ai = wp::min(wp::max((smin + 1.0f) * 0.5f * fk - 0.5f, lo_c), hi_c);
    const float bi = wp::min(wp::max((smax + 1.0f) * 0.5f * fk - 0.5f, lo_c), hi_c);
    const float aj = wp::min(wp::max((tmin + 1.0f) * 0.5f * fk - 0.5f, lo_c), hi_c);
    const float bj = wp::min(wp::max((tmax + 1.0f) * 0.5f * fk - 0.5f, lo_c), hi_c);
    int i0 = (int)ceilf(ai), i1 = (int)floorf(bi), j0 = (int)ceilf(aj), j1 = (int)floorf(bj);
    i0 = i0 < 0 ? 0 : i0;
    j0 = j0 < 0 ? 0 : j0;
    i1 = i1 > k - 1 ? k - 1 : i1;
    j1 = j1 > k - 1 ? k - 1 : j1;
    // not in front: every row, every column
    i0 = front ? i0 : 0;
    j0 = front ? j0 : 0;
    i1 = front ? i1 : k - 1;
    j1 = front ? j1 : k - 1;
    const bool empty = (i0 > i1) | (j0 > j1);
    const int w = empty ? 1 : i1 - i0 + 1;
    span[e] = (0xFFFFFFFFu >> (32 - w)) << (empty ? 0 : i0);
    row0[e] = j0;
    row1[e] = j1;
    hit[e] = (cull == 0) | !empty;
}
// 3. drop those whose box covers only samples already blocked; the rest, in walk order, to ``keep``
int kept = 0;
for (int e = 0; e < ns; ++e) {
    bool h = hit[e] != 0;
    if (h && cull != 0) {
        const unsigned int sp = span[e];
        unsigned int all = sp;
        for (int j = row0[e]; j <= row1[e]; ++j) all &= mrow[j];
        h = all != sp;
    }
    out[kept] = ids[first - sel[e]];
    kept += h ? 1 : 0;
}
return kept;
"""


@wp.func_native(_CULL_BATCH)
def cull_batch(corners: wp.array[wp.vec3], cell_tris: wp.array[int], first: int, n: int, p: wp.vec3, nrm: wp.vec3,
               du: wp.vec3, dv: wp.vec3, s0: float, t0: float, k: int, masks: wp.array2d[wp.uint32], r: int,
               cull: int, keep: wp.array2d[int]) -> int:
    """Conservative cull of ``n <= CULL_BATCH`` candidate triangles ``cell_tris[first], cell_tris[first-1], ...``
    for receiver ``r`` (at ``p``; ``nrm``, ``du``, ``dv``, ``s0``, ``t0`` as in :func:`rasterize_light_masks`).

    Drops a triangle only if it cannot set a bit of the mask: wholly outside the light's frustum (its
    planes pushed out by half a sample cell), wholly behind the receiver or beyond the light, or, in
    front of the receiver, when the box of its corners' projections (with a margin of 1000× their
    rounding) covers no sample or only samples already blocked. The kept triangle ids go to
    ``keep[r, :]`` in walk order; returns how many. ``cull = 0`` keeps all (for tests). Native C++ in
    levels, cheapest first: the frustum, behind and beyond tests (five dot products a corner, a
    branch-free loop clang vectorizes), the projected box of the ~20 % left (vectorized too), then
    the mask test and compaction. The margins only have to cover float32 rounding, so this code may
    round differently from the exact path (it is compiled with fused multiply-adds like the rest).
    """


_SCAN_KEPT = r"""
#pragma clang fp contract(off)
// The exact path, operation for operation as the Warp code it replaced (wp:: builtins, no fused
// multiply-adds): near/far clip, homogeneous light coordinates, frustum rejection, the 1.5x clip of
// far-reaching projections, then row spans by the half-open crossing rule.
const wp::vec3* __restrict__ C = (const wp::vec3*)corners.data;
const int* __restrict__ kp = (const int*)((const char*)keep.data + r * keep.strides[0]);
wp::uint32* __restrict__ mrow = (wp::uint32*)((char*)masks.data + r * masks.strides[0]);
const float fk = (float)k;
const wp::uint32 full = (~wp::uint32(0)) >> wp::uint32(32 - k);
// :func:`warpshade.geometry.kernels.clip_polygon` (Sutherland-Hodgman)
auto clip = [](const wp::vec3* in, int n, wp::vec3 plane, float offset, wp::vec3 origin, wp::vec3* out) -> int {
    int mm = 0;
    for (int i = 0; i < n; ++i) {
        const wp::vec3 a = in[i];
        const wp::vec3 b = in[(i + 1) % n];
        const float da = wp::sub(wp::dot(wp::sub(a, origin), plane), offset);
        const float db = wp::sub(wp::dot(wp::sub(b, origin), plane), offset);
        if (da >= 0.0f) {
            out[mm] = a;
            mm += 1;
        }
        if ((da >= 0.0f) != (db >= 0.0f)) {
            out[mm] = wp::add(a, wp::mul(wp::sub(b, a), wp::div(da, wp::sub(da, db))));
            mm += 1;
        }
    }
    return mm;
};
// indices i0..i1 of the cell-centre samples -1 + (2i+1)/k inside [lo, hi], clamped to 0..k-1 (empty when
// i0 > i1); coordinates are clamped before the integer conversion because projected blockers near the
// receiver reach huge light coordinates
auto index_range = [fk, k](float lo, float hi, int& i0, int& i1) {
    const float a = wp::clamp(wp::sub(wp::mul(wp::mul(wp::add(lo, 1.0f), 0.5f), fk), 0.5f), -2.0f, wp::add(fk, 2.0f));
    const float b = wp::clamp(wp::sub(wp::mul(wp::mul(wp::add(hi, 1.0f), 0.5f), fk), 0.5f), -2.0f, wp::add(fk, 2.0f));
    i0 = wp::max((int)wp::ceil(a), 0);
    i1 = wp::min((int)wp::floor(b), k - 1);
};
const float eps = 1e-06;
const float big_far = 1e+30;
const float tiny = 1e-30;
int q = 0;
for (; q < kept; ++q) {
    const int f = kp[q];
    const wp::vec3 a0 = C[3 * f], a1 = C[3 * f + 1], a2 = C[3 * f + 2];
    const float h0 = wp::dot(wp::sub(a0, p), nrm);
    const float h1 = wp::dot(wp::sub(a1, p), nrm);
    const float h2 = wp::dot(wp::sub(a2, p), nrm);
    if (wp::max(h0, wp::max(h1, h2)) < eps || wp::min(h0, wp::min(h1, h2)) > 1.0f)
        continue;
    wp::vec3 poly[16], tmp[16];
    poly[0] = a0;
    poly[1] = a1;
    poly[2] = a2;
    int m = 3;
    if (wp::min(h0, wp::min(h1, h2)) < eps || wp::max(h0, wp::max(h1, h2)) > 1.0f) {
        m = clip(poly, 3, nrm, eps, p, tmp);
        if (m == 0)
            continue;
        m = clip(tmp, m, wp::neg(nrm), -1.0f, p, poly);
        if (m < 3)
            continue;
    }
    bool out_lo_s = true, out_hi_s = true, out_lo_t = true, out_hi_t = true, big = false;
    for (int i = 0; i < m; ++i) {
        const wp::vec3 x = poly[i];
        const float hx = wp::dot(wp::sub(x, p), nrm);
        const wp::vec3 hom(wp::add(wp::mul(hx, s0), wp::dot(wp::sub(x, p), du)),
                           wp::add(wp::mul(hx, t0), wp::dot(wp::sub(x, p), dv)), hx);
        poly[i] = hom;
        out_lo_s = out_lo_s && hom[0] < wp::neg(hx);
        out_hi_s = out_hi_s && hom[0] > hx;
        out_lo_t = out_lo_t && hom[1] < wp::neg(hx);
        out_hi_t = out_hi_t && hom[1] > hx;
        if (!(wp::abs(hom[0]) <= wp::mul(4.0f, hx) && wp::abs(hom[1]) <= wp::mul(4.0f, hx)))
            big = true;
    }
    if (out_lo_s || out_hi_s || out_lo_t || out_hi_t)
        continue;
    if (big) {
        const wp::vec3 zero(0.0f, 0.0f, 0.0f);
        for (int j = 0; j < 4; ++j) {
            const wp::vec3 plane(j == 0 ? -1.0f : (j == 1 ? 1.0f : 0.0f), j == 2 ? -1.0f : (j == 3 ? 1.0f : 0.0f), 1.5f);
            m = clip(poly, m, plane, 0.0f, zero, tmp);
            for (int i = 0; i < m; ++i)
                poly[i] = tmp[i];
            if (m == 0)
                break;
        }
        if (m < 3)
            continue;
    }
    float tmin = big_far, tmax = wp::neg(big_far);
    for (int i = 0; i < m; ++i) {
        const wp::vec3 hom = poly[i];
        const float hh = wp::max(hom[2], tiny);
        tmp[i] = wp::vec3(wp::div(hom[0], hh), wp::div(hom[1], hh), 0.0f);
        tmin = wp::min(tmin, tmp[i][1]);
        tmax = wp::max(tmax, tmp[i][1]);
    }
    int j0, j1;
    index_range(tmin, tmax, j0, j1);
    for (int j = j0; j < j1 + 1; ++j) {
        const float t = wp::add(-1.0f, wp::div(wp::add(wp::mul(2.0f, (float)j), 1.0f), fk));
        float smin = big_far, smax = wp::neg(big_far);
        for (int i = 0; i < m; ++i) {
            const wp::vec3 a = tmp[i];
            const wp::vec3 b = tmp[i + 1 == m ? 0 : i + 1];
            // half-open crossing rule: an edge counts for rows in [min t, max t)
            if ((a[1] <= t && t < b[1]) || (b[1] <= t && t < a[1])) {
                const float sx = wp::add(a[0], wp::div(wp::mul(wp::sub(t, a[1]), wp::sub(b[0], a[0])), wp::sub(b[1], a[1])));
                smin = wp::min(smin, sx);
                smax = wp::max(smax, sx);
            }
        }
        if (smin <= smax) {
            int i0, i1;
            index_range(smin, smax, i0, i1);
            if (i0 <= i1) {
                const wp::uint32 ones = ~wp::uint32(0);
                mrow[j] = mrow[j] | ((ones >> wp::uint32(32 - (i1 - i0 + 1))) << wp::uint32(i0));
            }
        }
    }
    // fully blocked: no later triangle can change the mask
    if (q % 4 == 3) {
        bool done = true;
        for (int j = 0; j < k; ++j)
            done = done && mrow[j] == full;
        if (done)
            return q + 1;
    }
}
return q;
"""


@wp.func_native(_SCAN_KEPT)
def scan_kept(corners: wp.array[wp.vec3], keep: wp.array2d[int], kept: int, p: wp.vec3, nrm: wp.vec3, du: wp.vec3,
              dv: wp.vec3, s0: float, t0: float, k: int, masks: wp.array2d[wp.uint32], r: int) -> int:
    """Clip, project and scan-convert the ``kept`` triangles ``keep[r, :kept]`` (:func:`cull_batch`) into
    receiver ``r``'s mask (arguments as in :func:`rasterize_light_masks`); returns how many it took
    before the mask was full (all of them otherwise).

    Each triangle is clipped to ``1e-6 <= h <= 1`` (:func:`~warpshade.geometry.kernels.clip_polygon`),
    its corners taken to homogeneous light coordinates ``(s h, t h, h)`` (linear in X: the central
    projection X' = P + (X - P)/h has s = s0 + du·(X - P)/h with s0 = du·(P - c)) and rejected when
    all lie beyond one light edge. A projection reaching far past the light (a blocker close to the
    receiver, or a light seen almost edge-on), where float32 spans on huge coordinates lose samples, is
    clipped in homogeneous coordinates to ``|s|, |t| <= 1.5 h`` (GPU-style, well conditioned where 3-D
    planes through the receiver would be nearly parallel). Rows are then filled between the edges'
    crossings (half-open: an edge counts for rows in [min t, max t)), each span setting the bits of the
    cell-centre samples ``-1 + (2i+1)/k`` inside it. Native C++ calling the same Warp builtins in the same order as the Warp code it
    replaced, without fused multiply-adds: the same bits, several times faster.
    """


# -- GEARS visibility masks (the paper's step 4) ---------------------------------------------------
@wp.kernel
def rasterize_light_masks(
    points: wp.array[wp.vec3],
    normals: wp.array[wp.vec3],
    corners: wp.array[wp.vec3],
    offset: float,
    c: wp.vec3,
    u: wp.vec3,
    v: wp.vec3,
    du: wp.vec3,
    dv: wp.vec3,
    light_normal: wp.vec3,
    k: int,
    cell_of: wp.array[int],
    cell_start: wp.array[int],
    cell_count: wp.array[int],
    cell_tris: wp.array[int],
    cell_keys: wp.array[float],
    cull: int,
    keep: wp.array2d[int],
    masks: wp.array2d[wp.uint32],
    visibility: wp.array[float],
    form_factor: wp.array[float],
    tri_count: wp.array2d[int],
):
    """Per receiver: rasterize its blocker triangles, seen from it, onto the light's k×k mask.

    Each triangle is clipped to the part strictly between receiver P and the light's plane
    (``0 < h < 1`` with ``h(X) = n_L·(X-P) / n_L·(c-P)``), projected centrally from P onto the light
    plane (``X' = P + (X-P)/h``), expressed in light coordinates through the dual axes ``du, dv``
    (``s = du·(X'-c)``, computed homogeneously as ``(s h, t h, h)``, which is linear in X and is
    clipped to 1.5× the light when the projection would reach far past it), and scan-converted row
    by row into bit spans. ``cell_of[r] = -2`` means
    "all triangles" (brute force: ``cell_start[0] = 0``, ``cell_count[0] = F``). Each cell's list is
    sorted by the triangles' near height above the light: triangles no closer to the light than the
    receiver are skipped by a binary search (the near clip would reject them), and the rest are
    walked from the receiver toward the light, :data:`CULL_BATCH` at a time: :func:`cull_batch` drops
    those that cannot set a bit, :func:`scan_kept` clips and scan-converts the rest. ``corners[3 f + i]``: corner
    ``i`` of triangle ``f``; ``keep``: scratch, shape (V, CULL_BATCH); ``tri_count[r]``: (triangles
    the cull tested, triangles scan-converted).
    """
    r = wp.tid()
    n = normals[r]
    p = points[r] + n * offset
    for j in range(k):
        masks[r, j] = wp.uint32(0)
    denom = wp.dot(c - p, light_normal)
    cell = cell_of[r]
    tested = int(0)
    scanned = int(0)
    if denom != 0.0 and cell != -1:
        if cell == -2:
            cell = 0
        start = cell_start[cell]
        count = cell_count[cell]
        nrm = light_normal / denom  # h(X) = dot(X - p, nrm)
        s0 = wp.dot(p - c, du)
        t0 = wp.dot(p - c, dv)
        full = wp.uint32(0)
        full = ~full >> wp.uint32(32 - k)
        height = wp.abs(denom)
        # triangles with near height > receiver height cannot block (sorted: binary search the cut)
        lo = int(0)
        hi = count
        while lo < hi:
            mid = (lo + hi) / 2
            if cell_keys[start + mid] > height:
                hi = mid
            else:
                lo = mid + 1
        # walk from the receiver toward the light: near triangles subtend more of the light, so
        # fully shadowed receivers fill their mask and stop early
        e = int(0)
        done = bool(False)
        while e < lo and not done:
            nb = wp.min(CULL_BATCH, lo - e)
            kept = cull_batch(corners, cell_tris, start + lo - 1 - e, nb, p, nrm, du, dv, s0, t0, k, masks, r, cull,
                              keep)
            e += nb
            tested += nb
            scanned += scan_kept(corners, keep, kept, p, nrm, du, dv, s0, t0, k, masks, r)
            done = mask_full(masks, r, k, full)
    tri_count[r, 0] = tested
    tri_count[r, 1] = scanned
    dA = 4.0 * wp.length(wp.cross(u, v)) / float(k * k)
    res = summarize_mask(masks, r, k, points[r], n, c, u, v, light_normal, dA)
    visibility[r] = res[0]
    form_factor[r] = res[1]


# -- ray-traced reference --------------------------------------------------------------------------
@wp.kernel
def trace_light_masks(
    mesh: wp.uint64,
    points: wp.array[wp.vec3],
    normals: wp.array[wp.vec3],
    offset: float,
    c: wp.vec3,
    u: wp.vec3,
    v: wp.vec3,
    light_normal: wp.vec3,
    k: int,
    jitter: int,
    seed: int,
    masks: wp.array2d[wp.uint32],
    visibility: wp.array[float],
    form_factor: wp.array[float],
):
    """k×k stratified shadow rays from each receiver to the light (:func:`~warpshade.visibility.rays.trace_surface_ray`,
    near-field distance ``offset``: no origin pushed through a surface the receiver rests on).

    One ray per light cell, at the cell centre (``jitter = 0``, the same samples as the GEARS mask)
    or at a uniformly jittered point in the cell. Bits mark blocked rays like GEARS masks.
    """
    r = wp.tid()
    n = normals[r]
    p = points[r]
    eps = ray_eps(offset, p)
    near = near_faces(mesh, r, p, n, eps)
    rng = wp.rand_init(seed, r)
    dA = 4.0 * wp.length(wp.cross(u, v)) / float(k * k)
    blocked = int(0)
    ff = float(0.0)
    for j in range(k):
        row = wp.uint32(0)
        for i in range(k):
            ju = float(0.5)
            jv = float(0.5)
            if jitter != 0:
                ju = wp.randf(rng)
                jv = wp.randf(rng)
            s = -1.0 + 2.0 * (float(i) + ju) / float(k)
            t = -1.0 + 2.0 * (float(j) + jv) / float(k)
            q = light_point(c, u, v, s, t)
            d = q - p
            dist = wp.length(d)
            hit = bool(False)
            if dist > 0.0:
                # stop just short of the light so geometry lying in the light's plane does not count
                hit = trace_surface_ray(mesh, r, p, n, d / dist, eps, dist * (1.0 - 1.0e-6), near).face >= 0
            if hit:
                row = row | (wp.uint32(1) << wp.uint32(i))
                blocked += 1
            else:
                ff += light_sample_weight(points[r], n, q, light_normal) * dA
        masks[r, j] = row
    visibility[r] = 1.0 - float(blocked) / float(k * k)
    form_factor[r] = ff


# -- shading weight --------------------------------------------------------------------------------
@wp.kernel
def weight_visibility(
    points: wp.array[wp.vec3],
    normals: wp.array[wp.vec3],
    c: wp.vec3,
    u: wp.vec3,
    v: wp.vec3,
    light_normal: wp.vec3,
    k: int,
    clear: wp.array2d[wp.uint32],
    visibility: wp.array[float],
    form_factor: wp.array[float],
    weighted: wp.array[float],
):
    """Cosine-weighted visible fraction ``F_visible / F_all`` of the mask samples per receiver.

    ``F_all`` is :func:`summarize_mask` of an all-clear mask (``clear``, zeros, shape (V, k)), so the
    sums run over the same samples in the same order and an unblocked receiver gets exactly 1. Where
    no sample faces the receiver (``F_all = 0``) the plain visible fraction is used.
    """
    r = wp.tid()
    dA = 4.0 * wp.length(wp.cross(u, v)) / float(k * k)
    full = summarize_mask(clear, r, k, points[r], normals[r], c, u, v, light_normal, dA)[1]
    if full > 0.0:
        weighted[r] = wp.min(form_factor[r] / full, 1.0)
    else:
        weighted[r] = visibility[r]
