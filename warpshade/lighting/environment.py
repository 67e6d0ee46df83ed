"""Distant environment lights: lat-long HDR maps (UsdLux DomeLight) and constant environments.

Map layout: the OpenEXR lat-long convention that UsdLux DomeLight adopts (+Y up; longitude 0,
the image centre, looks along +Z; longitude π/2 along +X; the left edge is longitude +π), see
:mod:`warpshade.sh.projection`. ``up="Z"`` rotates the map by +90° about X so its pole is world +Z
(map +Y → world +Z, map +Z → world −Y) for Z-up stages; ``rotation`` is applied after that (e.g.
the DomeLight prim's world rotation).
"""

from __future__ import annotations

import copy
import dataclasses
import math

import numpy as np

from ..sh.projection import latlong_row_solid_angles, project_latlong
from ..sh.rotation import rotate
from .base import Light, as_rgb, check_rotation
from .images import ImageError, read_image

UP_FRAMES = {
    "Y": np.eye(3),
    "Z": np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]]),  # +90° about X
}
"""Rotation from the lat-long map frame (+Y pole) to world space for each stage up axis."""


def up_frame(up: str) -> np.ndarray:
    """The map-to-world rotation for stage up axis ``"Y"`` or ``"Z"``.

    Raises:
        ValueError: for any other axis.
    """
    key = str(up).upper()
    if key not in UP_FRAMES:
        raise ValueError(f"up axis must be 'Y' or 'Z', got {up!r}")
    return UP_FRAMES[key]


@dataclasses.dataclass
class EnvironmentMap(Light):
    """A lat-long HDR environment (UsdLux DomeLight with a ``latlong`` texture).

    From USD: ``EnvironmentMap.from_file(texture, intensity=intensity * 2**exposure * color,
    up="Y", rotation=<rotation part of the dome prim's world transform>)``. A plain DomeLight's pole
    is +Y in its own frame whatever the stage up axis; a DomeLight_1 with ``poleAxis`` Z (or "scene"
    on a Z-up stage) uses ``up="Z"``, which is a +90° turn about X.

    Attributes:
        image: Radiance per texel, linear RGB, shape (H, W, 3), float32 (before ``intensity``).
        intensity: RGB or scalar multiplier (UsdLux ``intensity * 2^exposure * color``).
        up: Stage up axis, ``"Y"`` or ``"Z"`` (where the map's pole points).
        rotation: Extra world rotation applied after the up-axis frame, shape (3, 3).
        path: File the image came from (messages only).
    """

    image: np.ndarray = None
    intensity: object = 1.0
    up: str = "Y"
    rotation: np.ndarray = dataclasses.field(default_factory=lambda: np.eye(3))
    path: str | None = None
    _cache: dict = dataclasses.field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self):
        img = np.asarray(self.image, dtype=np.float32)
        where = self.path or self.name
        if img.ndim != 3 or img.shape[2] != 3 or img.shape[0] < 1 or img.shape[1] < 1:
            raise ImageError(f"{where}: environment image must have shape (H, W, 3), got {img.shape}")
        if not np.isfinite(img).all():
            raise ImageError(f"{where}: environment image has NaN or infinite pixels")
        self.image = img
        self.intensity = as_rgb(self.intensity, f"{where}: intensity")
        up_frame(self.up)
        self.rotation = check_rotation(self.rotation, f"{where}: rotation")

    @classmethod
    def from_file(cls, path, intensity=1.0, up: str = "Y", rotation=None, name: str | None = None,
                  motion=None) -> "EnvironmentMap":
        """Load a lat-long ``.exr`` or ``.hdr`` file (see :func:`warpshade.lighting.read_image`).

        Raises:
            FileNotFoundError, ImageError: naming the file.
        """
        img = read_image(path)
        return cls(image=img, intensity=intensity, up=up, rotation=np.eye(3) if rotation is None else rotation,
                   path=str(path), name=name or str(path), motion=motion)

    @property
    def frame(self) -> np.ndarray:
        """Map-frame to world rotation, shape (3, 3)."""
        return self.rotation @ up_frame(self.up)

    def _sh(self, order: int) -> np.ndarray:
        # The projection (the only O(pixels) step) is cached per order in the map frame; a new
        # rotation per frame then costs one SH rotation.
        if order not in self._cache:
            self._cache[order] = project_latlong(self.image, order)
        return rotate(self._cache[order], self.frame, axis=0) * self.intensity

    def _rotated(self, rotation: np.ndarray) -> "EnvironmentMap":
        out = copy.copy(self)  # same image, same map-frame projection cache
        out.rotation = rotation @ self.rotation
        return out

    def radiance(self, dirs) -> np.ndarray:
        """Radiance of the texel each world direction falls in (nearest texel), shape (M, 3), float64."""
        d = np.asarray(dirs, dtype=np.float64).reshape(-1, 3) @ self.frame  # rows: frame^T d
        d = d / np.linalg.norm(d, axis=1, keepdims=True)
        h, w, _ = self.image.shape
        lat = np.arcsin(np.clip(d[:, 1], -1.0, 1.0))
        lon = np.arctan2(d[:, 0], d[:, 2])
        row = np.clip(((np.pi / 2 - lat) / np.pi * h).astype(int), 0, h - 1)
        col = np.clip(((np.pi - lon) / (2 * np.pi) * w).astype(int), 0, w - 1)
        return self.image[row, col].astype(np.float64) * self.intensity

    def mean_radiance(self) -> np.ndarray:
        """Solid-angle-weighted mean radiance, RGB, shape (3,) (= DC coefficient / sqrt(4π))."""
        h, w, _ = self.image.shape
        omega = latlong_row_solid_angles(h, w)
        return np.einsum("h,hwc->c", omega, self.image.astype(np.float64)) / (4 * math.pi) * self.intensity


@dataclasses.dataclass
class ConstantEnvironment(Light):
    """Uniform radiance from every direction (UsdLux DomeLight without a texture).

    Attributes:
        radiance: Linear RGB radiance, shape (3,) or scalar.
    """

    radiance: object = 1.0

    def __post_init__(self):
        self.radiance = as_rgb(self.radiance, f"{self.name}: radiance")

    def _sh(self, order: int) -> np.ndarray:
        out = np.zeros((order * order, 3))
        out[0] = self.radiance * math.sqrt(4 * math.pi)  # ∫ L y_00 dω = L · 4π · (1/sqrt(4π))
        return out

    def _rotated(self, rotation: np.ndarray) -> "ConstantEnvironment":
        return dataclasses.replace(self)
