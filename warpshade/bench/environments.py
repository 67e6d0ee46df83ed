"""Two band-limited SH environment maps the benchmark judges radiance under.

Both are defined as functions on the sphere and projected onto SH of order :data:`ENV_ORDER` (6) by
numerical quadrature with :func:`~warpshade.sh.basis.sh_eval` (convention there). Band-limiting at
the highest order the benchmark sweeps means the reference radiance ``Σ_i L_i R_i`` computed from an
order-6 reference transfer is exact (up to the reference's Monte-Carlo error), while lower-order
transfers lose the bands they lack — so radiance error shows SH truncation, transfer error shows the
visibility method.

* ``sky``: warpshade's default daylight (:func:`warpshade.lighting.default_environment`: Preetham sky,
  sun 45° up, Lambertian ground) projected onto order 6 by :mod:`warpshade.lighting`.
* ``studio``: two coloured lobes (warm key from the front-left, cool rim from behind-right,
  ``exp(6 (ω·d - 1))``) over a dim uniform fill.

Up is +z for the analytic definitions; :func:`environments` rotates them for a Y-up mesh set by
permuting axes (the benchmark meshes are Z-up except Warp's USD assets, which are Y-up — both maps
have a distinct up so the permutation matters less than it would for a single sun).
"""

from __future__ import annotations

import numpy as np

from ..sh.basis import sh_eval

ENV_ORDER = 6
"""SH order of the benchmark environments (bands 0..5, 36 coefficients)."""


def _fibonacci_sphere(n: int) -> np.ndarray:
    i = np.arange(n) + 0.5
    z = 1 - 2 * i / n
    r = np.sqrt(1 - z * z)
    phi = np.pi * (1 + 5**0.5) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def project(fn, order: int = ENV_ORDER, samples: int = 20000) -> np.ndarray:
    """SH coefficients of an RGB function on the sphere, shape (order*order, 3).

    Quadrature on a Fibonacci point set (equal-area, weights 4π/n): for the smooth lobes used here the
    projection error is below 1e-4 of the DC term at 20000 points.
    """
    d = _fibonacci_sphere(samples)
    y = sh_eval(d, order)
    return (4 * np.pi / samples) * y.T @ fn(d)


def _studio(d: np.ndarray) -> np.ndarray:
    key = np.array([-0.6, 0.7, 0.4])
    rim = np.array([0.7, -0.6, 0.3])
    key = key / np.linalg.norm(key)
    rim = rim / np.linalg.norm(rim)
    return (0.05 + np.exp(6 * (d @ key - 1))[:, None] * np.array([3.0, 2.4, 1.8])
            + np.exp(6 * (d @ rim - 1))[:, None] * np.array([0.8, 1.2, 2.2]))


def environments(order: int = ENV_ORDER, up: str = "Z") -> dict[str, np.ndarray]:
    """``{"sky": L, "studio": L}``, each SH radiance of shape (order*order, 3), world space.

    Args:
        order: SH order of the projection.
        up: ``"Z"`` or ``"Y"``: which world axis the maps' zenith points along.
    """
    from ..lighting import default_environment

    perm = {"Z": lambda f: f, "Y": lambda f: (lambda d: f(d[:, [2, 0, 1]]))}[up]
    return {"sky": default_environment(up=up).sh(order), "studio": project(perm(_studio), order)}


def radiance(transfer: np.ndarray, light: np.ndarray) -> np.ndarray:
    """Exit radiance of a white Lambertian surface, ``(1/π) Σ_i L_i T_i`` (docs/conventions.md §2), shape (V, 3).

    Uses the first ``min(N*N, M*M)`` coefficients of transfer (V, N*N) and light (M*M, 3), which is
    exactly what an order-N renderer would do.
    """
    n = min(transfer.shape[1], light.shape[0])
    return np.asarray(transfer[:, :n], dtype=np.float64) @ light[:n] / np.pi
