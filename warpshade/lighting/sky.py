"""Analytic daylight: Preetham sky + attenuated sun disc + Lambertian ground. Needs no file; it is
warpshade's default environment.

* Sky (upper hemisphere): Preetham, Shirley & Smits, "A Practical Analytic Model for Daylight"
  (SIGGRAPH 1999): Perez distribution ``F(θ, γ) = (1 + A e^{B/cos θ})(1 + C e^{Dγ} + E cos²γ)``
  for luminance Y and chromaticities x, y (their table 2 / appendix A.2 coefficients, linear in
  turbidity T), zenith values from their appendix A.2, ``Y = Y_z F(θ, γ) / F(0, θ_s)`` in kcd/m².
  CIE xyY → XYZ → linear Rec.709/sRGB primaries (D65).
* Sun: a disc of angular diameter 0.53° whose radiance is the extraterrestrial solar luminance
  (128 klux over the disc's solid angle, taken as white) times the direct transmittance
  ``exp(−m (τ_R + τ_A))`` per channel at 680/550/440 nm: Rayleigh depth ``0.0088 λ^−4.05`` (λ in µm),
  Ångström aerosol depth ``β λ^−1.3`` with Preetham's ``β = 0.04608 T − 0.04586``, Kasten–Young
  (1989) air mass ``m``. A documented simplification of Preetham's spectral sun.
* Ground (lower hemisphere): uniform radiance ``albedo · E_h / π`` with ``E_h`` the horizontal
  irradiance from sky and sun — a Lambertian ground lit by this sky (no ground-sky interreflection).

Units: with ``normalize=True`` (default) everything is scaled so that a white, unoccluded,
upward-facing Lambertian surface has exit luminance ``intensity`` — convenient for displayColor.
With ``normalize=False`` radiance is in kcd/m² (Preetham's units) times ``intensity``.

Valid range (Preetham's fit): turbidity 1.7..10, sun elevation 0..90°. Rotating the whole sky over
time (``motion``) is a rigid rotation of this environment, not a change of time of day.
"""

from __future__ import annotations

import copy
import dataclasses
import math

import numpy as np

from ..sh.projection import project_function
from ..sh.rotation import rotate
from ..sh.zonal import cap_zh, zh_rotate
from .base import Light, as_rgb, check_rotation
from .environment import up_frame

SUN_ANGLE_DEG = 0.53
"""Angular diameter of the sun [degrees] (as UsdLux DistantLight's default)."""
SOLAR_ILLUMINANCE_KLUX = 128.0
"""Extraterrestrial solar illuminance [klux] (≈ 1361 W/m² × 93.9 lm/W)."""
_WAVELENGTHS_UM = np.array([0.680, 0.550, 0.440])  # representative R, G, B wavelengths
_XYZ_TO_RGB = np.array([[3.2404542, -1.5371385, -0.4985314],
                        [-0.9692660, 1.8760108, 0.0415560],
                        [0.0556434, -0.2040259, 1.0572252]])
_LUMA = np.array([0.2126, 0.7152, 0.0722])  # Y of linear Rec.709 RGB

# Preetham et al. 1999, appendix A.2: Perez coefficients (A..E) = slope * T + intercept, rows Y, x, y.
_PEREZ_SLOPE = np.array([[0.1787, -0.3554, -0.0227, 0.1206, -0.0670],
                         [-0.0193, -0.0665, -0.0004, -0.0641, -0.0033],
                         [-0.0167, -0.0950, -0.0079, -0.0441, -0.0109]])
_PEREZ_INTERCEPT = np.array([[-1.4630, 0.4275, 5.3251, -2.5771, 0.3703],
                             [-0.2592, 0.0008, 0.2125, -0.8989, 0.0452],
                             [-0.2608, 0.0092, 0.2102, -1.6537, 0.0529]])
_ZENITH_X = np.array([[0.00166, -0.00375, 0.00209, 0.0],
                      [-0.02903, 0.06377, -0.03202, 0.00394],
                      [0.11693, -0.21196, 0.06052, 0.25886]])
_ZENITH_Y = np.array([[0.00275, -0.00610, 0.00317, 0.0],
                      [-0.04214, 0.08970, -0.04153, 0.00516],
                      [0.15346, -0.26756, 0.06670, 0.26688]])


def sun_direction(elevation_deg: float, azimuth_deg: float = 0.0, up: str = "Y") -> np.ndarray:
    """World direction towards the sun.

    Azimuth is measured like the lat-long map's longitude (:mod:`warpshade.sh.projection`): for a
    Y-up stage 0° → +Z, 90° → +X; for a Z-up stage the same frame rotated by +90° about X
    (0° → −Y, 90° → +X).
    """
    el, az = math.radians(elevation_deg), math.radians(azimuth_deg)
    local = np.array([math.cos(el) * math.sin(az), math.sin(el), math.cos(el) * math.cos(az)])
    return up_frame(up) @ local


def _perez(cos_theta, gamma, coeffs):
    a, b, c, d, e = coeffs
    return (1.0 + a * np.exp(b / cos_theta)) * (1.0 + c * np.exp(d * gamma) + e * np.cos(gamma) ** 2)


@dataclasses.dataclass
class Sky(Light):
    """Preetham daylight with sun and ground (module docstring), a distant light.

    Attributes:
        sun_elevation: Sun elevation above the horizon [degrees], 0..90.
        sun_azimuth: Sun azimuth [degrees] (see :func:`sun_direction`).
        turbidity: Atmospheric turbidity, 1.7 (very clear) .. 10 (hazy).
        up: Stage up axis, ``"Y"`` or ``"Z"``.
        ground_albedo: RGB albedo of the ground below the horizon.
        intensity: RGB or scalar multiplier.
        normalize: Scale so an upward white Lambertian surface has exit luminance ``intensity``.
        sun: Include the sun disc.
        rotation: World rotation applied to the whole sky, shape (3, 3).
    """

    sun_elevation: float = 45.0
    sun_azimuth: float = 30.0
    turbidity: float = 3.0
    up: str = "Y"
    ground_albedo: object = 0.2
    intensity: object = 1.0
    normalize: bool = True
    sun: bool = True
    rotation: np.ndarray = dataclasses.field(default_factory=lambda: np.eye(3))
    _cache: dict = dataclasses.field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self):
        if not 0.0 <= float(self.sun_elevation) <= 90.0:
            raise ValueError(f"{self.name}: sun_elevation must be in [0, 90] degrees (Preetham's range), "
                             f"got {self.sun_elevation}")
        if not 1.7 <= float(self.turbidity) <= 10.0:
            raise ValueError(f"{self.name}: turbidity must be in [1.7, 10] (Preetham's fit), got {self.turbidity}")
        self.ground_albedo = as_rgb(self.ground_albedo, f"{self.name}: ground_albedo")
        self.intensity = as_rgb(self.intensity, f"{self.name}: intensity")
        self.rotation = check_rotation(self.rotation, f"{self.name}: rotation")
        self._setup()

    # Model in the sky's own frame (before ``rotation``): up = up axis, sun = sun_direction(...).
    def _setup(self):
        self._up = up_frame(self.up)[:, 1]
        self._sun = sun_direction(self.sun_elevation, self.sun_azimuth, self.up)
        t = float(self.turbidity)
        theta_s = math.radians(90.0 - float(self.sun_elevation))
        self._coeffs = _PEREZ_SLOPE * t + _PEREZ_INTERCEPT
        chi = (4.0 / 9.0 - t / 120.0) * (math.pi - 2.0 * theta_s)
        y_z = (4.0453 * t - 4.9710) * math.tan(chi) - 0.2155 * t + 2.4192  # kcd/m²
        tv = np.array([t * t, t, 1.0])
        th = np.array([theta_s**3, theta_s**2, theta_s, 1.0])
        self._zenith = np.array([y_z, tv @ _ZENITH_X @ th, tv @ _ZENITH_Y @ th])
        self._perez_sun = np.array([_perez(1.0, theta_s, self._coeffs[k]) for k in range(3)])
        # Sun disc radiance per channel [kcd/m²].
        half = math.radians(SUN_ANGLE_DEG) / 2
        self._sun_cos = math.cos(half)
        omega = 2 * math.pi * (1 - self._sun_cos)
        zen_deg = 90.0 - float(self.sun_elevation)
        airmass = 1.0 / (math.cos(math.radians(zen_deg)) + 0.50572 * (96.07995 - zen_deg) ** -1.6364)
        beta = 0.04608365822050 * t - 0.04586025928522
        tau = 0.0088 * _WAVELENGTHS_UM**-4.05 + beta * _WAVELENGTHS_UM**-1.3
        self._sun_radiance = SOLAR_ILLUMINANCE_KLUX / omega * np.exp(-airmass * tau) if self.sun else np.zeros(3)
        # Horizontal irradiance from sky (quadrature, upper hemisphere) and sun (∫_cap cos = π sin²α cos θ_s).
        dirs, w, vals = self._upper_quadrature()
        e_sky = (w * (dirs @ self._up))[None, :] @ vals
        e_sun = self._sun_radiance * math.pi * math.sin(half) ** 2 * math.sin(math.radians(self.sun_elevation))
        e_h = e_sky[0] + e_sun
        self._ground = self.ground_albedo * e_h / math.pi
        self._scale = self.intensity / (float(_LUMA @ e_h) / math.pi) if self.normalize else self.intensity.copy()

    def _upper_quadrature(self, n: int = 48):
        from ..sh.projection import sphere_quadrature

        dirs, w = sphere_quadrature(n, 4 * n, pole=self._up, split=True)
        keep = dirs @ self._up > 0
        return dirs[keep], w[keep], self._sky_rgb(dirs[keep])

    def _sky_rgb(self, dirs: np.ndarray) -> np.ndarray:
        """Preetham sky radiance [kcd/m²], linear RGB, for directions above the horizon, (M, 3)."""
        cos_theta = np.clip(dirs @ self._up, 1e-4, 1.0)  # guard the 1/cos θ term at the horizon
        gamma = np.arccos(np.clip(dirs @ self._sun, -1.0, 1.0))
        big_y, x, y = (self._zenith[k] * _perez(cos_theta, gamma, self._coeffs[k]) / self._perez_sun[k] for k in range(3))
        xyz = np.stack([x * big_y / y, big_y, (1.0 - x - y) * big_y / y], axis=-1)
        return np.maximum(xyz @ _XYZ_TO_RGB.T, 0.0)  # tiny negatives from gamut clipping only

    def _radiance_local(self, dirs: np.ndarray, with_sun: bool = True) -> np.ndarray:
        d = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
        above = (d @ self._up) > 0
        out = np.where(above[:, None], 0.0, self._ground[None, :])
        if above.any():
            out[above] = self._sky_rgb(d[above])
        if with_sun:
            out[(d @ self._sun) >= self._sun_cos] += self._sun_radiance
        return out  # unscaled (kcd/m²)

    def radiance(self, dirs) -> np.ndarray:
        """Radiance towards the viewer from world directions ``dirs`` (M, 3), RGB, (M, 3), float64 (sun included)."""
        d = np.asarray(dirs, dtype=np.float64).reshape(-1, 3) @ self.rotation  # rows: R^T d
        return self._radiance_local(d) * self._scale

    def to_image(self, height: int = 512, up: str | None = None) -> np.ndarray:
        """Render to a lat-long image (OpenEXR layout, pole along ``up``, default the sky's own),
        e.g. as a UsdLux DomeLight texture so viewers see the same sky.

        The sun disc is usually smaller than a texel: it is splatted into the texel that contains
        its direction with radiance ``L_sun Ω_sun / Ω_texel``, so the image carries the sun's energy.

        Returns:
            Radiance, shape (height, 2*height, 3), float32.
        """
        from ..sh.projection import latlong_directions, latlong_row_solid_angles

        frame = up_frame(self.up if up is None else up)
        w = 2 * height
        dirs = latlong_directions(height, w).reshape(-1, 3) @ frame.T  # world directions
        local = dirs @ self.rotation  # rows: R^T d
        img = self._radiance_local(local, with_sun=False).reshape(height, w, 3)
        if self.sun:
            d = frame.T @ self.sun_direction  # sun in the map frame
            lat, lon = math.asin(max(-1.0, min(1.0, d[1]))), math.atan2(d[0], d[2])
            row = min(int((math.pi / 2 - lat) / math.pi * height), height - 1)
            col = min(int((math.pi - lon) / (2 * math.pi) * w), w - 1)
            omega_sun = 2 * math.pi * (1 - self._sun_cos)
            img[row, col] += self._sun_radiance * omega_sun / latlong_row_solid_angles(height, w)[row]
        return (img * self._scale).astype(np.float32)

    @property
    def sun_direction(self) -> np.ndarray:
        """World direction towards the sun (rotation applied), shape (3,)."""
        return self.rotation @ self._sun

    @property
    def sun_radiance(self) -> np.ndarray:
        """RGB radiance of the sun disc (same units as :meth:`radiance`)."""
        return self._sun_radiance * self._scale

    def _sh(self, order: int) -> np.ndarray:
        if order not in self._cache:
            # Sky + ground are smooth on each side of the horizon: a product rule split there,
            # 64 GL nodes per hemisphere × 256 azimuths (measured against 256 × 1024 at order 8: within
            # 1.3e-6 of DC, worst case sun 5° up). The sun disc is added analytically as a uniform cap.
            sky = project_function(lambda d: self._radiance_local(d, with_sun=False), order,
                                   n_theta=64, n_phi=256, pole=self._up, split=True)
            sun = zh_rotate(cap_zh(math.radians(SUN_ANGLE_DEG) / 2, order), self._sun)[:, None] * self._sun_radiance
            self._cache[order] = (sky + sun) * self._scale
        return rotate(self._cache[order], self.rotation, axis=0)

    def _rotated(self, rotation):
        out = copy.copy(self)  # shares the model and the per-order projection cache; no re-setup
        out.rotation = rotation @ self.rotation
        return out


def default_environment(up: str = "Y") -> Sky:
    """warpshade's default lighting: a clear :class:`Sky` (sun 45° up, azimuth 30°, turbidity 3)."""
    return Sky(up=up, name="default_sky")
