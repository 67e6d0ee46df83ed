"""Analytic lights: directional (UsdLux DistantLight), point, sphere (UsdLux SphereLight) and rect
(UsdLux RectLight), as RGB SH radiance in world space (conventions in :mod:`warpshade.lighting.base`).

Mapping from UsdLux (``L = intensity · 2^exposure · color``, divided by the emitting area when
``normalize`` is on — by the caller):

* DistantLight → :class:`DirectionalLight` ``(direction = light's +Z axis in world, radiance=L,
  angle=inputs:angle)`` via :meth:`DirectionalLight.from_radiance`; a normalized DistantLight gives
  the irradiance directly: ``DirectionalLight(direction, irradiance=L, angle=...)``.
* SphereLight → :class:`SphereLight` ``(position, radius, radiance=L)``; with ``treatAsPoint``
  use :meth:`SphereLight.as_point` (same power).
* RectLight → :class:`RectLight` ``(center, u = half width · local X, v = half height · local Y,
  radiance=L)``; it emits towards local −Z, i.e. ``−(u × v)``.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from ..sh import sh_eval
from ..sh.zonal import cap_zh, zh_rotate
from .base import Light, as_rgb, unit_vector


def _cap_sh(axis, angle, radiance: np.ndarray, order: int) -> np.ndarray:
    """SH of uniform caps: ``axis`` S+(3,), angular radius ``angle`` [rad] S -> S + (order*order, 3)."""
    f = zh_rotate(cap_zh(angle, order), axis)
    return f[..., None] * radiance


@dataclasses.dataclass
class DirectionalLight(Light):
    """Light from one direction, as the sun (UsdLux DistantLight).

    Attributes:
        direction: Unit vector from the scene towards the light, world space, shape (3,).
        irradiance: RGB irradiance on a surface facing the light (W/m², or any consistent unit).
        angle: Angular diameter [degrees] (UsdLux ``inputs:angle``); 0 is a delta direction, > 0 a
            uniform disc of radiance ``irradiance / (π sin²(angle/2))``.
    """

    direction: object = (0.0, 1.0, 0.0)
    irradiance: object = 1.0
    angle: float = 0.0

    def __post_init__(self):
        self.direction = unit_vector(self.direction, f"{self.name}: direction")
        self.irradiance = as_rgb(self.irradiance, f"{self.name}: irradiance")
        if not 0.0 <= float(self.angle) < 180.0:
            raise ValueError(f"{self.name}: angle must be in [0, 180) degrees, got {self.angle}")
        self.angle = float(self.angle)

    @classmethod
    def from_radiance(cls, direction, radiance, angle: float = 0.53, name: str = "light") -> "DirectionalLight":
        """From the disc's radiance (an unnormalized UsdLux DistantLight): ``E = L π sin²(angle/2)``."""
        if not 0.0 < float(angle) < 180.0:
            raise ValueError(f"{name}: a light given by radiance needs angle in (0, 180) degrees, got {angle}")
        s = math.sin(math.radians(angle) / 2)
        return cls(direction=direction, irradiance=as_rgb(radiance, f"{name}: radiance") * math.pi * s * s,
                   angle=angle, name=name)

    @property
    def radiance(self) -> np.ndarray:
        """Radiance of the disc (RGB); infinite for angle 0."""
        s = math.sin(math.radians(self.angle) / 2)
        return self.irradiance / (math.pi * s * s) if s > 0 else np.full(3, np.inf)

    def _sh(self, order: int) -> np.ndarray:
        if self.angle == 0.0:
            return sh_eval(self.direction, order)[:, None] * self.irradiance  # L(ω) = E δ(ω, d)
        return _cap_sh(self.direction, math.radians(self.angle) / 2, self.radiance, order)

    def _rotated(self, rotation):
        return dataclasses.replace(self, direction=rotation @ self.direction)


@dataclasses.dataclass
class PointLight(Light):
    """Isotropic point light: irradiance ``I / r²`` from the light's direction.

    Attributes:
        position: World position [m], shape (3,).
        intensity: RGB radiant intensity [W/sr] (or any consistent unit).
        min_distance: Receivers closer than this [m] are treated as at this distance (keeps 1/r² finite).
    """

    position: object = (0.0, 0.0, 0.0)
    intensity: object = 1.0
    min_distance: float = 1e-4

    local = True

    def __post_init__(self):
        self.position = np.asarray(self.position, dtype=np.float64).reshape(3)
        if not np.isfinite(self.position).all():
            raise ValueError(f"{self.name}: position must be finite, got {self.position}")
        self.intensity = as_rgb(self.intensity, f"{self.name}: intensity")

    def _sh_at(self, points, order):
        d = self.position[None, :] - points
        r2 = np.maximum((d * d).sum(axis=1), self.min_distance**2)
        return sh_eval(d, order)[:, :, None] * (self.intensity[None, None, :] / r2[:, None, None])

    def _rotated(self, rotation):
        return dataclasses.replace(self, position=rotation @ self.position)


@dataclasses.dataclass
class SphereLight(Light):
    """Uniformly emitting sphere (UsdLux SphereLight): from a receiver at distance ``r`` it is a cap
    of half-angle ``asin(radius / r)``; inside the sphere it fills every direction.

    The cap's zonal coefficients are analytic (:func:`~warpshade.sh.zonal.cap_zh`) and rotated
    with docs/conventions.md §1's formula, so the SH is exact for every receiver.

    Attributes:
        position: Centre [m], shape (3,).
        radius: Radius [m], > 0.
        radiance: RGB surface radiance.
    """

    position: object = (0.0, 0.0, 0.0)
    radius: float = 0.1
    radiance: object = 1.0

    local = True

    def __post_init__(self):
        self.position = np.asarray(self.position, dtype=np.float64).reshape(3)
        if not np.isfinite(self.position).all():
            raise ValueError(f"{self.name}: position must be finite, got {self.position}")
        if not (math.isfinite(self.radius) and self.radius > 0):
            raise ValueError(f"{self.name}: radius must be positive, got {self.radius}")
        self.radiance = as_rgb(self.radiance, f"{self.name}: radiance")

    def as_point(self) -> PointLight:
        """The point light of equal power (UsdLux ``treatAsPoint``): ``I = L π radius²``."""
        return PointLight(position=self.position, intensity=self.radiance * math.pi * self.radius**2,
                          name=self.name, motion=self.motion)

    def _sh_at(self, points, order):
        d = self.position[None, :] - points
        r = np.linalg.norm(d, axis=1)
        s = np.clip(self.radius / np.maximum(r, 1e-300), 0.0, 1.0)
        angle = np.where(r > self.radius, np.arcsin(s), np.pi)  # inside the sphere: every direction
        return _cap_sh(d, angle, self.radiance, order)

    def _rotated(self, rotation):
        return dataclasses.replace(self, position=rotation @ self.position)


@dataclasses.dataclass
class RectLight(Light):
    """Uniformly emitting rectangle with corners ``center ± u ± v`` (UsdLux RectLight).

    The SH seen from a receiver is integrated over the rectangle with a ``samples × samples``
    Gauss–Legendre rule: ``L_i(p) = L ∫ y_i(ω_q) cos θ_q / |q − p|² dA``. Accurate when the
    receiver is farther from the light than about its half-size (docs/guide/lighting.md has the measured
    errors); exact visibility of area lights is the GEARS method's job, this is the SH
    approximation used with environment-style shading.

    Attributes:
        center: Centre [m], shape (3,).
        u: Half-width vector [m] (UsdLux: ``width/2`` along local X), shape (3,).
        v: Half-height vector [m] (UsdLux: ``height/2`` along local Y), shape (3,).
        radiance: RGB radiance of the emitting side.
        two_sided: Emit on both sides (the visibility contract's convention) instead of only
            towards ``−(u × v)`` (UsdLux: local −Z).
        samples: Gauss–Legendre nodes per axis and tile.
        max_tiles: Upper bound on tiles per axis; a receiver at distance ``d`` from the rectangle
            uses ``ceil(max(|u|, |v|) / d)`` tiles per axis so the rule stays accurate up close.
        device: Warp device of the per-receiver kernel.
    """

    center: object = (0.0, 0.0, 0.0)
    u: object = (0.5, 0.0, 0.0)
    v: object = (0.0, 0.5, 0.0)
    radiance: object = 1.0
    two_sided: bool = False
    samples: int = 8
    max_tiles: int = 16
    device: str = "cpu"

    local = True

    def __post_init__(self):
        for attr in ("center", "u", "v"):
            val = np.asarray(getattr(self, attr), dtype=np.float64).reshape(3)
            if not np.isfinite(val).all():
                raise ValueError(f"{self.name}: {attr} must be finite, got {val}")
            setattr(self, attr, val)
        if np.linalg.norm(np.cross(self.u, self.v)) == 0.0:
            raise ValueError(f"{self.name}: u and v span no area (u={self.u}, v={self.v})")
        self.radiance = as_rgb(self.radiance, f"{self.name}: radiance")
        if int(self.samples) < 1 or int(self.max_tiles) < 1:
            raise ValueError(f"{self.name}: samples and max_tiles must be >= 1, got {self.samples}, {self.max_tiles}")
        self.samples = int(self.samples)
        self.max_tiles = int(self.max_tiles)

    @property
    def _half_max(self) -> float:
        return float(max(np.linalg.norm(self.u), np.linalg.norm(self.v)))

    def _tiles(self, x: np.ndarray) -> int:
        """Tiles per axis for receiver ``x`` (same rule as the kernel's ``rect_tiles``)."""
        rel = x - self.center
        s = np.clip(rel @ self.u / (self.u @ self.u), -1.0, 1.0)
        t = np.clip(rel @ self.v / (self.v @ self.v), -1.0, 1.0)
        dist = float(np.linalg.norm(self.center + s * self.u + t * self.v - x))
        if dist * self.max_tiles <= self._half_max:
            return self.max_tiles
        return int(min(max(math.ceil(self._half_max / dist), 1), self.max_tiles))

    @property
    def emit_normal(self) -> np.ndarray:
        """Unit normal of the emitting side, ``−(u × v)/|u × v|``."""
        return -self.normal

    @property
    def normal(self) -> np.ndarray:
        """Unit normal of the rectangle's plane, ``u × v / |u × v|`` (geometric; emission is along −normal)."""
        n = np.cross(self.u, self.v)
        return n / np.linalg.norm(n)

    @property
    def area(self) -> float:
        """Area [m²] (one side)."""
        return 4.0 * float(np.linalg.norm(np.cross(self.u, self.v)))

    @property
    def diagonal(self) -> float:
        """Diagonal length [m]."""
        return 2.0 * math.hypot(np.linalg.norm(self.u), np.linalg.norm(self.v))

    def point(self, s, t) -> np.ndarray:
        """Light point(s) ``c + s u + t v`` for light coordinates ``s, t ∈ [-1, 1]``, shape (..., 3)."""
        s = np.asarray(s, dtype=np.float64)[..., None]
        t = np.asarray(t, dtype=np.float64)[..., None]
        return self.center + s * self.u + t * self.v

    @classmethod
    def parse(cls, text: str, **kwargs):
        """From ``"cx,cy,cz,ux,uy,uz,vx,vy,vz"`` (the ``--rect-light`` syntax); ``kwargs`` set the other fields."""
        try:
            vals = [float(x) for x in text.split(",")]
        except ValueError:
            raise ValueError(f"--rect-light expects 9 comma-separated numbers, got '{text}'") from None
        if len(vals) != 9:
            raise ValueError(f"--rect-light expects 9 comma-separated numbers (c, u, v), got {len(vals)}: '{text}'")
        return cls(center=vals[0:3], u=vals[3:6], v=vals[6:9], **kwargs)

    @classmethod
    def over_points(cls, points, size: float = 0.3, height: float = 1.5, tilt: float = 0.0, **kwargs):
        """A light over a point set's bounding box (y up), for tests, benchmarks and quick looks.

        Args:
            points: Positions [m], shape (V, 3).
            size: Half-axes as fractions of the box's x and z extents.
            height: Centre height as a fraction of the y extent above the box's bottom (1 = top).
            tilt: Rotation of the v axis about x [rad] (0: horizontal light facing down and up).
            kwargs: The other fields (radiance, two_sided...).
        """
        p = np.asarray(points, dtype=np.float64)
        lo, hi = p.min(axis=0), p.max(axis=0)
        d = hi - lo
        c = lo + d * np.array([0.5, height, 0.5])
        u = np.array([d[0] * size, 0.0, 0.0])
        v = np.array([0.0, -np.sin(tilt), np.cos(tilt)]) * d[2] * size
        return cls(center=c, u=u, v=v, **kwargs)

    def corners(self) -> np.ndarray:
        """Corners in order ``c−u−v, c+u−v, c+u+v, c−u+v``, shape (4, 3)."""
        c, u, v = self.center, self.u, self.v
        return np.array([c - u - v, c + u - v, c + u + v, c - u + v])

    def _rule(self):
        """Tensor Gauss–Legendre nodes (K, 2) in [-1, 1]² and area weights (K,) summing to the area."""
        x, w = np.polynomial.legendre.leggauss(self.samples)
        s, t = np.meshgrid(x, x, indexing="ij")
        nodes = np.stack([s.reshape(-1), t.reshape(-1)], axis=1)
        return nodes, np.outer(w, w).reshape(-1) * float(np.linalg.norm(np.cross(self.u, self.v)))

    def _sh_at(self, points, order):
        """Warp kernel :func:`~warpshade.lighting.kernels.integrate_rect_light` (orders 1..8)."""
        import warp as wp

        from ..sh.basis import check_order
        from ..sh.kernels import normalization_array
        from .kernels import integrate_rect_light

        check_order(order)
        nodes, wq = self._rule()
        device = self.device
        out = wp.zeros((points.shape[0], order * order), dtype=float, device=device)
        wp.launch(integrate_rect_light, dim=points.shape[0],
                  inputs=[wp.array(points.astype(np.float32), dtype=wp.vec3, device=device), wp.vec3(*self.center),
                          wp.vec3(*self.u), wp.vec3(*self.v), wp.vec3(*self.emit_normal), int(self.two_sided),
                          wp.array(nodes.astype(np.float32), dtype=wp.vec2, device=device),
                          wp.array(wq.astype(np.float32), dtype=float, device=device), self._half_max,
                          self.max_tiles, order,
                          normalization_array(order, device)],
                  outputs=[out], device=device)
        return out.numpy().astype(np.float64)[:, :, None] * self.radiance

    def sh_at_reference(self, points, order: int) -> np.ndarray:
        """NumPy reference of :meth:`sh_at` (same tiled quadrature, float64, one receiver at a time),
        shape (P, order*order, 3)."""
        points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        nodes, wq = self._rule()
        n = self.emit_normal
        out = np.empty((points.shape[0], order * order, 3))
        for i, x in enumerate(points):
            tiles = self._tiles(x)
            centres = -1.0 + (2 * np.arange(tiles) + 1) / tiles
            sc, tc = np.meshgrid(centres, centres, indexing="ij")
            st = (np.stack([sc.reshape(-1), tc.reshape(-1)], 1)[:, None, :] + nodes[None] / tiles).reshape(-1, 2)
            w = np.tile(wq / tiles**2, tiles * tiles)
            d = self.center + st[:, :1] * self.u + st[:, 1:] * self.v - x  # receiver -> sample
            r2 = np.maximum((d * d).sum(axis=1), 1e-300)
            cos_e = -(d @ n) / np.sqrt(r2)  # cosine at the emitter, > 0 on the emitting side
            cos_e = np.abs(cos_e) if self.two_sided else np.maximum(cos_e, 0.0)
            out[i] = ((w * cos_e / r2) @ sh_eval(d, order))[:, None] * self.radiance
        return out

    def projected_solid_angle(self, points, normals, out=None, origin=None):
        """Exact unshadowed ``Φ(p) = ∫_light max(0, n_p·ω) dω`` per receiver (Lambert's polygon formula,
        Warp kernel :func:`~warpshade.lighting.kernels.integrate_rect_irradiance`); irradiance is
        ``Φ · radiance``. Zero behind a one-sided light's emitting side.

        Args:
            points: Receiver positions [m], shape (P, 3) or a ``wp.array`` of vec3.
            normals: Unit receiver normals, shape (P, 3) or a ``wp.array`` of vec3.
            out: Optional output ``wp.array`` of float, shape (P,), reused between frames.
            origin: Where ``points`` are relative to (world, shape (3,)): the light's centre is taken relative
                to it in float64 before the float32 kernel (a scene far from the world origin, traced about its
                own, :func:`warpshade.visibility.rays.local_origin`); None: ``points`` are world positions.

        Returns:
            ``wp.array`` of float [sr], shape (P,).
        """
        import warp as wp

        from .kernels import integrate_rect_irradiance

        dev = self.device
        pts = points if isinstance(points, wp.array) else wp.array(np.asarray(points, np.float32).reshape(-1, 3), dtype=wp.vec3, device=dev)
        nrm = normals if isinstance(normals, wp.array) else wp.array(np.asarray(normals, np.float32).reshape(-1, 3), dtype=wp.vec3, device=dev)
        if nrm.shape != pts.shape:
            raise ValueError(f"{self.name}: normals shape {nrm.shape} does not match points shape {pts.shape}")
        if out is None:
            out = wp.empty(pts.shape[0], dtype=float, device=dev)
        center = self.center if origin is None else self.center - np.asarray(origin, np.float64).reshape(3)
        wp.launch(integrate_rect_irradiance, dim=pts.shape[0],
                  inputs=[pts, nrm, wp.vec3(*center), wp.vec3(*self.u), wp.vec3(*self.v),
                          wp.vec3(*self.emit_normal), int(self.two_sided)], outputs=[out], device=dev)
        return out

    def irradiance_at(self, points, normals) -> np.ndarray:
        """Unshadowed RGB irradiance per receiver, ``Φ · radiance`` (:meth:`projected_solid_angle`), shape (P, 3), float64."""
        return self.projected_solid_angle(points, normals).numpy().astype(np.float64)[:, None] * self.radiance

    def irradiance_at_reference(self, points, normals) -> np.ndarray:
        """NumPy reference of :meth:`irradiance_at` (float64, one receiver at a time): the rectangle
        clipped to the receiver's upper hemisphere, then Lambert's formula
        (:func:`~warpshade.geometry.polygons.projected_solid_angle_np`). Shape (P, 3)."""
        from ..geometry.polygons import projected_solid_angle_np

        pts = np.asarray(points, np.float64).reshape(-1, 3)
        nrm = np.asarray(normals, np.float64).reshape(-1, 3)
        out = np.zeros((len(pts), 3))
        for i, (x, n) in enumerate(zip(pts, nrm)):
            if not self.two_sided and np.dot(x - self.center, self.emit_normal) <= 0.0:
                continue
            t1 = np.cross(n, [1.0, 0.0, 0.0] if abs(n[0]) < 0.9 else [0.0, 1.0, 0.0])
            t1 /= np.linalg.norm(t1)
            frame = np.stack([t1, np.cross(n, t1), n])  # world -> tangent frame (normal +z)
            corners = (self.corners() - x) @ frame.T
            poly = []  # Sutherland–Hodgman against z >= 0
            for a, b in zip(corners, np.roll(corners, -1, axis=0)):
                if a[2] >= 0:
                    poly.append(a)
                if (a[2] >= 0) != (b[2] >= 0):
                    poly.append(a + (b - a) * (a[2] / (a[2] - b[2])))
            if len(poly) >= 3:
                out[i] = projected_solid_angle_np(np.maximum(np.array(poly), [-np.inf, -np.inf, 0.0])) * self.radiance
        return out

    def _rotated(self, rotation):
        return dataclasses.replace(self, center=rotation @ self.center, u=rotation @ self.u, v=rotation @ self.v)
