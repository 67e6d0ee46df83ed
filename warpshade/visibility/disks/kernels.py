"""Kernels of disk-hierarchy anisotropic occlusion (Gong et al.; Bunnell's disk form factors).

Direction bins: the receiver's hemisphere is split by a 4×4 grid (the paper's 16 directions) in
the square ``[0,1]²`` mapped onto the tangent-plane unit disk by the Shirley–Chiu concentric map.
The map preserves area, so every bin has the same projected (cosine-weighted) solid angle π/16;
occlusion of bin ``b`` is the fraction of that cosine measure that disks cover.
"""

from __future__ import annotations

import warp as wp

from ...sh.kernels import sh_accumulate, zh_rotate_accumulate
from ..rays import concentric_disk, orthonormal_basis

wp.set_module_options({"enable_backward": False})

GRID = 4
BINS = GRID * GRID
STACK = 64  # traversal stack; median splits keep the depth near log2(V), far below this
stack_t = wp.types.vector(length=STACK, dtype=int)
weights_t = wp.types.vector(length=STACK, dtype=float)
LOD_BAND = 1.5  # nodes between lod and LOD_BAND*lod radii blend parent and children (no popping)
CONTACT = 1.0e-3
"""Contact rule (:func:`contact_half_space`): a receiver within CONTACT × ρ of a leaf disk's plane (ρ the disk's
radius) is in contact with the surface the disk samples."""
CONTACT_LEANING = 2.0e-4
"""... but within CONTACT_LEANING × ρ only when the receiver's normal leans into the disk's back (``n·N <``
:data:`CONTACT_FACING`: a cube's base corner on a ground, n·N = -0.58, or a box's bottom face): float32 rounding of
a vertex in the plane (1.2e-5 m at 1 km, 1.1e-4 of a 0.1 m disk), where a cloth crossing itself at 131° passed
9e-4 ρ from another part's disk and went black."""
CONTACT_FACING = -0.5
"""``n·N`` below which a receiver leans into the disk's back (:data:`CONTACT_LEANING`)."""
CONTACT_REACH = 1.5
"""... when its foot lies within CONTACT_REACH × ρ of the disk's centre: vertex disks of a mesh do not tile its
surface (on a square grid a point of the plane can lie 1.25 ρ from the nearest vertex)."""
CONTACT_SAMPLES = 4  # per bin side: the contact half-space's coverage of a bin is a 4×4 midpoint rule


@wp.func
def concentric_inverse(x: float, y: float) -> wp.vec2:
    """Inverse of :func:`concentric_disk`: unit-disk point -> ``[0,1]²``."""
    r = wp.sqrt(x * x + y * y)
    if r == 0.0:
        return wp.vec2(0.5, 0.5)
    phi = wp.atan2(y, x)
    q = wp.pi / 4.0
    if phi < -q:
        phi += 2.0 * wp.pi
    a = float(0.0)
    b = float(0.0)
    if phi < q:
        a = r
        b = phi * a / q
    elif phi < 3.0 * q:
        b = r
        a = -(phi - 2.0 * q) * b / q
    elif phi < 5.0 * q:
        a = -r
        b = (phi - 4.0 * q) * a / q
    else:
        b = -r
        a = -(phi - 6.0 * q) * b / q
    return wp.vec2(0.5 * (a + 1.0), 0.5 * (b + 1.0))


@wp.func
def box_overlap(lo: float, hi: float, cell: int) -> float:
    """Length of ``[lo, hi] ∩ [cell/4, (cell+1)/4]``."""
    a = wp.max(lo, float(cell) / float(GRID))
    b = wp.min(hi, float(cell + 1) / float(GRID))
    return wp.max(0.0, b - a)


# -- per-frame disks and hierarchy ------------------------------------------------------------------
@wp.kernel
def accumulate_disk_areas(points: wp.array[wp.vec3], faces: wp.array2d[wp.int32], areas: wp.array[float]):
    """Disk area of each vertex: a third of each incident triangle's area (the one-ring's barycentric share)."""
    f = wp.tid()
    i = faces[f, 0]
    j = faces[f, 1]
    k = faces[f, 2]
    a = 0.5 * wp.length(wp.cross(points[j] - points[i], points[k] - points[i])) / 3.0
    wp.atomic_add(areas, i, a)
    wp.atomic_add(areas, j, a)
    wp.atomic_add(areas, k, a)


@wp.kernel
def set_leaf_disks(
    points: wp.array[wp.vec3],
    normals: wp.array[wp.vec3],
    areas: wp.array[float],
    leaf_of_vertex: wp.array[int],
    node_pos: wp.array[wp.vec3],
    node_nrm: wp.array[wp.vec3],
    node_area: wp.array[float],
    node_radius: wp.array[float],
    node_coherence: wp.array[float],
    node_cone: wp.array[float],
):
    """Leaf disk = the vertex: position, unit normal, area; bounding radius sqrt(A/π); coherence 1; normal cone 0."""
    v = wp.tid()
    node = leaf_of_vertex[v]
    node_pos[node] = points[v]
    node_nrm[node] = normals[v]
    node_area[node] = areas[v]
    node_radius[node] = wp.sqrt(areas[v] / wp.pi)
    node_coherence[node] = 1.0
    node_cone[node] = 0.0


@wp.kernel
def merge_child_disks(
    level: wp.array[int],
    left: wp.array[int],
    right: wp.array[int],
    node_pos: wp.array[wp.vec3],
    node_nrm: wp.array[wp.vec3],
    node_area: wp.array[float],
    node_radius: wp.array[float],
    node_coherence: wp.array[float],
    node_cone: wp.array[float],
):
    """Parent disk from its two children (the paper: "a larger disk whose value is the average").

    Area = sum; centre = area-weighted mean; normal = normalised area-weighted mean; coherence =
    |Σ a n| / Σ a (1 for a flat cluster, 0 for a closed one) feeds the projected-area estimate in
    :func:`disk_form_factor`; radius bounds both children's spheres (for the LOD test) and the
    cone half-angle [rad] around the normal bounds all leaf normals (for back-face culling).
    """
    node = level[wp.tid()]
    l = left[node]
    r = right[node]
    al = node_area[l]
    ar = node_area[r]
    a = al + ar
    c = (node_pos[l] + node_pos[r]) * 0.5
    if a > 0.0:
        c = (node_pos[l] * al + node_pos[r] * ar) / a
    s = node_nrm[l] * (al * node_coherence[l]) + node_nrm[r] * (ar * node_coherence[r])
    ls = wp.length(s)
    n = wp.vec3(0.0, 0.0, 1.0)
    coh = float(0.0)
    if ls > 0.0:
        n = s / ls
        if a > 0.0:
            coh = wp.min(1.0, ls / a)
    node_pos[node] = c
    node_nrm[node] = n
    node_area[node] = a
    node_coherence[node] = coh
    cone_l = wp.acos(wp.clamp(wp.dot(n, node_nrm[l]), -1.0, 1.0)) + node_cone[l]
    cone_r = wp.acos(wp.clamp(wp.dot(n, node_nrm[r]), -1.0, 1.0)) + node_cone[r]
    node_cone[node] = wp.min(wp.pi, wp.max(cone_l, cone_r))
    node_radius[node] = wp.max(wp.length(node_pos[l] - c) + node_radius[l], wp.length(node_pos[r] - c) + node_radius[r])


@wp.kernel
def merge_child_access(level: wp.array[int], left: wp.array[int], right: wp.array[int],
                       node_area: wp.array[float], node_access: wp.array[float]):
    """Parent accessibility = area-weighted mean of its children's (for the second pass)."""
    node = level[wp.tid()]
    l = left[node]
    r = right[node]
    a = node_area[l] + node_area[r]
    acc = 0.5 * (node_access[l] + node_access[r])
    if a > 0.0:
        acc = (node_access[l] * node_area[l] + node_access[r] * node_area[r]) / a
    node_access[node] = acc


@wp.kernel
def set_leaf_access(occlusion: wp.array2d[float], leaf_of_vertex: wp.array[int], node_access: wp.array[float]):
    """Leaf accessibility = 1 - ambient occlusion = mean over bins of the visible fraction."""
    v = wp.tid()
    s = float(0.0)
    for b in range(BINS):
        s += wp.min(1.0, occlusion[v, b])
    node_access[leaf_of_vertex[v]] = 1.0 - s / float(BINS)


# -- occlusion -------------------------------------------------------------------------------------
@wp.func
def disk_form_factor(x: wp.vec3, n: wp.vec3, c: wp.vec3, ne: wp.vec3, area: float, coherence: float,
                     back_weight: float) -> float:
    """Fraction of the receiver's cosine-weighted hemisphere (π) covered by a disk (thesis eq. 3.44).

    ``F = A cos θ_e cos θ_p / (π r² + A)`` is exact for a disk facing the receiver on its axis.
    For cluster disks the projected area ``A cos θ_e`` is blended toward ``A/4`` (the mean projected
    area of a closed surface, Cauchy) by ``1 - coherence``. Disks seen from behind count with
    ``back_weight`` (0: one-sided, 1: two-sided); disks below the receiver's horizon cover nothing
    (with a smooth blend across it).
    """
    d = c - x
    r2 = wp.dot(d, d)
    if r2 == 0.0 or area <= 0.0:
        return 0.0
    dist = wp.sqrt(r2)
    w = d / dist
    # A disk whose centre is just below the horizon still pokes above it: with the disk radius rho
    # and height z = n·d, use (z + rho)² / (4 rho r) for |z| < rho, the C1 blend between 0
    # (entirely below) and the cosine z / r (entirely above).
    rho = wp.sqrt(area / wp.pi)
    z = wp.dot(n, d)
    cp = z / dist
    if z <= -rho:
        return 0.0
    if z < rho:
        cp = (z + rho) * (z + rho) / (4.0 * rho * dist)
    ce = -wp.dot(ne, w)
    if ce < 0.0:
        ce = -ce * back_weight
    proj = area * (coherence * ce + (1.0 - coherence) * 0.25)
    return proj * cp / (wp.pi * r2 + area)


@wp.func
def splat_bins(x: wp.vec3, frame: wp.mat33, c: wp.vec3, ff: float, area: float, row: int,
               occlusion: wp.array2d[float], centroid_u: wp.array2d[float], centroid_v: wp.array2d[float]):
    """Spread form factor ``ff`` over the 16 bins with a box footprint of the disk's angular size.

    Each bin holds π/16 of the cosine measure, so a fraction ``ff`` of π landing in one bin
    occludes ``16 ff`` of it (eq. 5's per-direction coverage, normalised to conserve the total).
    Beyond the paper, each bin also accumulates the occlusion-weighted centroid (in the concentric
    square) of what covers it, so the SH integral can place a partial occlusion where it is.
    """
    d = c - x
    r2 = wp.dot(d, d)
    w = d / wp.sqrt(r2)
    local = wp.transpose(frame) * w
    uv = concentric_inverse(local[0], local[1])
    # disk angular radius: sin² α = A / (π r² + A); the unit disk spans [0,1] so half that size
    half = wp.max(0.5 * wp.sqrt(area / (wp.pi * r2 + area)), 1.0e-4)
    u0 = wp.max(0.0, uv[0] - half)
    u1 = wp.min(1.0, uv[0] + half)
    v0 = wp.max(0.0, uv[1] - half)
    v1 = wp.min(1.0, uv[1] + half)
    norm = (u1 - u0) * (v1 - v0)
    if norm <= 0.0:
        return
    scale = ff * float(BINS) / norm
    # only the bins under the footprint (most disks are small and touch one or two)
    i0 = wp.min(int(u0 * float(GRID)), GRID - 1)
    i1 = wp.min(int(u1 * float(GRID)), GRID - 1)
    j0 = wp.min(int(v0 * float(GRID)), GRID - 1)
    j1 = wp.min(int(v1 * float(GRID)), GRID - 1)
    for i in range(i0, i1 + 1):
        ou = box_overlap(u0, u1, i)
        if ou > 0.0:
            cu = wp.clamp(uv[0], float(i) / float(GRID), float(i + 1) / float(GRID))
            for j in range(j0, j1 + 1):
                ov = box_overlap(v0, v1, j)
                if ov > 0.0:
                    cv = wp.clamp(uv[1], float(j) / float(GRID), float(j + 1) / float(GRID))
                    b = i * GRID + j
                    o = scale * ou * ov
                    occlusion[row, b] = occlusion[row, b] + o
                    centroid_u[row, b] = centroid_u[row, b] + o * cu
                    centroid_v[row, b] = centroid_v[row, b] + o * cv


@wp.func
def edge_neighbour(i: int, j: int, ring_start: wp.array[int], ring: wp.array[int]) -> bool:
    """Whether vertex j is one edge away from vertex i (CSR adjacency)."""
    for k in range(ring_start[i], ring_start[i + 1]):
        if ring[k] == j:
            return True
    return False


@wp.func
def contact_foot(d: wp.vec3, ne: wp.vec3, n: wp.vec3, area: float) -> float:
    """Distance, in disk radii ρ = sqrt(A/π), from a leaf disk's centre (``d`` = centre - receiver, ``ne`` its
    normal) to the receiver's foot in its plane when the receiver touches it (within :data:`CONTACT` ρ of the
    plane; within :data:`CONTACT_LEANING` ρ when its normal ``n`` leans into the disk's back, ``n·ne <``
    :data:`CONTACT_FACING`: a box's base corner on a ground); :data:`CONTACT_REACH` (no contact) otherwise.
    Disks of the receiver's edge neighbours (its own sheet) are left out by the caller.
    """
    h = wp.dot(ne, d)
    tol = wp.where(wp.dot(n, ne) >= CONTACT_FACING, CONTACT, CONTACT_LEANING)
    if area <= 0.0 or wp.pi * h * h > tol * tol * area:  # the usual case, without a square root
        return float(CONTACT_REACH)
    rho = wp.sqrt(area / wp.pi)
    s = wp.length(d - ne * h)
    if s < CONTACT_REACH * rho:
        return s / rho
    return float(CONTACT_REACH)


@wp.func
def contact_half_space(frame: wp.mat33, ne: wp.vec3, row: int, occlusion: wp.array2d[float],
                       centroid_u: wp.array2d[float], centroid_v: wp.array2d[float]):
    """Occlusion by the surface a receiver stands on: every direction behind its plane (``w·ne < 0``).

    A post standing on a floor puts its base vertices in the floor's plane, where each floor disk is edge-on
    and covers nothing (:func:`disk_form_factor`); seen from just above (the floor's front, where the post
    stands) the floor covers the whole half-space below, as a renderer's ray from the base sees it. Each bin
    gets the covered fraction of its cosine measure (a :data:`CONTACT_SAMPLES`² midpoint rule in the
    concentric square) and that part's centroid, like :func:`splat_bins`.
    """
    cell = 1.0 / float(GRID)
    for b in range(BINS):
        bi = b / GRID
        bj = b % GRID
        hit = float(0.0)
        su = float(0.0)
        sv = float(0.0)
        for si in range(CONTACT_SAMPLES):
            for sj in range(CONTACT_SAMPLES):
                u = (float(bi) + (float(si) + 0.5) / float(CONTACT_SAMPLES)) * cell
                w = (float(bj) + (float(sj) + 0.5) / float(CONTACT_SAMPLES)) * cell
                d2 = concentric_disk(u, w)
                z = wp.sqrt(wp.max(0.0, 1.0 - wp.dot(d2, d2)))
                if wp.dot(frame * wp.vec3(d2[0], d2[1], z), ne) < 0.0:
                    hit += 1.0
                    su += u
                    sv += w
        if hit > 0.0:
            o = hit / float(CONTACT_SAMPLES * CONTACT_SAMPLES)
            occlusion[row, b] = occlusion[row, b] + o
            centroid_u[row, b] = centroid_u[row, b] + o * su / hit
            centroid_v[row, b] = centroid_v[row, b] + o * sv / hit


@wp.kernel
def accumulate_occlusion(
    points: wp.array[wp.vec3],
    normals: wp.array[wp.vec3],
    left: wp.array[int],
    right: wp.array[int],
    node_vertex: wp.array[int],
    ring_start: wp.array[int],
    ring: wp.array[int],
    node_pos: wp.array[wp.vec3],
    node_nrm: wp.array[wp.vec3],
    node_area: wp.array[float],
    node_radius: wp.array[float],
    node_coherence: wp.array[float],
    node_cone: wp.array[float],
    node_access: wp.array[float],
    use_access: int,
    lod: float,
    back_weight: float,
    occlusion: wp.array2d[float],
    centroid_u: wp.array2d[float],
    centroid_v: wp.array2d[float],
    visited: wp.array[int],
):
    """Per receiver vertex: walk the disk tree and add every disk's coverage to its 16 direction bins.

    A node whose bounding sphere is farther than ``LOD_BAND * lod`` radii stands for its subtree
    (level of detail by distance); closer than ``lod`` radii its children are visited; in between
    both are used with smoothstep weights, so a deforming mesh never pops between levels. Subtrees
    below the receiver's horizon are skipped (exact), and with one-sided disks so are subtrees whose
    normal cone faces away from the receiver (their only loss is the A/4 term of incoherent
    clusters, which back-facing clusters should not have). Leaves are
    vertex disks; the receiver's own is skipped. A receiver touching a leaf disk of another sheet (not an
    edge neighbour, ``ring_start``/``ring`` its CSR adjacency) gets the contact half-space
    (:func:`contact_foot`, :func:`contact_half_space`) once, from the disk nearest its foot. With ``use_access`` (second pass, Bunnell) each
    disk's coverage is scaled by its accessibility from the first pass, which discounts occluders
    that are themselves hidden.
    """
    v = wp.tid()
    x = points[v]
    n = normals[v]
    frame = orthonormal_basis(n)
    for b in range(BINS):
        occlusion[v, b] = 0.0
        centroid_u[v, b] = 0.0
        centroid_v[v, b] = 0.0
    stack = stack_t()
    weight = weights_t()
    stack[0] = 0
    weight[0] = 1.0
    top = int(1)
    count = int(0)
    contact = float(CONTACT_REACH)  # best foot distance (in disk radii) of a contact disk so far
    contact_nrm = wp.vec3(0.0)
    while top > 0:
        top -= 1
        node = stack[top]
        wn = weight[top]
        leaf = left[node] < 0
        if leaf and node_vertex[node] == v:
            continue
        c = node_pos[node]
        d = c - x
        dist = wp.length(d)
        radius = node_radius[node]
        if leaf:
            foot = contact_foot(d, node_nrm[node], n, node_area[node])
            if foot < contact and not edge_neighbour(v, node_vertex[node], ring_start, ring):
                contact = foot
                contact_nrm = node_nrm[node]
        # Subtree entirely below the receiver's horizon (its own disk included): nothing to add.
        if wp.dot(n, d) <= -wp.max(radius, wp.sqrt(node_area[node] / wp.pi)):
            continue
        # One-sided: subtree whose every disk faces away (normal cone + view cone within 90°).
        if back_weight == 0.0 and dist > radius:
            view = wp.asin(wp.min(1.0, radius / dist))
            facing = wp.acos(wp.clamp(wp.dot(node_nrm[node], d / dist), -1.0, 1.0))
            if facing + node_cone[node] + view <= 0.5 * wp.pi:
                continue
        ratio = dist / wp.max(lod * radius, 1.0e-30)
        use = float(1.0)
        if not leaf:
            # 0 below lod radii, 1 beyond LOD_BAND * lod radii, smoothstep in between
            use = wp.smoothstep(1.0, LOD_BAND, ratio)
        if use > 0.0:
            count += 1
            ff = disk_form_factor(x, n, c, node_nrm[node], node_area[node], node_coherence[node], back_weight)
            if ff > 0.0:
                if use_access != 0:
                    ff = ff * node_access[node]
                splat_bins(x, frame, c, ff * wn * use, node_area[node], v, occlusion, centroid_u, centroid_v)
        if use < 1.0 and top + 2 <= STACK:
            stack[top] = left[node]
            stack[top + 1] = right[node]
            weight[top] = wn * (1.0 - use)
            weight[top + 1] = wn * (1.0 - use)
            top += 2
    if contact < CONTACT_REACH:
        contact_half_space(frame, contact_nrm, v, occlusion, centroid_u, centroid_v)
    visited[v] = count


@wp.kernel
def combine_passes(
    occ1: wp.array2d[float],
    cu1: wp.array2d[float],
    cv1: wp.array2d[float],
    occ2: wp.array2d[float],
    cu2: wp.array2d[float],
    cv2: wp.array2d[float],
    passes: int,
    occlusion: wp.array2d[float],
    centroid: wp.array3d[float],
):
    """Bin occlusion clamped to [0, 1] and its centroid in the concentric square, shape (V, 16, 2).

    One pass, or the mean of passes 1 and 2 (Bunnell: the first over-, the second under-estimates
    overlapping occluders). Empty bins get their centre as centroid.
    """
    v, b = wp.tid()
    o = occ1[v, b]
    su = cu1[v, b]
    sv = cv1[v, b]
    oc = wp.min(1.0, o)
    if passes > 1:
        oc = 0.5 * (oc + wp.min(1.0, occ2[v, b]))
        o += occ2[v, b]
        su += cu2[v, b]
        sv += cv2[v, b]
    occlusion[v, b] = oc
    bi = b / GRID
    bj = b % GRID
    if o > 0.0:
        centroid[v, b, 0] = su / o
        centroid[v, b, 1] = sv / o
    else:
        centroid[v, b, 0] = (float(bi) + 0.5) / float(GRID)
        centroid[v, b, 1] = (float(bj) + 0.5) / float(GRID)


# -- shading ---------------------------------------------------------------------------------------
@wp.kernel
def integrate_disk_transfer(
    normals: wp.array[wp.vec3],
    occlusion: wp.array2d[float],
    centroid: wp.array3d[float],
    cosine_zh: wp.array2d[float],
    kz: wp.array[float],
    samples: int,
    order: int,
    k: wp.array[float],
    transfer: wp.array2d[float],
):
    """Diffuse transfer (docs/conventions.md §2): analytic unoccluded transfer minus the occluded bins.

    ``T = sqrt(4π/(2l+1)) A_l y_lm(n) - Σ_b ∫_{occluded part of b} y cos dω``. The occluded part of
    bin b is modelled as a square of area ``O_b`` (in bin units) around the occluders' centroid,
    kept inside the bin; its integral is a ``samples²`` midpoint rule in the concentric square, i.e.
    equal-weight cosine-distributed directions of weight ``O_b π / (16 samples²)``. An unoccluded
    vertex is therefore exact, and a fully occluded bin integrates the whole bin.
    """
    v = wp.tid()
    n = normals[v]
    frame = orthonormal_basis(n)
    for i in range(order * order):
        transfer[v, i] = 0.0
    # unoccluded part: the clamped cosine's zonal coefficients A_l (row 0 of cosine_zh) rotated to n
    zh_rotate_accumulate(n, cosine_zh, 0, 1.0, order, kz, transfer, v)
    cell = 1.0 / float(GRID)
    for b in range(BINS):
        o = occlusion[v, b]
        if o > 0.0:
            bi = b / GRID
            bj = b % GRID
            side = wp.sqrt(o) * cell
            lo_u = float(bi) * cell
            lo_v = float(bj) * cell
            cu = wp.clamp(centroid[v, b, 0], lo_u + 0.5 * side, lo_u + cell - 0.5 * side)
            cv = wp.clamp(centroid[v, b, 1], lo_v + 0.5 * side, lo_v + cell - 0.5 * side)
            weight = -o * wp.pi / float(BINS * samples * samples)
            for si in range(samples):
                for sj in range(samples):
                    u = cu + side * ((float(si) + 0.5) / float(samples) - 0.5)
                    w = cv + side * ((float(sj) + 0.5) / float(samples) - 0.5)
                    d2 = concentric_disk(u, w)
                    z = wp.sqrt(wp.max(0.0, 1.0 - wp.dot(d2, d2)))
                    sh_accumulate(frame * wp.vec3(d2[0], d2[1], z), weight, order, k, transfer, v)


@wp.kernel
def lookup_light_visibility(
    points: wp.array[wp.vec3],
    normals: wp.array[wp.vec3],
    occlusion: wp.array2d[float],
    direction: wp.vec3,
    position: wp.vec3,
    is_point: int,
    visibility: wp.array[float],
):
    """Visibility toward a light: bilinear interpolation of the 16 bins' ``1 - O`` at the light direction.

    ``direction`` points toward a directional light; point and spot lights use ``position``. Below
    the receiver's horizon the surface itself blocks the light: 0.
    """
    v = wp.tid()
    x = points[v]
    n = normals[v]
    w = direction
    if is_point != 0:
        w = position - x
    lw = wp.length(w)
    if lw == 0.0:
        visibility[v] = 1.0
        return
    w = w / lw
    if wp.dot(w, n) <= 0.0:
        visibility[v] = 0.0
        return
    local = wp.transpose(orthonormal_basis(n)) * w
    uv = concentric_inverse(local[0], local[1])
    # bin centres sit at (i + 0.5)/4: interpolate between the nearest four (clamped at the rim)
    fu = wp.clamp(uv[0] * float(GRID) - 0.5, 0.0, float(GRID - 1))
    fv = wp.clamp(uv[1] * float(GRID) - 0.5, 0.0, float(GRID - 1))
    i0 = wp.min(int(fu), GRID - 2)
    j0 = wp.min(int(fv), GRID - 2)
    tu = fu - float(i0)
    tv = fv - float(j0)
    o00 = occlusion[v, i0 * GRID + j0]
    o10 = occlusion[v, (i0 + 1) * GRID + j0]
    o01 = occlusion[v, i0 * GRID + j0 + 1]
    o11 = occlusion[v, (i0 + 1) * GRID + j0 + 1]
    o = (1.0 - tu) * ((1.0 - tv) * o00 + tv * o01) + tu * ((1.0 - tv) * o10 + tv * o11)
    visibility[v] = 1.0 - wp.clamp(o, 0.0, 1.0)
