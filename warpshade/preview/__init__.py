"""A small Warp ray-cast viewer for shaded output (``warpshade preview``): no DCC needed to look.

The colours are the baked per-vertex exit radiance (``primvars:displayColor``); the viewer only
interpolates them barycentrically, adds a ground plane and a sky, tone-maps (exposure, sRGB) and
frames the camera on the meshes' extent.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from .kernels import cast_primary_rays


@dataclass
class Camera:
    """A pinhole camera.

    Attributes:
        eye: Position [scene units], shape (3,).
        target: Point looked at, shape (3,).
        up: World up axis, shape (3,).
        fov: Vertical field of view [degrees].
    """

    eye: np.ndarray
    target: np.ndarray
    up: np.ndarray
    fov: float = 35.0


def frame_camera(points: np.ndarray, up_axis: str = "Y", azimuth: float = 35.0, elevation: float = 25.0,
                 fov: float = 35.0, aspect: float = 4 / 3) -> Camera:
    """A camera that looks at the bounding sphere of ``points`` (shape (P, 3)) and fits it in view."""
    up = np.array([0.0, 1.0, 0.0]) if up_axis.upper() == "Y" else np.array([0.0, 0.0, 1.0])
    lo, hi = points.min(axis=0), points.max(axis=0)
    center = 0.5 * (lo + hi)
    radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-6)
    az, el = np.radians(azimuth), np.radians(elevation)
    if up_axis.upper() == "Y":
        d = np.array([np.sin(az) * np.cos(el), np.sin(el), np.cos(az) * np.cos(el)])
    else:
        d = np.array([np.sin(az) * np.cos(el), -np.cos(az) * np.cos(el), np.sin(el)])
    half = np.radians(fov) / 2
    half = min(half, np.arctan(np.tan(half) * aspect))  # fit the narrower of the two extents
    dist = radius / np.sin(half) * 1.05
    return Camera(eye=center + d * dist, target=center, up=up, fov=fov)


def render(meshes: list[tuple[np.ndarray, np.ndarray, np.ndarray]], camera: Camera, width: int = 640,
           height: int = 480, ground_height: float | None = None, device: str = "cpu") -> np.ndarray:
    """Ray-cast meshes with per-vertex colours.

    Args:
        meshes: ``(points (V, 3), faces (F, 3), colors (V, 3))`` per mesh, world space, linear RGB, optionally
            with a fourth item, the colours seen from the back of its triangles (V, 3) (a two-sided
            output's back-side mesh, docs/conventions.md §6); without it both sides show ``colors``.
        camera: View.
        width, height: Image size [pixels].
        ground_height: Height of the ground plane along ``camera.up`` (default: just below the
            lowest point).
        device: Warp device.

    Returns:
        Linear RGB image, shape (height, width, 3), float32, row 0 at the top.
    """
    pts = np.concatenate([m[0] for m in meshes]).astype(np.float32)
    offs = np.cumsum([0] + [len(m[0]) for m in meshes])[:-1]
    faces = np.concatenate([m[1] + o for m, o in zip(meshes, offs)]).astype(np.int32)
    cols = np.concatenate([m[2] for m in meshes]).astype(np.float32)
    back = np.concatenate([m[3] if len(m) > 3 and m[3] is not None else m[2] for m in meshes]).astype(np.float32)
    up = np.asarray(camera.up, dtype=np.float64)
    if ground_height is None:
        h = pts @ up
        ground_height = float(h.min() - 1e-3 * (h.max() - h.min() + 1e-6))
    fwd = camera.target - camera.eye
    fwd = fwd / np.linalg.norm(fwd)
    right = np.cross(fwd, up)
    right = right / (np.linalg.norm(right) or 1.0)
    cup = np.cross(right, fwd)
    wpts = wp.array(pts, dtype=wp.vec3, device=device)
    wfaces = wp.array(faces, dtype=wp.int32, device=device)
    mesh = wp.Mesh(points=wpts, indices=wp.array(faces.reshape(-1), dtype=wp.int32, device=device))
    image = wp.zeros((height, width), dtype=wp.vec3, device=device)
    bright = float(np.percentile(cols.max(axis=1), 95)) if len(cols) else 1.0
    ground = wp.vec3(*(0.35 * bright,) * 3)
    sky = wp.vec3(0.55 * bright, 0.65 * bright, 0.8 * bright)
    diag = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))) + float(np.linalg.norm(camera.eye - camera.target))
    wp.launch(cast_primary_rays, dim=(height, width),
              inputs=[mesh.id, wfaces, wp.array(cols, dtype=wp.vec3, device=device),
                      wp.array(back, dtype=wp.vec3, device=device), wp.vec3(*camera.eye),
                      wp.vec3(*fwd), wp.vec3(*right), wp.vec3(*cup), float(np.tan(np.radians(camera.fov) / 2)),
                      width, height, wp.vec3(*up), ground_height, ground, sky, 4.0 * diag],
              outputs=[image], device=device)
    return image.numpy()


def tonemap(image: np.ndarray, exposure: float | None = None) -> np.ndarray:
    """Linear radiance -> 8-bit sRGB. ``exposure`` scales radiance before encoding (default: the
    99th percentile maps to 0.9, so a bright sun-lit patch does not wash out the frame).

    Returns:
        uint8 image, same height and width, 3 channels.
    """
    if exposure is None:
        p = float(np.percentile(image.max(axis=-1), 99))
        exposure = 0.9 / p if p > 0 else 1.0
    x = np.clip(image * exposure, 0.0, 1.0)
    srgb = np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)
    return (srgb * 255 + 0.5).astype(np.uint8)


def contact_sheet(images: list[np.ndarray], columns: int = 4, labels: list[str] | None = None) -> np.ndarray:
    """Tile equally sized uint8 images (row-major) into one, with a 2-pixel white gutter."""
    h, w = images[0].shape[:2]
    rows = (len(images) + columns - 1) // columns
    sheet = np.full((rows * (h + 2) + 2, columns * (w + 2) + 2, 3), 255, dtype=np.uint8)
    for k, img in enumerate(images):
        r, c = divmod(k, columns)
        sheet[2 + r * (h + 2):2 + r * (h + 2) + h, 2 + c * (w + 2):2 + c * (w + 2) + w] = img
    return sheet


__all__ = ["Camera", "contact_sheet", "frame_camera", "render", "tonemap"]
