"""Static tables of hemispherical rasterization (Kautz et al. 2004 §3.1): mask layout, plane LUT, SH weights.

Everything here is built once per setting on the host (NumPy, or one Warp launch for the LUT) and
cached; the per-frame kernels only read it.

**Visibility mask.** An ``M×M`` grid over the square ``[-1, 1]²`` in the receiver's tangent frame
(normal = +z). Pixel ``(i, j)`` has centre ``x = -1 + (i + ½)·2/M``, ``y = -1 + (j + ½)·2/M`` and is
*valid* when the centre lies inside the unit disk; its direction is ``(x, y, sqrt(1 - x² - y²))``.
Dropping z maps the hemisphere onto the disk with ``dA = cos θ dω`` (Nusselt analog, paper §3.1),
so a disk region's *area* is its projected solid angle and ``T_i = ∫_disk y_i V dA``.

Bits are stored in Morton (Z) order of ``(i, j)`` in uint64 words: every aligned ``D×D`` block
(``D`` a power of two) is a run of ``D²`` contiguous bits inside one word, so downsampling is a
mask-and-popcount and the LUT does not depend on ``D``.

**Plane LUT.** For a plane through the origin with normal ``n``, the bitmask of valid pixels whose
direction ``d`` has ``n·d > 0``. Normals are quantised with a cube map of ``6×R×R`` cells (paper
§3.1.1): face ``2a`` (``n_a >= 0``) or ``2a+1`` on the major axis ``a`` (ties go to the lower axis),
``u = n_{(a+1)%3}/|n_a|``, ``v = n_{(a+2)%3}/|n_a|``, cell ``(⌊(u+1)R/2⌋, ⌊(v+1)R/2⌋)`` clamped;
a negative face uses the mirror ``(R-1-i, R-1-j)`` of the cell of ``-n``, so ``cell(-n)`` mirrors
``cell(n)`` exactly and the two triangles sharing an edge get exactly complementary masks.
Each row has the ``W`` mask words; the rasterizer keeps the positive faces (:func:`positive_half`)
in chunks of 16 words (:func:`chunked_rows`) and combines whole chunks.

**SH weights.** Per ``D×D`` block intersecting the disk, ``W_b,i = ∫_{block ∩ disk} y_i dA`` in the
tangent frame (supersampled, so ``Σ_b W_b`` is the analytic unoccluded transfer to ~1e-5). A block
with visible fraction ``f_b`` (visible valid pixels / valid pixels) contributes ``f_b W_b``.
"""

from __future__ import annotations

import functools
import platform
import time

import numpy as np
import warp as wp

from ... import _cache
from ...geometry.polygons import projected_solid_angle_np  # noqa: F401  (moved to geometry; re-exported)
from ...sh import basis as _sh_basis
from ...sh.basis import sh_eval

MASK_SIZES = (8, 16, 32, 64)
"""Supported mask resolutions (pixels across)."""


def check_mask(mask: int, downsample: int) -> None:
    """Validate the mask resolution and the downsampling block size.

    Raises:
        ValueError: naming the offending knob.
    """
    if mask not in MASK_SIZES:
        raise ValueError(f"hemiraster: mask must be one of {MASK_SIZES} pixels across, got {mask}")
    if downsample not in (1, 2, 4, 8) or downsample > mask:
        raise ValueError(f"hemiraster: downsample must be 1, 2, 4 or 8 (and <= mask {mask}), got {downsample}")


def morton2(i: np.ndarray, j: np.ndarray) -> np.ndarray:
    """Interleave the bits of ``i`` (even positions) and ``j`` (odd positions), 6 bits each."""
    out = np.zeros_like(np.asarray(i, dtype=np.int64))
    for b in range(6):
        out |= ((np.asarray(i) >> b) & 1) << (2 * b)
        out |= ((np.asarray(j) >> b) & 1) << (2 * b + 1)
    return out


def words_per_mask(mask: int) -> int:
    """uint64 words of an ``mask×mask`` bit mask."""
    return (mask * mask + 63) // 64


def pixel_directions(mask: int) -> tuple[np.ndarray, np.ndarray]:
    """Direction of every mask bit, in bit order.

    Returns:
        ``(dirs, valid)``: dirs shape (M*M, 3) float64 unit vectors (zero for pixels outside the
        disk), valid shape (M*M,) bool.
    """
    i, j = np.meshgrid(np.arange(mask), np.arange(mask), indexing="ij")
    i, j = i.ravel(), j.ravel()
    x = -1.0 + (i + 0.5) * 2.0 / mask
    y = -1.0 + (j + 0.5) * 2.0 / mask
    r2 = x * x + y * y
    valid = r2 < 1.0
    dirs = np.zeros((mask * mask, 3))
    bit = morton2(i, j)
    dirs[bit, 0] = np.where(valid, x, 0.0)
    dirs[bit, 1] = np.where(valid, y, 0.0)
    dirs[bit, 2] = np.where(valid, np.sqrt(np.maximum(0.0, 1.0 - r2)), 0.0)
    v = np.zeros(mask * mask, dtype=bool)
    v[bit] = valid
    return dirs, v


def pack_bits(bits: np.ndarray) -> np.ndarray:
    """Pack booleans (..., M*M) in bit order into uint64 words (..., W); bit k -> word k//64, bit k%64."""
    bits = np.asarray(bits, dtype=bool)
    n = bits.shape[-1]
    w = (n + 63) // 64
    padded = np.zeros(bits.shape[:-1] + (w * 64,), dtype=np.uint64)
    padded[..., :n] = bits
    shifts = np.arange(64, dtype=np.uint64)
    return (padded.reshape(bits.shape[:-1] + (w, 64)) << shifts).sum(axis=-1, dtype=np.uint64)


def unpack_bits(words: np.ndarray, nbits: int) -> np.ndarray:
    """Inverse of :func:`pack_bits`: (..., W) uint64 -> (..., nbits) bool."""
    words = np.asarray(words, dtype=np.uint64)
    shifts = np.arange(64, dtype=np.uint64)
    bits = ((words[..., None] >> shifts) & np.uint64(1)).astype(bool)
    return bits.reshape(words.shape[:-1] + (-1,))[..., :nbits]


# ---------------------------------------------------------------------------------------------
# cube-map quantisation of plane normals
def cube_cell_np(n: np.ndarray, lut: int) -> np.ndarray:
    """LUT row of each plane normal (cube-map cell; the convention of the module docstring).

    Args:
        n: Plane normals, shape (..., 3), any non-zero length.
        lut: Cube-map resolution R.

    Returns:
        Row indices in ``0..6R²-1``, int64, shape (...).
    """
    n = np.asarray(n, dtype=np.float32)
    a = np.abs(n)
    axis = np.where((a[..., 0] >= a[..., 1]) & (a[..., 0] >= a[..., 2]), 0, np.where(a[..., 1] >= a[..., 2], 1, 2))
    major = np.take_along_axis(n, axis[..., None], -1)[..., 0]
    u = np.take_along_axis(n, ((axis + 1) % 3)[..., None], -1)[..., 0]
    v = np.take_along_axis(n, ((axis + 2) % 3)[..., None], -1)[..., 0]
    neg = major < 0
    face = 2 * axis + neg
    # negative faces are indexed as the mirror of the positive one (see the kernel's cube_cell)
    u = np.where(neg, -u, u)
    v = np.where(neg, -v, v)
    half = np.float32(0.5 * lut)
    inv = half / np.abs(major)
    iu = np.clip((u * inv + half).astype(np.int64), 0, lut - 1)
    iv = np.clip((v * inv + half).astype(np.int64), 0, lut - 1)
    iu = np.where(neg, lut - 1 - iu, iu)
    iv = np.where(neg, lut - 1 - iv, iv)
    return (face * lut + iu) * lut + iv


def cube_cell_normals(lut: int) -> np.ndarray:
    """Centre normal of every cube-map cell, shape (6R², 3) float64 (not normalised)."""
    c = -1.0 + (np.arange(lut) + 0.5) * 2.0 / lut
    out = np.zeros((6, lut, lut, 3))
    cu, cv = np.meshgrid(c, c, indexing="ij")
    for face in range(6):
        a, s = face // 2, (1.0 if face % 2 == 0 else -1.0)
        out[face, :, :, a] = s
        out[face, :, :, (a + 1) % 3] = cu
        out[face, :, :, (a + 2) % 3] = cv
    return out.reshape(-1, 3)


def build_lut_np(mask: int, lut: int) -> np.ndarray:
    """Plane LUT by plain NumPy (the obviously-correct reference of :func:`build_lut`).

    Returns:
        shape (6R², W) uint64: bit k of row r set when valid pixel k lies strictly above cell r's
        plane.
    """
    dirs, valid = pixel_directions(mask)
    normals = cube_cell_normals(lut)
    nw = words_per_mask(mask)
    out = np.empty((len(normals), nw), dtype=np.uint64)
    for s in range(0, len(normals), 4096):
        above = (normals[s:s + 4096] @ dirs.T > 0.0) & valid
        out[s:s + 4096] = pack_bits(above)
    return out


@wp.kernel
def fill_plane_lut(
    normals: wp.array[wp.vec3],
    pixel_dirs: wp.array[wp.vec3],
    lut: wp.array2d[wp.uint64],
):
    """One plane LUT row: bit k set when pixel direction k is above the cell's plane.

    Pixels outside the disk carry a zero direction, so ``n·d > 0`` never holds for them.
    """
    row = wp.tid()
    n = normals[row]
    for word in range(lut.shape[1]):
        bits = wp.uint64(0)
        for k in range(64):
            p = word * 64 + k
            if p < pixel_dirs.shape[0]:
                if wp.dot(n, pixel_dirs[p]) > 0.0:
                    bits = bits | (wp.uint64(1) << wp.uint64(k))
        lut[row, word] = bits


_LUT_CACHE: dict[tuple[int, int], np.ndarray] = {}
_LUT_BUILD_SECONDS: dict[tuple[int, int], float] = {}


LUT_KIND = "hemiraster_lut"
"""Subdirectory of the disk cache (:mod:`warpshade._cache`) holding plane LUTs."""


def build_lut(mask: int, lut: int, cache_dir: str | None = None, device: str = "cpu") -> tuple[np.ndarray, float, str]:
    """The plane LUT for ``(mask, lut)``: from memory, else from the disk cache, else built with Warp (and
    stored there).

    Args:
        mask: Mask resolution M.
        lut: Cube-map resolution R (>= 2).
        cache_dir: Root of the disk cache to use; None: the per-user cache (:func:`warpshade._cache.root`,
            off with ``WARPSHADE_CACHE=none``). The entry is keyed by M, R, this file's source and
            the Warp version; an unreadable entry or an unwritable directory means building as without it.
        device: Warp device that builds it (the table is returned on the host either way).

    Returns:
        ``(table, seconds, source)``: table shape (6R², W) uint64; build (or load) seconds of the
        first request in this process; source ``"built"``, ``"disk"`` or ``"memory"``.
    """
    if lut < 2:
        raise ValueError(f"hemiraster: lut (cube-map resolution R) must be >= 2, got {lut}")
    key = (int(mask), int(lut))
    if key in _LUT_CACHE:
        return _LUT_CACHE[key], _LUT_BUILD_SECONDS[key], "memory"
    t0 = time.perf_counter()
    shape = (6 * lut * lut, words_per_mask(mask))
    disk_key = _cache.Key("plane lut 1", _cache.source_digest(__file__), wp.__version__, *key).hexdigest()
    entry = _cache.load(LUT_KIND, disk_key, where=cache_dir,
                        check=lambda a: _cache.has_layout(a, {"table": (shape, np.uint64)}))
    table, source = (entry["table"], "disk") if entry is not None else (None, "built")
    if table is None:
        dirs, _ = pixel_directions(mask)
        normals = wp.array(cube_cell_normals(lut).astype(np.float32), dtype=wp.vec3, device=device)
        out = wp.zeros(shape, dtype=wp.uint64, device=device)
        wp.launch(fill_plane_lut, dim=out.shape[0],
                  inputs=[normals, wp.array(dirs.astype(np.float32), dtype=wp.vec3, device=device)],
                  outputs=[out], device=device)
        table = out.numpy()
        _cache.save(LUT_KIND, disk_key, {"table": table}, where=cache_dir)
    _LUT_CACHE[key] = table
    _LUT_BUILD_SECONDS[key] = time.perf_counter() - t0
    return table, _LUT_BUILD_SECONDS[key], source


# ---------------------------------------------------------------------------------------------
# blocks and SH weights
def _read_only(arrays: dict) -> dict:
    """``arrays`` with every array made read-only: the tables below are cached (one copy per process,
    shared by every method instance, e.g. a group's front and back pass), so no caller may change them."""
    for a in arrays.values():
        a.flags.writeable = False
    return arrays


BLOCKS_KIND = "hemiraster_blocks"
"""Subdirectory of the disk cache (:mod:`warpshade._cache`) holding :func:`block_tables`' arrays."""


@functools.lru_cache(maxsize=None)
def block_tables(mask: int, downsample: int, order: int, supersample: int = 512) -> dict:
    """:func:`build_block_tables` (same arguments, the same arrays bit for bit), read from the disk cache
    when it holds them, else built and stored there. The entry is keyed by the arguments, the source of
    this file and of ``sh/basis.py`` (the SH evaluation), the NumPy version and the machine; one that
    does not have the tables' names, shapes and dtypes is rebuilt. Cached per arguments in memory as
    well; the arrays are read-only."""
    check_mask(mask, downsample)
    blocks, n = (mask // downsample) ** 2, order * order
    layout = {"valid": ((blocks,), np.int32), "weights": ((blocks, n), np.float64), "dirs": ((blocks, 3), np.float64),
              "area": ((blocks,), np.float64)}
    key = _cache.Key("block tables 1", _cache.source_digest(__file__), _cache.source_digest(_sh_basis.__file__),
                     platform.machine(), *_cache.versions("numpy"), int(mask), int(downsample), int(order),
                     int(supersample)).hexdigest()
    arrays = _cache.load(BLOCKS_KIND, key, check=lambda a: _cache.has_layout(a, layout))
    if arrays is None:
        arrays = build_block_tables(mask, downsample, order, supersample)
        _cache.save(BLOCKS_KIND, key, arrays)
    return _read_only(arrays)


def build_block_tables(mask: int, downsample: int, order: int, supersample: int = 512) -> dict:
    """Per-block tables for downsampled integration, over all ``(M/D)²`` blocks in Morton block order.

    Block ``b`` owns mask bits ``b·D² .. (b+1)·D² - 1`` (Morton contiguity), i.e. word
    ``b·D² // 64``. A block with no valid pixel centre hands its sliver of the disk to the nearest
    block that has one, so every part of the hemisphere can be blocked and ``Σ_b W_b`` is the whole
    unoccluded integral.

    Args:
        mask: Mask resolution M.
        downsample: Block size D in pixels (power of two, D² <= 64).
        order: SH order N.
        supersample: Integration grid across the disk for the block integrals.

    Returns:
        dict: ``valid`` (B,) int32 (valid pixels per block), ``weights`` (B, N*N) float64
        (``∫_{block∩disk} y_i dA``, tangent frame), ``dirs`` (B, 3) float64 (unit mean direction
        of the block's part of the disk, zero for blocks outside it), ``area`` (B,) float64.
    """
    check_mask(mask, downsample)
    _, valid = pixel_directions(mask)
    nb = mask // downsample
    bbits = downsample * downsample
    # fine grid of sample points (cell centres) covering [-1, 1]²
    s = max(supersample, 8 * mask)
    s -= s % mask
    c = -1.0 + (np.arange(s) + 0.5) * 2.0 / s
    x, y = np.meshgrid(c, c, indexing="ij")
    r2 = x * x + y * y
    inside = r2 < 1.0
    d = np.stack([x, y, np.sqrt(np.maximum(0.0, 1.0 - r2))], axis=-1)[inside]
    ysh = sh_eval(d, order) * (2.0 / s) ** 2
    bi = (np.floor((x[inside] + 1.0) * 0.5 * nb)).astype(np.int64).clip(0, nb - 1)
    bj = (np.floor((y[inside] + 1.0) * 0.5 * nb)).astype(np.int64).clip(0, nb - 1)
    bid = morton2(bi, bj)
    weights = np.zeros((nb * nb, order * order))
    np.add.at(weights, bid, ysh)
    dsum = np.zeros((nb * nb, 3))
    np.add.at(dsum, bid, d)
    area = np.bincount(bid, minlength=nb * nb) * (2.0 / s) ** 2
    counts = valid.reshape(nb * nb, bbits).sum(axis=1)
    # slivers of the disk in blocks without a valid pixel centre could never be blocked; hand their
    # integrals to the nearest block that has one (Σ_b W_b stays the whole hemisphere)
    bc = -1.0 + (np.arange(nb) + 0.5) * 2.0 / nb
    ci, cj = np.meshgrid(bc, bc, indexing="ij")
    centre = np.zeros((nb * nb, 2))
    centre[morton2(*np.meshgrid(np.arange(nb), np.arange(nb), indexing="ij")).ravel()] = np.stack(
        [ci.ravel(), cj.ravel()], 1)
    live = np.flatnonzero(counts > 0)
    for b in np.flatnonzero((counts == 0) & (area > 0)):
        to = live[np.argmin(np.linalg.norm(centre[live] - centre[b], axis=1))]
        weights[to] += weights[b]
        dsum[to] += dsum[b]
        area[to] += area[b]
        weights[b] = 0.0
        dsum[b] = 0.0
        area[b] = 0.0
    ln = np.linalg.norm(dsum, axis=1, keepdims=True)
    dirs = np.where(ln > 0, dsum / np.where(ln > 0, ln, 1.0), 0.0)
    return {"valid": counts.astype(np.int32), "weights": weights, "dirs": dirs, "area": area}


@functools.lru_cache(maxsize=None)
def rotation_directions(order: int) -> tuple[np.ndarray, np.ndarray]:
    """Directions and pseudo-inverses that rotate a band-limited SH vector by sampling.

    Band ``l`` of an SH vector rotates by an orthogonal ``R_l`` with ``y_l(Q s) = R_l y_l(s)``. With
    ``K = 2N-1`` fixed directions ``s_k``, ``R_l = Y_l(QS) Y_l(S)^+``, so a local vector ``c`` maps to
    world as ``g_l = Y_l(QS) (Y_l(S)^+ c_l)``: K SH evaluations per vertex, no rotation recurrences.
    The directions are the best-conditioned of a few seeded random sets.

    Returns:
        ``(dirs, pinv)``: dirs shape (K, 3) float64 unit; pinv shape (K, N*N) float64 with
        ``pinv[k, l(l+1)+m] = (Y_l(S)^+)[k, m]``. Cached per order; the arrays are read-only.
    """
    k = 2 * order - 1
    best, best_cond = None, np.inf
    rng = np.random.default_rng(20040621)
    for _ in range(200):
        dirs = rng.normal(size=(k, 3))
        dirs /= np.linalg.norm(dirs, axis=1, keepdims=True)
        y = sh_eval(dirs, order)
        cond = max(np.linalg.cond(y[:, l * l:(l + 1) ** 2]) for l in range(order))
        if cond < best_cond:
            best, best_cond = dirs, cond
    y = sh_eval(best, order)
    pinv = np.zeros((k, order * order))
    for l in range(order):
        pinv[:, l * l:(l + 1) ** 2] = np.linalg.pinv(y[:, l * l:(l + 1) ** 2].T)
    _read_only({"dirs": best, "pinv": pinv})
    return best, pinv


def positive_half(table: np.ndarray, mask: int, lut: int) -> dict:
    """The half of the plane LUT the rasterizer keeps: the rows of the positive cube faces.

    A negative face's row is the complement within the valid pixels of the row of its mirror
    cell on the positive face (the plane ``-n`` keeps exactly the other pixels; tested bit for bit),
    so the kernel complements on the fly and the table it reads is half as large.

    Returns:
        dict of ``rows`` (3R², W) uint64 and ``valid`` (W,) uint64 (valid pixels per word).
    """
    w = words_per_mask(mask)
    rows = np.ascontiguousarray(table.reshape(6, lut * lut, w)[0::2].reshape(3 * lut * lut, w))
    return {"rows": rows, "valid": pack_bits(pixel_directions(mask)[1])}


COPLANAR = 1.0e-3
"""Lift of the coplanar rule (:func:`.kernels.coplanar_lift`), relative to a triangle's size L = sqrt(|N|),
N = (b-a)×(c-a): a receiver that lies in a triangle's plane (within :data:`COPLANAR_NEAR` × L, its foot in the
triangle: barycentric coordinates >= -COPLANAR) sees the triangle from COPLANAR × L on its front side."""
COPLANAR_NEAR = 1.0e-4
"""Distance to a triangle's plane, relative to L, within which the coplanar rule takes a receiver to lie in it:
float32 rounding of a vertex that lies in the plane (a post's base on a floor 100 units from the origin: about
6e-5 L). Far less than :data:`COPLANAR`: a receiver truly off the plane keeps its view (4 cm behind or 14 cm in front
of a 200-unit wall, 2e-4 and 7e-4 of its size: lifting it moved the wall to its other side, or opened a gap
between the lifted triangle and the rest of the wall)."""

CHUNK_WORDS = 16
"""Words per chunk of the rasterizer's LUT rows (the kernels' ``MaskChunk``)."""


def chunked_rows(rows: np.ndarray) -> np.ndarray:
    """Rows of mask words (..., W) as chunks of :data:`CHUNK_WORDS` words, (..., C, 16) uint64 with
    ``C = ceil(W/16)`` and words past W zero: the rasterizer fetches and combines whole chunks."""
    rows = np.asarray(rows, dtype=np.uint64)
    w = rows.shape[-1]
    c = -(-w // CHUNK_WORDS)
    out = np.zeros(rows.shape[:-1] + (c * CHUNK_WORDS,), dtype=np.uint64)
    out[..., :w] = rows
    return np.ascontiguousarray(out.reshape(rows.shape[:-1] + (c, CHUNK_WORDS)))


def lut_bytes(mask: int, lut: int) -> int:
    """Memory of the plane LUT the rasterizer reads [bytes]: the rows of the positive cube faces
    (:func:`positive_half`) in whole chunks (:func:`chunked_rows`; M <= 32: one 128-byte chunk per row)."""
    return 3 * lut * lut * (-(-words_per_mask(mask) // CHUNK_WORDS)) * CHUNK_WORDS * 8


