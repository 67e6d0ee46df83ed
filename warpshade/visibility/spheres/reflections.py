"""One bounce of diffuse reflection from sphere sets (thesis §4.3, ch. 5), on top of :class:`SpheresTransfer`.

Build once per reflecting object: the triangles each leaf sphere owns (eq. 4.10), its surface samples
in evenly spaced directions (geodesic sphere, §4.3.1) stored as rest-pose triangle + barycentrics, and
the Voronoi-cell SH sums of eq. 4.19. Per frame (:meth:`SphereReflections.update`):

1. re-read the samples from the current, possibly deformed, mesh (beyond the thesis, which keeps
   samples rigid) and their normals;
2. first pass: sphere-set soft shadows at the samples (the same kernel as the receivers, one cluster
   per sphere) give the white shadowed exit radiance, projected to a radiance SH vector per sphere and
   colour (eqs. 4.16–4.20); or the samples read a given per-vertex exit radiance (the pipeline's own
   direct shading, :meth:`SphereReflections.shade_samples`);
3. second pass: per receiver vertex, the reflected irradiance ``E_R = Σ_s L̃_s Ṽ_s`` (eq. 4.22) with
   the sphere visibility of eq. 4.32 (optionally with the thesis' rule for intersecting spheres of one
   object, ``exclude_intersecting``) and, optionally, without the receiver's own object's spheres.

Exit radiance including the bounce: ``(ρ/π) (L · T + E_R)`` (docs/conventions.md §2 for the first term).

Hierarchy (``cuts=True``, §4.3.3 "Using sphere hierarchies with diffuse reflections"): every level of
every reflecting object gets its own samples (ownership of eq. 4.10 among the spheres of that level,
so the black-sample occlusions of intersecting spheres are valid within a level, as the thesis
requires), and each receiver cluster uses, per object, one level: the coarsest whose spheres all
subtend at most ``threshold`` over the cluster (eq. 4.8). Ratios between levels (eq. 4.34, applied by
eq. 4.35) are computed per frame at each cluster centre. As printed, eq. 4.34 is
``w = (L̃Ṽ)_parent / Σ_children (L̃Ṽ)``; applied to the parent's value by eq. 4.35 it gives
``(L̃Ṽ)²_parent / Σ_children``, which reproduces neither level. The ratio that makes the coarse level
reproduce the detailed one at the cluster centre — what eq. 4.9 does for the shadow logs and what the
text says the ratio is for ("to avoid discontinuities at cluster borders") — is the inverse,
``w = Σ_j (L̃Ṽ)_j / (L̃Ṽ)_parent``; we implement that, with the leaf descendants as the ``S_j`` (as
our eq. 4.9 uses leaves), evaluated with every object at its leaf level, clamped to [0, 4] (1 where
the parent's value is ~0).
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
from .sets import csr
from .tables import sphere_tables


def sample_directions(subdivisions: int = 1) -> np.ndarray:
    """Evenly spaced unit directions: vertices of an icosahedral geodesic sphere (thesis Fig. 4.10), (m, 3)."""
    from ...geometry.shapes import sphere_shape

    return sphere_shape(1.0, subdivisions)[0]


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
        cuts: Per receiver cluster and object, the coarsest hierarchy level whose spheres subtend at most
            ``method.threshold`` (eq. 4.8) instead of the leaves (module docstring); samples are traced
            for every level.
        ratios: With ``cuts``, scale each coarse sphere by the corrected ratio of eq. 4.34 (``"printed"``:
            the equation as printed, for measurements only).
        exclude_intersecting: The thesis' rule for eq. 4.32 (below eq. 4.33): closer spheres of the same
            object that intersect sphere ``i`` are left out of its visibility. Off by default: measured
            less accurate and 2.5x slower (docs/methods/spheres.md).
        self_reflection: Whether receivers get light from their own object's spheres; False needs
            ``receiver_objects``.
        receiver_objects: Object (index into ``method.scene``) of each receiver vertex, shape (V,), int;
            -1 for vertices that take every object's light.
    """

    def __init__(self, method: SpheresTransfer, meshes: list[TriMesh | None], subdivisions: int = 1,
                 exp: str = "ol", cuts: bool = False, ratios: bool | str = True, exclude_intersecting: bool = False,
                 self_reflection: bool = True, receiver_objects: np.ndarray | None = None):
        if len(meshes) != len(method.scene.trees):
            raise ValueError(f"need one mesh (or None) per sphere-set object: {len(method.scene.trees)}, "
                             f"got {len(meshes)}")
        if exp not in EXP_MODES:
            raise ValueError(f"exp must be one of {', '.join(EXP_MODES)}, got {exp!r}")
        self.method, self.exp, self.device = method, exp, method.device
        if ratios not in (True, False, "printed"):
            raise ValueError(f"ratios must be True, False or 'printed', got {ratios!r}")
        self.cuts, self.ratios, self.exclude_intersecting = bool(cuts), ratios, bool(exclude_intersecting)
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
        rows, faces_all, bary_all, owner_obj = [], [], [], []
        for o, (tree, mesh) in enumerate(zip(sc.trees, meshes)):
            if mesh is None:
                continue
            lo = int(sc.offsets[o])
            first = len(rows)
            # one sample set per level, ownership (eq. 4.10) among the spheres of that level
            for lev in (range(tree.num_levels) if self.cuts else [0]):
                sph = np.flatnonzero(tree.level == lev)
                face, bary = self._trace(mesh, tree, sph)
                rows.extend((sph + lo).tolist())
                faces_all.append(face)
                bary_all.append(bary)
                owner_obj.extend([o] * len(sph))
            self.objects.append(dict(obj=o, mesh=mesh, first=first, count=len(rows) - first,
                                     faces=wp.array(mesh.faces, dtype=wp.int32, device=d),
                                     normals=wp.zeros(mesh.num_vertices, dtype=wp.vec3, device=d)))
        self.rows = np.array(rows, dtype=np.int32)
        """Global sphere id of each radiance row (reflecting spheres), shape (L,), int32."""
        self.row_object = np.array(owner_obj, dtype=np.int32)
        L = len(rows)
        self.leaves = self.rows[sc.level[self.rows] == 0] if L else self.rows
        self._row_of = -np.ones(sc.num_spheres, dtype=np.int64)
        self._row_of[self.rows] = np.arange(L)
        self.num_samples = L * m
        self._row_sphere = wp.array(self.rows if L else np.zeros(1, np.int32), dtype=wp.int32, device=d)
        self._row_object = wp.array(self.row_object if L else np.zeros(1, np.int32), dtype=wp.int32, device=d)
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
        """Radiance SH vector of each reflecting sphere (row) per colour, rest frame, shape (L, 3, N*N)."""
        V = method.mesh.num_vertices
        if receiver_objects is None or self_reflection:
            receiver_objects = -np.ones(V, dtype=np.int32)
        receiver_objects = np.asarray(receiver_objects, dtype=np.int32)
        if receiver_objects.shape != (V,):
            raise ValueError(f"receiver_objects must have shape ({V},), got {receiver_objects.shape}")
        self.self_reflection = bool(self_reflection)
        self._recv_obj_np = receiver_objects
        self._recv_obj = wp.array(receiver_objects, dtype=wp.int32, device=d)
        self.irradiance = wp.zeros(V, dtype=wp.vec3, device=d)
        """Reflected irradiance at each receiver vertex (eq. 4.22, no albedo, no 1/π), shape (V,), vec3."""
        ms, mi = csr([np.arange(i * m, (i + 1) * m) for i in range(max(L, 1))])
        self._s_members = (wp.array(ms, dtype=wp.int32, device=d), wp.array(mi, dtype=wp.int32, device=d))
        self._stats = {}
        self._scratch = {}

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

    def shade_samples(self, light, albedo, exit_radiance: list | None = None) -> wp.array:
        """First pass (§4.3.2): re-read the surface samples from the current meshes, shade them with the
        sphere-set shadows and project the white exit radiance times albedo to :attr:`radiance`.

        Args:
            light, albedo: As :meth:`update`.
            exit_radiance: Optional, per object of ``method.scene``, the exit radiance of its vertices
                (albedo included), shape (V_o, 3), e.g. the direct radiance another method already shaded.
                Given, the samples take it (barycentric interpolation) instead of being shaded by sphere-set
                shadows: cheaper, and as exact as that method (the thesis' sphere shadows at the samples
                miss, e.g., a ground plane's shadow on the bottom of a ball resting on it: sphere sets of
                a plane bulge over it and contain the ball's bottom, so the tangent-plane rules drop them).
                ``light`` and ``albedo`` are then unused.

        Returns:
            :attr:`radiance`, shape (L, 3, N*N).
        """
        meth, d = self.method, self.device
        n2 = meth.order * meth.order
        given = exit_radiance is not None
        if given:
            if len(exit_radiance) != len(meth.scene.trees):
                raise ValueError(f"need one exit radiance (or None) per sphere-set object ({len(meth.scene.trees)}), "
                                 f"got {len(exit_radiance)}")
            albedo = exit_radiance
        else:
            light = np.asarray(light, dtype=np.float32)
            if light.shape != (n2, 3):
                raise ValueError(f"light must have shape ({n2}, 3), got {light.shape}")
        if len(albedo) != len(meth.scene.trees):
            raise ValueError(f"need one albedo per sphere-set object ({len(meth.scene.trees)}), got {len(albedo)}")
        L = len(self.rows)
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
                what = "exit radiance" if given else "albedo"
                raise ValueError(f"{ob['mesh'].name}: {what} must be finite RGB (3,) or ({nv}, 3), got {a.shape}")
            k0, k1 = ob["first"], ob["first"] + ob["count"]
            wp.launch(resample_surface, dim=(k1 - k0, m),
                      inputs=[self._face[k0:k1], self._bary[k0:k1], ob["faces"], pts, ob["normals"],
                              wp.array(np.ascontiguousarray(a), dtype=wp.vec3, device=d)],
                      outputs=[self._spts[k0:k1], self._snrm[k0:k1], self._salb[k0:k1]], device=d)
        if not given:
            # shadows at the samples, one cluster per sphere (bounded by the sphere itself)
            spts = self._spts.reshape((L * m,))
            snrm = self._snrm.reshape((L * m,))
            wp.launch(fit_clusters, dim=L, inputs=[*self._s_members, spts], outputs=[self._s_centers, self._s_radii],
                      device=d)
            meth.shade_points(spts, snrm, self._s_cluster, self._s_centers, self._s_radii,
                              self._s_used, self._s_fallback, self._s_vis, self._s_transfer)
            light = wp.array(light, dtype=float, device=d)
        else:
            light = wp.zeros((n2, 3), dtype=float, device=d)
        wp.launch(project_sphere_radiance, dim=(L, 3),
                  inputs=[self._s_transfer, self._face, light, self._salb, self._voronoi, n2, int(given)],
                  outputs=[self.radiance], device=d)
        return self.radiance

    def gather(self, points: wp.array | None = None, normals: wp.array | None = None,
               out: wp.array | None = None) -> wp.array:
        """Second pass (§4.3.3): reflected irradiance (eq. 4.22) at receivers from the current :attr:`radiance`.

        Args:
            points, normals: Receivers, shape (R,), vec3 (default: the method's vertices and clusters,
                output :attr:`irradiance`). Other receivers form one cluster that uses the leaves.
            out: Output for other receivers, shape (R,), vec3 (allocated when None).

        Returns:
            Reflected irradiance (no albedo, no 1/π), shape (R,), vec3.
        """
        meth, d = self.method, self.device
        if points is None:
            points, normals, out = meth.points, meth.normals, self.irradiance
            cluster, recv_obj = meth.cluster, self._recv_obj
            starts, rws, ratio = self._receiver_cuts()
        else:
            if normals is None:
                raise ValueError("gather needs normals with points")
            R = points.shape[0]
            cluster = wp.zeros(R, dtype=wp.int32, device=d)
            recv_obj = wp.array(-np.ones(R, np.int32), dtype=wp.int32, device=d)
            lr = self._row_of[self.leaves].astype(np.int32)
            starts, rws, ratio = np.array([0, len(lr)], np.int32), lr, np.ones(len(lr), np.float32)
        R = points.shape[0]
        if out is None:
            out = wp.zeros(R, dtype=wp.vec3, device=d)
        if len(self.rows) == 0 or len(rws) == 0:
            out.zero_()
            return out
        self._launch(points, normals, cluster, recv_obj, starts, rws, ratio, out, None)
        return out

    def _launch(self, points, normals, cluster, recv_obj, starts, rows, ratio, out, contribution):
        meth, d = self.method, self.device
        R = points.shape[0]
        width = max(int(np.diff(starts).max()), 1)
        scratch = self._scratch.get((R, width))
        if scratch is None:  # reused across frames (cut sizes change little); a few shapes at most
            scratch = self._scratch[(R, width)] = (wp.empty((R, width), dtype=float, device=d),
                                                   wp.empty((R, width), dtype=wp.int32, device=d))
            if len(self._scratch) > 8:
                self._scratch.pop(next(iter(self._scratch)))
        E = max(len(rows), 1)
        rec = contribution if contribution is not None else wp.empty(1, dtype=float, device=d)
        t, sc = meth.tables, meth.scene
        wp.launch(meth._fixed.reflect, dim=R,
                  inputs=[points, normals, cluster, recv_obj, wp.array(starts, dtype=wp.int32, device=d),
                          wp.array(np.resize(rows, E).astype(np.int32), dtype=wp.int32, device=d),
                          wp.array(np.resize(ratio, E).astype(np.float32), dtype=float, device=d),
                          self._row_sphere, self._row_object, sc.centers, sc.radii, sc.rotations,
                          self.radiance, self._log_vec, meth._ff_vec, t.theta_step, meth._cos_vec, meth._fixed.kz,
                          meth._ol, meth._products, EXP_MODES[self.exp], meth.tau, int(self.exclude_intersecting),
                          int(contribution is not None), *scratch],
                  outputs=[out, rec], device=d)

    def _receiver_cuts(self):
        """Per receiver cluster: radiance rows and eq. 4.34 ratios, CSR ``(start (K+1,), rows (E,), ratio (E,))``.

        Without ``cuts`` every cluster uses every reflecting leaf with ratio 1. With ``cuts``, per cluster
        and object the coarsest level whose spheres all subtend <= ``method.threshold`` over the cluster
        (eq. 4.8); the ratios (corrected eq. 4.34, module docstring) from the per-sphere values ``Ṽ L̃`` at
        the cluster centre (mean normal of the cluster, object of its first member).
        """
        meth, sc = self.method, self.method.scene
        K = meth.clusters
        leaf_rows = self._row_of[self.leaves].astype(np.int32)
        cc = meth.cluster_centers.numpy().astype(np.float64)
        cen = sc.centers.numpy().astype(np.float64)

        def presorted(lists):
            # each cluster's rows by distance from its centre: the kernel's insertion sort then shifts little
            out = [np.asarray(x, dtype=np.int32)[np.argsort(np.linalg.norm(cen[self.rows[x]] - cc[k], axis=1),
                                                            kind="stable")] if len(x) else np.zeros(0, np.int32)
                   for k, x in enumerate(lists)]
            start = np.zeros(K + 1, np.int32)
            start[1:] = np.cumsum([len(x) for x in out])
            return start, (np.concatenate(out) if out else np.zeros(0, np.int32)).astype(np.int32)

        if not self.cuts:
            self._stats = {"reflect_spheres_per_cluster": float(len(leaf_rows))}
            start, rows = presorted([leaf_rows] * K)
            return start, rows, np.ones(len(rows), np.float32)
        cr = meth.cluster_radii.numpy().astype(np.float64)
        rad = sc.radii.numpy().astype(np.float64)
        per_cluster = [[] for _ in range(K)]
        leaves_cluster = [[] for _ in range(K)]
        for ob in self.objects:
            rows = np.arange(ob["first"], ob["first"] + ob["count"])
            sph = self.rows[rows]
            lev = sc.level[sph]
            chosen = np.zeros(K, dtype=int)
            for level in range(int(lev.max()), 0, -1):  # coarsest level first
                s = sph[lev == level]
                gap = np.linalg.norm(cen[s][None] - cc[:, None], axis=2) - cr[:, None]
                with np.errstate(divide="ignore", invalid="ignore"):
                    theta = np.where(gap > rad[s][None], np.arcsin(np.clip(rad[s][None] / np.maximum(gap, 1e-300), 0, 1)),
                                     0.5 * np.pi)
                ok = (theta.max(axis=1) <= meth.threshold) & (chosen == 0)
                chosen[ok] = level
            for k in range(K):
                per_cluster[k].extend(rows[lev == chosen[k]].tolist())
                leaves_cluster[k].extend(rows[lev == 0].tolist())
        start, rows = presorted(per_cluster)
        ratio = np.ones(len(rows), np.float32)
        coarse = sc.level[self.rows[rows]] > 0 if len(rows) else np.zeros(0, bool)
        self._stats = {"reflect_spheres_per_cluster": len(rows) / max(K, 1),
                       "reflect_coarse_entries": int(coarse.sum())}
        if self.ratios and coarse.any():
            ratio = self._ratios(cc, start, rows, leaves_cluster)
        return start, rows, ratio

    def _ratios(self, cc, start, rows, leaves_cluster) -> np.ndarray:
        """Corrected eq. 4.34 per cut entry: Σ over leaf descendants of ``Ṽ L̃`` / the entry's own ``Ṽ L̃``."""
        meth, sc, d = self.method, self.method.scene, self.device
        K = len(cc)
        lab = meth.cluster.numpy()
        first = np.array([np.flatnonzero(lab == k)[0] for k in range(K)])
        nrm = np.zeros((K, 3))
        np.add.at(nrm, lab, meth.normals.numpy().astype(np.float64))
        ln = np.linalg.norm(nrm, axis=1)
        nrm = np.where(ln[:, None] > 0, nrm / np.maximum(ln, 1e-300)[:, None], [0.0, 0.0, 1.0])
        pts = wp.array(cc.astype(np.float32), dtype=wp.vec3, device=d)
        nw = wp.array(nrm.astype(np.float32), dtype=wp.vec3, device=d)
        clu = wp.array(np.arange(K, dtype=np.int32), dtype=wp.int32, device=d)
        obj = wp.array(self._recv_obj_np[first], dtype=wp.int32, device=d)
        out = wp.zeros(K, dtype=wp.vec3, device=d)
        coarse = wp.zeros(max(len(rows), 1), dtype=float, device=d)
        self._launch(pts, nw, clu, obj, start, rows, np.ones(len(rows), np.float32), out, coarse)
        ls = np.zeros(K + 1, np.int32)
        ls[1:] = np.cumsum([len(x) for x in leaves_cluster])
        lrows = np.array([r for x in leaves_cluster for r in x], dtype=np.int32)
        fine = wp.zeros(max(len(lrows), 1), dtype=float, device=d)
        self._launch(pts, nw, clu, obj, ls, lrows, np.ones(len(lrows), np.float32), out, fine)
        coarse, fine = coarse.numpy(), fine.numpy()
        ratio = np.ones(len(rows), np.float32)
        for k in range(K):
            leaf_value = dict(zip(self.rows[lrows[ls[k]:ls[k + 1]]].tolist(), fine[ls[k]:ls[k + 1]].tolist()))
            for e in range(start[k], start[k + 1]):
                s = int(self.rows[rows[e]])
                if sc.level[s] == 0:
                    continue
                num = sum(leaf_value.get(int(j), 0.0) for j in sc.leaf_index[sc.leaf_start[s]:sc.leaf_start[s + 1]])
                den = float(coarse[e])
                scale = max(abs(den), abs(num))
                if scale > 0 and abs(den) > 1e-6 * scale and abs(num) > 1e-6 * scale:
                    # "printed": eq. 4.34 as printed (inverted), kept only to measure that it is wrong
                    r = den / num if self.ratios == "printed" else num / den
                    ratio[e] = float(np.clip(r, 0.0, 4.0))
        return ratio

    def stats(self) -> dict:
        """Counters of the last :meth:`gather` at the method's receivers (spheres per cluster cut...)."""
        return dict(self._stats)
