"""Common light interface, validation helpers, motion over time and light-list summation.

Every light turns into RGB SH radiance coefficients in world space (SH convention:
:mod:`warpshade.sh.basis`), shape (N*N, 3), float64: ``L(ω) ≈ Σ_i L_i y_i(ω)`` is the radiance
arriving from direction ``ω`` (``ω`` points from the receiver towards the light). Distant lights
(environments, sky, directional) have one SH vector for the whole scene; local lights (point,
sphere, rect) depend on the receiver position and are evaluated per vertex with :meth:`Light.sh_at`.

Time: a light may carry ``motion``, a callable ``t [s] -> 3×3 rotation``; :meth:`Light.at_time`
returns the light rotated by ``motion(t)`` (about the world origin). :func:`spin` builds the common
constant-rate rotation.
"""

from __future__ import annotations

import copy
import dataclasses
import math
from typing import Callable, ClassVar

import numpy as np

from ..sh.rotation import check_rotation, rotation_from_axis_angle  # check_rotation re-exported

Motion = Callable[[float], np.ndarray]


FLOAT32_MAX = float(np.finfo(np.float32).max)
"""Largest value shading can hold: kernels and the output file store float32."""


def as_rgb(value, what: str) -> np.ndarray:
    """A scalar or length-3 RGB value (an emission, a reflectance: never negative) as a float64
    array of shape (3,).

    Raises:
        ValueError: naming ``what`` if the value is not finite, negative, beyond float32 or has the
            wrong shape.
    """
    v = np.asarray(value, dtype=np.float64)
    if v.ndim == 0:
        v = np.full(3, float(v))
    if v.shape != (3,) or not np.isfinite(v).all():
        raise ValueError(f"{what} must be a finite scalar or RGB triple, got {value!r}")
    if (v < 0).any():
        raise ValueError(f"{what} must not be negative, got {v.tolist()}")
    if (v > FLOAT32_MAX).any():
        raise ValueError(f"{what} overflows float32 (max {FLOAT32_MAX:.3g}), got {v.tolist()}")
    return v


def check_sh_range(light: "Light", sh: np.ndarray) -> np.ndarray:
    """``sh`` (a light's SH radiance) if every coefficient fits in float32, else ValueError naming the light."""
    peak = float(np.max(np.abs(sh))) if sh.size else 0.0
    if not np.isfinite(peak) or peak > FLOAT32_MAX:
        raise ValueError(f"{light.name}: its SH radiance reaches {peak:.3g}, beyond float32 "
                         f"(max {FLOAT32_MAX:.3g}); lower its intensity")
    return sh


def unit_vector(value, what: str) -> np.ndarray:
    """``value`` normalised, shape (3,), float64.

    Raises:
        ValueError: naming ``what`` for zero-length or non-finite vectors.
    """
    v = np.asarray(value, dtype=np.float64).reshape(-1)
    n = float(np.linalg.norm(v)) if v.shape == (3,) else 0.0
    if v.shape != (3,) or not np.isfinite(n) or n == 0.0:
        raise ValueError(f"{what} must be a finite non-zero 3-vector, got {value!r}")
    return v / n


@dataclasses.dataclass(frozen=True)
class Spin:
    """Constant-rate rotation about an axis through the origin: ``t [s] -> (3, 3)`` rotation by
    ``start_degrees + degrees_per_second * t``. A plain dataclass, so lights carrying it pickle
    (e.g. to parallel workers)."""

    axis: tuple
    degrees_per_second: float
    start_degrees: float = 0.0

    def __call__(self, t: float) -> np.ndarray:
        return rotation_from_axis_angle(self.axis, math.radians(self.start_degrees + self.degrees_per_second * float(t)))


@dataclasses.dataclass(frozen=True, eq=False)
class Keyed:
    """Rotation given per frame (a light keyed in a scene file): ``t [s] -> rotations[round(t * fps)]``,
    the first or last for times outside. A plain dataclass, so lights carrying it pickle.

    Attributes:
        rotations: Rotation of the light at each frame relative to its pose at frame 0, shape (F, 3, 3).
        fps: Frames per second.
    """

    rotations: np.ndarray
    fps: float

    def __call__(self, t: float) -> np.ndarray:
        f = int(round(float(t) * self.fps))
        return self.rotations[min(max(f, 0), len(self.rotations) - 1)]


def spin(axis, degrees_per_second: float, start_degrees: float = 0.0) -> Spin:
    """Motion rotating at a constant rate about ``axis`` through the origin (see :class:`Spin`)."""
    return Spin(tuple(unit_vector(axis, "spin axis").tolist()), float(degrees_per_second), float(start_degrees))


@dataclasses.dataclass
class Light:
    """Base class. Subclasses implement :meth:`_sh` (distant) or :meth:`_sh_at` (local) and
    :meth:`_rotated`.

    Attributes:
        name: For messages and USD prim paths.
        motion: Optional ``t [s] -> (3, 3)`` rotation about the world origin (see :func:`spin`).
    """

    name: str = dataclasses.field(default="light", kw_only=True)
    motion: Motion | None = dataclasses.field(default=None, kw_only=True, repr=False)

    local: ClassVar[bool] = False
    """Whether the SH depends on the receiver position (point, sphere, rect lights)."""

    def sh(self, order: int, point=None) -> np.ndarray:
        """RGB SH radiance coefficients, world space, shape (order*order, 3), float64.

        Args:
            order: SH order (bands 0..order-1).
            point: Receiver position, shape (3,); required for local lights, ignored otherwise.

        Raises:
            ValueError: for a local light without ``point``.
        """
        if self.local:
            if point is None:
                raise ValueError(f"{self.name}: {type(self).__name__} depends on the receiver; pass point= or use sh_at()")
            return check_sh_range(self, self._sh_at(np.asarray(point, dtype=np.float64).reshape(1, 3), order)[0])
        return check_sh_range(self, self._sh(order))

    def sh_at(self, points, order: int) -> np.ndarray:
        """Per-receiver SH coefficients, shape (P, order*order, 3), float64.

        Args:
            points: Receiver positions, shape (P, 3).
            order: SH order.
        """
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if self.local:
            return check_sh_range(self, self._sh_at(pts, order))
        return np.broadcast_to(self.sh(order), (pts.shape[0], order * order, 3)).copy()

    def rotated(self, rotation) -> "Light":
        """A copy rotated by ``rotation`` (3×3, about the world origin); ``motion`` is kept."""
        return self._rotated(check_rotation(rotation, f"{self.name}: rotation"))

    def at_time(self, t: float) -> "Light":
        """The light at time ``t`` [s]: rotated by ``motion(t)``, with no motion of its own."""
        if self.motion is None:
            return self
        out = copy.copy(self.rotated(self.motion(t)))
        out.motion = None
        return out

    def with_motion(self, motion: Motion | None) -> "Light":
        """A copy with ``motion`` set."""
        return dataclasses.replace(self, motion=motion)

    # Subclass hooks ---------------------------------------------------------------------------
    def _sh(self, order: int) -> np.ndarray:
        raise NotImplementedError

    def _sh_at(self, points: np.ndarray, order: int) -> np.ndarray:
        raise NotImplementedError

    def _rotated(self, rotation: np.ndarray) -> "Light":
        raise NotImplementedError


def lights_sh(lights, order: int, points=None) -> tuple[np.ndarray, np.ndarray | None]:
    """Sum a list of lights into one distant SH vector and, if any light is local, per-point SH.

    Args:
        lights: Iterable of :class:`Light`.
        order: SH order.
        points: Receiver positions, shape (V, 3); required if any light is local.

    Returns:
        ``(distant, local)``: distant-light sum, shape (order*order, 3); local-light sum, shape
        (V, order*order, 3), or None when no light is local. Both float64, world space.

    Raises:
        ValueError: if a local light is present and ``points`` is None.
    """
    distant = np.zeros((order * order, 3))
    local = None
    for light in lights:
        if light.local:
            if points is None:
                raise ValueError(f"{light.name}: local light needs receiver points")
            s = light.sh_at(points, order)
            local = s if local is None else local + s
        else:
            distant += light.sh(order)
    if np.max(np.abs(distant), initial=0.0) > FLOAT32_MAX:
        raise ValueError(f"the distant lights ({', '.join(li.name for li in lights if not li.local)}) sum to "
                         f"SH radiance beyond float32 (max {FLOAT32_MAX:.3g}); lower their intensities")
    return distant, local
