"""Integration of hemiraster visibility masks into SH transfer, compiled per SH order (Kautz et al. 2004 §3.1, eq. 3).

The rasterization kernel (:mod:`.kernels`) leaves one bit mask per receiver; :func:`integrate_kernels`
builds, once per order, the kernels that turn masks into the transfer of docs/conventions.md §2 (diffuse)
or the glossy Phong transfer of eq. 3, with every SH vector a fixed-length Warp vector held in
registers (the ``vec_sh`` of :func:`~warpshade.sh.kernels.zh_vector_funcs`).

**Diffuse.** The blocked fraction ``f_b`` of a ``D×D`` block weighs its integral ``W_b``, and
``f_b W_b = Σ_{blocked pixels of b} W_b / n_b`` (``n_b`` valid pixels): the transfer is linear in the
mask bits with per-pixel weight ``W_b / n_b``. So a table holds, for every group of four
consecutive mask bits (a nibble: a 2×2 pixel square in Morton order) and each of its 16 values, the
summed weights of the set bits (:func:`nibble_table`); a receiver adds one table row per nibble of
each non-empty mask word, no branch per bit. Against the earlier walk through 8×8 / 4×4 / 2×2
groups with a gather list subtracted coefficient by coefficient from a row of a 2D array, the same
transfer (float32 rounding) at about a third of the cost.

**Glossy.** Each block's lobe value depends on the receiver's mirrored view direction, so blocks
are visited one by one: ``Σ_b (1 - f_b) lobe_b W_b``.

**Rotation to world.** Band ``l`` of a local vector ``c`` maps to world as ``g_l = Y_l(QS) (Y_l(S)^+ c_l)``
with ``K = 2N-1`` fixed directions ``s_k`` (:func:`.tables.rotation_directions`): per direction, the
band factors ``(Y_l(S)^+ c_l)_k`` times the basis at ``Q s_k``, i.e. one
:func:`~warpshade.sh.kernels.zh_vector_funcs` ``zh_rotate`` with the plain basis constants.

This module deliberately does not use postponed annotations: Warp reads the closure-local vector
types from the annotations of the generated kernels.
"""

import functools
from types import SimpleNamespace

import numpy as np
import warp as wp

from ...sh.basis import normalization
from ...sh.kernels import zh_vector_funcs
from ..rays import orthonormal_basis

wp.set_module_options({"enable_backward": False, "optimization_level": 3})

def pixel_weights(weights: np.ndarray, valid_per_block: np.ndarray, valid_pixels: np.ndarray, downsample: int) -> np.ndarray:
    """Per mask bit (Morton order) its share ``W_b / n_b`` of its block's integral, 0 for invalid pixels.

    Args:
        weights: Block integrals ``W_b``, shape (B, N²) (:func:`.tables.block_tables`).
        valid_per_block: Valid pixels per block ``n_b``, shape (B,).
        valid_pixels: Valid mask bits, shape (M²,) bool.
        downsample: Block size D (block b owns bits ``b·D² .. (b+1)·D² - 1``).
    """
    bb = downsample * downsample
    block = np.arange(len(valid_pixels)) // bb
    n_b = np.maximum(valid_per_block[block], 1)[:, None]
    return np.where(valid_pixels[:, None], weights[block] / n_b, 0.0)


def nibble_table(pix: np.ndarray) -> np.ndarray:
    """Summed per-pixel weights of every value of every nibble of the mask.

    Args:
        pix: Per-bit weights, shape (M², N²) (:func:`pixel_weights`), M² a multiple of 4.

    Returns:
        shape (M²/4 · 16, N²) float64: row ``16·g + x`` is the sum over the set bits ``k`` of ``x``
        of ``pix[4g + k]`` (nibble ``g`` is bits ``4g .. 4g+3``: word ``g // 16``, shift ``4 (g % 16)``).
    """
    groups = pix.reshape(-1, 4, pix.shape[1])
    x = np.arange(16)
    sel = ((x[:, None] >> np.arange(4)[None, :]) & 1).astype(np.float64)  # (16 values, 4 bits)
    return np.einsum("vk,gki->gvi", sel, groups).reshape(-1, pix.shape[1])


@functools.lru_cache(maxsize=None)
def integrate_kernels(order: int) -> SimpleNamespace:
    """Kernels ``diffuse`` and ``glossy`` (and ``vec_sh``) for one SH order; built and cached on first use.

    ``diffuse(mask, normals, nibbles, unoccluded, rot_dirs, rot_pinv, basis, receivers) -> transfer``
    (the rows of ``receivers`` only, one per thread):
    ``mask`` (V, W) uint64, ``normals`` (V,) vec3 (the tangent frame is
    :func:`~warpshade.visibility.rays.orthonormal_basis` of the normal, as in the
    rasterizer), ``nibbles`` (16·W·16,) vec_sh (:func:`nibble_table`), ``unoccluded`` vec_sh
    (``Σ_b W_b``), ``rot_dirs`` (K,) vec3, ``rot_pinv`` (K,) vec_sh (:func:`.tables.rotation_directions`),
    ``basis`` vec_sh (``K_lm``), ``transfer`` (V, N²) float32.

    ``glossy(mask, normals, block_weights, block_valid, block_dirs, block_bits, view, phong, rot_dirs,
    rot_pinv, basis) -> transfer``: ``block_weights`` (B,) vec_sh, ``block_valid`` (B,) int32,
    ``block_dirs`` (B,) vec3 (tangent frame), ``block_bits`` = D², ``view`` world vec3 towards the
    viewer, ``phong`` exponent.

    ``blocked_part(receivers, normals, unoccluded, rot_dirs, rot_pinv, basis, transfer) -> blocked, doubt``:
    per receiver, the unoccluded transfer of its normal minus its transfer, (V,) vec_sh, and a doubt of 0.
    ``interpolate(targets, nbr_start, nbrs, normals, unoccluded, rot_dirs, rot_pinv, basis, blocked,
    tolerance, doubt) -> transfer, redo``: per target vertex, the unoccluded transfer of its normal minus
    the mean blocked part of its neighbours (CSR ``nbr_start`` (V+1,), ``nbrs``), which it also writes as
    its own ``blocked`` part; its ``doubt`` is the largest distance (L2) of a neighbour's blocked part from
    that mean plus the largest doubt of a neighbour (interpolated neighbours, on a coarser level), and
    ``redo[v]`` = 1 where it exceeds ``tolerance`` or, with ``rise`` < 1, where a vertex of its 1-ring
    (CSR ``ring_start``, ``ring``; ``points``) lies more than ``asin(rise)`` above its tangent plane.
    """
    zf = zh_vector_funcs(order)
    vec_sh, vec_zh, zh_rotate = zf.vec_sh, zf.vec_zh, zf.zh_rotate
    bands = wp.constant(order)

    def to_world(local: vec_sh, frame: wp.mat33, rot_dirs: wp.array(dtype=wp.vec3),
                 rot_pinv: wp.array(dtype=vec_sh), basis: vec_sh) -> vec_sh:
        out = vec_sh()
        for k in range(rot_dirs.shape[0]):
            pk = rot_pinv[k]
            g = vec_zh()
            for l in range(bands):
                acc = float(0.0)
                for i in range(l * l, (l + 1) * (l + 1)):
                    acc += pk[i] * local[i]
                g[l] = acc
            out = out + zh_rotate(frame * rot_dirs[k], g, basis)
        return out

    to_world.__annotations__ = {"local": vec_sh, "frame": wp.mat33, "rot_dirs": wp.array(dtype=wp.vec3),
                                "rot_pinv": wp.array(dtype=vec_sh), "basis": vec_sh, "return": vec_sh}
    to_world.__name__ = f"hemiraster_to_world_order{order}"
    to_world = wp.func(to_world)

    def diffuse(mask: wp.array2d(dtype=wp.uint64), normals: wp.array(dtype=wp.vec3), nibbles: wp.array(dtype=vec_sh),
                unoccluded: vec_sh, rot_dirs: wp.array(dtype=wp.vec3), rot_pinv: wp.array(dtype=vec_sh),
                basis: vec_sh, receivers: wp.array(dtype=wp.int32), transfer: wp.array2d(dtype=float)):
        v = receivers[wp.tid()]
        blocked = vec_sh()
        for w in range(mask.shape[1]):
            x = mask[v, w]
            if x != wp.uint64(0):
                base = w * 256
                for j in range(16):
                    blocked = blocked + nibbles[base + j * 16 + int((x >> wp.uint64(4 * j)) & wp.uint64(15))]
        out = to_world(unoccluded - blocked, orthonormal_basis(normals[v]), rot_dirs, rot_pinv, basis)
        for i in range(bands * bands):
            transfer[v, i] = out[i]

    def glossy(mask: wp.array2d(dtype=wp.uint64), normals: wp.array(dtype=wp.vec3), block_weights: wp.array(dtype=vec_sh),
               block_valid: wp.array(dtype=wp.int32), block_dirs: wp.array(dtype=wp.vec3), block_bits: int,
               view: wp.vec3, phong: float, rot_dirs: wp.array(dtype=wp.vec3), rot_pinv: wp.array(dtype=vec_sh),
               basis: vec_sh, transfer: wp.array2d(dtype=float)):
        v = wp.tid()
        frame = orthonormal_basis(normals[v])
        lv = wp.transpose(frame) * view
        refl = wp.vec3(-lv[0], -lv[1], lv[2])  # mirror of the view direction about the normal (+z)
        lobe_norm = (phong + 2.0) / (2.0 * wp.pi)
        ones = wp.uint64(0xFFFFFFFFFFFFFFFF)
        if block_bits < 64:
            ones = (wp.uint64(1) << wp.uint64(block_bits)) - wp.uint64(1)
        local = vec_sh()
        for b in range(block_valid.shape[0]):
            cosr = wp.dot(refl, block_dirs[b])
            if cosr > 0.0 and block_valid[b] > 0:
                first = b * block_bits
                bits = (mask[v, first // 64] >> wp.uint64(first % 64)) & ones
                visible = 1.0 - float(wp.bit_count(bits)) / float(block_valid[b])
                local = local + (visible * lobe_norm * wp.pow(cosr, phong)) * block_weights[b]
        out = to_world(local, frame, rot_dirs, rot_pinv, basis)
        for i in range(bands * bands):
            transfer[v, i] = out[i]

    def blocked_part(receivers: wp.array(dtype=wp.int32), normals: wp.array(dtype=wp.vec3), unoccluded: vec_sh,
                     rot_dirs: wp.array(dtype=wp.vec3), rot_pinv: wp.array(dtype=vec_sh), basis: vec_sh,
                     transfer: wp.array2d(dtype=float), blocked: wp.array(dtype=vec_sh),
                     doubt: wp.array(dtype=float)):
        # the unoccluded transfer of the receiver's normal minus its transfer: what varies slowly
        # along a surface (the unoccluded part is exact at every normal)
        v = receivers[wp.tid()]
        b = to_world(unoccluded, orthonormal_basis(normals[v]), rot_dirs, rot_pinv, basis)
        for i in range(bands * bands):
            b[i] = b[i] - transfer[v, i]
        blocked[v] = b
        doubt[v] = 0.0

    def interpolate(targets: wp.array(dtype=wp.int32), nbr_start: wp.array(dtype=wp.int32),
                    nbrs: wp.array(dtype=wp.int32), normals: wp.array(dtype=wp.vec3), unoccluded: vec_sh,
                    rot_dirs: wp.array(dtype=wp.vec3), rot_pinv: wp.array(dtype=vec_sh), basis: vec_sh,
                    blocked: wp.array(dtype=vec_sh), tolerance: float, doubt: wp.array(dtype=float),
                    points: wp.array(dtype=wp.vec3), ring_start: wp.array(dtype=wp.int32),
                    ring: wp.array(dtype=wp.int32), rise: float,
                    transfer: wp.array2d(dtype=float), redo: wp.array(dtype=wp.int32)):
        v = targets[wp.tid()]
        mean = vec_sh()
        count = float(0.0)
        for r in range(nbr_start[v], nbr_start[v + 1]):
            mean = mean + blocked[nbrs[r]]
            count += 1.0
        mean = mean / wp.max(count, 1.0)
        spread = float(0.0)
        inherited = float(0.0)
        for r in range(nbr_start[v], nbr_start[v + 1]):
            spread = wp.max(spread, wp.length(blocked[nbrs[r]] - mean))
            inherited = wp.max(inherited, doubt[nbrs[r]])
        spread = spread + inherited  # interpolated neighbours bring their own (0 for computed ones)
        out = to_world(unoccluded, orthonormal_basis(normals[v]), rot_dirs, rot_pinv, basis) - mean
        for i in range(bands * bands):
            transfer[v, i] = out[i]
        blocked[v] = mean  # what a finer level's targets read (no neighbour of this level is a target)
        doubt[v] = spread
        steep = int(0)
        if rise < 1.0:  # a 1-ring vertex steeper than asin(rise) above the tangent plane: a crease or pit
            for r in range(ring_start[v], ring_start[v + 1]):
                d = points[ring[r]] - points[v]
                if wp.dot(d, normals[v]) > rise * wp.length(d):
                    steep = 1
        redo[v] = wp.where(spread > tolerance or steep == 1, 1, 0)

    blocked_part.__annotations__ = {"receivers": wp.array(dtype=wp.int32), "normals": wp.array(dtype=wp.vec3),
                                    "unoccluded": vec_sh, "rot_dirs": wp.array(dtype=wp.vec3),
                                    "rot_pinv": wp.array(dtype=vec_sh), "basis": vec_sh,
                                    "transfer": wp.array2d(dtype=float), "blocked": wp.array(dtype=vec_sh),
                                    "doubt": wp.array(dtype=float)}
    blocked_part.__name__ = f"hemiraster_blocked_part_order{order}"
    interpolate.__annotations__ = {"targets": wp.array(dtype=wp.int32), "nbr_start": wp.array(dtype=wp.int32),
                                   "nbrs": wp.array(dtype=wp.int32), "normals": wp.array(dtype=wp.vec3),
                                   "unoccluded": vec_sh, "rot_dirs": wp.array(dtype=wp.vec3),
                                   "rot_pinv": wp.array(dtype=vec_sh), "basis": vec_sh,
                                   "blocked": wp.array(dtype=vec_sh), "tolerance": float, "doubt": wp.array(dtype=float),
                                   "points": wp.array(dtype=wp.vec3), "ring_start": wp.array(dtype=wp.int32),
                                   "ring": wp.array(dtype=wp.int32), "rise": float,
                                   "transfer": wp.array2d(dtype=float), "redo": wp.array(dtype=wp.int32)}
    interpolate.__name__ = f"hemiraster_interpolate_order{order}"

    arr_u64 = wp.array2d(dtype=wp.uint64)
    diffuse.__annotations__ = {"mask": arr_u64, "normals": wp.array(dtype=wp.vec3), "nibbles": wp.array(dtype=vec_sh),
                               "unoccluded": vec_sh, "rot_dirs": wp.array(dtype=wp.vec3),
                               "rot_pinv": wp.array(dtype=vec_sh), "basis": vec_sh,
                               "receivers": wp.array(dtype=wp.int32), "transfer": wp.array2d(dtype=float)}
    glossy.__annotations__ = {"mask": arr_u64, "normals": wp.array(dtype=wp.vec3),
                              "block_weights": wp.array(dtype=vec_sh), "block_valid": wp.array(dtype=wp.int32),
                              "block_dirs": wp.array(dtype=wp.vec3), "block_bits": int, "view": wp.vec3,
                              "phong": float, "rot_dirs": wp.array(dtype=wp.vec3),
                              "rot_pinv": wp.array(dtype=vec_sh), "basis": vec_sh,
                              "transfer": wp.array2d(dtype=float)}
    diffuse.__name__ = f"hemiraster_diffuse_order{order}"
    glossy.__name__ = f"hemiraster_glossy_order{order}"

    def basis_constants():
        return vec_sh(*normalization(order).astype(np.float32).tolist())

    return SimpleNamespace(order=order, vec_sh=vec_sh, basis_constants=basis_constants,
                           diffuse=wp.kernel(diffuse, enable_backward=False), glossy=wp.kernel(glossy, enable_backward=False),
                           interpolate=wp.kernel(interpolate, enable_backward=False),
                           blocked_part=wp.kernel(blocked_part, enable_backward=False))
