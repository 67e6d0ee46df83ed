"""One bounce of diffuse reflection from sphere sets (thesis §4.3, ch. 5), on top of :class:`SpheresTransfer`.

Build once per reflecting object: the triangles each leaf sphere owns (eq. 4.10), its surface samples
in evenly spaced directions (geodesic sphere, §4.3.1) stored as rest-pose triangle + barycentrics, and
the Voronoi-cell SH sums of eq. 4.19. Per frame (:meth:`SphereReflections.update`):

1. re-read the samples from the current, possibly deformed, mesh (beyond the thesis, which keeps
   samples rigid) and their normals;
2. first pass: sphere-set soft shadows at the samples (the same kernel as the receivers, one cluster
   per sphere) give the white shadowed exit radiance, projected to a radiance SH vector per sphere and
   colour (eqs. 4.16–4.20);
3. second pass: per receiver vertex, the reflected irradiance ``E_R = Σ_s L̃_s Ṽ_s`` (eq. 4.22).

Exit radiance including the bounce: ``(ρ/π) (L · T + E_R)`` (CONTRACTS.md §2 for the first term).
Leaves only, so the ratios of eq. 4.34 (between hierarchy levels) are all 1.
"""

from __future__ import annotations

import math

import numpy as np
import warp as wp

from ...geometry.mesh import TriMesh
from ...geometry.normals import vertex_normals
from ...sh.basis import sh_eval
from .kernels import fit_clusters
from .method import EXP_MODES, SpheresTransfer
from .reflection_kernels import project_sphere_radiance, resample_surface, trace_sphere_samples
from .sets import _csr
from .tables import sphere_tables


def sample_directions(subdivisions: int = 1) -> np.ndarray:
    """Evenly spaced unit directions: vertices of an icosahedral geodesic sphere (thesis Fig. 4.10), (m, 3)."""
    import trimesh

    return np.asarray(trimesh.creation.icosphere(subdivisions).vertices, dtype=np.float64)


def voronoi_sh(directions: np.ndarray, order: int, fine: int = 16384, seed: int = 0) -> np.ndarray:
    """Eq. 4.19: ``(4π/N) Σ_{k in cell j} y(ω̂_k)`` over N random directions, per sample direction j, (m, N*N)."""
    from scipy.spatial import cKDTree

    rng = np.random.default_rng(seed)
    w = rng.normal(size=(fine, 3))
    w /= np.linalg.norm(w, axis=1)[:, None]
    cell = cKDTree(directions).query(w)[1]
    out = np.zeros((len(directions), order * order))
    np.add.at(out, cell, sh_eval(w, order))
    return out * (4 * math.pi / fine)


class SphereReflections:
    """Diffuse reflections from the sphere sets of a :class:`SpheresTransfer`'s objects onto its receiver.

    Args:
        method: The shadow method (its sphere scene, refit and cuts are reused; call its ``update`` first).
        meshes: Per object of ``method.scene`` (own mesh first when it self-shadows, then its blockers), the
            mesh whose surface the spheres reflect, or None for an object that does not reflect.
        subdivisions: Geodesic sphere subdivisions for the sample directions (1: 42, 2: 162 per sphere).
        exp: Exponential of the second pass (``"ol"`` default: one exponential per sphere and receiver).
    """

    def __init__(self, method: SpheresTransfer, meshes: list[TriMesh | None], subdivisions: int = 1,
                 exp: str = "ol"):
        if len(meshes) != len(method.scene.trees):
            raise ValueError(f"need one mesh (or None) per sphere-set object: {len(method.scene.trees)}, "
                             f"got {len(meshes)}")
        if exp not in EXP_MODES:
            raise ValueError(f"exp must be one of {', '.join(EXP_MODES)}, got {exp!r}")
        self.method, self.exp, self.device = method, exp, method.device
        d, order = method.device, method.order
        # The log blocker table is fitted to the exponential that will use it (tables.py); the second pass
        # may use another exponential than the shadows (default ol vs hyb), so it gets its own table. With
        # the shadows' hybrid-fitted table, OL overshot a lit ball's reflection by 20 % at distance 1.5.
        self._log_vec = wp.array(sphere_tables(order, exp, method.tau).log_blocker.astype(np.float32),
                                 dtype=method._fixed.vec_zh, device=d)
        self.directions = sample_directions(subdivisions)
        m = len(self.directions)
        self._voronoi = wp.array(voronoi_sh(self.directions, order).astype(np.float32), dtype=float, device=d)
        sc = method.scene
        self.objects = []
        leaves, faces_all, bary_all, owner_obj = [], [], [], []
        for o, (tree, mesh) in enumerate(zip(sc.trees, meshes)):
            if mesh is None:
                continue
            lo = int(sc.offsets[o])
            leaf = np.flatnonzero(tree.level == 0)
            face, bary = self._trace(mesh, tree, leaf)
            self.objects.append(dict(obj=o, mesh=mesh, leaf=leaf + lo, first=len(leaves),
                                     faces=wp.array(mesh.faces, dtype=wp.int32, device=d),
                                     normals=wp.zeros(mesh.num_vertices, dtype=wp.vec3, device=d)))
            leaves.extend((leaf + lo).tolist())
            faces_all.append(face)
            bary_all.append(bary)
            owner_obj.extend([o] * len(leaf))
        self.leaves = np.array(leaves, dtype=np.int32)
        self.leaf_object = np.array(owner_obj, dtype=np.int32)
        L = len(leaves)
        self.num_samples = L * m
        self._spheres = wp.array(self.leaves if L else np.zeros(1, np.int32), dtype=wp.int32, device=d)
        face = np.concatenate(faces_all) if L else -np.ones((1, m), np.int32)
        bary = np.concatenate(bary_all) if L else np.zeros((1, m, 3), np.float32)
        self.valid_fraction = float((face >= 0).mean()) if L else 0.0
        self._face = wp.array(face.astype(np.int32), dtype=wp.int32, device=d)
        self._bary = wp.array(bary.astype(np.float32), dtype=wp.vec3, device=d)
        R = max(L * m, 1)
        self._spts = wp.zeros((max(L, 1), m), dtype=wp.vec3, device=d)
        self._salb = wp.zeros((max(L, 1), m), dtype=wp.vec3, device=d)
        self._snrm = wp.zeros((max(L, 1), m), dtype=wp.vec3, device=d)
        n2 = order * order
        self._s_used = wp.zeros(R, dtype=wp.int32, device=d)
        self._s_fallback = wp.zeros(R, dtype=wp.int32, device=d)
        self._s_vis = wp.zeros((R, n2), dtype=float, device=d)
        self._s_transfer = wp.zeros((R, n2), dtype=float, device=d)
        self._s_cluster = wp.array(np.repeat(np.arange(max(L, 1)), m).astype(np.int32), dtype=wp.int32, device=d)
        self._s_centers = wp.zeros(max(L, 1), dtype=wp.vec3, device=d)
        self._s_radii = wp.zeros(max(L, 1), dtype=float, device=d)
        self.radiance = wp.zeros((max(L, 1), 3, n2), dtype=float, device=d)
        """Radiance SH vector of each reflecting leaf sphere per colour, rest frame, shape (L, 3, N*N)."""
        V = method.mesh.num_vertices
        self._key = wp.zeros((V, max(L, 1)), dtype=float, device=d)
        self.irradiance = wp.zeros(V, dtype=wp.vec3, device=d)
        """Reflected irradiance at each receiver vertex (eq. 4.22, no albedo, no 1/π), shape (V,), vec3."""
        ms, mi = _csr([np.arange(i * m, (i + 1) * m) for i in range(max(L, 1))])
        self._s_members = (wp.array(ms, dtype=wp.int32, device=d), wp.array(mi, dtype=wp.int32, device=d))

    def _trace(self, mesh: TriMesh, tree, leaf: np.ndarray):
        """Rest-pose sample triangles and barycentrics of each leaf of one object, shapes (L, m), (L, m, 3)."""
        d = self.device
        pts = mesh.points.astype(np.float64)
        tri = pts[mesh.faces]
        cent = tri.mean(axis=1)
        # eq. 4.10: a triangle belongs to the leaf with the smallest ||p - x|| / r (by its centroid)
        dist = np.linalg.norm(cent[:, None, :] - tree.centers[leaf][None], axis=2) / tree.radii[leaf][None]
        owner = leaf[np.argmin(dist, axis=1)].astype(np.int32)
        wmesh = wp.Mesh(points=wp.array(mesh.points, dtype=wp.vec3, device=d),
                        indices=wp.array(mesh.faces.reshape(-1), dtype=wp.int32, device=d))
        m = len(self.directions)
        hit_face = wp.zeros((len(leaf), m), dtype=wp.int32, device=d)
        hit_point = wp.zeros((len(leaf), m), dtype=wp.vec3, device=d)
        diag = float(np.linalg.norm(np.ptp(pts, axis=0))) + float(tree.radii.max())
        wp.launch(trace_sphere_samples, dim=(len(leaf), m),
                  inputs=[wmesh.id, wp.array(owner, dtype=wp.int32, device=d),
                          wp.array(tree.centers.astype(np.float32), dtype=wp.vec3, device=d),
                          wp.array(leaf.astype(np.int32), dtype=wp.int32, device=d),
                          wp.array(self.directions.astype(np.float32), dtype=wp.vec3, device=d), 4.0 * diag, 64],
                  outputs=[hit_face, hit_point], device=d)
        face = hit_face.numpy()
        hp = hit_point.numpy().astype(np.float64)
        bary = np.zeros(face.shape + (3,))
        ok = face >= 0
        a, b, c = (tri[face[ok], k] for k in range(3))
        # barycentrics of the hit point (least squares in the triangle's plane)
        v0, v1, v2 = b - a, c - a, hp[ok] - a
        d00, d01, d11 = (v0 * v0).sum(1), (v0 * v1).sum(1), (v1 * v1).sum(1)
        d20, d21 = (v2 * v0).sum(1), (v2 * v1).sum(1)
        den = np.where(np.abs(d00 * d11 - d01 ** 2) > 0, d00 * d11 - d01 ** 2, 1.0)
        bv = (d11 * d20 - d01 * d21) / den
        bw = (d00 * d21 - d01 * d20) / den
        bary[ok] = np.stack([1 - bv - bw, bv, bw], axis=1)
        return face, bary

    def update(self, light, albedo) -> wp.array:
        """Recompute :attr:`irradiance` for the current frame (call ``method.update`` or ``method.move`` first).

        :meth:`shade_samples` (first pass) then :meth:`gather` (second pass) at the method's receivers.

        Args:
            light: Distant lighting, SH radiance per colour, shape (N*N, 3) (world space).
            albedo: Per object of ``method.scene``, diffuse albedo: RGB (3,) or per vertex (V_o, 3) (objects
                without a mesh are ignored; give them any RGB).

        Returns:
            :attr:`irradiance`, shape (V,), vec3.
        """
        self.shade_samples(light, albedo)
        return self.gather()

    def shade_samples(self, light, albedo) -> wp.array:
        """First pass (§4.3.2): re-read the surface samples from the current meshes, shade them with the
        sphere-set shadows and project the white exit radiance times albedo to :attr:`radiance`.

        Arguments as :meth:`update`. Returns :attr:`radiance`, shape (L, 3, N*N).
        """
        meth, d = self.method, self.device
        n2 = meth.order * meth.order
        light = np.asarray(light, dtype=np.float32)
        if light.shape != (n2, 3):
            raise ValueError(f"light must have shape ({n2}, 3), got {light.shape}")
        if len(albedo) != len(meth.scene.trees):
            raise ValueError(f"need one albedo per sphere-set object ({len(meth.scene.trees)}), got {len(albedo)}")
        L = len(self.leaves)
        if L == 0:
            return self.radiance
        m = len(self.directions)
        for ob in self.objects:
            pts = meth._blocker_points[ob["obj"]]
            if pts is None:
                pts = wp.array(ob["mesh"].points, dtype=wp.vec3, device=d)
            elif not isinstance(pts, wp.array):
                pts = wp.array(np.asarray(pts, dtype=np.float32), dtype=wp.vec3, device=d)
            vertex_normals(pts, ob["faces"], out=ob["normals"])
            nv = ob["mesh"].num_vertices
            a = np.asarray(albedo[ob["obj"]], dtype=np.float32)
            if a.shape == (3,):
                a = np.broadcast_to(a, (nv, 3))
            if a.shape != (nv, 3) or not np.isfinite(a).all():
                raise ValueError(f"{ob['mesh'].name}: albedo must be finite RGB (3,) or ({nv}, 3), got {a.shape}")
            k0, k1 = ob["first"], ob["first"] + len(ob["leaf"])
            wp.launch(resample_surface, dim=(k1 - k0, m),
                      inputs=[self._face[k0:k1], self._bary[k0:k1], ob["faces"], pts, ob["normals"],
                              wp.array(np.ascontiguousarray(a), dtype=wp.vec3, device=d)],
                      outputs=[self._spts[k0:k1], self._snrm[k0:k1], self._salb[k0:k1]], device=d)
        # shadows at the samples, one cluster per sphere (bounded by the sphere itself)
        spts = self._spts.reshape((L * m,))
        snrm = self._snrm.reshape((L * m,))
        wp.launch(fit_clusters, dim=L, inputs=[*self._s_members, spts], outputs=[self._s_centers, self._s_radii],
                  device=d)
        meth.shade_points(spts, snrm, self._s_cluster, self._s_centers, self._s_radii,
                          self._s_used, self._s_fallback, self._s_vis, self._s_transfer)
        wp.launch(project_sphere_radiance, dim=(L, 3),
                  inputs=[self._s_transfer, self._face, wp.array(light, dtype=float, device=d), self._salb,
                          self._voronoi, n2],
                  outputs=[self.radiance], device=d)
        return self.radiance

    def gather(self, points: wp.array | None = None, normals: wp.array | None = None,
               out: wp.array | None = None) -> wp.array:
        """Second pass (§4.3.3): reflected irradiance (eq. 4.22) at receivers from the current :attr:`radiance`.

        Args:
            points, normals: Receivers, shape (R,), vec3 (default: the method's vertices, output
                :attr:`irradiance`).
            out: Output for other receivers, shape (R,), vec3 (allocated when None).

        Returns:
            Reflected irradiance (no albedo, no 1/π), shape (R,), vec3.
        """
        meth, d = self.method, self.device
        if points is None:
            points, normals, out = meth.points, meth.normals, self.irradiance
        elif normals is None:
            raise ValueError("gather needs normals with points")
        R = points.shape[0]
        if out is None:
            out = wp.zeros(R, dtype=wp.vec3, device=d)
        L = len(self.leaves)
        if L == 0:
            out.zero_()
            return out
        key = self._key if R == self._key.shape[0] else wp.zeros((R, L), dtype=float, device=d)
        t, sc = meth.tables, meth.scene
        wp.launch(meth._fixed.reflect, dim=R,
                  inputs=[points, normals, self._spheres, sc.centers, sc.radii, sc.rotations,
                          self.radiance, self._log_vec, meth._ff_vec, t.theta_step, meth._cos_vec, meth._fixed.kz,
                          meth._ol, meth._products, EXP_MODES[self.exp], meth.tau, key],
                  outputs=[out], device=d)
        return out

    def exit_radiance(self, light, albedo_receiver) -> np.ndarray:
        """``(ρ/π)(L · T + E_R)`` at the receiver vertices: shadowed direct plus one bounce, shape (V, 3).

        The direct part is :func:`warpshade.radiance.exit_radiance` of the method's transfer.

        Args:
            light: SH radiance per colour, shape (N*N, 3).
            albedo_receiver: Receiver albedo: scalar, RGB (3,) or per vertex (V, 3).
        """
        from ...radiance import exit_radiance

        direct = exit_radiance(self.method.transfer, light, albedo_receiver, clamp=False, device=self.device).numpy()
        rho = np.broadcast_to(np.asarray(albedo_receiver, dtype=np.float64), direct.shape)
        return direct + rho / math.pi * self.irradiance.numpy()
