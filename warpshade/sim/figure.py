"""A procedural walking figure: a skeleton of 11 joints, a body of capsules skinned to it.

The skinned body is a union of closed capsule meshes (overlapping at the joints), usable as a
mesh collider (winding-number inside test) and as a shadow caster; :meth:`WalkingFigure.capsules`
gives the same body as analytic capsules. Y is up, the figure faces and walks along +z.
"""

from __future__ import annotations

import math

import numpy as np

from ..geometry.mesh import TriMesh
from .skinning import LBSSkinner

# name, parent, pivot (rest, metres at 1.8 m height), capsules [(p0, p1, radius)]
_SKELETON = [
    ("pelvis", -1, (0.0, 0.95, 0.0), [((-0.09, 0.95, 0.0), (0.09, 0.95, 0.0), 0.13)]),
    ("torso", 0, (0.0, 1.0, 0.0), [((0.0, 1.06, 0.0), (0.0, 1.36, 0.0), 0.15),
                                   ((-0.17, 1.42, 0.0), (0.17, 1.42, 0.0), 0.075)]),
    ("head", 1, (0.0, 1.5, 0.0), [((0.0, 1.57, 0.01), (0.0, 1.67, 0.01), 0.1)]),
    ("upper_arm_l", 1, (0.22, 1.42, 0.0), [((0.22, 1.42, 0.0), (0.24, 1.14, 0.0), 0.05)]),
    ("forearm_l", 3, (0.24, 1.14, 0.0), [((0.24, 1.14, 0.0), (0.25, 0.86, 0.0), 0.042)]),
    ("upper_arm_r", 1, (-0.22, 1.42, 0.0), [((-0.22, 1.42, 0.0), (-0.24, 1.14, 0.0), 0.05)]),
    ("forearm_r", 5, (-0.24, 1.14, 0.0), [((-0.24, 1.14, 0.0), (-0.25, 0.86, 0.0), 0.042)]),
    ("thigh_l", 0, (0.1, 0.92, 0.0), [((0.1, 0.9, 0.0), (0.1, 0.5, 0.0), 0.075)]),
    ("shin_l", 7, (0.1, 0.5, 0.0), [((0.1, 0.5, 0.0), (0.1, 0.09, 0.0), 0.055),
                                    ((0.1, 0.05, -0.03), (0.1, 0.04, 0.13), 0.04)]),
    ("thigh_r", 0, (-0.1, 0.92, 0.0), [((-0.1, 0.9, 0.0), (-0.1, 0.5, 0.0), 0.075)]),
    ("shin_r", 9, (-0.1, 0.5, 0.0), [((-0.1, 0.5, 0.0), (-0.1, 0.09, 0.0), 0.055),
                                     ((-0.1, 0.05, -0.03), (-0.1, 0.04, 0.13), 0.04)]),
]

JOINT_NAMES = [j[0] for j in _SKELETON]


def capsule_mesh(p0, p1, radius: float, around: int = 16, cap_rings: int = 4, body_rings: int = 4):
    """Closed, outward-oriented triangle mesh of a capsule around segment p0-p1.

    Returns:
        (points (V, 3) float64, faces (F, 3) int64, t (V,) position along the axis in [0, 1]).
    """
    p0, p1 = np.asarray(p0, dtype=np.float64), np.asarray(p1, dtype=np.float64)
    axis = p1 - p0
    length = np.linalg.norm(axis)
    a = axis / length if length > 0 else np.array([0.0, 1.0, 0.0])
    tmp = np.array([1.0, 0.0, 0.0]) if abs(a[0]) < 0.9 else np.array([0.0, 0.0, 1.0])
    u = np.cross(a, tmp)
    u /= np.linalg.norm(u)
    w = np.cross(a, u)
    # rings from the p0 pole to the p1 pole: (axial offset along a, ring radius, segment end)
    rings = []
    for k in range(1, cap_rings + 1):
        th = math.pi / 2 * (1 - k / cap_rings)
        rings.append((p0, -radius * math.sin(th), radius * math.cos(th)))
    for k in range(1, body_rings):
        rings.append((p0 + axis * (k / body_rings), 0.0, radius))
    for k in range(cap_rings):
        th = math.pi / 2 * (k / cap_rings)
        rings.append((p1, radius * math.sin(th), radius * math.cos(th)))
    phi = np.linspace(0.0, 2 * math.pi, around, endpoint=False)
    circle = np.cos(phi)[:, None] * u + np.sin(phi)[:, None] * w
    pts = [p0 - a * radius]
    for c, off, r in rings:
        pts.extend(c + a * off + r * circle)
    pts.append(p1 + a * radius)
    pts = np.array(pts)
    nr = len(rings)
    faces = []
    for i in range(around):
        j = (i + 1) % around
        faces.append((0, 1 + j, 1 + i))  # bottom cap fan faces away from p1
        for r in range(nr - 1):
            a0, a1 = 1 + r * around, 1 + (r + 1) * around
            faces.append((a0 + i, a0 + j, a1 + j))
            faces.append((a0 + i, a1 + j, a1 + i))
        last = 1 + (nr - 1) * around
        faces.append((last + i, last + j, len(pts) - 1))
    t = np.clip((pts - p0) @ a / max(length, 1e-12), 0.0, 1.0)
    return pts, np.array(faces, dtype=np.int64), t


def _rot(axis: str, angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    if axis == "x":
        return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])
    if axis == "y":
        return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


class WalkingFigure:
    """A skinned capsule figure walking along +z.

    Args:
        height: Standing height [m] (the skeleton is scaled from 1.8 m).
        speed: Walking speed [m/s] (>= 0).
        period: Duration of one gait cycle (two steps) [s] (> 0).
        origin: Position of the feet at t = 0, (3,).
        device: Warp device, default ``"cpu"``.

    Attributes:
        rest_points: Body rest positions [m], shape (V, 3), float32.
        faces: Body triangles, shape (F, 3), int32.
        joint_indices, joint_weights: Two influences per vertex, shape (V, 2).
        skinner: The :class:`LBSSkinner` posing the body.
    """

    def __init__(self, height: float = 1.8, speed: float = 0.8, period: float = 1.2, origin=(0.0, 0.0, 0.0),
                 device: str = "cpu"):
        for name, val, low in (("height", height, 0.0), ("period", period, 0.0)):
            if not np.isfinite(val) or val <= low:
                raise ValueError(f"WalkingFigure: {name} must be finite and > {low}, got {val}")
        if not np.isfinite(speed) or speed < 0:
            raise ValueError(f"WalkingFigure: speed must be finite and >= 0, got {speed}")
        self.scale = float(height) / 1.8
        self.speed, self.period = float(speed), float(period)
        self.origin = np.asarray(origin, dtype=np.float64)
        self.parents = [j[1] for j in _SKELETON]
        self.pivots = np.array([j[2] for j in _SKELETON]) * self.scale
        pts, faces, idx, wts = [], [], [], []
        base = 0
        self._capsules = []
        for b, (_, parent, pivot, caps) in enumerate(_SKELETON):
            for c0, c1, r in caps:
                c0s, c1s = np.array(c0) * self.scale, np.array(c1) * self.scale
                self._capsules.append((b, c0s, c1s, r * self.scale))
                p, f, t = capsule_mesh(c0s, c1s, r * self.scale)
                # blend the first 20 % of a limb with its parent so joints bend smoothly
                near = np.linalg.norm(p - np.array(pivot) * self.scale, axis=1)
                blend = 0.5 * np.clip(1.0 - near / (0.12 * self.scale), 0.0, 1.0) if parent >= 0 else np.zeros(len(p))
                pts.append(p)
                faces.append(f + base)
                idx.append(np.stack([np.full(len(p), b), np.full(len(p), max(parent, 0))], axis=1))
                wts.append(np.stack([1.0 - blend, blend], axis=1))
                base += len(p)
        self.rest_points = (np.concatenate(pts) + self.origin).astype(np.float32)
        self.faces = np.concatenate(faces).astype(np.int32)
        self.joint_indices = np.concatenate(idx).astype(np.int32)
        self.joint_weights = np.concatenate(wts).astype(np.float32)
        self.skinner = LBSSkinner(self.rest_points, self.joint_indices, self.joint_weights, len(_SKELETON), device)

    @property
    def joint_names(self) -> list[str]:
        return list(JOINT_NAMES)

    def _local_angles(self, t: float) -> dict:
        ph = 2 * math.pi * t / self.period
        s = math.sin(ph)
        return {
            "pelvis": _rot("y", 0.08 * s),
            "torso": _rot("y", -0.12 * s) @ _rot("x", 0.05),
            "head": _rot("y", 0.04 * s),
            "thigh_l": _rot("x", -0.42 * s),
            "thigh_r": _rot("x", 0.42 * s),
            "shin_l": _rot("x", 0.7 * max(0.0, math.sin(ph + 0.9 * math.pi / 2 + math.pi))),
            "shin_r": _rot("x", 0.7 * max(0.0, math.sin(ph + 0.9 * math.pi / 2))),
            "upper_arm_l": _rot("x", 0.35 * s) @ _rot("z", 0.08),
            "upper_arm_r": _rot("x", -0.35 * s) @ _rot("z", -0.08),
            "forearm_l": _rot("x", -0.25 - 0.15 * max(0.0, s)),
            "forearm_r": _rot("x", -0.25 - 0.15 * max(0.0, -s)),
        }

    def transforms(self, t: float) -> np.ndarray:
        """Skinning transforms (rest -> posed) at time t [s], shape (J, 4, 4), column-vector convention."""
        if not np.isfinite(t):
            raise ValueError(f"WalkingFigure.transforms: time must be finite, got {t}")
        rots = self._local_angles(t)
        ph = 2 * math.pi * t / self.period
        root = np.eye(4)
        root[:3, 3] = (0.0, 0.015 * self.scale * math.cos(2 * ph), self.speed * t)
        out = np.zeros((len(_SKELETON), 4, 4))
        for j, (name, parent, _, _) in enumerate(_SKELETON):
            p = self.pivots[j] + self.origin
            local = np.eye(4)
            local[:3, :3] = rots[name]
            local[:3, 3] = p - rots[name] @ p  # rotate about the joint's rest pivot
            out[j] = (out[parent] if parent >= 0 else root) @ local
        return out

    def points(self, t: float) -> np.ndarray:
        """Skinned body positions at time t [m], shape (V, 3), float32."""
        return self.skinner.update(self.transforms(t)).numpy().copy()

    def mesh(self, t: float) -> TriMesh:
        """The posed body as a TriMesh (a shadow caster)."""
        return TriMesh(self.points(t), self.faces, name="walking_figure")

    def capsules(self, t: float) -> list[tuple[np.ndarray, np.ndarray, float]]:
        """The body as analytic capsules at time t: [(p0, p1, radius)] in world space."""
        m = self.transforms(t)
        out = []
        for b, c0, c1, r in self._capsules:
            h0, h1 = np.append(c0 + self.origin, 1.0), np.append(c1 + self.origin, 1.0)
            out.append(((m[b] @ h0)[:3], (m[b] @ h1)[:3], r))
        return out

    def joint_transform(self, name: str, t: float) -> np.ndarray:
        """Skinning transform of one joint at time t, (4, 4): maps rest positions rigidly with it."""
        return self.transforms(t)[JOINT_NAMES.index(name)]
