"""One bounce of diffuse reflection for a whole scene (``warpshade run --reflections``; thesis §4.3, ch. 5).

Every shaded object reflects through its own sphere set (fitted once on its rest pose, refitted to its
current vertices every frame) and every shaded vertex receives: the first pass shades each sphere's
surface samples (re-read from the deformed mesh, so cloth and skinned characters reflect too) under the
frame's distant lights and projects them to radiance vectors; the second pass sums, per receiver, form
factor times sphere visibility (eqs. 4.22–4.33). The result is the reflected irradiance ``E_R`` (no
albedo, no ``1/π``); :class:`~.shading.SceneShader` adds ``(ρ/π) E_R`` to each object's shadowed
direct exit radiance (eq. 4.23), whatever method shaded the direct light.

Objects reflect light only where their sphere samples hit their surface (closed meshes; a flat ground
plane's spheres sample almost nothing and reflect almost nothing, but still block reflected light).
Local lights (sphere, rect) are not bounced: the first pass uses the distant lights' SH.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..geometry.mesh import TriMesh


class SceneReflections:
    """Reflected irradiance at every shaded vertex of a scene, from the sphere sets of every shaded object.

    Args:
        meshes: Rest meshes of the shaded objects, in output order (receivers and reflectors).
        order: SH order.
        device: Warp device.
        spheres: Leaf spheres per object.
        levels: Sphere hierarchy levels (cuts and the ratios of eq. 4.34 between levels).
        exp: Exponential of the second pass (``"ol"`` default, see :class:`SphereReflections`).
        ratios: Apply the ratio vectors of eq. 4.34 to cut spheres above the leaves.
    """

    def __init__(self, meshes: list[TriMesh], order: int, device: str = "cpu", spheres: int = 15,
                 levels: int = 1, exp: str = "ol", ratios: bool = True):
        from ..visibility.spheres import SpheresTransfer, SphereReflections, build_sphere_tree

        self.meshes = list(meshes)
        self.offsets = np.cumsum([0] + [m.num_vertices for m in self.meshes])
        faces = np.concatenate([m.faces + o for m, o in zip(self.meshes, self.offsets[:-1])])
        rest = np.concatenate([m.points for m in self.meshes])
        receivers = TriMesh(rest, faces, name="reflection receivers")
        trees = [build_sphere_tree(m.points, m.faces, spheres, levels, device=device) for m in self.meshes]
        self.method = SpheresTransfer(receivers, order=order, device=device, spheres=spheres, levels=levels,
                                      self_shadow=False, blockers=[(t, m.points) for t, m in zip(trees, self.meshes)],
                                      ratios=ratios)
        self.reflections = SphereReflections(self.method, self.meshes, exp=exp)
        self.device = device

    def update(self, points: list[np.ndarray], normals: list[np.ndarray], light: np.ndarray,
               albedos: list[np.ndarray]) -> np.ndarray:
        """Reflected irradiance this frame.

        Args:
            points: Per object, current vertex positions, shape (V_o, 3).
            normals: Per object, current unit vertex normals, shape (V_o, 3).
            light: Distant lighting, SH radiance per colour, shape (N*N, 3), world space.
            albedos: Per object, diffuse albedo RGB (3,) or per vertex (V_o, 3).

        Returns:
            ``E_R`` per vertex of all objects (concatenated in ``meshes`` order), shape (V, 3), float32.
        """
        pts = np.concatenate(points).astype(np.float32)
        nrm = np.concatenate(normals).astype(np.float32)
        self.method.move(pts, nrm, blocker_points=list(points))
        n2 = self.method.order ** 2
        return self.reflections.update(np.asarray(light, dtype=np.float64)[:n2], list(albedos)).numpy().copy()

    def slice(self, irradiance: np.ndarray, k: int) -> np.ndarray:
        """Rows of object ``k`` in an :meth:`update` result, shape (V_k, 3)."""
        return irradiance[self.offsets[k]:self.offsets[k + 1]]


__all__ = ["SceneReflections"]
