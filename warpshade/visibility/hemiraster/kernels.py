"""Kernels of hemispherical rasterization (Kautz et al. 2004); orchestration lives in :mod:`.method`.

Per frame: :func:`follow_coarse_points` (coarse vertices ride the fine mesh), :func:`refit_blocker_boxes`
and :func:`union_boxes` (bounding boxes of blockers with their fine triangles, clusters, super-clusters), :func:`triangle_bounds` (per-triangle plane and
bounding sphere, for pre-tests without vertex gathers), then one :func:`rasterize_masks` launch
that, per receiver vertex, rasterizes blockers into a bit mask; :mod:`.integrate` turns the masks
into SH transfer. Mask layout, LUT convention and block tables: :mod:`.tables`.
"""

from __future__ import annotations

import warp as wp

from ..rays import orthonormal_basis
from .tables import CHUNK_WORDS, COPLANAR, COPLANAR_NEAR

# forward only (nothing here is differentiated): half the generated code and compile time. No fused
# multiply-adds: then ``b × a`` is exactly ``-(a × b)`` (both products of each component are computed
# and rounded alike), so the two triangles sharing an edge get exactly opposite edge planes
# (:func:`edge_plane`) and complementary masks without ordering the corners first. Fixed loops of at
# most 8 iterations are unrolled (Warp's default is 16): the loops over a chunk's 16 words in
# :func:`queue_fine_set` and :func:`rasterize_mid_set` stay loops, whose bodies unrolled 16 times made
# the module's compile take 3.4x as long.
wp.set_module_options({"enable_backward": False, "optimization_level": 3, "fuse_fp": False, "max_unroll": 8})

class MaskChunk(wp.types.vector(length=CHUNK_WORDS, dtype=wp.uint64)):
    """16 mask words handled as one value: ``&``, ``|``, ``^`` of two chunks compile to four 256-bit
    instructions on the CPU (clang's tuning for this host prefers 256-bit vectors to AVX-512's), so a
    whole chunk is fetched and combined without a loop or a branch per word."""


@wp.struct
class PlaneLut:
    """The plane LUT and how triangles use it (see :mod:`.tables`)."""

    rows: wp.array2d[MaskChunk]
    """Mask words above each quantised plane of the positive cube faces, cell-major in chunks of
    16 words: shape (3R², C) with C = ceil(W/16), dtype :class:`MaskChunk` (words past W are 0;
    :func:`.tables.chunked_rows`). A negative face's row is the complement (within the valid
    pixels) of its mirror cell's row (:mod:`.tables`), so only half the table is stored."""
    valid: wp.array[MaskChunk]
    """Valid pixels of each chunk of mask words, shape (C,)."""
    chunks: int
    """Chunks per mask C."""
    res: int
    """Cube-map resolution R."""
    words: int
    """Words per mask W."""
    backface: float
    """Skip triangles with ``det * backface > 0`` (0: keep both sides)."""
    min_area: float
    """Skip triangles whose projected solid angle bound is below this disk area (0: keep all)."""
    fine_area: float
    """Tiny-image cull (as ``min_area``) for the fine triangles of refined blockers (0: keep all)."""
    rim: float
    """Sine of the elevation of the lowest valid pixel centre: images wholly below it hold no pixel."""
    direct: float
    """Direct rasterization of the coarse far field's small images (:func:`far_field_bits`; the method's
    ``direct_far``): how far (disk units) the LUT's quantised planes may reach past the exact ones, the
    widening of the box of a blocker's corners' disk images; < 0: off."""
    lut_half: float
    """Half the LUT's cube-map resolution, ``R/2``."""
    lut_last: float
    """The last cell index of the cube map, ``R - 1``."""
    half_mask: float
    """Half the mask resolution, ``M/2`` (disk units to pixel units)."""


@wp.struct
class FineMesh:
    """The full-resolution blocker scene (receiver mesh, then static occluders) this frame."""

    points: wp.array[wp.vec3]
    """Vertex positions [m], shape (V + occluder vertices,), dtype vec3; the first V are the receivers."""
    faces: wp.array2d[wp.int32]
    """Triangles, shape (F + occluder triangles, 3), dtype int32."""
    plane: wp.array[wp.vec4]
    """Per triangle (N, N·a) with N = (b-a)×(c-a) (:func:`triangle_bounds`), dtype vec4."""
    sphere: wp.array[wp.vec4]
    """Per triangle bounding sphere (centroid [m], radius [m]), dtype vec4."""
    nlen: wp.array[float]
    """Per triangle ``|N|`` of ``plane`` (:func:`triangle_bounds`; read by :func:`bounds_below`)."""
    fan_start: wp.array[wp.int32]
    """CSR offsets into ``fan_tris`` per receiver, shape (V+1,), dtype int32."""
    fan_tris: wp.array[wp.int32]
    """Triangles incident to each receiver, dtype int32 (:func:`rasterize_fan`)."""
    fan: int
    """1: rasterize the receiver's own fan as seen from just above it (:func:`rasterize_fan`); 0: off
    (closed meshes, where the back faces already block those directions)."""


@wp.struct
class Blockers:
    """The far-field blocker triangles: the coarse mesh (or the fine scene without the hierarchy),
    in cluster order, with their per-frame bounds."""

    points: wp.array[wp.vec3]
    """Blocker vertex positions [m], dtype vec3."""
    faces: wp.array2d[wp.int32]
    """Blocker triangles in cluster order, shape (Fc, 3), dtype int32."""
    plane: wp.array[wp.vec4]
    """Per blocker (N, N·a) (:func:`triangle_bounds`), dtype vec4."""
    sphere: wp.array[wp.vec4]
    """Per blocker bounding sphere (centroid [m], radius [m]), dtype vec4."""
    nlen: wp.array[float]
    """Per blocker ``|N|`` of ``plane`` (:func:`triangle_bounds`)."""
    source: wp.array[wp.int32]
    """Index of each blocker before the cluster reordering (exclusion and PVS bits), dtype int32."""
    order: wp.array[wp.int32]
    """Reordered index of each blocker by its index before the reordering (inverse of ``source``), dtype int32."""
    refined: wp.array2d[wp.uint64]
    """Per slot, bits of the blockers refined for its current receiver (:func:`mark_refined`), shape
    (slots, ceil(Fc/64)); all 0 without refinement and k-ring exclusion bits."""
    skip_incident: int
    """1 when the blockers are the fine triangles themselves (skip those incident to the receiver)."""
    precull: int
    """1: the per-frame culls and refinement bits of every blocker are computed for each receiver in
    one vectorized pass before the far field (:func:`far_field_bits`; a coarse far field of a few
    hundred blockers); 0: per cluster that reaches above the tangent plane (the full mesh)."""
    cull: wp.array2d[wp.uint64]
    """Per slot, bits of the blockers :func:`skip_early` culls for the current receiver (``precull``),
    shape (slots, ceil(Fc/64))."""
    tiny: wp.array2d[wp.uint64]
    """Per slot, bits of the blockers :func:`bounds_below` deems tiny (``precull``), as ``cull``."""
    corners: wp.array2d[float]
    """The blockers' corners [m] (rows x, y, z of a, b, c: :func:`blocker_corners`, for
    :func:`far_field_bits`' empty-image cull), shape (9, Fc); (9, 1) when that cull is off."""
    ring: wp.array2d[wp.uint64]
    """Per receiver, bits (reordered index) of the blockers standing for its k-ring (``near_mode`` 2,
    the exclusion bits of ``excl`` reordered), shape (V, ceil(Fc/64)); (1, 1) otherwise."""


@wp.struct
class Refinement:
    """Coarse-to-fine map and per-frame bounds of the spatial near-field refinement (:mod:`.hierarchy`)."""

    refine: float
    """Refinement radius in deviations (0: off)."""
    lo: wp.array[wp.vec3]
    """Per blocker: box corner [m] over it and its fine triangles, shape (Fc,), dtype vec3."""
    hi: wp.array[wp.vec3]
    """Per blocker: the other box corner [m], shape (Fc,), dtype vec3."""
    dev: wp.array[float]
    """Per blocker: deviation from its primary fine triangles [m] (:func:`refit_blocker_boxes`), shape (Fc,)."""
    start: wp.array[wp.int32]
    """CSR offsets into ``tris`` per blocker, shape (Fc+1,), dtype int32."""
    mid: wp.array[wp.int32]
    """Per blocker: end of its primary fine triangles (extras follow), shape (Fc,), dtype int32."""
    tris: wp.array[wp.int32]
    """Fine triangle indices, primaries then extras per blocker, dtype int32."""
    owner: wp.array[wp.int32]
    """Primary blocker of each entry of ``tris`` (reordered index), dtype int32; a blocker's extras
    are sorted by it."""
    run_end: wp.array[wp.int32]
    """End of each entry's run of extras with the same owner (:func:`.hierarchy.groups_in_order`), dtype int32."""
    seen: wp.array2d[wp.uint64]
    """Per slot, bits of the fine triangles already rasterized for its current receiver, shape
    (slots, ceil(F/64)); cleared at the start of each receiver."""
    use_seen: int
    """1: skip fine triangles already in ``seen`` (a seam triangle belongs to several refined coarse
    triangles; OR fusion makes the repeat harmless but not free); 0: no such table (large meshes)."""
    use_set: int
    """1: the far-field pass collects what its refined blockers list as a bit set (``listed``), handled
    after the far field (:func:`rasterize_mid_set`, :func:`rasterize_fine_set`); 0: each refined
    blocker's group is walked when the pass visits it (:func:`rasterize_group`; also while recording
    a PVS, which credits each triangle to the blocker whose group listed it)."""
    cover: wp.array2d[MaskChunk]
    """Per blocker (reordered index), bits of every triangle its group lists (primaries and seam-cover
    extras) in chunks of 16 words, shape (Fc, ceil(count/1024)) (:func:`.hierarchy.group_bits`)."""
    primary: wp.array2d[MaskChunk]
    """Per blocker, bits of its primary triangles, as ``cover``."""
    listed: wp.array2d[MaskChunk]
    """Per slot, OR of ``cover`` over the refined blockers the far-field pass visited for the current
    receiver, shape (slots, ceil(count/1024)); cleared when the set is handled."""
    visited: wp.array2d[wp.uint64]
    """Per slot, bits of those visited refined blockers, shape (slots, ceil(Fc/64))."""


@wp.struct
class MidLevel:
    """The mid mesh between the coarse and the fine one (``mid`` knob): a refined coarse blocker is
    replaced by the mid triangles it stands for (:class:`Refinement` ``groups`` then maps coarse to
    mid triangles), and only the mid triangles near the receiver by their fine triangles (``sub``)."""

    on: int
    """1: the coarse blockers' groups list mid triangles (this level is used); 0: they list fine ones."""
    points: wp.array[wp.vec3]
    """Mid vertex positions [m] (riding the fine surface), dtype vec3."""
    faces: wp.array2d[wp.int32]
    """Mid triangles, shape (Fm, 3), dtype int32."""
    plane: wp.array[wp.vec4]
    """Per mid triangle (N, N·a) (:func:`triangle_bounds`), dtype vec4."""
    sphere: wp.array[wp.vec4]
    """Per mid triangle bounding sphere, dtype vec4."""
    coarse: wp.array[wp.int32]
    """Primary coarse blocker (reordered index) of each mid triangle, shape (Fm,), dtype int32."""
    ring_start: wp.array[wp.int32]
    """CSR offsets per receiver into ``ring_tris``, shape (V+1,), dtype int32."""
    ring_tris: wp.array[wp.int32]
    """Mid triangles standing for each receiver's k-ring: always replaced by their fine triangles, dtype int32."""
    ring_bits: wp.array2d[wp.uint64]
    """Per slot, bits of the current receiver's ``ring_tris``, shape (slots, ceil(Fm/64)); set at the
    start of each receiver and cleared at its end."""
    counts: wp.array[wp.int32]
    """Mid triangles queued per receiver, shape (V,)."""


@wp.struct
class Batch:
    """Per slot (:func:`rasterize_masks`) queue of blocker triangles that passed the culls, rasterized in batches
    (:func:`flush_batch`): the LUT codes of a whole batch are computed in one branch-free loop, so
    the core overlaps the triangles' divisions and loads instead of stalling on each after a
    mispredicted cull."""

    a: wp.array2d[wp.vec3]
    """First corner relative to the receiver [m], world axes, shape (slots, B), dtype vec3."""
    b: wp.array2d[wp.vec3]
    """Second corner, shape (slots, B), dtype vec3."""
    c: wp.array2d[wp.vec3]
    """Third corner, shape (slots, B), dtype vec3."""
    src: wp.array2d[wp.int32]
    """Blocker to mark in the receiver's PVS bits when the triangle sets a bit (-1: none), shape (slots, B)."""
    area: wp.array2d[float]
    """Tiny-image threshold of each queued triangle (:func:`image_below`'s ``min_area``; 0: no such
    test), shape (slots, B)."""
    fine_flag: wp.array2d[wp.int32]
    """1 for a fine triangle standing in for a refined blocker (counted in ``refined`` when its image
    is not tiny), shape (slots, B)."""
    codes: wp.array2d[wp.vec3i]
    """Scratch: LUT codes of the three oriented edge planes (-1: culled), shape (slots, B)."""
    cand: wp.array2d[wp.int32]
    """Scratch: fine triangles of a refined group that passed the culls from per-frame data
    (:func:`stage_fine`), waiting for the gathers and the exact tests (:func:`queue_candidates`),
    shape (slots, :data:`CANDIDATES`)."""
    record: int
    """1 while recording a PVS (``hits``)."""
    hits: wp.array2d[wp.uint32]
    """PVS recording bits per receiver and blocker source index, shape (V, ceil(Fc/32))."""
    counts: wp.array[wp.int32]
    """Triangles rasterized per receiver (not culled by the exact tests), shape (V,)."""
    refined: wp.array[wp.int32]
    """Fine triangles of refined blockers queued per receiver (not incident, image not tiny), shape (V,)."""
    stop_free: int
    """A receiver may stop rasterizing only while at most this many valid pixels of its mask are free
    (-1: never; :meth:`.method.HemirasterTransfer.stop_when_dark`)."""
    stop_dc: float
    """It stops once the summed ``dark`` shares of its free pixels are at most this."""
    dark: wp.array[float]
    """Per mask bit, its share of the transfer's DC coefficient (0 for invalid bits), shape (64 W,)."""
    near_first: int
    """1: with the stop, the refined blockers' fine triangles are queued before the far field
    (:func:`refined_first`)."""
    halt: wp.array[wp.int32]
    """Per slot, the current receiver's stop state: -1 no stop, 0 running, 1 stopped (its later
    triangles are neither rasterized nor counted), shape (slots,)."""


@wp.struct
class StaticPart:
    """The part of unmoved receivers' masks that unmoved blockers give (:meth:`.method.HemirasterTransfer._static_mode`).

    A mask is the OR of the images of the triangles rasterized for the receiver, each decided from that
    triangle's and the receiver's geometry alone, and the set of a visited refined blocker's triangles splits
    the same way (:func:`listed_set`: a triangle has one primary blocker, so the set is the stored part's and
    what the rest lists besides), so a receiver's mask is the OR of
    what the blockers in ``blockers`` give and what the others give. Where the receiver, its fan and k-ring
    and those blockers (their vertices, bound fine triangles and fine triangles) have not moved since the
    first part was stored, only the second is rasterized."""

    mode: int
    """0: off; 1: rasterize the receivers' fan, k-ring and the ``blockers`` only (stored into ``mask``,
    ``counts``, ``refined`` by the caller passing them as the outputs); 2: receivers flagged in
    ``receiver`` start from ``mask``, ``counts`` and ``refined`` and rasterize the other blockers only."""
    blockers: wp.array2d[wp.uint64]
    """Bits of the unmoved blockers (reordered index), shape (1, ceil(Fc/64))."""
    receiver: wp.array[wp.int32]
    """Per receiver: 1 + its row of ``listed`` where its part is stored, else 0, shape (V,)."""
    mask: wp.array2d[wp.uint64]
    """The stored part of each flagged receiver's mask, shape (V, words)."""
    counts: wp.array[wp.int32]
    """Triangles the stored part rasterized per receiver (:attr:`Batch.counts`), shape (V,)."""
    refined: wp.array[wp.int32]
    """Fine triangles of refined blockers the stored part queued per receiver (:attr:`Batch.refined`), shape (V,)."""
    listed: wp.array2d[MaskChunk]
    """Per stored receiver, the fine triangles of the stored part's refined blockers (:func:`rasterize_fine_set`),
    left out of the rest: a seam triangle listed by a stored and a moving blocker is handled once, as without
    the split; shape (stored receivers, ceil(F/1024)) ((1, 1) without the refinement)."""


@wp.func
def popcount64(x: wp.uint64) -> int:
    """Number of set bits (SWAR; Warp has no popcount intrinsic)."""
    x = x - ((x >> wp.uint64(1)) & wp.uint64(0x5555555555555555))
    x = (x & wp.uint64(0x3333333333333333)) + ((x >> wp.uint64(2)) & wp.uint64(0x3333333333333333))
    x = (x + (x >> wp.uint64(4))) & wp.uint64(0x0F0F0F0F0F0F0F0F)
    return int((x * wp.uint64(0x0101010101010101)) >> wp.uint64(56))


@wp.func
def cube_cell(n: wp.vec3, res: int) -> int:
    """LUT row of a plane normal, encoded ``2·cell + negative`` (cube-map convention in :mod:`.tables`,
    mirrored by ``cube_cell_np``): ``cell`` indexes the stored positive faces; a normal on a
    negative face uses the complement of the row of ``-n``'s cell, which is exactly its own row
    (the negative face is indexed as the mirror of the positive one).

    Branch-free: the major axis changes from edge to edge, so branches would mispredict. The axis
    is chosen as an integer and the components picked with selects on it (:func:`cube_cell_xyz`,
    no sign flips). The cell of a
    negative face is the mirror cell of ``-n`` on the positive face: ``u / major`` with the signed
    major component is ``(-u) / |major|`` exactly, so ``cell(-n)`` and ``cell(n)`` are exact
    mirrors (also when u or v is exactly 0) and the two triangles sharing an edge get
    complementary masks (no crack).
    """
    return cube_cell_xyz(n[0], n[1], n[2], res)


@wp.func(inline=True)
def cube_cell_xyz(x: float, y: float, z: float, res: int) -> int:
    """:func:`cube_cell` of the normal (x, y, z), on scalars: the major component and the two others
    are picked with selects, not by indexing the vector with the axis (which made the compiler spill
    the vector to the stack and reload the components)."""
    ax = wp.abs(x)
    ay = wp.abs(y)
    az = wp.abs(z)
    # ties go to the lower axis
    axis = wp.where(ax >= ay, wp.where(ax >= az, 0, 2), wp.where(ay >= az, 1, 2))
    major = wp.where(axis == 0, x, wp.where(axis == 1, y, z))
    nu = wp.where(axis == 0, y, wp.where(axis == 1, z, x))
    nv = wp.where(axis == 0, z, wp.where(axis == 1, x, y))
    half = 0.5 * float(res)
    inv = half / major
    iu = wp.clamp(int(nu * inv + half), 0, res - 1)
    iv = wp.clamp(int(nv * inv + half), 0, res - 1)
    return 2 * ((axis * res + iu) * res + iv) + wp.where(major < 0.0, 1, 0)


@wp.func(inline=True)
def lut_chunk(lut: PlaneLut, code: int, ch: int) -> MaskChunk:
    """Chunk ``ch`` of the row of ``code`` (:func:`cube_cell`), without the valid-pixel AND: the
    stored row, complemented for a negative face (XOR with all ones, no select). A negative face
    sets the invalid pixels too; AND with ``lut.valid[ch]`` before the words are used (the OR
    fusion of images lets :func:`flush_batch` do it once per batch)."""
    return lut.rows[code >> 1, ch] ^ MaskChunk(wp.uint64(0) - wp.uint64(code & 1))


@wp.func
def lut_word(lut: PlaneLut, code: int, w: int) -> wp.uint64:
    """Word ``w`` of the row of ``code`` (:func:`cube_cell`), valid pixels only: what the
    rasterizer ANDs for that plane."""
    ch = w // CHUNK_WORDS
    return (lut_chunk(lut, code, ch) & lut.valid[ch])[w % CHUNK_WORDS]


@wp.func
def edge_plane(a: wp.vec3, b: wp.vec3) -> wp.vec3:
    """``a × b``: the plane through the receiver and the edge. The module compiles without fused
    multiply-adds, so the neighbour across the edge, which computes ``b × a``, gets exactly the
    opposite normal, hence the complementary LUT row (:func:`cube_cell`)."""
    return wp.cross(a, b)


EDGE_ON_SINE = wp.constant(0.5)
"""The tiny-image cull skips only triangles whose plane passes within asin(0.5) = 30° of the
receiver's line of sight: many small triangles *facing* the receiver together form a surface that
blocks (bunny with a 1024-triangle coarse mesh: 1.6 -> 2.8 % error without this condition), while
grazing slivers are what wastes the time (cloth). Measured: 0.25 keeps too many cloth slivers
(208 vs 144 triangles per vertex), 0.7 costs the bunny 0.13 % error."""


@wp.func(inline=True)
def image_below(a: wp.vec3, b: wp.vec3, c: wp.vec3, nz: wp.vec3, min_area: float) -> bool:
    """True when the projected solid angle of triangle (a, b, c) (relative to the receiver) is below ``min_area``.

    Tiny images (mostly far triangles seen almost edge-on: slivers between pixel centres) cost three
    cube cells and ~3 LUT words each but rarely cover a pixel centre. Van Oosterom–Strackee:
    tan(Ω/2) = |det| / d, so Ω <= 2|det|/d; the projected solid angle is at most Ω times the largest
    corner cosine (an approximation for images whose cosine peaks inside an edge). Branch-free (its
    outcome is a coin flip on the cloth's far field).
    """
    ra = wp.length(a)
    rb = wp.length(b)
    rc = wp.length(c)
    det = wp.dot(a, wp.cross(b, c))
    # only triangles seen at a grazing angle: |n̂_t·â| = |det| / (|N| |a|) with N = (b-a)×(c-a)
    grazing = wp.abs(det) < EDGE_ON_SINE * wp.length(wp.cross(b - a, c - a)) * ra
    d = ra * rb * rc + wp.dot(a, b) * rc + wp.dot(a, c) * rb + wp.dot(b, c) * ra
    zmax = wp.max(wp.max(wp.dot(nz, a) * rb * rc, wp.dot(nz, b) * ra * rc), wp.dot(nz, c) * ra * rb)  # max cos · ra rb rc
    return wp.where(grazing, 2.0 * wp.abs(det) * zmax < min_area * d * ra * rb * rc, False)


@wp.func(inline=True)
def skip_early(plane: wp.vec4, sphere: wp.vec4, p: wp.vec3, nz: wp.vec3, backface: float, rim: float) -> bool:
    """Per-frame triangle data say: wholly at or below the tangent plane, below the lowest pixel
    centre, or back-facing (``backface``).

    The sphere test is a subset of :func:`push_triangle`'s exact horizon cull; ``N·a - N·p`` is
    its determinant ``det[a-p, b-p, c-p]`` computed another way (signs can differ only for
    triangles seen exactly edge-on, which have empty images). Branch-free (selects): on one CPU
    thread, mispredicted cull branches cost more than computing every test.
    """
    q = wp.vec3(sphere[0], sphere[1], sphere[2]) - p
    h = wp.dot(nz, q) + sphere[3]
    # below the lowest pixel centre: every point x of the sphere has sine of elevation
    # n·(x-p)/|x-p| <= h / (|q| - r) <= rim, i.e. (h + rim r)² <= rim² |q|² (no square root)
    hr = h + rim * sphere[3]
    back = (plane[3] - wp.dot(wp.vec3(plane[0], plane[1], plane[2]), p)) * backface > 0.0
    return wp.where(h <= 0.0, True, wp.where(hr * hr <= rim * rim * wp.dot(q, q), True, back))


@wp.func(inline=True)
def bounds_below(plane: wp.vec4, sphere: wp.vec4, nlen: float, p: wp.vec3, n: wp.vec3, min_area: float) -> bool:
    """Cheap pre-test of :func:`image_below` from per-frame triangle data (no vertex gathers).

    ``plane`` = (N, N·a) with N = (b-a)×(c-a) (twice the area times the unit normal), ``sphere`` =
    (centroid, radius), ``nlen`` = ``|N|`` (stored per frame: one square root less per test). A triangle of area A whose plane is h from the receiver and whose points
    are at least d_min = |centroid - p| - radius away subtends Ω = ∫ h/|x|³ dA <= A h / d_min³
    = |N·p - N·a| / (2 d_min³); its largest cosine is at most (n·(centroid - p) + radius) / d_min.
    Branch-free, as :func:`skip_early`.
    """
    q = wp.vec3(sphere[0], sphere[1], sphere[2]) - p
    dmin = wp.length(q) - sphere[3]
    nrm = wp.vec3(plane[0], plane[1], plane[2])
    twice_ah = wp.abs(wp.dot(nrm, p) - plane[3])
    # only triangles seen at a grazing angle: h / d_min bounds the sine seen from any corner, so this
    # skips nothing that :func:`image_below` would keep
    grazing = twice_ah < EDGE_ON_SINE * nlen * dmin
    cmax = wp.min(1.0, (wp.dot(n, q) + sphere[3]) / dmin)
    small = twice_ah * cmax < min_area * 2.0 * dmin * dmin * dmin
    return wp.where(dmin > 0.0, wp.where(grazing, small, False), False)


@wp.kernel
def blocker_corners(points: wp.array[wp.vec3], faces: wp.array2d[wp.int32], corners: wp.array2d[float]):
    """Per triangle its corners' coordinates, one row per coordinate (x, y, z of a, b, c: shape (9, F),
    so a vectorized pass over the triangles reads contiguous rows)."""
    t = wp.tid()
    for k in range(3):
        x = points[faces[t, k]]
        corners[3 * k, t] = x[0]
        corners[3 * k + 1, t] = x[1]
        corners[3 * k + 2, t] = x[2]


@wp.kernel
def triangle_bounds(
    points: wp.array[wp.vec3],
    faces: wp.array2d[wp.int32],
    plane: wp.array[wp.vec4],
    sphere: wp.array[wp.vec4],
    nlen: wp.array[float],
):
    """Per triangle: (N, N·a) with N = (b-a)×(c-a), ``|N|``, and a bounding sphere (centroid, max corner distance)."""
    t = wp.tid()
    a = points[faces[t, 0]]
    b = points[faces[t, 1]]
    c = points[faces[t, 2]]
    nrm = wp.cross(b - a, c - a)
    plane[t] = wp.vec4(nrm[0], nrm[1], nrm[2], wp.dot(nrm, a))
    nlen[t] = wp.length(nrm)
    cen = (a + b + c) / 3.0
    r = wp.max(wp.max(wp.length(a - cen), wp.length(b - cen)), wp.length(c - cen))
    sphere[t] = wp.vec4(cen[0], cen[1], cen[2], r)


COPLANAR_K = wp.constant(COPLANAR)
""":data:`.tables.COPLANAR` in kernels."""
COPLANAR_NEAR_K = wp.constant(COPLANAR_NEAR)
""":data:`.tables.COPLANAR_NEAR` in kernels."""


@wp.func(inline=True)
def coplanar_lift(a: wp.vec3, b: wp.vec3, c: wp.vec3) -> wp.vec3:
    """Where the receiver lies in triangle (a, b, c) (corners relative to it; its foot within the triangle and
    its distance to the plane at most :data:`.tables.COPLANAR_NEAR` × L), the triangle as seen from
    :data:`.tables.COPLANAR` × L on its front side: returns the offset to subtract from the corners (zero for every other triangle).

    A post standing on a floor puts its base vertices in the floor's plane. Seen from a point of the plane, the
    floor triangle under it has no solid angle, and the sign of its rounded determinant decides whether its
    image is the half-sphere below the floor or the one above (the receiver blacked out): neighbouring base
    vertices flip between the two. Seen from just above (the floor's front, where the post stands), the floor
    triangles around the foot cover the lower half, as a renderer's ray from the post's base sees them. Whatever
    the receiver's normal: a box's base corner (its normal leaning into the floor, three faces averaged) or its
    bottom face (facing the floor) sees the floor from its front too, as the reference's rays do.
    """
    g = wp.cross(b - a, c - a)
    gg = wp.dot(g, g)
    gl = wp.sqrt(gg)
    size = wp.sqrt(gl)  # L = sqrt(|N|)
    near = wp.abs(wp.dot(g, a)) <= COPLANAR_NEAR_K * gl * size  # |N·a| = |N| × distance to the plane
    # the foot's barycentric coordinates (N·(a×b) = 2 area(p, a, b) |N|, ...) each >= -COPLANAR
    inside = wp.min(wp.min(wp.dot(g, wp.cross(a, b)), wp.dot(g, wp.cross(b, c))), wp.dot(g, wp.cross(c, a))) >= -COPLANAR_K * gg
    lift = g * (COPLANAR_K * size / gl)
    return wp.where(near and inside and gg > 0.0, lift, wp.vec3(0.0))


@wp.func(inline=True)
def triangle_codes(a: wp.vec3, b: wp.vec3, c: wp.vec3, ft: wp.mat33, backface: float,
                   res: int) -> wp.vec3i:
    """LUT codes (:func:`cube_cell`) of the three oriented edge planes of triangle (a, b, c) (corners
    relative to the receiver, world axes; ``ft`` world -> tangent frame), or -1s when culled.

    Paper §3.1.1: each edge and the receiver span a plane; a pixel is inside the image when it is
    above all three planes, so the image is the AND of three LUT masks (:func:`flush_batch`).
    Planes are oriented by the sign of ``det[a b c]`` so both windings block. Culled: degenerate or
    edge-on (zero solid angle), or facing the receiver when ``backface`` skips that side.
    """
    la = ft * a
    lb = ft * b
    lc = ft * c
    nab = edge_plane(la, lb)
    nbc = edge_plane(lb, lc)
    nca = edge_plane(lc, la)
    det = wp.dot(la, nbc)
    # det = -(face normal)·(receiver - a): on a closed mesh every blocked direction leaves the solid
    # through a triangle facing away from the receiver, so the others add no bits (``backface`` = ±1
    # skips the side facing the receiver for the mesh's orientation; 0 keeps both)
    if det == 0.0 or det * backface > 0.0:
        return wp.vec3i(-1, -1, -1)
    # orient the planes so the triangle's image is above all three (either winding blocks)
    orient = wp.where(det < 0.0, -1.0, 1.0)
    pab = orient * nab
    pbc = orient * nbc
    pca = orient * nca
    return wp.vec3i(cube_cell_xyz(pab[0], pab[1], pab[2], res), cube_cell_xyz(pbc[0], pbc[1], pbc[2], res),
                    cube_cell_xyz(pca[0], pca[1], pca[2], res))


_BATCH_CODES = f"#define WS_COPLANAR {COPLANAR!r}f\n#define WS_COPLANAR_NEAR {COPLANAR_NEAR!r}f\n" + r"""
// corners of slot ``sl``'s queue: rows of contiguous vec3 (wp.zeros), codes rows of contiguous vec3i
const float* __restrict__ pa = (const float*)((const char*)a.data + sl * a.strides[0]);
const float* __restrict__ pb = (const float*)((const char*)b.data + sl * b.strides[0]);
const float* __restrict__ pc = (const float*)((const char*)c.data + sl * c.strides[0]);
int* __restrict__ out = (int*)((char*)codes.data + sl * codes.strides[0]);
// rows of the transposed frame (:func:`triangle_codes`: ``transpose(frame) * a``)
const float t00 = frame.data[0][0], t01 = frame.data[1][0], t02 = frame.data[2][0];
const float t10 = frame.data[0][1], t11 = frame.data[1][1], t12 = frame.data[2][1];
const float t20 = frame.data[0][2], t21 = frame.data[1][2], t22 = frame.data[2][2];
const float half = 0.5f * (float)res;
const int top = res - 1;
int done = 0;
#define WS_CELL(X, Y, Z, CODE) { \
    const float x_ = (X), y_ = (Y), z_ = (Z); \
    const float ax_ = fabsf(x_), ay_ = fabsf(y_), az_ = fabsf(z_); \
    const int axis_ = ax_ >= ay_ ? (ax_ >= az_ ? 0 : 2) : (ay_ >= az_ ? 1 : 2); \
    const float major_ = axis_ == 0 ? x_ : (axis_ == 1 ? y_ : z_); \
    const float nu_ = axis_ == 0 ? y_ : (axis_ == 1 ? z_ : x_); \
    const float nv_ = axis_ == 0 ? z_ : (axis_ == 1 ? x_ : y_); \
    const float inv_ = half / major_; \
    int iu_ = (int)(nu_ * inv_ + half); iu_ = iu_ < 0 ? 0 : iu_; iu_ = iu_ > top ? top : iu_; \
    int iv_ = (int)(nv_ * inv_ + half); iv_ = iv_ < 0 ? 0 : iv_; iv_ = iv_ > top ? top : iv_; \
    CODE = 2 * ((axis_ * res + iu_) * res + iv_) + (major_ < 0.0f ? 1 : 0); }
const float* __restrict__ parea = (const float*)((const char*)area.data + sl * area.strides[0]);
const int* __restrict__ pflag = (const int*)((const char*)fine_flag.data + sl * fine_flag.strides[0]);
int* __restrict__ psrc = (int*)((char*)src.data + sl * src.strides[0]);
// the receiver's normal: the frame's third column (:func:`push_triangle`'s ``nz``)
const float nx = frame.data[0][2], ny = frame.data[1][2], nz = frame.data[2][2];
// a receiver in a blocker's plane (:func:`coplanar_lift`) is rare: the loop screens for it on the way
// (|det| <= 2 COPLANAR_NEAR |N|^1.5: wider than the exact test, so it misses none), and a queue where some triangle
// passes the screen gets the exact test (the Warp function's operations and order), its lifted corners written
// back in place, and the loop once more
int nref = 0;
for (int attempt = 0; attempt < 2; ++attempt) {
nref = 0;
int any_near = 0;
for (int k = 0; k < nb; ++k) {
    const float ax = pa[3 * k], ay = pa[3 * k + 1], az = pa[3 * k + 2];
    const float bx = pb[3 * k], by = pb[3 * k + 1], bz = pb[3 * k + 2];
    const float cx = pc[3 * k], cy = pc[3 * k + 1], cz = pc[3 * k + 2];
    // :func:`image_below` in the same operations and order (Warp's dot, cross, length, max)
    const float ra = sqrtf(ax * ax + ay * ay + az * az);
    const float rb = sqrtf(bx * bx + by * by + bz * bz);
    const float rc = sqrtf(cx * cx + cy * cy + cz * cz);
    const float wdet = ax * (by * cz - bz * cy) + ay * (bz * cx - bx * cz) + az * (bx * cy - by * cx);
    const float ex = bx - ax, ey = by - ay, ez = bz - az;
    const float fx = cx - ax, fy = cy - ay, fz = cz - az;
    const float gx = ey * fz - ez * fy, gy = ez * fx - ex * fz, gz = ex * fy - ey * fx;
    const float adet = fabsf(wdet);
    const float gg = gx * gx + gy * gy + gz * gz;
    const float glen = sqrtf(gg);
    const bool grazing = adet < 0.5f * glen * ra;
    any_near |= (wdet * wdet <= 4.0f * WS_COPLANAR_NEAR * WS_COPLANAR_NEAR * gg * glen) ? 1 : 0;
    const float d = ra * rb * rc + (ax * bx + ay * by + az * bz) * rc + (ax * cx + ay * cy + az * cz) * rb
                    + (bx * cx + by * cy + bz * cz) * ra;
    const float ha = nx * ax + ny * ay + nz * az;
    const float hb = nx * bx + ny * by + nz * bz;
    const float hc = nx * cx + ny * cy + nz * cz;
    const float za = ha * rb * rc, zb = hb * ra * rc, zc = hc * ra * rb;
    const float z1 = (za >= zb) ? za : ((zb == zb) ? zb : za);
    const float zmax = (z1 >= zc) ? z1 : ((zc == zc) ? zc : z1);
    const float mina = parea[k];
    const bool tiny = mina > 0.0f && grazing && 2.0f * adet * zmax < mina * d * ra * rb * rc;
    nref += (pflag[k] != 0 && !tiny) ? 1 : 0;
    // :func:`push_triangle`'s exact horizon cull
    const float h1 = (ha >= hb) ? ha : ((hb == hb) ? hb : ha);
    const float hmax = (h1 >= hc) ? h1 : ((hc == hc) ? hc : h1);
    const float lax = t00 * ax + t01 * ay + t02 * az;
    const float lay = t10 * ax + t11 * ay + t12 * az;
    const float laz = t20 * ax + t21 * ay + t22 * az;
    const float lbx = t00 * bx + t01 * by + t02 * bz;
    const float lby = t10 * bx + t11 * by + t12 * bz;
    const float lbz = t20 * bx + t21 * by + t22 * bz;
    const float lcx = t00 * cx + t01 * cy + t02 * cz;
    const float lcy = t10 * cx + t11 * cy + t12 * cz;
    const float lcz = t20 * cx + t21 * cy + t22 * cz;
    const float abx = lay * lbz - laz * lby, aby = laz * lbx - lax * lbz, abz = lax * lby - lay * lbx;
    const float bcx = lby * lcz - lbz * lcy, bcy = lbz * lcx - lbx * lcz, bcz = lbx * lcy - lby * lcx;
    const float cax = lcy * laz - lcz * lay, cay = lcz * lax - lcx * laz, caz = lcx * lay - lcy * lax;
    const float det = lax * bcx + lay * bcy + laz * bcz;
    const bool culled = det == 0.0f || det * backface > 0.0f || tiny || !(hmax > 0.0f);
    const float o = det < 0.0f ? -1.0f : 1.0f;
    int c0, c1, c2;
    WS_CELL(abx * o, aby * o, abz * o, c0)
    WS_CELL(bcx * o, bcy * o, bcz * o, c1)
    WS_CELL(cax * o, cay * o, caz * o, c2)
    out[3 * k] = culled ? -1 : c0;
    out[3 * k + 1] = culled ? -1 : c1;
    out[3 * k + 2] = culled ? -1 : c2;
}
if (attempt > 0 || !any_near) break;
{
    float* qa = (float*)pa;
    float* qb = (float*)pb;
    float* qc = (float*)pc;
    for (int k = 0; k < nb; ++k) {
        float ax = qa[3 * k], ay = qa[3 * k + 1], az = qa[3 * k + 2];
        float bx = qb[3 * k], by = qb[3 * k + 1], bz = qb[3 * k + 2];
        float cx = qc[3 * k], cy = qc[3 * k + 1], cz = qc[3 * k + 2];
        const float ux = bx - ax, uy = by - ay, uz = bz - az, wx = cx - ax, wy = cy - ay, wz = cz - az;
        const float qx = uy * wz - uz * wy, qy = uz * wx - ux * wz, qz = ux * wy - uy * wx;
        const float qq = qx * qx + qy * qy + qz * qz;
        const float ql = sqrtf(qq);
        const float size = sqrtf(ql);
        const bool near_ = fabsf(qx * ax + qy * ay + qz * az) <= WS_COPLANAR_NEAR * ql * size;
        const float s0 = qx * (ay * bz - az * by) + qy * (az * bx - ax * bz) + qz * (ax * by - ay * bx);
        const float s1 = qx * (by * cz - bz * cy) + qy * (bz * cx - bx * cz) + qz * (bx * cy - by * cx);
        const float s2 = qx * (cy * az - cz * ay) + qy * (cz * ax - cx * az) + qz * (cx * ay - cy * ax);
        const float m01 = s0 < s1 ? s0 : s1;
        const float smin = m01 < s2 ? m01 : s2;
        const bool inside_ = smin >= -WS_COPLANAR * qq;
        const bool lift_ = near_ && inside_ && qq > 0.0f;
        const float sc = WS_COPLANAR * size / ql;
        const float lx = qx * sc, ly = qy * sc, lz = qz * sc;
        ax = lift_ ? ax - lx : ax; ay = lift_ ? ay - ly : ay; az = lift_ ? az - lz : az;
        bx = lift_ ? bx - lx : bx; by = lift_ ? by - ly : by; bz = lift_ ? bz - lz : bz;
        cx = lift_ ? cx - lx : cx; cy = lift_ ? cy - ly : cy; cz = lift_ ? cz - lz : cz;
        qa[3 * k] = ax; qa[3 * k + 1] = ay; qa[3 * k + 2] = az;
        qb[3 * k] = bx; qb[3 * k + 1] = by; qb[3 * k + 2] = bz;
        qc[3 * k] = cx; qc[3 * k + 1] = cy; qc[3 * k + 2] = cz;
    }
}
}
#undef WS_CELL
// the kept ones moved to the front (in order, with their PVS source): no test in the AND/OR loop
for (int k = 0; k < nb; ++k) {
    const int c0 = out[3 * k], c1 = out[3 * k + 1], c2 = out[3 * k + 2], s = psrc[k];
    out[3 * done] = c0;
    out[3 * done + 1] = c1;
    out[3 * done + 2] = c2;
    psrc[done] = s;
    done += c0 >= 0 ? 1 : 0;
}
int* prefined = (int*)((char*)refined.data + v * refined.strides[0]);
*prefined += nref;
return done;
#undef WS_COPLANAR
#undef WS_COPLANAR_NEAR
"""


@wp.func_native(_BATCH_CODES)
def batch_codes(a: wp.array2d[wp.vec3], b: wp.array2d[wp.vec3], c: wp.array2d[wp.vec3], area: wp.array2d[float],
                fine_flag: wp.array2d[wp.int32], src: wp.array2d[wp.int32], codes: wp.array2d[wp.vec3i],
                refined: wp.array[wp.int32], v: int, sl: int, nb: int, frame: wp.mat33, backface: float, res: int) -> int:
    """The exact culls and :func:`triangle_codes` of the ``nb`` queued triangles of slot ``sl``, on their
    corners moved by :func:`coplanar_lift` (written back into the queue): the
    tiny-image cull (:func:`image_below` with each entry's ``area``), the horizon cull, then the
    codes (the same operations in the same order as the Warp functions, so the same bits). The
    kept triangles' codes and PVS sources are moved to the front of ``codes`` and ``src``; returns
    how many; adds the kept-by-the-image-test fine triangles (``fine_flag``) to ``refined[v]``.
    Native C++ in one loop without calls or branches, which clang vectorizes (8 triangles per AVX2
    instruction), run a second time after the lift in a queue that has a triangle to lift (rare), then a
    compaction loop; the rows must be contiguous."""


_OR_IMAGES = r"""
// lanes of 4 mask words (256 bits, 4 per chunk): 512-bit vectors here made clang use them in the whole
// rasterizer (batch_codes too) and the kernel slower; loads through memcpy: rows need only 8-byte alignment
typedef unsigned long long U4 __attribute__((ext_vector_type(4)));
auto load4 = [](const unsigned long long* p) -> U4 { U4 x; __builtin_memcpy(&x, p, sizeof(U4)); return x; };
const int nc = rows.shape[1];
const long rs = rows.strides[0] / 8;  // words per LUT row: nc chunks of 16
const unsigned long long* __restrict__ rb = (const unsigned long long*)rows.data;
const unsigned long long* __restrict__ pv = (const unsigned long long*)valid.data;
const int* __restrict__ pc = (const int*)((const char*)codes.data + sl * codes.strides[0]);
const int* __restrict__ ps = (const int*)((const char*)src.data + sl * src.strides[0]);
unsigned long long* __restrict__ pm = (unsigned long long*)((char*)mask.data + v * mask.strides[0]);
unsigned int* ph = (unsigned int*)((char*)hits.data + v * hits.strides[0]);
int nfree = 0;
for (int ch = 0; ch < nc; ++ch) {
    const unsigned long long* vc = pv + 16 * ch;
    U4 acc[4] = {0, 0, 0, 0};
    // :func:`lut_chunk` of triangle k's three codes: the stored row of ``code >> 1``, complemented when
    // ``code & 1``; the AND of the three, lane group j of the chunk
#define WS_IMAGE(K) \
        const int c0 = pc[3 * (K)], c1 = pc[3 * (K) + 1], c2 = pc[3 * (K) + 2]; \
        const unsigned long long* r0 = rb + (c0 >> 1) * rs + 16 * ch; \
        const unsigned long long* r1 = rb + (c1 >> 1) * rs + 16 * ch; \
        const unsigned long long* r2 = rb + (c2 >> 1) * rs + 16 * ch; \
        const U4 s0 = 0ull - (unsigned long long)(c0 & 1); \
        const U4 s1 = 0ull - (unsigned long long)(c1 & 1); \
        const U4 s2 = 0ull - (unsigned long long)(c2 & 1); \
        U4 m[4]; \
        for (int j = 0; j < 4; ++j) { \
            m[j] = (load4(r0 + 4 * j) ^ s0) & (load4(r1 + 4 * j) ^ s1) & (load4(r2 + 4 * j) ^ s2); \
            acc[j] |= m[j]; \
        }
    if (!record) {
        for (int k = 0; k < done; ++k) {
            WS_IMAGE(k)
        }
    } else {
        for (int k = 0; k < done; ++k) {
            WS_IMAGE(k)
            // recording a PVS: the triangle's source gets its bit when the image holds a valid pixel
            U4 any = 0;
            for (int j = 0; j < 4; ++j) any |= m[j] & load4(vc + 4 * j);
            const int s = ps[k];
            if (s >= 0 && (any[0] | any[1] | any[2] | any[3]) != 0ull) ph[s >> 5] |= 1u << (s & 31);
        }
    }
#undef WS_IMAGE
    const int n = words - 16 * ch < 16 ? words - 16 * ch : 16;
    for (int i = 0; i < n; ++i) {
        const unsigned long long word = pm[16 * ch + i] | (acc[i >> 2][i & 3] & vc[i]);
        pm[16 * ch + i] = word;
        nfree += __builtin_popcountll(vc[i] & ~word);
    }
}
return nfree;
"""


@wp.func_native(_OR_IMAGES)
def or_images(rows: wp.array2d[MaskChunk], valid: wp.array[MaskChunk], codes: wp.array2d[wp.vec3i],
              src: wp.array2d[wp.int32], mask: wp.array2d[wp.uint64], hits: wp.array2d[wp.uint32], v: int, sl: int,
              done: int, words: int, record: int) -> int:
    """ORs the images of the ``done`` triangles whose LUT codes lead slot ``sl``'s row of ``codes``
    (:func:`batch_codes`) into receiver ``v``'s mask row (``words`` words); returns how many valid pixels
    of that row are still free.

    Paper §3.1.1: a triangle's image is the AND of its three edge-plane rows (:func:`lut_chunk`: a negative
    face's code takes the complement); images fuse by OR (no depth, any order), so each chunk of the batch
    is ORed in registers, ANDed with the valid pixels once, and the mask row is updated once per chunk.
    With ``record``, each triangle whose image holds a valid pixel sets the bit of its ``src`` (unless -1)
    in ``hits[v]`` (PVS recording).

    Native C++ in clang vector lanes of 4 words (256 bits, four per chunk): a triangle's row loads, XORs
    and ANDs are vector operations, its row addresses plain pointer arithmetic (``rows``, ``valid`` and the
    rows of ``codes``, ``src``, ``mask`` must be contiguous), the free pixels a hardware popcount."""


@wp.func(inline=False)
def flush_batch(nb: int, v: int, sl: int, frame: wp.mat33, lut: PlaneLut, mask: wp.array2d[wp.uint64], bt: Batch) -> int:
    """Rasterize the ``nb`` queued triangles of receiver ``v`` (:class:`Batch`); returns 0 (the new
    queue length). First all their LUT codes (straight-line arithmetic), then their images.

    The images (:func:`or_images`: the AND of each triangle's three LUT rows, ORed into the mask row
    chunk by chunk; docs/benchmarks/history.md has what this replaced), then, when few pixels are
    left free, the ``stop_when_dark`` test.
    """
    if bt.halt[sl] > 0:
        return 0
    done = batch_codes(bt.a, bt.b, bt.c, bt.area, bt.fine_flag, bt.src, bt.codes, bt.refined, v, sl, nb, frame,
                       lut.backface, lut.res)
    counting = bt.halt[sl] == 0
    free = or_images(lut.rows, lut.valid, bt.codes, bt.src, mask, bt.hits, v, sl, done, lut.words, bt.record)
    bt.counts[v] = bt.counts[v] + done
    if counting and free <= bt.stop_free:
        # few pixels free: stop when their DC shares sum to at most stop_dc
        dc = float(0.0)
        for w in range(lut.words):
            x = lut.valid[w // CHUNK_WORDS][w % CHUNK_WORDS] & ~mask[v, w]
            while x != wp.uint64(0):
                k = wp.bit_count((x & (~x + wp.uint64(1))) - wp.uint64(1))
                x = x & (x - wp.uint64(1))
                dc += bt.dark[w * 64 + k]
        if dc <= bt.stop_dc:
            bt.halt[sl] = 1
    return 0


@wp.func(inline=True)
def push_triangle(a: wp.vec3, b: wp.vec3, c: wp.vec3, src: int, skip: bool, area: float, fine_flag: int, nb: int, v: int,
                  sl: int, frame: wp.mat33, lut: PlaneLut, mask: wp.array2d[wp.uint64], bt: Batch) -> int:
    """Queue triangle (a, b, c) (corners relative to the receiver) for receiver ``v`` unless ``skip``
    or it is wholly at or below the horizon; flushes a full queue. Returns the new queue length.

    The exact horizon cull (3 dots): such a triangle has no image, and quantised planes would
    otherwise leak bits at the disk rim. Branch-free: the triangle is always written to the next
    free entry, which only a kept triangle takes.
    """
    bt.a[sl, nb] = a
    bt.b[sl, nb] = b
    bt.c[sl, nb] = c
    bt.src[sl, nb] = src
    bt.area[sl, nb] = area
    bt.fine_flag[sl, nb] = fine_flag
    nb = nb + wp.where(skip, 0, 1)
    if nb == bt.a.shape[1]:
        return flush_batch(nb, v, sl, frame, lut, mask, bt)
    return nb


@wp.func(inline=True)
def rasterize_fan(v: int, sl: int, p: wp.vec3, n: wp.vec3, fine: FineMesh, frame: wp.mat33, lut: PlaneLut,
                  mask: wp.array2d[wp.uint64], bt: Batch, nb: int) -> int:
    """Queue the receiver's own triangles as seen from just above it; returns the queue length.

    Seen from the vertex itself, a triangle through it subtends no solid angle; but where the surface
    folds up around the vertex (valleys, creases), the directions under its fan pass through the
    surface right at the receiver. The ray-traced reference sees that fan from ``p + eps n``
    (:func:`~warpshade.visibility.rays.trace_surface_ray`); as ``eps -> 0`` the image of
    triangle (p, b, c) from there is the spherical triangle (nadir, b - p, c - p), whose part above
    the horizon is the region between the horizon and the fan's arc b -> c. Neighbouring fan
    triangles share their nadir edge exactly (same corners, no fused multiply-adds: complementary
    planes, no crack), and the arc's plane is the one of the real triangle across edge bc.
    """
    down = -n
    for r in range(fine.fan_start[v], fine.fan_start[v + 1]):
        t = fine.fan_tris[r]
        i = fine.faces[t, 0]
        j = fine.faces[t, 1]
        k = fine.faces[t, 2]
        # the two corners other than the receiver, in winding order
        b = wp.where(i == v, j, wp.where(j == v, k, i))
        c = wp.where(i == v, k, wp.where(j == v, i, j))
        nb = push_triangle(down, fine.points[b] - p, fine.points[c] - p, -1, False, 0.0, 0, nb, v, sl, frame, lut, mask, bt)
    return nb


@wp.func
def box_above_plane(lo: wp.vec3, hi: wp.vec3, n: wp.vec3, offset: float) -> bool:
    """True when some corner of box [lo, hi] has ``n·x > offset`` (the box reaches above the tangent plane), or
    comes within :data:`.tables.COPLANAR_NEAR` × its diagonal of it: a triangle of the box whose plane passes that
    near the receiver may be lifted above it (:func:`coplanar_lift`; its L is at most the diagonal). A flat ground's
    cluster has a box of no height: for a receiver in its plane facing down (a box's bottom face) it was culled."""
    center = 0.5 * (lo + hi)
    half = 0.5 * (hi - lo)
    reach = wp.dot(n, center) + wp.abs(n[0]) * half[0] + wp.abs(n[1]) * half[1] + wp.abs(n[2]) * half[2]
    return reach > offset - COPLANAR_NEAR_K * wp.length(hi - lo)


@wp.kernel
def follow_coarse_points(
    points: wp.array[wp.vec3],
    faces: wp.array2d[wp.int32],
    bind_face: wp.array[wp.int32],
    bind_bary: wp.array[wp.vec3],
    bind_offset: wp.array[float],
    coarse_points: wp.array[wp.vec3],
):
    """Coarse vertex = barycentric point of its bound fine triangle + offset along that triangle's unit normal."""
    i = wp.tid()
    f = bind_face[i]
    a = points[faces[f, 0]]
    b = points[faces[f, 1]]
    c = points[faces[f, 2]]
    w = bind_bary[i]
    q = w[0] * a + w[1] * b + w[2] * c
    n = wp.cross(b - a, c - a)
    ln = wp.length(n)
    if ln > 0.0:
        q = q + n * (bind_offset[i] / ln)
    coarse_points[i] = q


@wp.kernel
def refit_blocker_boxes(
    bpoints: wp.array[wp.vec3],
    bfaces: wp.array2d[wp.int32],
    points: wp.array[wp.vec3],
    faces: wp.array2d[wp.int32],
    use_groups: int,
    group_start: wp.array[wp.int32],
    group_mid: wp.array[wp.int32],
    group_tris: wp.array[wp.int32],
    bind_offset: wp.array[float],
    lo: wp.array[wp.vec3],
    hi: wp.array[wp.vec3],
    deviation: wp.array[float],
):
    """Per blocker triangle: bounding box of it and (``use_groups``) of the fine triangles it stands
    for, and their deviation [m] across the surface: the largest distance of those fine vertices
    from the blocker's plane, or of the blocker's corners from the fine surface (``bind_offset``,
    indexed by blocker vertex).

    With refinement a blocker is either rasterized itself or replaced by its fine triangles, so
    culling and the refinement test need the box of both. The deviation bounds how far the coarse
    triangle is from the surface it stands for in this frame (0 on flat ground, large across a fold).
    """
    t = wp.tid()
    bmin = wp.vec3(1.0e30, 1.0e30, 1.0e30)
    bmax = wp.vec3(-1.0e30, -1.0e30, -1.0e30)
    for k in range(3):
        q = bpoints[bfaces[t, k]]
        bmin = wp.min(bmin, q)
        bmax = wp.max(bmax, q)
    dev = float(0.0)
    if use_groups != 0:
        a = bpoints[bfaces[t, 0]]
        b = bpoints[bfaces[t, 1]]
        c = bpoints[bfaces[t, 2]]
        nrm = wp.cross(b - a, c - a)
        ln = wp.length(nrm)
        # across the surface only: fine vertices off the coarse plane, and the coarse corners off the
        # fine surface (their binding offsets). Along it, a fine triangle sticking out past the coarse
        # triangle's edge lies on its neighbour's plane and changes nothing (flat ground: 0).
        dev = wp.max(wp.max(wp.abs(bind_offset[bfaces[t, 0]]), wp.abs(bind_offset[bfaces[t, 1]])),
                     wp.abs(bind_offset[bfaces[t, 2]]))
        for r in range(group_start[t], group_start[t + 1]):
            f = group_tris[r]
            for k in range(3):
                q = points[faces[f, k]]
                bmin = wp.min(bmin, q)
                bmax = wp.max(bmax, q)
                if r >= group_mid[t]:
                    continue  # extras (seam cover) are in the box, not in the deviation
                if ln > 0.0:
                    dev = wp.max(dev, wp.abs(wp.dot(nrm, q - a)) / ln)
                else:
                    dev = wp.max(dev, wp.length(q - a))
        cen = (a + b + c) / 3.0
        size = wp.max(wp.max(wp.length(a - cen), wp.length(b - cen)), wp.length(c - cen))
        if group_mid[t] == group_start[t]:
            # stands for nothing (a sliver left by the assignment): its size, so it is dropped near
            # receivers and rasterized as part of the far field
            dev = wp.max(dev, size)
        # at least 1/1000 of its size: a large ``refine`` converges to the exact fine mesh also where
        # the coarse triangle is flat with its fine triangles (its outline still differs from theirs)
        dev = wp.max(dev, 1.0e-3 * size)
    lo[t] = bmin
    hi[t] = bmax
    deviation[t] = dev


@wp.kernel
def union_boxes(
    child_lo: wp.array[wp.vec3],
    child_hi: wp.array[wp.vec3],
    child_reach: wp.array[float],
    start: wp.array[wp.int32],
    lo: wp.array[wp.vec3],
    hi: wp.array[wp.vec3],
    reach: wp.array[float],
):
    """Bounding box of each contiguous range of child boxes (clusters from triangles, super-clusters
    from clusters), and the largest ``child_reach`` (deviation) of its children."""
    s = wp.tid()
    bmin = wp.vec3(1.0e30, 1.0e30, 1.0e30)
    bmax = wp.vec3(-1.0e30, -1.0e30, -1.0e30)
    r = float(0.0)
    for c in range(start[s], start[s + 1]):
        bmin = wp.min(bmin, child_lo[c])
        bmax = wp.max(bmax, child_hi[c])
        r = wp.max(r, child_reach[c])
    lo[s] = bmin
    hi[s] = bmax
    reach[s] = r


@wp.kernel
def raise_deviation(floor: wp.array[float], deviation: wp.array[float]):
    """``deviation = max(deviation, floor)`` per blocker (the mid level's outline deviation,
    :func:`.hierarchy.outline_deviation`)."""
    t = wp.tid()
    deviation[t] = wp.max(deviation[t], floor[t])


@wp.kernel
def union_child_boxes(
    start: wp.array[wp.int32],
    children: wp.array[wp.int32],
    child_lo: wp.array[wp.vec3],
    child_hi: wp.array[wp.vec3],
    lo: wp.array[wp.vec3],
    hi: wp.array[wp.vec3],
):
    """Grow each blocker's box [lo, hi] by the boxes of the children it lists (``children[start[t]:start[t+1]]``):
    a coarse blocker's box then holds the mid triangles that replace it and their fine triangles."""
    t = wp.tid()
    bmin = lo[t]
    bmax = hi[t]
    for r in range(start[t], start[t + 1]):
        c = children[r]
        bmin = wp.min(bmin, child_lo[c])
        bmax = wp.max(bmax, child_hi[c])
    lo[t] = bmin
    hi[t] = bmax


@wp.func
def box_near(p: wp.vec3, lo: wp.vec3, hi: wp.vec3, radius: float) -> bool:
    """True when the box [lo, hi] comes within ``radius`` of ``p``."""
    d = wp.max(wp.max(lo - p, p - hi), wp.vec3(0.0, 0.0, 0.0))
    return wp.dot(d, d) < radius * radius


@wp.func
def refine_here(p: wp.vec3, lo: wp.vec3, hi: wp.vec3, deviation: float, refine: float) -> bool:
    """Refinement test of one blocker: its box (own and its fine triangles') comes within ``refine``
    times its deviation of the receiver. The coarse triangle lies within ``deviation`` of the fine
    surface it stands for, so seen from farther than ``refine · deviation`` its image is off by
    at most about 1/refine radians; nearer, it can cut through the fine surface (contact, folds)
    and is replaced by that surface."""
    return box_near(p, lo, hi, refine * deviation)


@wp.func(inline=True)
def blocker_refined(blockers: Blockers, sl: int, t: int) -> bool:
    """Whether blocker ``t`` (reordered index) is refined for the slot's current receiver (:func:`mark_refined`)."""
    return (blockers.refined[sl, t >> 6] >> wp.uint64(t & 63)) & wp.uint64(1) != wp.uint64(0)


@wp.func(inline=True)
def slot_bits(bits: wp.array2d[wp.uint64], sl: int, t0: int, t1: int) -> wp.uint64:
    """Bits ``t0 .. t1-1`` (at most 64) of the slot's row of a per-blocker bit set (:func:`mark_refined`,
    :func:`far_field_bits`), bit 0 = ``t0``."""
    w = t0 >> 6
    s = wp.uint64(t0 & 63)
    x = bits[sl, w] >> s
    if w + 1 < bits.shape[1]:
        # (``<< 1 << (63 - s)``: no shift by 64 when s = 0)
        x = x | ((bits[sl, w + 1] << wp.uint64(1)) << (wp.uint64(63) - s))
    if t1 - t0 < 64:
        x = x & ((wp.uint64(1) << wp.uint64(t1 - t0)) - wp.uint64(1))
    return x


PRECULL_BLOCKERS = 4096
"""Largest far field (coarse blockers) whose culls are computed for every blocker per receiver in one
vectorized pass (:func:`far_field_bits`, whose flags sit in a stack buffer of this size); larger ones
(the full mesh as blockers) are culled per cluster that reaches above the tangent plane."""

DIRECT_SPAN = 2
"""Largest image, in pixel centres across and down, that :func:`far_field_bits` rasterizes itself (the
method's ``direct_far``). 3 (441 instead of 653 triangles queued per receiver on the draped cloth, the
same error) was slower than 2 (9 centre tests per blocker; docs/benchmarks/history.md)."""


_FAR_FIELD_BITS = r"""
// per blocker t (reordered index): :func:`skip_early`, :func:`bounds_below` and :func:`refine_here`
// in the same operations and order as the Warp functions (Warp's dot, length, min, max, abs)
const int nt = plane.shape[0];
const float* __restrict__ pl = (const float*)plane.data;
const float* __restrict__ sp = (const float*)sphere.data;
const float* __restrict__ nl = (const float*)nlen.data;
const float* __restrict__ blo = (const float*)lo.data;
const float* __restrict__ bhi = (const float*)hi.data;
const float* __restrict__ bdv = (const float*)dev.data;
uint64_t* __restrict__ pc = (uint64_t*)((char*)cull.data + sl * cull.strides[0]);
uint64_t* __restrict__ pt = (uint64_t*)((char*)tiny.data + sl * tiny.strides[0]);
uint64_t* __restrict__ pr = (uint64_t*)((char*)refined.data + sl * refined.strides[0]);
const uint64_t* __restrict__ pring = (const uint64_t*)((const char*)ring.data + (use_ring ? v : 0) * ring.strides[0]);
const float px = p.c[0], py = p.c[1], pz = p.c[2];
const float nx = n.c[0], ny = n.c[1], nz = n.c[2];
const float rim2 = rim * rim;
const float area2 = min_area * 2.0f;
const bool do_tiny = min_area > 0.0f;
const bool do_refine = refine > 0.0f;
const bool do_direct = direct >= 0.0f;
const float between = direct;
unsigned short hits[PRECULL_BLOCKERS + 64], listed[PRECULL_BLOCKERS + 64], sethit[PRECULL_BLOCKERS + 64];
float bi[PRECULL_BLOCKERS + 64], bj[PRECULL_BLOCKERS + 64], bk[PRECULL_BLOCKERS + 64], bl[PRECULL_BLOCKERS + 64];
const int words = (nt + 63) / 64;
const uint64_t ones = 0x0101010101010101ull, magic = 0x0102040810204080ull;
#define WS_MIN(A, B) ((A) < (B) ? (A) : (B))
#define WS_MAX(A, B) ((A) > (B) ? (A) : (B))
const float* __restrict__ pco = (const float*)corners.data;
const int cs = (int)(corners.strides[0] / sizeof(float));
// the frame's tangent columns (pixel x and y)
const float f00 = frame.data[0][0], f10 = frame.data[1][0], f20 = frame.data[2][0];
const float f01 = frame.data[0][1], f11 = frame.data[1][1], f21 = frame.data[2][1];
const float f02 = frame.data[0][2], f12 = frame.data[1][2], f22 = frame.data[2][2];
// flags per blocker (bit 0 culled, 1 tiny, 2 refined) in a straight loop over the flat rows, then
// packed 8 at a time into the bit rows (a byte b_i at byte i of x: ((x >> j) & 0x01..01) * 0x0102040810204080
// >> 56 has bit j of b_i at bit i)
unsigned char flags[PRECULL_BLOCKERS + 64];
for (int t = 0; t < nt; ++t) {
    const float s0 = sp[4 * t], s1 = sp[4 * t + 1], s2 = sp[4 * t + 2], s3 = sp[4 * t + 3];
    const float n0 = pl[4 * t], n1 = pl[4 * t + 1], n2 = pl[4 * t + 2], n3 = pl[4 * t + 3];
    const float qx = s0 - px, qy = s1 - py, qz = s2 - pz;
    const float qq = qx * qx + qy * qy + qz * qz;
    const float nq = nx * qx + ny * qy + nz * qz;
    const float np_ = n0 * px + n1 * py + n2 * pz;
    // skip_early
    const float h = nq + s3;
    const float hr = h + rim * s3;
    const bool back = (n3 - np_) * backface > 0.0f;
    const bool culled = (h <= 0.0f) ? true : ((hr * hr <= rim2 * qq) ? true : back);
    // bounds_below
    const float dmin = sqrtf(qq) - s3;
    const float twice_ah = fabsf(np_ - n3);
    const bool grazing = twice_ah < 0.5f * nl[t] * dmin;
    const float cq = (nq + s3) / dmin;
    const float cmax = (1.0f <= cq) ? 1.0f : ((cq == cq) ? cq : 1.0f);
    const bool small = twice_ah * cmax < area2 * dmin * dmin * dmin;
    const bool tiny_ = (dmin > 0.0f) ? (grazing ? small : false) : false;
    // refine_here: box_near(p, lo, hi, refine * dev)
    const float ax = blo[3 * t] - px, bx = px - bhi[3 * t];
    const float ay = blo[3 * t + 1] - py, by = py - bhi[3 * t + 1];
    const float az = blo[3 * t + 2] - pz, bz = pz - bhi[3 * t + 2];
    float dx = (ax >= bx) ? ax : ((bx == bx) ? bx : ax);
    float dy = (ay >= by) ? ay : ((by == by) ? by : ay);
    float dz = (az >= bz) ? az : ((bz == bz) ? bz : az);
    dx = (dx >= 0.0f) ? dx : 0.0f;
    dy = (dy >= 0.0f) ? dy : 0.0f;
    dz = (dz >= 0.0f) ? dz : 0.0f;
    const float rad = refine * bdv[t];
    const bool near_ = dx * dx + dy * dy + dz * dz < rad * rad;
    flags[t] = (unsigned char)((culled ? 1 : 0) | ((do_tiny && tiny_) ? 2 : 0) | ((do_refine && near_) ? 4 : 0));
}
if (do_direct) {
  // coarse blockers whose image spans at most 2 x 2 pixel centres: their LUT images at those centres
  // (the edge planes quantised to their LUT cells' centre normals, as :func:`.tables.cube_cell_normals`)
  // go straight into the mask, and they are not queued. In two branch-free passes that vectorize: the
  // first over all blockers finds those (``ok``: the box of their disk image) and those of them whose box
  // holds a pixel centre, the second quantises the planes and tests the centres of the latter only
  // (listed: the others have no centre to set); the stores in a third loop
#define WS_LOCAL(T) \
    const float ax_ = pco[T] - px, ay_ = pco[cs + T] - py, az_ = pco[2 * cs + T] - pz; \
    const float bx_ = pco[3 * cs + T] - px, by_ = pco[4 * cs + T] - py, bz_ = pco[5 * cs + T] - pz; \
    const float cx_ = pco[6 * cs + T] - px, cy_ = pco[7 * cs + T] - py, cz_ = pco[8 * cs + T] - pz; \
    const float lax = f00 * ax_ + f10 * ay_ + f20 * az_, lay = f01 * ax_ + f11 * ay_ + f21 * az_; \
    const float laz = f02 * ax_ + f12 * ay_ + f22 * az_; \
    const float lbx = f00 * bx_ + f10 * by_ + f20 * bz_, lby = f01 * bx_ + f11 * by_ + f21 * bz_; \
    const float lbz = f02 * bx_ + f12 * by_ + f22 * bz_; \
    const float lcx = f00 * cx_ + f10 * cy_ + f20 * cz_, lcy = f01 * cx_ + f11 * cy_ + f21 * cz_; \
    const float lcz = f02 * cx_ + f12 * cy_ + f22 * cz_;
  for (int t = 0; t < nt; ++t) {
    WS_LOCAL(t)
    const float ia_ = 1.0f / sqrtf(lax * lax + lay * lay + laz * laz);
    const float ib_ = 1.0f / sqrtf(lbx * lbx + lby * lby + lbz * lbz);
    const float ic_ = 1.0f / sqrtf(lcx * lcx + lcy * lcy + lcz * lcz);
    const float xa = lax * ia_, ya = lay * ia_, xb = lbx * ib_, yb = lby * ib_, xc = lcx * ic_, yc = lcy * ic_;
    const float dab = (lax * lbx + lay * lby + laz * lbz) * ia_ * ib_;
    const float dbc = (lbx * lcx + lby * lcy + lbz * lcz) * ib_ * ic_;
    const float dca = (lcx * lax + lcy * lay + lcz * laz) * ic_ * ia_;
    const float dmin_ = WS_MIN(dab, WS_MIN(dbc, dca));
    // the disk image lies in the corners' box widened by the arcs' bulge (1 - dmin) and the interior's
    // (1/sqrt(dmin) - 1 < 1 - dmin for dmin >= 0.5), plus ``between``: how far the LUT's quantised
    // planes may reach past the exact ones
    const float pad = 2.0f * (1.0f - dmin_) + between;
    // pixel-centre indices (floor and ceiling through an int conversion of the shifted, positive value)
    const float u0 = (WS_MIN(xa, WS_MIN(xb, xc)) - pad + 1.0f) * half_mask + 127.5f;
    const float u1 = (WS_MAX(xa, WS_MAX(xb, xc)) + pad + 1.0f) * half_mask + 127.5f;
    const float v0 = (WS_MIN(ya, WS_MIN(yb, yc)) - pad + 1.0f) * half_mask + 127.5f;
    const float v1 = (WS_MAX(ya, WS_MAX(yb, yc)) + pad + 1.0f) * half_mask + 127.5f;
    const float fu0 = (float)(int)u0, fv0 = (float)(int)v0;
    const float i0 = fu0 + (fu0 < u0 ? 1.0f : 0.0f) - 128.0f, i1 = (float)(int)u1 - 128.0f;
    const float j0 = fv0 + (fv0 < v0 ? 1.0f : 0.0f) - 128.0f, j1 = (float)(int)v1 - 128.0f;
    const float e1x = lby * lcz - lbz * lcy, e1y = lbz * lcx - lbx * lcz, e1z = lbx * lcy - lby * lcx;
    const float det = lax * e1x + lay * e1y + laz * e1z;
    const bool ok = (dmin_ >= 0.5f) & (i1 - i0 <= DIRECT_SPAN - 1.0f) & (j1 - j0 <= DIRECT_SPAN - 1.0f) & (det != 0.0f)
                    & ((flags[t] & 5) == 0);
    bi[t] = i0;
    bj[t] = j0;
    bk[t] = i1;
    bl[t] = j1;
    // bit 1: not queued; bit 3: its box holds a pixel centre
    flags[t] |= (unsigned char)((ok ? 2 : 0) | ((ok & (i1 >= i0) & (j1 >= j0)) ? 8 : 0));
  }
  for (int t = nt; t < words * 64; ++t)
    flags[t] = 0;
  int m = 0;
  for (int w = 0; w < words; ++w) {
    uint64_t mh = 0;
    for (int b = 0; b < 8; ++b) {
      uint64_t x;
      memcpy(&x, flags + w * 64 + 8 * b, 8);
      mh |= ((((x >> 3) & ones) * magic) >> 56) << (8 * b);
    }
    // (a blocker standing for the receiver's k-ring is refined: its fine triangles stand in for it)
    if (use_ring)
      mh &= ~pring[w];
    while (mh != 0) {
      listed[m++] = (unsigned short)(w * 64 + __builtin_ctzll(mh));
      mh &= mh - 1;
    }
  }
  for (int k = 0; k < m; ++k) {
    const int t = listed[k];
    WS_LOCAL(t)
    const float i0 = bi[t], j0 = bj[t], i1 = bk[t], j1 = bl[t];
    float e0x = lay * lbz - laz * lby, e0y = laz * lbx - lax * lbz, e0z = lax * lby - lay * lbx;
    float e1x = lby * lcz - lbz * lcy, e1y = lbz * lcx - lbx * lcz, e1z = lbx * lcy - lby * lcx;
    float e2x = lcy * laz - lcz * lay, e2y = lcz * lax - lcx * laz, e2z = lcx * lay - lcy * lax;
    const float det = lax * e1x + lay * e1y + laz * e1z;
    const float o = det < 0.0f ? -1.0f : 1.0f;
    e0x *= o; e0y *= o; e0z *= o;
    e1x *= o; e1y *= o; e1z *= o;
    e2x *= o; e2y *= o; e2z *= o;
    // each plane's LUT cell centre normal (module docstring of .tables: major axis, ties to the lower,
    // the cell of (u, v) / |major| on the positive face, the negative face its mirror: q(-e) = -q(e))
#define WS_CELL(EX, EY, EZ, QX, QY, QZ) { \
        const float ax2 = fabsf(EX), ay2 = fabsf(EY), az2 = fabsf(EZ); \
        const bool a0 = (ax2 >= ay2) & (ax2 >= az2); \
        const bool a1 = (!a0) & (ay2 >= az2); \
        const float mj = a0 ? (EX) : (a1 ? (EY) : (EZ)); \
        const float s_ = mj < 0.0f ? -1.0f : 1.0f; \
        const float uu = s_ * (a0 ? (EY) : (a1 ? (EZ) : (EX))); \
        const float vv = s_ * (a0 ? (EZ) : (a1 ? (EX) : (EY))); \
        const float inv = lut_half / fabsf(mj); \
        const float fu = WS_MAX(0.0f, WS_MIN(lut_last, (float)(int)(uu * inv + lut_half))); \
        const float fv = WS_MAX(0.0f, WS_MIN(lut_last, (float)(int)(vv * inv + lut_half))); \
        const float cu = s_ * (-1.0f + (fu + 0.5f) / lut_half), cv = s_ * (-1.0f + (fv + 0.5f) / lut_half); \
        QX = a0 ? s_ : (a1 ? cv : cu); QY = a0 ? cu : (a1 ? s_ : cv); QZ = a0 ? cv : (a1 ? cu : s_); }
    float q0x, q0y, q0z, q1x, q1y, q1z, q2x, q2y, q2z;
    WS_CELL(e0x, e0y, e0z, q0x, q0y, q0z)
    WS_CELL(e1x, e1y, e1z, q1x, q1y, q1z)
    WS_CELL(e2x, e2y, e2z, q2x, q2y, q2z)
#undef WS_CELL
    // the centres (i0 + di, j0 + dj) within the box (up to i1, j1) above the three quantised planes
    // q: q·g > 0 for g = (x, y, sqrt(1 - x² - y²)), tested without the root (q_z g_z > -(q_x x + q_y y))
    const float step = 1.0f / half_mask;
    unsigned int hb_ = 0;
#define WS_CENTRE(DI, DJ) { \
        const float gx = -1.0f + (i0 + (0.5f + DI)) * step, gy = -1.0f + (j0 + (0.5f + DJ)) * step; \
        const float gz2 = 1.0f - gx * gx - gy * gy; \
        const float s0_ = q0x * gx + q0y * gy, s1_ = q1x * gx + q1y * gy, s2_ = q2x * gx + q2y * gy; \
        const float t0_ = q0z * q0z * gz2, t1_ = q1z * q1z * gz2, t2_ = q2z * q2z * gz2; \
        const bool in0 = (q0z >= 0.0f) ? ((s0_ > 0.0f) | (t0_ > s0_ * s0_)) : ((s0_ > 0.0f) & (t0_ < s0_ * s0_)); \
        const bool in1 = (q1z >= 0.0f) ? ((s1_ > 0.0f) | (t1_ > s1_ * s1_)) : ((s1_ > 0.0f) & (t1_ < s1_ * s1_)); \
        const bool in2 = (q2z >= 0.0f) ? ((s2_ > 0.0f) | (t2_ > s2_ * s2_)) : ((s2_ > 0.0f) & (t2_ < s2_ * s2_)); \
        const bool h = (gz2 > 0.0f) & in0 & in1 & in2 & (DI <= i1 - i0) & (DJ <= j1 - j0); \
        hb_ |= h ? (1u << (DIRECT_SPAN * (int)DI + (int)DJ)) : 0u; }
DIRECT_CENTRES
#undef WS_CENTRE
    hits[k] = (unsigned short)hb_;
  }
#undef WS_LOCAL
  // the listed blockers with a centre to set, then their centres
  int nh = 0;
  for (int k = 0; k < m; ++k) {
    sethit[nh] = (unsigned short)k;
    nh += hits[k] != 0 ? 1 : 0;
  }
  uint64_t* __restrict__ pm = (uint64_t*)((char*)mask.data + v * mask.strides[0]);
  // centre (i, j) -> bit: i in the even bits, j in the odd ones (.tables.morton2; 6 bits each, spread by
  // shifts and masks)
  auto spread = [](unsigned int x) -> unsigned int {
    x = (x | (x << 4)) & 0x30fu;
    x = (x | (x << 2)) & 0x333u;
    return (x | (x << 1)) & 0x555u;
  };
  for (int h = 0; h < nh; ++h) {
    const int k = sethit[h], t = listed[k];
    unsigned int hb = hits[k];
    while (hb != 0) {
      const int d = __builtin_ctz(hb);
      hb &= hb - 1;
      const unsigned int i = (unsigned int)((int)bi[t] + d / DIRECT_SPAN), j = (unsigned int)((int)bj[t] + d % DIRECT_SPAN);
      const unsigned int bit = spread(i) | (spread(j) << 1);
      pm[bit >> 6] |= (uint64_t)1 << (bit & 63);
    }
  }
}
#undef WS_MIN
#undef WS_MAX
for (int t = nt; t < words * 64; ++t)
    flags[t] = 0;
for (int w = 0; w < words; ++w) {
    uint64_t mc = 0, mt = 0, mr = 0;
    for (int b = 0; b < 8; ++b) {
        uint64_t x;
        memcpy(&x, flags + w * 64 + 8 * b, 8);
        mc |= (((x & ones) * magic) >> 56) << (8 * b);
        mt |= ((((x >> 1) & ones) * magic) >> 56) << (8 * b);
        mr |= ((((x >> 2) & ones) * magic) >> 56) << (8 * b);
    }
    pc[w] = mc;
    pt[w] = mt;
    pr[w] = mr | (use_ring ? pring[w] : (uint64_t)0);
}
"""


_FAR_FIELD_BITS = _FAR_FIELD_BITS.replace("PRECULL_BLOCKERS", str(PRECULL_BLOCKERS)).replace(
    "DIRECT_CENTRES", "\n".join(f"    WS_CENTRE({di}.0f, {dj}.0f)" for di in range(DIRECT_SPAN) for dj in range(DIRECT_SPAN))).replace(
    "DIRECT_SPAN", str(DIRECT_SPAN))


@wp.func_native(_FAR_FIELD_BITS)
def far_field_bits(plane: wp.array[wp.vec4], sphere: wp.array[wp.vec4], nlen: wp.array[float], lo: wp.array[wp.vec3],
                   hi: wp.array[wp.vec3], dev: wp.array[float], ring: wp.array2d[wp.uint64], use_ring: int, v: int, sl: int,
                   p: wp.vec3, n: wp.vec3, backface: float, rim: float, min_area: float, refine: float,
                   cull: wp.array2d[wp.uint64], tiny: wp.array2d[wp.uint64], refined: wp.array2d[wp.uint64],
                   corners: wp.array2d[float], frame: wp.mat33, direct: float, half_mask: float, lut_half: float,
                   lut_last: float, mask: wp.array2d[wp.uint64]):
    """For receiver ``v`` (slot ``sl``) and every blocker, in one pass: the bits of :func:`skip_early`
    (``cull``), of :func:`bounds_below` (``tiny``; none when ``min_area`` is 0) and of the blockers
    refined here (``refined``: :func:`refine_here` with ``refine`` > 0, or the receiver's k-ring row of
    ``ring`` with ``use_ring``), the same operations in the same order as those Warp functions, so
    the same bits (:func:`mark_refined` tests only the clusters that come near; its bits equal the
    per-blocker test). With ``direct`` >= 0 a second pass rasterizes the blockers that are neither culled
    nor refined here and whose image spans at most 2 x 2 pixel centres of the ``2·half_mask``-pixel mask
    (the box of the corners' disk images, widened by the arcs' bulge and ``direct``, holds at most 2 x 2
    centres; corners within 60° of each other) straight into row ``v`` of ``mask``: each of those centres
    lies in the image when it is above the three edge planes quantised as the plane LUT does (its cell's
    centre normal, :func:`.tables.cube_cell_normals`, the cube map of resolution ``2·lut_half``), which
    is the LUT's image at those centres; such blockers get the ``tiny`` bit (not queued). ``frame`` is the
    receiver's tangent frame, ``corners`` the blockers' corners (:func:`blocker_corners`). Native C++ over
    flat rows, which clang
    vectorizes; the arrays must be contiguous."""


@wp.func(inline=True)
def mark_refined(
    v: int,
    sl: int,
    p: wp.vec3,
    n: wp.vec3,
    frame: wp.mat33,
    lut: PlaneLut,
    blockers: Blockers,
    groups: Refinement,
    near_mode: int,
    excl: wp.array2d[wp.uint32],
    cluster_start: wp.array[wp.int32],
    cluster_lo: wp.array[wp.vec3],
    cluster_hi: wp.array[wp.vec3],
    cluster_reach: wp.array[float],
    mask: wp.array2d[wp.uint64],
    part: int,
):
    """Set the slot's bits of the blockers replaced by their fine (or mid) triangles for receiver ``v``:
    those standing for its k-ring (``near_mode`` 2: its exclusion bits) and those passing
    :func:`refine_here`. Decided once per receiver for the whole far field, so the far-field pass
    and the seam-cover extras of every refined group (whose primary blocker may be anywhere) read
    one bit. Per-blocker tests only in clusters that come near enough: a cluster's box and reach
    hold its blockers' boxes and deviations, so a cluster failing :func:`box_near` has no blocker
    passing :func:`refine_here` (the same float operations on smaller distances and a larger radius).
    With ``blockers.precull``, :func:`far_field_bits` sets these bits for every blocker instead (and
    the per-frame culls' bits; with ``lut.direct`` >= 0 and ``part`` 0, also row ``v`` of ``mask``'s bits of
    the small far-field images it rasterizes itself)."""
    if blockers.precull != 0:
        far_field_bits(blockers.plane, blockers.sphere, blockers.nlen, groups.lo, groups.hi, groups.dev, blockers.ring,
                       wp.where(near_mode == 2, 1, 0), v, sl, p, n, lut.backface, lut.rim, lut.min_area, groups.refine,
                       blockers.cull, blockers.tiny, blockers.refined, blockers.corners, frame,
                       wp.where(part == 0, lut.direct, -1.0), lut.half_mask, lut.lut_half, lut.lut_last, mask)
        return
    for w in range(blockers.refined.shape[1]):
        blockers.refined[sl, w] = wp.uint64(0)
    if near_mode == 2:
        for w in range(excl.shape[1]):
            x = excl[v, w]
            while x != wp.uint32(0):
                b = wp.bit_count((x & (~x + wp.uint32(1))) - wp.uint32(1))
                x = x & (x - wp.uint32(1))
                t = blockers.order[w * 32 + b]
                blockers.refined[sl, t >> 6] = blockers.refined[sl, t >> 6] | (wp.uint64(1) << wp.uint64(t & 63))
    if groups.refine > 0.0:
        for c in range(cluster_start.shape[0] - 1):
            if box_near(p, cluster_lo[c], cluster_hi[c], groups.refine * cluster_reach[c]):
                for t in range(cluster_start[c], cluster_start[c + 1]):
                    bit = wp.where(refine_here(p, groups.lo[t], groups.hi[t], groups.dev[t], groups.refine),
                                   wp.uint64(1) << wp.uint64(t & 63), wp.uint64(0))
                    blockers.refined[sl, t >> 6] = blockers.refined[sl, t >> 6] | bit


CANDIDATES = wp.constant(64)
"""Fine triangles staged per slot (:attr:`Batch.cand`) before their gathers and exact tests."""


@wp.func(inline=True)
def stage_fine(
    f: int,
    sl: int,
    p: wp.vec3,
    n: wp.vec3,
    fine: FineMesh,
    use_seen: int,
    seen: wp.array2d[wp.uint64],
    lut: PlaneLut,
    bt: Batch,
    nc: int,
) -> int:
    """Stage fine triangle ``f`` standing in for a refined blocker (coarse or mid) unless a cull from
    per-frame data (:func:`skip_early`) drops it or, with ``use_seen``, it was already staged for this
    receiver; returns the number staged. (The pre-test :func:`bounds_below` of the tiny-image cull is
    not applied here: it dropped only ~8 % of the Table 1 cloth's fine candidates and cost more than
    their gathers. The two bounds differ, so a triangle only it deemed tiny is now rasterized; on the
    Table 1 cloth, the bunny and the crumpled cloth :func:`image_below` drops them all.) Branch-free: ``f`` is always written
    to the next free entry, which only a kept one takes. The slot's row of ``seen`` is marked even
    when culled (the culls depend only on the triangle and the receiver, so any other group listing
    it culls it too). The gathers and the exact tests wait for :func:`queue_candidates`: about half
    the fine triangles of a refined group (slivers below the horizon, repeats) never need them."""
    fpl = fine.plane[f]
    fsp = fine.sphere[f]
    drop = skip_early(fpl, fsp, p, n, lut.backface, lut.rim)
    if use_seen != 0:
        bit = wp.uint64(1) << wp.uint64(f & 63)
        word = seen[sl, f >> 6]
        drop = wp.where(drop, True, (word & bit) != wp.uint64(0))
        seen[sl, f >> 6] = word | bit
    bt.cand[sl, nc] = f
    return nc + wp.where(drop, 0, 1)


@wp.func(inline=True)
def queue_candidates(
    nc: int,
    src: int,
    v: int,
    sl: int,
    p: wp.vec3,
    n: wp.vec3,
    fine: FineMesh,
    frame: wp.mat33,
    lut: PlaneLut,
    mask: wp.array2d[wp.uint64],
    bt: Batch,
    nb: int,
) -> int:
    """Queue the ``nc`` staged fine triangles (:func:`stage_fine`) unless incident to the receiver (they
    contain it: no solid angle); returns the queue length. Their tiny-image test (:func:`image_below`
    with ``lut.fine_area``) and the count in ``refined`` wait for :func:`batch_codes`.
    Branch-free (:func:`push_triangle`)."""
    for e in range(nc):
        f = bt.cand[sl, e]
        i = fine.faces[f, 0]
        j = fine.faces[f, 1]
        k = fine.faces[f, 2]
        drop = wp.where(i == v, True, wp.where(j == v, True, k == v))
        fa = fine.points[i] - p
        fb = fine.points[j] - p
        fc = fine.points[k] - p
        nb = push_triangle(fa, fb, fc, src, drop, lut.fine_area, 1, nb, v, sl, frame, lut, mask, bt)
    return nb


@wp.func(inline=True)
def rasterize_group(
    t: int,
    v: int,
    sl: int,
    p: wp.vec3,
    n: wp.vec3,
    fine: FineMesh,
    groups: Refinement,
    blockers: Blockers,
    frame: wp.mat33,
    lut: PlaneLut,
    mask: wp.array2d[wp.uint64],
    bt: Batch,
    nb: int,
) -> int:
    """Queue the fine triangles blocker ``t`` stands for (spatial near field); returns the queue
    length (:func:`batch_codes` counts them in ``refined[v]``).

    The seam-cover extras (``groups.mid[t]`` on) are skipped when their primary coarse triangle is
    refined for this receiver too (:func:`mark_refined`): it rasterizes them itself (in PVS mode,
    when it is in the set: it was refined whenever the extra set a bit while recording). Triangles
    incident to the receiver are skipped (they contain it: no solid angle); a triangle rasterized
    twice (also in a k-ring) is harmless under the OR fusion of §3.1.1.
    """
    src = blockers.source[t]
    r = groups.start[t]
    end = groups.start[t + 1]
    mid = groups.mid[t]
    nc = int(0)
    while r < end:
        if r >= mid:
            # a run of extras of one primary blocker: all skipped when it is refined here too,
            # with one test for the run
            if blocker_refined(blockers, sl, groups.owner[r]):
                r = groups.run_end[r]
                continue
        nc = stage_fine(groups.tris[r], sl, p, n, fine, groups.use_seen, groups.seen, lut, bt, nc)
        r += 1
        if nc == CANDIDATES:
            nb = queue_candidates(nc, src, v, sl, p, n, fine, frame, lut, mask, bt, nb)
            nc = 0
    return queue_candidates(nc, src, v, sl, p, n, fine, frame, lut, mask, bt, nb)


@wp.func
def mid_refined(m: int, sl: int, p: wp.vec3, sub: Refinement, mids: MidLevel) -> bool:
    """Whether mid triangle ``m`` is replaced by its fine triangles for the slot's receiver (when it
    is visited): it stands for the receiver's k-ring or passes :func:`refine_here` with its own bounds."""
    ring = (mids.ring_bits[sl, m >> 6] >> wp.uint64(m & 63)) & wp.uint64(1) != wp.uint64(0)
    return wp.where(ring, True, refine_here(p, sub.lo[m], sub.hi[m], sub.dev[m], sub.refine))


@wp.func(inline=True)
def rasterize_mid_fine(
    m: int,
    src: int,
    v: int,
    sl: int,
    p: wp.vec3,
    n: wp.vec3,
    fine: FineMesh,
    groups: Refinement,
    sub: Refinement,
    mids: MidLevel,
    blockers: Blockers,
    frame: wp.mat33,
    lut: PlaneLut,
    mask: wp.array2d[wp.uint64],
    bt: Batch,
    nb: int,
) -> int:
    """Queue the fine triangles mid triangle ``m`` stands for, as :func:`rasterize_group` does for a
    coarse blocker; returns the queue length. A run of seam-cover extras is
    skipped when its primary mid triangle is replaced by its fine triangles here too: that mid
    triangle is then certainly visited (its primary coarse blocker is refined) and expanded."""
    r = sub.start[m]
    end = sub.start[m + 1]
    mid = sub.mid[m]
    nc = int(0)
    while r < end:
        if r >= mid:
            o = sub.owner[r]
            if mid_refined(o, sl, p, sub, mids):
                if blocker_refined(blockers, sl, mids.coarse[o]):
                    r = sub.run_end[r]
                    continue
        nc = stage_fine(sub.tris[r], sl, p, n, fine, sub.use_seen, sub.seen, lut, bt, nc)
        r += 1
        if nc == CANDIDATES:
            nb = queue_candidates(nc, src, v, sl, p, n, fine, frame, lut, mask, bt, nb)
            nc = 0
    return queue_candidates(nc, src, v, sl, p, n, fine, frame, lut, mask, bt, nb)


@wp.func(inline=True)
def rasterize_mid_group(
    t: int,
    v: int,
    sl: int,
    p: wp.vec3,
    n: wp.vec3,
    fine: FineMesh,
    groups: Refinement,
    sub: Refinement,
    mids: MidLevel,
    blockers: Blockers,
    frame: wp.mat33,
    lut: PlaneLut,
    mask: wp.array2d[wp.uint64],
    bt: Batch,
    nb: int,
) -> int:
    """Queue what refined coarse blocker ``t`` stands for at the mid level: each of its mid triangles
    (primaries, and the seam-cover extras whose primary coarse blocker is not refined here) is
    queued itself, or, when it stands for the receiver's k-ring or comes within ``refine`` times its
    own deviation of the receiver (:func:`mid_refined`), replaced by its fine triangles
    (:func:`rasterize_mid_fine`). Returns the queue length; counts the mid triangles in
    ``mids.counts[v]`` (the fine ones are counted by :func:`batch_codes`)."""
    cmid = int(0)
    src = blockers.source[t]
    r = groups.start[t]
    end = groups.start[t + 1]
    gm = groups.mid[t]
    while r < end:
        if r >= gm:
            if blocker_refined(blockers, sl, groups.owner[r]):
                r = groups.run_end[r]
                continue
        m = groups.tris[r]
        r += 1
        if groups.use_seen != 0:
            # a mid triangle listed by several refined coarse blockers is handled once per receiver
            bit = wp.uint64(1) << wp.uint64(m & 63)
            word = groups.seen[sl, m >> 6]
            groups.seen[sl, m >> 6] = word | bit
            if (word & bit) != wp.uint64(0):
                continue
        if mid_refined(m, sl, p, sub, mids):
            nb = rasterize_mid_fine(m, src, v, sl, p, n, fine, groups, sub, mids, blockers, frame, lut, mask, bt, nb)
        else:
            # exact, as the fine triangles it stands for (a tiny-image cull here cost more than it saved)
            drop = skip_early(mids.plane[m], mids.sphere[m], p, n, lut.backface, lut.rim)
            a = mids.points[mids.faces[m, 0]] - p
            b = mids.points[mids.faces[m, 1]] - p
            c = mids.points[mids.faces[m, 2]] - p
            nb = push_triangle(a, b, c, src, drop, 0.0, 0, nb, v, sl, frame, lut, mask, bt)
            cmid += wp.where(drop, 0, 1)
    mids.counts[v] = mids.counts[v] + cmid
    return nb


@wp.func(inline=True)
def list_cover(level: Refinement, sl: int, r: int):
    """Add blocker ``r``'s ``cover`` row to the slot's set ``level.listed``."""
    for u in range(level.listed.shape[1]):
        level.listed[sl, u] = level.listed[sl, u] | level.cover[r, u]


@wp.func(inline=True)
def unlist_primary(level: Refinement, sl: int, r: int):
    """Remove blocker ``r``'s ``primary`` row from the slot's set ``level.listed``."""
    for u in range(level.listed.shape[1]):
        level.listed[sl, u] = level.listed[sl, u] & (level.primary[r, u] ^ MaskChunk(~wp.uint64(0)))


@wp.func(inline=True)
def listed_set(sl: int, blockers: Blockers, groups: Refinement):
    """Finish the slot's set of the triangles listed by the refined blockers the far-field pass visited
    (``groups.listed``: the OR of their ``cover`` rows) by removing the primary triangles of the
    refined blockers the pass did not visit (below the horizon).

    That is the union of what the per-group walk (:func:`rasterize_group`, :func:`rasterize_mid_group`)
    queues for each visited blocker: its primaries, and the extras whose primary blocker is not
    refined (those whose primary blocker is refined and visited are primaries of that one; those
    whose primary blocker is refined and not visited are left out by both; a triangle has one
    primary blocker). Not for recording a PVS (``bt.record``), which credits each triangle to the
    blocker whose group listed it."""
    for w in range(blockers.refined.shape[1]):
        x = blockers.refined[sl, w] & ~groups.visited[sl, w]
        while x != wp.uint64(0):
            t = w * 64 + lowest_bit(x)
            x = x & (x - wp.uint64(1))
            unlist_primary(groups, sl, t)


@wp.func(inline=True)
def clear_visited(sl: int, groups: Refinement):
    """Clear the slot's bits of the visited refined blockers (after :func:`listed_set`'s set is handled)."""
    for w in range(groups.visited.shape[1]):
        groups.visited[sl, w] = wp.uint64(0)


@wp.func(inline=True)
def queue_fine_set(
    v: int,
    sl: int,
    p: wp.vec3,
    n: wp.vec3,
    fine: FineMesh,
    level: Refinement,
    frame: wp.mat33,
    lut: PlaneLut,
    mask: wp.array2d[wp.uint64],
    bt: Batch,
    nb: int,
) -> int:
    """Queue the fine triangles of the slot's set ``level.listed`` (bits over the fine mesh) and clear it;
    returns the queue length. Each fine triangle is handled once, in index order: 64 at a time
    classified from per-frame data (:func:`skip_early`, as :func:`stage_fine`), then the kept ones
    gathered and queued unless incident to the receiver (as :func:`queue_candidates`; the tiny-image
    test with ``lut.fine_area`` and the count in ``refined`` wait for :func:`batch_codes`)."""
    zero = wp.uint64(0)
    for u in range(level.listed.shape[1]):
        chunk = level.listed[sl, u]
        level.listed[sl, u] = MaskChunk()
        for i in range(CHUNK_WORDS):
            base = (u * CHUNK_WORDS + i) * 64
            x = wp.where(bt.halt[sl] > 0, zero, chunk[i])  # a stopped receiver only clears the set
            keep = zero
            while x != zero:
                k = lowest_bit(x)
                x = x & (x - wp.uint64(1))
                f = base + k
                drop = skip_early(fine.plane[f], fine.sphere[f], p, n, lut.backface, lut.rim)
                keep = keep | wp.where(drop, zero, wp.uint64(1) << wp.uint64(k))
            while keep != zero:
                f = base + lowest_bit(keep)
                keep = keep & (keep - wp.uint64(1))
                i0 = fine.faces[f, 0]
                j0 = fine.faces[f, 1]
                k0 = fine.faces[f, 2]
                drop = wp.where(i0 == v, True, wp.where(j0 == v, True, k0 == v))
                nb = push_triangle(fine.points[i0] - p, fine.points[j0] - p, fine.points[k0] - p, -1, drop, lut.fine_area, 1,
                                   nb, v, sl, frame, lut, mask, bt)
    return nb


@wp.func(inline=True)
def rasterize_fine_set(
    v: int,
    sl: int,
    p: wp.vec3,
    n: wp.vec3,
    fine: FineMesh,
    groups: Refinement,
    blockers: Blockers,
    frame: wp.mat33,
    lut: PlaneLut,
    mask: wp.array2d[wp.uint64],
    bt: Batch,
    nb: int,
    part: int,
    st: StaticPart,
) -> int:
    """Queue the fine triangles of the refined blockers the far-field pass visited (the set of
    :func:`listed_set`), as :func:`rasterize_group` would blocker by blocker, without walking the
    groups' lists or a rasterized-once table (:func:`queue_fine_set`); returns the queue length.
    ``part`` 1 stores the set in ``st.listed``, 2 leaves out what is stored there (:class:`StaticPart`).
    A stopped receiver (``bt.halt``) only clears the set."""
    if bt.halt[sl] > 0:
        clear_visited(sl, groups)
        for u in range(groups.listed.shape[1]):
            groups.listed[sl, u] = MaskChunk()
        return nb
    listed_set(sl, blockers, groups)
    clear_visited(sl, groups)
    if part == 1:
        r = st.receiver[v] - 1
        for u in range(groups.listed.shape[1]):
            st.listed[r, u] = groups.listed[sl, u]
    elif part == 2:
        r = st.receiver[v] - 1
        for u in range(groups.listed.shape[1]):
            groups.listed[sl, u] = groups.listed[sl, u] & (st.listed[r, u] ^ MaskChunk(~wp.uint64(0)))
    return queue_fine_set(v, sl, p, n, fine, groups, frame, lut, mask, bt, nb)


@wp.func(inline=True)
def rasterize_mid_set(
    v: int,
    sl: int,
    p: wp.vec3,
    n: wp.vec3,
    fine: FineMesh,
    groups: Refinement,
    sub: Refinement,
    mids: MidLevel,
    blockers: Blockers,
    frame: wp.mat33,
    lut: PlaneLut,
    mask: wp.array2d[wp.uint64],
    bt: Batch,
    nb: int,
) -> int:
    """Queue the mid triangles of the refined coarse blockers the far-field pass visited (the set of
    :func:`listed_set`), as :func:`rasterize_mid_group` would blocker by blocker; returns the queue
    length. Each mid triangle is handled once, in index order, without walking the groups' lists,
    testing a run of extras per primary blocker, or a rasterized-once table.

    With ``sub.use_set`` the mid triangles replaced by their fine triangles are collected the same
    way, as a set over the fine mesh (``sub.listed``: the OR of their ``cover`` rows), less the primary
    fine triangles of the mid triangles that :func:`rasterize_mid_fine` treats as replaced elsewhere
    (those passing :func:`mid_refined` whose primary coarse blocker is refined) but which are not in
    the set: those of the refined coarse blockers the pass did not visit (a mid triangle in the set
    whose coarse blocker is refined and visited is replaced here). That is the union of what
    :func:`rasterize_mid_fine` queues for each replaced mid triangle; it is queued once, in index
    order (:func:`queue_fine_set`)."""
    listed_set(sl, blockers, groups)
    zero = wp.uint64(0)
    cmid = int(0)
    for u in range(groups.listed.shape[1]):
        chunk = groups.listed[sl, u]
        groups.listed[sl, u] = MaskChunk()
        for i in range(CHUNK_WORDS):
            base = (u * CHUNK_WORDS + i) * 64
            # first each listed mid triangle classified from per-frame data (selects), as in
            # :func:`rasterize_far_chunk`: replaced by its fine triangles, culled, or kept
            x = chunk[i]
            expand = zero
            keep = zero
            while x != zero:
                k = lowest_bit(x)
                x = x & (x - wp.uint64(1))
                m = base + k
                bit = wp.uint64(1) << wp.uint64(k)
                ref = mid_refined(m, sl, p, sub, mids)
                expand = expand | wp.where(ref, bit, zero)
                drop = skip_early(mids.plane[m], mids.sphere[m], p, n, lut.backface, lut.rim)
                keep = keep | wp.where(ref, zero, wp.where(drop, zero, bit))
            while expand != zero:
                m = base + lowest_bit(expand)
                expand = expand & (expand - wp.uint64(1))
                if sub.use_set != 0:
                    list_cover(sub, sl, m)
                else:
                    nb = rasterize_mid_fine(m, -1, v, sl, p, n, fine, groups, sub, mids, blockers, frame, lut, mask, bt, nb)
            # exact, as the fine triangles they stand for (a tiny-image cull here cost more than it saved)
            cmid += wp.bit_count(keep)
            while keep != zero:
                m = base + lowest_bit(keep)
                keep = keep & (keep - wp.uint64(1))
                a = mids.points[mids.faces[m, 0]] - p
                b = mids.points[mids.faces[m, 1]] - p
                c = mids.points[mids.faces[m, 2]] - p
                nb = push_triangle(a, b, c, -1, False, 0.0, 0, nb, v, sl, frame, lut, mask, bt)
    mids.counts[v] = mids.counts[v] + cmid
    if sub.use_set != 0:
        # after every OR: the primaries of the replaced mid triangles not in the set
        for w in range(blockers.refined.shape[1]):
            x = blockers.refined[sl, w] & ~groups.visited[sl, w]
            while x != wp.uint64(0):
                t = w * 64 + lowest_bit(x)
                x = x & (x - wp.uint64(1))
                for r in range(groups.start[t], groups.mid[t]):
                    o = groups.tris[r]
                    if mid_refined(o, sl, p, sub, mids):
                        unlist_primary(sub, sl, o)
    clear_visited(sl, groups)
    if sub.use_set != 0:
        nb = queue_fine_set(v, sl, p, n, fine, sub, frame, lut, mask, bt, nb)
    return nb


@wp.func
def excluded(excl: wp.array2d[wp.uint32], v: int, t: int) -> bool:
    """Bit ``t`` of receiver ``v``'s exclusion set."""
    return (excl[v, t >> 5] >> wp.uint32(t & 31)) & wp.uint32(1) != wp.uint32(0)


@wp.func(inline=True)
def queue_blocker(
    t: int,
    v: int,
    sl: int,
    p: wp.vec3,
    blockers: Blockers,
    frame: wp.mat33,
    lut: PlaneLut,
    mask: wp.array2d[wp.uint64],
    bt: Batch,
    nb: int,
) -> int:
    """Queue blocker triangle ``t`` that passed the per-frame culls, unless it is incident to the
    receiver (full-mesh blockers only) or its exact image is tiny (:func:`image_below`); returns
    the queue length. Branch-free (:func:`push_triangle`)."""
    i = blockers.faces[t, 0]
    j = blockers.faces[t, 1]
    k = blockers.faces[t, 2]
    skip = False
    if blockers.skip_incident != 0:
        skip = wp.where(i == v, True, wp.where(j == v, True, k == v))
    a = blockers.points[i] - p
    b = blockers.points[j] - p
    c = blockers.points[k] - p
    return push_triangle(a, b, c, blockers.source[t], skip, lut.min_area, 0, nb, v, sl, frame, lut, mask, bt)


FAR_CHUNK = wp.constant(64)
"""Far-field blockers tested per branch-free pass of :func:`rasterize_far_chunk` (the bits of a uint64)."""


@wp.func(inline=True)
def lowest_bit(x: wp.uint64) -> int:
    """Index of the lowest set bit of ``x`` (non-zero): the popcount of the bits below it."""
    return wp.bit_count((x & (~x + wp.uint64(1))) - wp.uint64(1))


@wp.func(inline=True)
def visit_refined(x: wp.uint64, t0: int, sl: int, groups: Refinement):
    """Mark the refined blockers ``t0 + k`` of the bits ``k`` of ``x`` visited and list their groups'
    triangles in the slot's set (:func:`listed_set`)."""
    while x != wp.uint64(0):
        t = t0 + lowest_bit(x)
        x = x & (x - wp.uint64(1))
        groups.visited[sl, t >> 6] = groups.visited[sl, t >> 6] | (wp.uint64(1) << wp.uint64(t & 63))
        list_cover(groups, sl, t)


@wp.func(inline=True)
def refined_bits(t0: int, t1: int, sl: int, blockers: Blockers, part: int, st: StaticPart) -> wp.uint64:
    """Bits of the refined blockers among ``t0 .. t1-1`` (at most 64; ``part`` as :func:`rasterize_far_chunk`)."""
    x = slot_bits(blockers.refined, sl, t0, t1)
    if part != 0:
        sb = slot_bits(st.blockers, 0, t0, t1)
        x = x & wp.where(part == 1, sb, ~sb)
    return x


@wp.func(inline=True)
def rasterize_far_chunk(
    t0: int,
    t1: int,
    v: int,
    sl: int,
    p: wp.vec3,
    n: wp.vec3,
    fine: FineMesh,
    groups: Refinement,
    sub: Refinement,
    mids: MidLevel,
    blockers: Blockers,
    use_excl: int,
    excl: wp.array2d[wp.uint32],
    frame: wp.mat33,
    lut: PlaneLut,
    mask: wp.array2d[wp.uint64],
    bt: Batch,
    nb: int,
    part: int,
    st: StaticPart,
    fine_done: int,
) -> int:
    """Far-field blockers ``t0 .. t1-1`` (at most :data:`FAR_CHUNK`, consecutive; the PVS path passes
    one at a time): each is rasterized itself, or replaced by its fine triangles near the receiver
    (:func:`rasterize_group`). Returns the receiver's queue length. ``part`` 1: only the blockers of
    ``st.blockers``, 2: only the others, 0: all (:class:`StaticPart`; a refined blocker left out counts as
    not visited; ``fine_done`` 1: the refined blockers were handled before the far field, by
    :func:`refined_first`, and are left out here).

    First a branch-free pass over all of them classifies each from per-frame data alone: dropped
    (near-field exclusion of the paper scheme), refined (the receiver's bits, :func:`mark_refined`),
    culled (:func:`skip_early`, :func:`bounds_below`), or kept; the outcome goes into two bit sets. Then only the refined and the kept blockers are visited. On one CPU thread
    per-blocker branches mispredicted about as often as they were taken (a coarse cloth triangle
    is kept, culled or tiny with similar odds), and their stalls cost more than the tests themselves.
    """
    zero = wp.uint64(0)
    # (Python's ``and``/``or`` would become branches in the generated code: bits are combined with
    # ``wp.where`` selects and bitwise operators instead)
    cull = zero
    tiny = zero
    if blockers.precull != 0:
        cull = slot_bits(blockers.cull, sl, t0, t1)
        tiny = slot_bits(blockers.tiny, sl, t0, t1)
    else:
        for t in range(t0, t1):
            bit = wp.uint64(1) << wp.uint64(t - t0)
            sph = blockers.sphere[t]
            pln = blockers.plane[t]
            cull = cull | wp.where(skip_early(pln, sph, p, n, lut.backface, lut.rim), bit, zero)
            if lut.min_area > 0.0:  # the same for every blocker: predicted
                tiny = tiny | wp.where(bounds_below(pln, sph, blockers.nlen[t], p, n, lut.min_area), bit, zero)
    refine_bits = refined_bits(t0, t1, sl, blockers, part, st)
    ex = zero
    if use_excl == 1:
        # near-field exclusion bits of the paper scheme (no refinement): dropped
        for t in range(t0, t1):
            ex = ex | wp.where(excluded(excl, v, blockers.source[t]), wp.uint64(1) << wp.uint64(t - t0), zero)
    keep = ~(ex | refine_bits | cull | tiny)
    if t1 - t0 < 64:
        keep = keep & ((wp.uint64(1) << wp.uint64(t1 - t0)) - wp.uint64(1))
    if part != 0:
        sb = slot_bits(st.blockers, 0, t0, t1)
        keep = keep & wp.where(part == 1, sb, ~sb)
    if groups.use_set != 0 and bt.record == 0:
        # queued with the other visited ones' after the far field (:func:`rasterize_mid_set`,
        # :func:`rasterize_fine_set`), or before it (``fine_done``)
        if fine_done == 0:
            visit_refined(refine_bits, t0, sl, groups)
    else:
        while refine_bits != wp.uint64(0):
            k = lowest_bit(refine_bits)
            refine_bits = refine_bits & (refine_bits - wp.uint64(1))
            if mids.on != 0:
                nb = rasterize_mid_group(t0 + k, v, sl, p, n, fine, groups, sub, mids, blockers, frame, lut, mask, bt, nb)
            else:
                nb = rasterize_group(t0 + k, v, sl, p, n, fine, groups, blockers, frame, lut, mask, bt, nb)
    while keep != wp.uint64(0):
        k = lowest_bit(keep)
        keep = keep & (keep - wp.uint64(1))
        nb = queue_blocker(t0 + k, v, sl, p, blockers, frame, lut, mask, bt, nb)
    return nb


@wp.func(inline=True)
def refined_first(
    v: int,
    sl: int,
    p: wp.vec3,
    n: wp.vec3,
    fine: FineMesh,
    groups: Refinement,
    blockers: Blockers,
    use_cull: int,
    cluster_start: wp.array[wp.int32],
    cluster_lo: wp.array[wp.vec3],
    cluster_hi: wp.array[wp.vec3],
    super_start: wp.array[wp.int32],
    super_lo: wp.array[wp.vec3],
    super_hi: wp.array[wp.vec3],
    frame: wp.mat33,
    lut: PlaneLut,
    mask: wp.array2d[wp.uint64],
    bt: Batch,
    nb: int,
    part: int,
    st: StaticPart,
) -> int:
    """Queue the fine triangles of the refined blockers the far-field pass would visit (those of the
    clusters reaching above the tangent plane with ``use_cull``, else all; ``part`` as
    :func:`rasterize_far_chunk`) before that pass, as :func:`rasterize_fine_set` does after it; returns the
    queue length. The same set, so the same images and counts in another order."""
    if use_cull != 0:
        offset = wp.dot(n, p)
        for s in range(super_start.shape[0] - 1):
            if box_above_plane(super_lo[s], super_hi[s], n, offset):
                for c in range(super_start[s], super_start[s + 1]):
                    if box_above_plane(cluster_lo[c], cluster_hi[c], n, offset):
                        for t0 in range(cluster_start[c], cluster_start[c + 1], FAR_CHUNK):
                            t1 = wp.min(t0 + FAR_CHUNK, cluster_start[c + 1])
                            visit_refined(refined_bits(t0, t1, sl, blockers, part, st), t0, sl, groups)
    else:
        for t0 in range(0, blockers.faces.shape[0], FAR_CHUNK):
            t1 = wp.min(t0 + FAR_CHUNK, blockers.faces.shape[0])
            visit_refined(refined_bits(t0, t1, sl, blockers, part, st), t0, sl, groups)
    return rasterize_fine_set(v, sl, p, n, fine, groups, blockers, frame, lut, mask, bt, nb, part, st)


@wp.kernel
def rasterize_masks(
    fine: FineMesh,
    normals: wp.array[wp.vec3],
    ring_start: wp.array[wp.int32],
    ring_tris: wp.array[wp.int32],
    blockers: Blockers,
    use_excl: int,
    excl: wp.array2d[wp.uint32],
    groups: Refinement,
    sub: Refinement,
    mids: MidLevel,
    use_cull: int,
    cluster_start: wp.array[wp.int32],
    cluster_lo: wp.array[wp.vec3],
    cluster_hi: wp.array[wp.vec3],
    cluster_reach: wp.array[float],
    super_start: wp.array[wp.int32],
    super_lo: wp.array[wp.vec3],
    super_hi: wp.array[wp.vec3],
    use_pvs: int,
    pvs_start: wp.array[wp.int32],
    pvs_tris: wp.array[wp.int32],
    lut: PlaneLut,
    bt: Batch,
    st: StaticPart,
    receivers: wp.array[wp.int32],
    num_receivers: int,
    num_slots: int,
    mask: wp.array2d[wp.uint64],
    refined: wp.array[wp.int32],
):
    """Per receiver vertex: rasterize its blockers into its visibility mask (paper §3.1).

    Thread ``sl`` of ``num_slots`` handles receivers ``receivers[sl], receivers[sl + num_slots], ...``
    (the first ``num_receivers``) with scratch row
    ``sl`` of the :class:`Batch` queue and the rasterized-once table: on the CPU one slot (one
    thread runs the launch anyway), so that scratch stays in the L1 cache from receiver to
    receiver; on a GPU one slot per receiver.

    Blockers: the receiver's full-resolution k-ring (``ring_*``) plus the blocker mesh (``b*``:
    coarse mesh, or the fine mesh itself when the hierarchy is off), traversed through the
    culled super-cluster / cluster hierarchy, linearly, or through the receiver's PVS list. With
    ``refine > 0`` a coarse blocker near the receiver is replaced by the fine triangles it stands
    for (``group_*``, :func:`refine_here`), so contact and folds see the exact surface.

    With ``st.mode`` (:class:`StaticPart`) the flagged receivers get only the part of the blockers the
    mode selects (1: the stored part with their fan and k-ring; 2: the rest, ORed into the stored part).

    The masks are integrated into SH transfer by the per-order kernels of :mod:`.integrate`.
    """
    sl = wp.tid()
    row = sl
    while row < num_receivers:
        v = receivers[row]
        p = fine.points[v]
        n = normals[v]
        frame = orthonormal_basis(n)
        part = int(0)
        if st.mode != 0:
            if st.receiver[v] != 0:
                part = st.mode
        stored = part == 2
        # (branches, not selects: the StaticPart's arrays are placeholders while it is off)
        if stored:
            for w in range(lut.words):
                mask[v, w] = st.mask[v, w]
        else:
            for w in range(lut.words):
                mask[v, w] = wp.uint64(0)
        if groups.use_seen != 0:
            for w in range(groups.seen.shape[1]):
                groups.seen[sl, w] = wp.uint64(0)
        if mids.on != 0:
            if sub.use_seen != 0:
                for w in range(sub.seen.shape[1]):
                    sub.seen[sl, w] = wp.uint64(0)
            for r in range(mids.ring_start[v], mids.ring_start[v + 1]):
                m = mids.ring_tris[r]
                mids.ring_bits[sl, m >> 6] = mids.ring_bits[sl, m >> 6] | (wp.uint64(1) << wp.uint64(m & 63))
            mids.counts[v] = 0
        if stored:
            bt.counts[v] = st.counts[v]
            refined[v] = st.refined[v]
        else:
            bt.counts[v] = 0
            refined[v] = 0
        # the early stop (Batch.stop_free): not while recording a PVS or storing a static part, which
        # later frames build on
        bt.halt[sl] = -1
        if bt.stop_free >= 0 and bt.record == 0 and part != 1:
            bt.halt[sl] = 0
        mark_refined(v, sl, p, n, frame, lut, blockers, groups, use_excl, excl, cluster_start, cluster_lo, cluster_hi,
                     cluster_reach, mask, part)
        nb = int(0)
        if fine.fan != 0 and not stored:
            nb = rasterize_fan(v, sl, p, n, fine, frame, lut, mask, bt, nb)
        # near field at full resolution (in the stored part when there is one)
        for r in range(ring_start[v], wp.where(stored, ring_start[v], ring_start[v + 1])):
            t = ring_tris[r]
            if skip_early(fine.plane[t], fine.sphere[t], p, n, lut.backface, lut.rim):
                continue
            i = fine.faces[t, 0]
            j = fine.faces[t, 1]
            k = fine.faces[t, 2]
            nb = push_triangle(fine.points[i] - p, fine.points[j] - p, fine.points[k] - p, -1, False, 0.0, 0, nb, v, sl, frame, lut,
                               mask, bt)
        # far field: coarse blockers, replaced by their fine triangles near the receiver; with the early
        # stop (Batch.halt) and near_first those fine triangles first: the near field is what buries a receiver
        fine_first = int(0)
        if bt.halt[sl] == 0 and bt.near_first != 0 and groups.use_set != 0 and mids.on == 0 and use_pvs == 0:
            fine_first = 1
            nb = refined_first(v, sl, p, n, fine, groups, blockers, use_cull, cluster_start, cluster_lo, cluster_hi,
                               super_start, super_lo, super_hi, frame, lut, mask, bt, nb, part, st)
        offset = wp.dot(n, p)
        if use_pvs != 0:
            for r in range(pvs_start[v], pvs_start[v + 1]):
                t = pvs_tris[r]
                if bt.halt[sl] > 0:
                    break
                nb = rasterize_far_chunk(t, t + 1, v, sl, p, n, fine, groups, sub, mids, blockers, use_excl, excl, frame,
                                         lut, mask, bt, nb, part, st, 0)
        elif use_cull != 0:
            for s in range(super_start.shape[0] - 1):
                if box_above_plane(super_lo[s], super_hi[s], n, offset):
                    for c in range(super_start[s], super_start[s + 1]):
                        if box_above_plane(cluster_lo[c], cluster_hi[c], n, offset):
                            for t0 in range(cluster_start[c], cluster_start[c + 1], FAR_CHUNK):
                                if bt.halt[sl] > 0:
                                    break
                                t1 = wp.min(t0 + FAR_CHUNK, cluster_start[c + 1])
                                nb = rasterize_far_chunk(t0, t1, v, sl, p, n, fine, groups, sub, mids, blockers, use_excl, excl,
                                                         frame, lut, mask, bt, nb, part, st, fine_first)
        else:
            for t0 in range(0, blockers.faces.shape[0], FAR_CHUNK):
                if bt.halt[sl] > 0:
                    break
                t1 = wp.min(t0 + FAR_CHUNK, blockers.faces.shape[0])
                nb = rasterize_far_chunk(t0, t1, v, sl, p, n, fine, groups, sub, mids, blockers, use_excl, excl, frame, lut,
                                         mask, bt, nb, part, st, fine_first)
        if groups.use_set != 0 and bt.record == 0 and fine_first == 0:
            if mids.on != 0:
                nb = rasterize_mid_set(v, sl, p, n, fine, groups, sub, mids, blockers, frame, lut, mask, bt, nb)
            else:
                nb = rasterize_fine_set(v, sl, p, n, fine, groups, blockers, frame, lut, mask, bt, nb, part, st)
        if nb > 0:
            flush_batch(nb, v, sl, frame, lut, mask, bt)
        if mids.on != 0:
            for r in range(mids.ring_start[v], mids.ring_start[v + 1]):
                m = mids.ring_tris[r]
                mids.ring_bits[sl, m >> 6] = wp.uint64(0)
        row += num_slots
