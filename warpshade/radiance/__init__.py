"""Exit radiance of Lambertian vertices from transfer vectors and lights (docs/conventions.md §2).

``L_out[v] = (ρ_v / π) Σ_i L_i T_v,i`` per RGB channel, with ``L`` the SH radiance of all lights
summed (distant lights: one vector; local lights: one vector per vertex, see
:func:`warpshade.lighting.lights_sh`). Transfer stays on the device between frames, so a change of
lighting costs one upload of ``N*N*3`` floats and this dot product per vertex.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from .kernels import shade_vertices


def _albedo_rows(albedo, n_vertices: int) -> np.ndarray:
    a = np.asarray(albedo, dtype=np.float32)
    if a.ndim == 0:
        a = np.full((1, 3), float(a), dtype=np.float32)
    a = a.reshape(-1, 3) if a.size % 3 == 0 else a
    if a.ndim != 2 or a.shape[1] != 3 or a.shape[0] not in (1, n_vertices):
        raise ValueError(f"albedo must be a scalar, RGB (3,) or per-vertex (V={n_vertices}, 3); got shape {np.shape(albedo)}")
    return a


def exit_radiance_reference(transfer, light_sh, albedo, local_sh=None, clamp: bool = True) -> np.ndarray:
    """NumPy reference of :func:`exit_radiance`, float64, shape (V, 3)."""
    t = np.asarray(transfer, dtype=np.float64)
    lsh = np.asarray(light_sh, dtype=np.float64)
    n = t.shape[1]
    out = t @ lsh[:n]
    if local_sh is not None:
        out += np.einsum("vi,vic->vc", t, np.asarray(local_sh, dtype=np.float64)[:, :n])
    out = _albedo_rows(albedo, t.shape[0]).astype(np.float64) / np.pi * out
    return np.maximum(out, 0.0) if clamp else out


def exit_radiance(transfer, light_sh, albedo=1.0, local_sh=None, out: wp.array | None = None,
                  clamp: bool = True, device: str = "cpu") -> wp.array:
    """Exit radiance per vertex (Warp kernel).

    Args:
        transfer: Transfer vectors, shape (V, N*N), float32 ``wp.array2d`` (kept on the device) or array-like.
        light_sh: Distant-light SH radiance, shape (M*M, 3) with M >= N (extra bands ignored).
        albedo: Diffuse albedo ρ: scalar, RGB (3,) or per vertex (V, 3).
        local_sh: Optional per-vertex SH of local lights, shape (V, M*M, 3).
        out: Optional output array, shape (V,), dtype vec3 (reused between frames).
        clamp: Clamp negative radiance (SH truncation ringing behind bright lights) to 0.
        device: Warp device.

    Returns:
        Linear RGB exit radiance, shape (V,), dtype vec3 (same units as the lights).

    Raises:
        ValueError: on mismatched shapes (message gives them).
    """
    if not isinstance(transfer, wp.array):
        transfer = wp.array(np.asarray(transfer, dtype=np.float32), dtype=float, device=device)
    n_vertices, n = transfer.shape
    lsh = np.asarray(light_sh, dtype=np.float32)
    if lsh.ndim != 2 or lsh.shape[1] != 3 or lsh.shape[0] < n:
        raise ValueError(f"light SH must have shape (>= {n}, 3) for transfer of shape {transfer.shape}; got {lsh.shape}")
    light = wp.array(np.ascontiguousarray(lsh[:n]), dtype=wp.vec3, device=device)
    if local_sh is None:
        local = wp.zeros((0, n), dtype=wp.vec3, device=device)
    else:
        loc = np.asarray(local_sh, dtype=np.float32)
        if loc.ndim != 3 or loc.shape[0] != n_vertices or loc.shape[1] < n or loc.shape[2] != 3:
            raise ValueError(f"local light SH must have shape ({n_vertices}, >= {n}, 3); got {loc.shape}")
        local = wp.array(np.ascontiguousarray(loc[:, :n]), dtype=wp.vec3, device=device)
    alb = wp.array(_albedo_rows(albedo, n_vertices), dtype=wp.vec3, device=device)
    if out is None:
        out = wp.empty(n_vertices, dtype=wp.vec3, device=device)
    elif out.shape != (n_vertices,):
        raise ValueError(f"out must have shape ({n_vertices},), got {out.shape}")
    wp.launch(shade_vertices, dim=n_vertices, inputs=[transfer, light, local, alb, int(bool(clamp))],
              outputs=[out], device=device)
    return out


def shade(transfer, lights, order: int, albedo=1.0, points=None, time: float | None = None,
          clamp: bool = True, device: str = "cpu") -> wp.array:
    """Convenience: sum ``lights`` (at ``time`` if given) and shade.

    Args:
        transfer: (V, order*order) transfer.
        lights: Iterable of :class:`warpshade.lighting.Light`.
        order: SH order of the transfer.
        albedo: As in :func:`exit_radiance`.
        points: Vertex positions (V, 3), needed for local lights.
        time: Seconds; each light is taken ``at_time(time)`` when given.
        clamp: As in :func:`exit_radiance`.
        device: Warp device.
    """
    from ..lighting import lights_sh

    lights = list(lights)
    if time is not None:
        lights = [lt.at_time(time) for lt in lights]
    distant, local = lights_sh(lights, order, points)
    return exit_radiance(transfer, distant, albedo, local, clamp=clamp, device=device)
