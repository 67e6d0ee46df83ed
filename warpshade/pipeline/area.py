"""Rect lights with GEARS area-light soft shadows in ``warpshade run`` (``--area-lights gears``, the default).

Projecting a rect light to SH (``--area-lights sh``) keeps only its low-frequency part, so its
shadows are blurred and its light leaks under blockers. Here each rect light is kept out of the SH
sum; per frame and per vertex of every shaded object

    E(p) = L_e · Φ(p) · w(p),        L_out += (ρ/π) E(p)

with ``Φ`` the exact unshadowed projected solid angle of the rectangle (Lambert's polygon formula,
:meth:`warpshade.lighting.RectLight.projected_solid_angle`) and ``w`` the visible share of the light
from GEARS masks (Popescu et al., step 4: every blocker triangle rasterized onto a k×k mask of the
light as seen from the vertex). The paper shades with the plain fraction of visible samples ``v_p``;
we weight the samples by their form factor (:meth:`~warpshade.visibility.gears.AreaVisibilityMethod.
weighted_visibility`), which is exact for unblocked and fully blocked vertices and measured closer to
ray tracing in between (``benchmarks/area_lights.py``). Blockers are all shaded objects of the frame
that cast shadows (every shading group merged into one mesh), so cloth, colliders and ground shadow
each other and themselves whatever their SH visibility method; an object with
``warpshade:castsShadows = false`` receives but its triangles are left out of the blocker mesh.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..geometry.mesh import TriMesh
from ..visibility.rays import local_origin
from .config import AREA_MODES, DEFAULT_AREA_KNOBS, WEIGHTINGS


def is_area_light(light) -> bool:
    """Whether ``light`` is shaded by this module under ``--area-lights gears`` (a rect light)."""
    from ..lighting import RectLight

    return isinstance(light, RectLight)


def split_area_lights(lights: list) -> tuple[list, list]:
    """``(other lights, rect lights)``."""
    rect = [li for li in lights if is_area_light(li)]
    return [li for li in lights if not is_area_light(li)], rect


def area_lights_used(shader) -> tuple[str | None, str]:
    """How a :class:`~.shading.SceneShader` shades rect lights: ``("gears" | "sh" | None, one line)``
    (None and "" when it has no rect light)."""
    names = shader.rect_lights()
    if not names:
        return None, ""
    if shader.area_lights == "sh":
        return "sh", f"SH projection (low-frequency shadows through the transfer): {', '.join(names)}"
    kn = {**DEFAULT_AREA_KNOBS, **shader.area_knobs}
    return shader.area_lights, (f"GEARS soft shadows ({', '.join(f'{k}={v}' for k, v in kn.items())}) from every "
                                f"shaded object, exact unshadowed irradiance: {', '.join(names)}")


class AreaLightShading:
    """GEARS-shadowed rect lights over all shading groups of a run.

    Args:
        meshes: Rest meshes of the shading groups, in group order (merged into one receiver and blocker mesh).
        lights: The :class:`warpshade.lighting.RectLight` s (with their motion, if any).
        k: Light samples per side of the GEARS masks (default: :data:`~.config.DEFAULT_AREA_KNOBS`, as grid
            and weighting).
        grid: GEARS acceleration grid cells per side.
        weighting: One of :data:`WEIGHTINGS`.
        static: Nothing in the scene moves: with motionless lights, frame 0's result is reused.
        device: Warp device.
        blocker_faces: Per mesh, the triangles that block the lights (indices into that mesh), shape
            (F_c, 3) int; None: all of them. Vertices in no blocking triangle still receive.
    """

    def __init__(self, meshes: list, lights: list, k: int = DEFAULT_AREA_KNOBS["k"],
                 grid: int = DEFAULT_AREA_KNOBS["grid"], weighting: str = DEFAULT_AREA_KNOBS["weighting"],
                 static: bool = False, device: str = "cpu", blocker_faces: list | None = None):
        from ..visibility import get_method
        from ..visibility.gears import LightRect

        gears = get_method("gears", kind="area")

        if weighting not in WEIGHTINGS:
            raise ValueError(f"area-light weighting must be one of {', '.join(WEIGHTINGS)}, got {weighting!r}")
        self.lights, self.weighting, self.device = list(lights), weighting, device
        self.sizes = [m.num_vertices for m in meshes]
        offsets = np.cumsum([0] + self.sizes)
        if blocker_faces is None:
            blocker_faces = [m.faces for m in meshes]
        faces = np.concatenate([np.asarray(f, dtype=np.int32).reshape(-1, 3) + off
                                for f, off in zip(blocker_faces, offsets[:-1])])
        points = np.concatenate([m.points for m in meshes])
        normals = np.concatenate([m.normals for m in meshes])
        # no blocking triangle at all (no object casts shadows): every light is fully visible
        self.mesh = TriMesh(points, faces, normals=normals, name="area-light blockers") if len(faces) else None
        self.visibility = []
        for light in self.lights:
            try:
                rect = LightRect.from_light(light)
            except ValueError as exc:
                raise ValueError(f"{light.name}: GEARS needs a rectangle with orthogonal axes ({exc}); "
                                 "use --area-lights sh for this scene") from None
            self.visibility.append(gears(self.mesh, rect, k=k, grid=grid, device=device)
                                   if self.mesh is not None else None)
        self.static = bool(static) and all(li.motion is None for li in self.lights)
        self._phi = wp.empty(len(points), dtype=float, device=device)
        self._w = wp.empty(len(points), dtype=float, device=device)
        self._cached = None

    def irradiance(self, t: float, points: list, normals: list) -> list:
        """Shadowed RGB irradiance ``L_e Φ w`` summed over the lights, per group.

        Args:
            t: Time [s] (lights move by their ``motion``).
            points: Per group, vertex positions [m], shape (V_g, 3).
            normals: Per group, unit normals, shape (V_g, 3) (the ones the group's SH shading used).

        Returns:
            Per group, shape (V_g, 3), float64.
        """
        if self._cached is not None:
            return self._cached
        pts = np.concatenate(points).astype(np.float32)
        nrm = np.concatenate(normals).astype(np.float32)
        total = np.zeros((len(pts), 3))
        for vis, light in zip(self.visibility, self.lights):
            light = light.at_time(t)
            if vis is None:
                origin = local_origin(pts)
                local = (pts.astype(np.float64) - origin).astype(np.float32)
                phi = light.projected_solid_angle(local, nrm, out=self._phi, origin=origin)
                total += phi.numpy().astype(np.float64)[:, None] * light.radiance
                continue
            vis.set_light(light)
            vis.update(pts, nrm)
            w = vis.weighted_visibility(out=self._w) if self.weighting == "cosine" else vis.visibility
            # about the scene's local origin, as GEARS traces (a light's centre in float32 world coordinates
            # moves by its rounding there: 1.9 % of a 2 cm scene's irradiance at 1e4 units)
            phi = light.projected_solid_angle(vis.local_points, vis.normals, out=self._phi, origin=vis.origin)
            total += (phi.numpy().astype(np.float64) * w.numpy())[:, None] * light.radiance
        out = np.split(total, np.cumsum(self.sizes)[:-1])
        if self.static:
            self._cached = out
        return out

    def stats(self) -> dict:
        """GEARS counters of the last frame, per light."""
        return {li.name: vis.stats() if vis is not None else {} for li, vis in zip(self.lights, self.visibility)}


__all__ = ["AREA_MODES", "DEFAULT_AREA_KNOBS", "WEIGHTINGS", "AreaLightShading", "area_lights_used", "is_area_light",
           "split_area_lights"]
