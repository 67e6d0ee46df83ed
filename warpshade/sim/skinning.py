"""Linear blend skinning (LBS) of animated characters on the device.

Matrices follow the column-vector convention: a skinning transform M (4 x 4) maps a rest position
r to ``(M @ [r, 1])[:3]``; for a joint it is ``joint_world(t) @ inverse(joint_world(bind))``.
(UsdSkel's row-vector matrices are transposed by :func:`warpshade.usd.read_usd_skel`.)
"""

from __future__ import annotations

import numpy as np
import warp as wp

from . import kernels as k


class LBSSkinner:
    """Skins a rest mesh by per-joint transforms; build once, :meth:`update` per frame.

    Args:
        rest_points: Rest positions [m], shape (V, 3).
        joint_indices: Joint of each influence, shape (V, K), int (unused slots: weight 0).
        joint_weights: Influence weights, shape (V, K), >= 0; renormalised to sum 1 per vertex.
        num_joints: Number of joints J (transforms passed to :meth:`update`).
        device: Warp device, default ``"cpu"``.

    Raises:
        ValueError: naming the vertex with a non-finite position, a joint index outside 0..J-1, a
            negative or non-finite weight, or weights summing to 0.
    """

    def __init__(self, rest_points: np.ndarray, joint_indices: np.ndarray, joint_weights: np.ndarray,
                 num_joints: int, device: str = "cpu"):
        rest = np.asarray(rest_points, dtype=np.float64)
        idx = np.asarray(joint_indices)
        w = np.asarray(joint_weights, dtype=np.float64)
        if idx.ndim == 1:
            idx, w = idx[:, None], w[:, None]
        if rest.ndim != 2 or rest.shape[1] != 3:
            raise ValueError(f"LBSSkinner: rest_points must have shape (V, 3), got {rest.shape}")
        if idx.shape != (len(rest), idx.shape[1]) or w.shape != idx.shape:
            raise ValueError(f"LBSSkinner: joint_indices {idx.shape} and joint_weights {w.shape} must both be "
                             f"({len(rest)}, K)")
        if not np.issubdtype(idx.dtype, np.integer):
            raise ValueError(f"LBSSkinner: joint_indices must be integers, got {idx.dtype}")
        self.num_joints = int(num_joints)
        for name, bad in (("position is not finite", ~np.isfinite(rest).all(axis=1)),
                          (f"joint index outside 0..{self.num_joints - 1}", ((idx < 0) | (idx >= self.num_joints)).any(1)),
                          ("weight is negative or not finite", (~np.isfinite(w) | (w < 0)).any(axis=1))):
            if bad.any():
                v = int(np.flatnonzero(bad)[0])
                raise ValueError(f"LBSSkinner: vertex {v}: {name} (indices {idx[v].tolist()}, weights {w[v].tolist()})")
        total = w.sum(axis=1)
        if (total <= 0).any():
            v = int(np.flatnonzero(total <= 0)[0])
            raise ValueError(f"LBSSkinner: vertex {v} has no joint influence (weights sum to 0)")
        self.device = wp.get_device(device)
        self.rest_points = wp.array(rest.astype(np.float32), dtype=wp.vec3, device=self.device)
        self.joint_indices = wp.array(idx.astype(np.int32), dtype=wp.int32, device=self.device)
        self.joint_weights = wp.array((w / total[:, None]).astype(np.float32), dtype=wp.float32, device=self.device)
        self.transforms = wp.zeros(self.num_joints, dtype=wp.mat44, device=self.device)
        self.points = wp.array(rest.astype(np.float32), dtype=wp.vec3, device=self.device)
        """Skinned positions [m], shape (V,), dtype vec3 (after :meth:`update`)."""

    def update(self, transforms: np.ndarray) -> wp.array:
        """Skin with per-joint transforms, shape (J, 4, 4), column-vector convention.

        Returns:
            :attr:`points`, shape (V,), dtype vec3.

        Raises:
            ValueError: wrong shape or a non-finite transform (naming the joint).
        """
        m = np.asarray(transforms, dtype=np.float32)
        if m.shape != (self.num_joints, 4, 4):
            raise ValueError(f"LBSSkinner.update: expected transforms of shape ({self.num_joints}, 4, 4), got {m.shape}")
        bad = ~np.isfinite(m).all(axis=(1, 2))
        if bad.any():
            raise ValueError(f"LBSSkinner.update: transform of joint {int(np.flatnonzero(bad)[0])} is not finite")
        self.transforms.assign(m)
        wp.launch(k.skin_points, dim=self.points.shape[0],
                  inputs=[self.rest_points, self.joint_indices, self.joint_weights, self.transforms],
                  outputs=[self.points], device=self.device)
        return self.points
