"""One bounce of diffuse reflection for a whole scene (``warpshade run --reflections``; thesis §4.3, ch. 5).

Every shaded object reflects through its own sphere set (fitted once on its rest pose, refitted to its
current vertices every frame) and every shaded vertex receives. First pass: each sphere's surface
samples are re-read from the deformed mesh (so cloth and skinned characters reflect too) and take the
direct exit radiance the pipeline has just shaded at the object's vertices (all lights, local ones
included, with the object's own visibility method) — beyond the thesis, which shades the samples again
with sphere-set shadows (available as ``update(..., exit_radiance=None)``); they are projected to
radiance vectors (eqs. 4.17–4.20). Second pass: per receiver, form factor times sphere visibility
(eqs. 4.22–4.33). The result is the reflected irradiance ``E_R`` (no albedo, no ``1/π``);
:class:`~.shading.SceneShader` adds ``(ρ/π) E_R`` to each object's shadowed direct exit radiance
(eq. 4.23), whatever method shaded the direct light.

Objects reflect light only where their sphere samples hit their surface from inside (§4.3.1), so a
closed mesh reflects everywhere and an open one (a ground plane, cloth) only where a sphere centre
lies behind it; every object's spheres also block reflected light.
"""

from __future__ import annotations

import numpy as np

from ..geometry.mesh import TriMesh


class SceneReflections:
    """Reflected irradiance at every shaded vertex of a scene, from the sphere sets of every shaded object.

    Args:
        meshes: Rest meshes of the shaded objects, in output order (receivers and reflectors).
        order: SH order.
        device: Warp device.
        spheres: Leaf spheres per object.
        levels: Sphere hierarchy levels incl. leaves (1: leaves only, no cuts).
        exp: Exponential of the second pass (``"ol"`` default, see :class:`SphereReflections`).
        cuts: Per receiver cluster and object, use the coarsest hierarchy level that subtends at most
            ``threshold`` (eq. 4.8) instead of the leaves (needs ``levels`` > 1).
        ratios: With ``cuts``, the ratios between levels (corrected eq. 4.34).
        exclude_intersecting: The thesis' rule for eq. 4.32: intersecting spheres of one object do not
            occlude each other's reflection.
        self_reflection: Whether an object receives light reflected by its own spheres (``"auto"``:
            closed meshes do, open ones such as a ground plane or cloth do not).
        threshold: Cut threshold [rad] (eq. 4.8). Default 1.0: on the benchmark scene the cuts with the
            corrected ratios are as accurate as the leaves and faster (docs/methods/spheres.md).
        seed: Random seed of the sphere fits.
        trees: Sphere trees already fitted to ``meshes`` (rest pose), to skip the fits.
    """

    def __init__(self, meshes: list[TriMesh], order: int, device: str = "cpu", spheres: int = 15,
                 levels: int = 3, exp: str = "ol", cuts: bool = True, ratios: bool | str = True,
                 exclude_intersecting: bool = False, self_reflection: bool | str = "auto", threshold: float = 1.0,
                 seed: int = 0, trees: list | None = None):
        from ..visibility import get_method
        from ..visibility.spheres import SphereReflections, build_sphere_tree

        self.meshes = list(meshes)
        self.offsets = np.cumsum([0] + [m.num_vertices for m in self.meshes])
        faces = np.concatenate([m.faces + o for m, o in zip(self.meshes, self.offsets[:-1])])
        rest = np.concatenate([m.points for m in self.meshes])
        receivers = TriMesh(rest, faces, name="reflection receivers")
        if trees is None:
            trees = [build_sphere_tree(m.points, m.faces, spheres, levels, seed=seed, device=device)
                     for m in self.meshes]
        self.trees = trees
        self.method = get_method("spheres")(receivers, order=order, device=device, spheres=spheres, levels=levels,
                                             threshold=threshold, seed=seed, self_shadow=False,
                                             blockers=[(t, m.points) for t, m in zip(trees, self.meshes)])
        # receiver object ids: -1 lets the object's own spheres reflect onto it. A closed object's own
        # spheres stand for its other parts (concavities: measured better on the bunny and bear); an open
        # one's (a ground plane) bulge over its own surface and would light it spuriously.
        if self_reflection not in (True, False, "auto"):
            raise ValueError(f"self_reflection must be True, False or 'auto', got {self_reflection!r}")
        own = np.arange(len(self.meshes), dtype=np.int32)
        if self_reflection is True:
            own[:] = -1
        elif self_reflection == "auto":
            own[[t.closed for t in trees]] = -1
        owner = np.repeat(own, np.diff(self.offsets))
        self.reflections = SphereReflections(self.method, self.meshes, exp=exp, cuts=cuts, ratios=ratios,
                                             exclude_intersecting=exclude_intersecting,
                                             self_reflection=False, receiver_objects=owner)
        self.device = device

    def update(self, points: list[np.ndarray], normals: list[np.ndarray], light: np.ndarray,
               albedos: list[np.ndarray], exit_radiance: list[np.ndarray] | None = None) -> np.ndarray:
        """Reflected irradiance this frame.

        Args:
            points: Per object, current vertex positions, shape (V_o, 3).
            normals: Per object, current unit vertex normals, shape (V_o, 3).
            light: Distant lighting, SH radiance per colour, shape (N*N, 3), world space.
            albedos: Per object, diffuse albedo RGB (3,) or per vertex (V_o, 3).
            exit_radiance: Optional per object direct exit radiance of its vertices (V_o, 3) (the
                pipeline's shading): the first pass then reads it at the samples instead of shading them
                with sphere-set shadows (:meth:`SphereReflections.shade_samples`).

        Returns:
            ``E_R`` per vertex of all objects (concatenated in ``meshes`` order), shape (V, 3), float32.
        """
        pts = np.concatenate(points).astype(np.float32)
        nrm = np.concatenate(normals).astype(np.float32)
        self.method.move(pts, nrm, blocker_points=list(points))
        n2 = self.method.order ** 2
        light = None if light is None else np.asarray(light, dtype=np.float64)[:n2]
        self.reflections.shade_samples(light, list(albedos),
                                       None if exit_radiance is None else list(exit_radiance))
        return self.reflections.gather().numpy().copy()

    def slice(self, irradiance: np.ndarray, k: int) -> np.ndarray:
        """Rows of object ``k`` in an :meth:`update` result, shape (V_k, 3)."""
        return irradiance[self.offsets[k]:self.offsets[k + 1]]


__all__ = ["SceneReflections"]
