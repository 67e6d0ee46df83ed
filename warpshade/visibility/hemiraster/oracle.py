"""Plain NumPy hemispherical rasterizer: the obviously-correct oracle the Warp kernels are tested against.

Brute force, one receiver at a time, no hierarchy and no culling structures: every triangle not
incident to the receiver is tested pixel by pixel. With ``lut=None`` pixels are classified against
the exact edge planes; with a LUT table they use the same cube-map quantisation as the kernels.
The tangent-frame transfer is rotated to world space with the Ivanic–Ruedenberg matrices of
:mod:`warpshade.sh.rotation` (a different route from the kernel's sampling rotation).
Conventions: :mod:`.tables`.
"""

from __future__ import annotations

import numpy as np

from ...sh.rotation import rotation_matrix
from ..disks.oracle import frame_np as tangent_frame_np  # the kernels' frame (Duff et al. 2017)
from . import tables


def coplanar_lift_np(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> np.ndarray:
    """:func:`.kernels.coplanar_lift` for corners in the receiver's tangent frame (normal +z), in float64."""
    g = np.cross(b - a, c - a)
    gl = float(np.linalg.norm(g))
    if gl == 0.0:
        return np.zeros(3)
    size = np.sqrt(gl)
    near = abs(g @ a) <= tables.COPLANAR_NEAR * gl * size
    inside = min(g @ np.cross(a, b), g @ np.cross(b, c), g @ np.cross(c, a)) >= -tables.COPLANAR * gl * gl
    return g * (tables.COPLANAR * size / gl) if near and inside else np.zeros(3)


def rasterize_np(local_tris: np.ndarray, mask: int, lut: np.ndarray | None = None, lut_res: int = 0) -> np.ndarray:
    """Blocked-pixel mask of triangles given in the receiver's tangent frame.

    Args:
        local_tris: Triangle corners relative to the receiver, tangent frame, shape (T, 3, 3).
        mask: Mask resolution M.
        lut: Optional plane LUT (:func:`.tables.build_lut`) to classify pixels as the kernels do.
        lut_res: Its cube-map resolution R.

    Returns:
        Blocked pixels in bit order, shape (M*M,) bool.
    """
    dirs, valid = tables.pixel_directions(mask)
    blocked = np.zeros(mask * mask, dtype=bool)
    nw = tables.words_per_mask(mask)
    for a, b, c in np.asarray(local_tris, dtype=np.float64):
        a, b, c = (a, b, c) - coplanar_lift_np(a, b, c)
        if a[2] <= 0 and b[2] <= 0 and c[2] <= 0:
            continue  # wholly at or below the horizon
        planes = np.array([np.cross(a, b), np.cross(b, c), np.cross(c, a)])
        det = np.dot(a, planes[1])
        if det == 0:
            continue  # edge-on or degenerate: no solid angle
        planes *= np.sign(det)
        if lut is None:
            inside = (dirs @ planes.T > 0).all(axis=1) & valid
        else:
            rows = tables.cube_cell_np(planes.astype(np.float32), lut_res)
            words = lut[rows[0], :nw] & lut[rows[1], :nw] & lut[rows[2], :nw]
            inside = tables.unpack_bits(words, mask * mask)
        blocked |= inside
    return blocked


def transfer_np(points: np.ndarray, faces: np.ndarray, normals: np.ndarray, order: int = 5, mask: int = 32,
                downsample: int = 2, lut: np.ndarray | None = None, lut_res: int = 0,
                vertices=None, fan: bool = True) -> np.ndarray:
    """Diffuse transfer (docs/conventions.md §2) by brute-force hemispherical rasterization of the full mesh.

    Args:
        points: Positions, shape (V, 3). faces: shape (F, 3). normals: unit normals, shape (V, 3).
        order, mask, downsample: As the method's knobs.
        lut, lut_res: Optional LUT (else exact planes).
        vertices: Receivers to compute (default all).
        fan: Also block what the receiver's own triangles hide seen from just above it: triangle
            (v, b, c) as the spherical triangle (nadir, b, c) (the method's ``fan`` knob; the
            caller decides whether the mesh is open).

    Returns:
        shape (len(vertices), N*N) float64, world space.
    """
    points = np.asarray(points, dtype=np.float64)
    faces = np.asarray(faces)
    vertices = np.arange(len(points)) if vertices is None else np.asarray(vertices)
    blocks = tables.block_tables(mask, downsample, order)
    bb = downsample * downsample
    out = np.zeros((len(vertices), order * order))
    for row, v in enumerate(vertices):
        frame = tangent_frame_np(np.asarray(normals[v], dtype=np.float64))
        keep = (faces != v).all(axis=1)
        local = (points[faces[keep]] - points[v]) @ frame
        if fan:
            own = faces[~keep]
            # the two other corners in winding order: rotate each triangle so v comes first
            first = np.argmax(own == v, axis=1)
            rolled = np.stack([np.roll(f, -k) for f, k in zip(own, first)]) if len(own) else own.reshape(0, 3)
            virt = (points[rolled] - points[v]) @ frame
            virt[:, 0] = (0.0, 0.0, -1.0)
            local = np.concatenate([local, virt])
        blocked = rasterize_np(local, mask, lut, lut_res)
        counts = blocked.reshape(-1, bb).sum(axis=1)
        frac = np.where(blocks["valid"] > 0, counts / np.maximum(blocks["valid"], 1), 0.0)
        local_t = ((1.0 - frac)[:, None] * blocks["weights"]).sum(axis=0)
        out[row] = rotation_matrix(frame, order) @ local_t  # f(Q^T ω): tangent frame -> world
    return out
