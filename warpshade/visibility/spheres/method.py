"""Sphere-set soft shadows by SH exponentiation (Ren et al. 2006, thesis ch. 4) as a :class:`TransferMethod`.

Build once: fit a bounding sphere hierarchy to every blocker object (its own mesh for self-shadowing,
plus ``blockers`` for shadows from other objects), cluster the receiver vertices, load the tables.
Per frame (:meth:`SpheresTransfer.update`): refit spheres to the current vertices, bound the clusters,
choose cuts (eq. 4.8), ratio vectors (eq. 4.9), then per vertex the visibility and the diffuse transfer
of docs/conventions.md §2. Between objects, :meth:`SpheresTransfer.shadow` multiplies another method's
self-shadowed transfer by this visibility (visibilities multiply, eq. 4.5).
"""

from __future__ import annotations

import math

import numpy as np
import warp as wp

from ...geometry.mesh import TriMesh
from ...sh.kernels import ol_table_arrays, product_table_arrays, zh_normalization_array
from ...sh.zonal import clamped_cosine_zh
from ..base import TransferMethod
from ..knobs import Knob
from .fitting import SphereTree, build_sphere_tree, cluster_receivers
from .fixed_kernels import shade_kernel_fixed
from .kernels import EXP_HYBRID, EXP_OL, EXP_SERIES, compute_cut_ratios, fit_clusters, multiply_transfer
from .sets import SphereScene, csr
from .tables import sphere_tables

EXP_MODES = {"ol": EXP_OL, "hyb": EXP_HYBRID, "series": EXP_SERIES}


def auto_clusters(num_vertices: int) -> int:
    """Default receiver cluster count: about 800 vertices per cluster (thesis: 33k vertices, 40 clusters)."""
    return int(min(64, max(1, round(num_vertices / 800))))


class SpheresTransfer(TransferMethod):
    """Diffuse transfer with visibility from sphere sets (self-shadowing and/or shadows from other objects).

    Args:
        mesh: Receiver mesh (also a blocker of itself when ``self_shadow``).
        order: SH order.
        device: Warp device.
        spheres: Leaf spheres fitted to each mesh.
        levels: Hierarchy levels (1 = leaves only).
        threshold: Cut threshold on the maximum angular radius over a cluster [rad] (eq. 4.8).
        exp: SH exponential: ``"hyb"`` (default), ``"ol"`` (optimal linear) or ``"series"`` (Taylor
            with scaling/squaring; slow, accurate).
        clusters: Receiver clusters (0: about one per 800 vertices).
        tau: Hybrid exponential: largest ``||f̂||`` handed to the optimal-linear step before squaring.
        seed: Random seed of the fits and clustering.
        self_shadow: Whether the receiver's own spheres shadow it (False when another method, e.g.
            hemispherical rasterization, does self-shadowing and this one adds other objects).
        blockers: Other objects that cast shadows on ``mesh``: :class:`TriMesh` (fitted here with the
            same knobs) or ``(SphereTree, rest_points)`` pairs.
        ratios: Apply the ratio vectors of eq. 4.9 to cut spheres above the leaves (off only to measure
            what they do).
        self_tree: A sphere tree already fitted to ``mesh`` (rest pose), to skip the fit.
    """

    name = "spheres"
    KNOBS = (
        Knob("spheres", int, "leaf spheres per object", minimum=1),
        Knob("levels", int, "sphere hierarchy levels incl. leaves", minimum=1),
        Knob("threshold", float, "cut threshold on a sphere's max angular radius over a cluster [rad] (eq. 4.8)"),
        Knob("exp", str, "SH exponential: hyb, ol (optimal linear), series (accurate, slow)",
             choices=tuple(sorted(EXP_MODES))),
        Knob("clusters", int, "receiver clusters (0: ~800 vertices each)", minimum=0),
        Knob("seed", int, "random seed of the sphere fit and clustering"),
        Knob("tau", float, "tau of the SH exponential's tables", cli=False),
        Knob("self_shadow", bool, "the receiver's own sphere tree shadows it", cli=False),
        Knob("ratios", bool, "ratio vectors of eq. 4.9 on cut spheres above the leaves", cli=False),
    )

    def __init__(self, mesh: TriMesh, order: int = 5, device: str = "cpu", spheres: int = 30, levels: int = 3,
                 threshold: float = 0.5, exp: str = "hyb", clusters: int = 0, tau: float = 0.5, seed: int = 0,
                 self_shadow: bool = True, blockers: list | None = None, ratios: bool = True,
                 self_tree: SphereTree | None = None):
        super().__init__(mesh, order, device)
        if exp not in EXP_MODES:
            raise ValueError(f"exp must be one of {', '.join(EXP_MODES)}, got {exp!r}")
        if not 0.0 < threshold <= 0.5 * math.pi:
            raise ValueError(f"threshold must be in (0, pi/2] rad, got {threshold}")
        if tau <= 0:
            raise ValueError(f"tau must be > 0, got {tau}")
        self.spheres, self.levels, self.threshold, self.exp = int(spheres), int(levels), float(threshold), exp
        self.tau, self.seed, self.self_shadow = float(tau), int(seed), bool(self_shadow)
        self.ratios = bool(ratios)
        self.clusters = int(clusters) if clusters else auto_clusters(mesh.num_vertices)
        trees, rests = [], []
        if self_shadow:
            trees.append(self_tree if self_tree is not None else
                         build_sphere_tree(mesh.points, mesh.faces, spheres, levels, seed=seed, device=device))
            rests.append(mesh.points)
        for b in blockers or []:
            if isinstance(b, TriMesh):
                trees.append(build_sphere_tree(b.points, b.faces, spheres, levels, seed=seed, device=device))
                rests.append(b.points)
            else:
                tree, rest = b
                if not isinstance(tree, SphereTree):
                    raise TypeError(f"blockers must be TriMesh or (SphereTree, rest_points), got {type(b).__name__}")
                trees.append(tree)
                rests.append(np.asarray(rest))
        self.num_blockers = len(blockers or [])
        self.scene = SphereScene(trees, rests, device)
        lab = cluster_receivers(mesh.points, self.clusters, seed=seed)
        self.clusters = int(lab.max()) + 1
        self.cluster = wp.array(lab.astype(np.int32), dtype=wp.int32, device=device)
        ms, mi = csr([np.flatnonzero(lab == k) for k in range(self.clusters)])
        self._members = (wp.array(ms, dtype=wp.int32, device=device), wp.array(mi, dtype=wp.int32, device=device))
        self.cluster_centers = wp.zeros(self.clusters, dtype=wp.vec3, device=device)
        self.cluster_radii = wp.zeros(self.clusters, dtype=float, device=device)
        self._load_tables()
        V, n2 = mesh.num_vertices, self.order * self.order
        self.visibility = wp.zeros((V, n2), dtype=float, device=device)
        """Sphere-set visibility, shape (V, N*N), dtype float32, world space (eq. 4.7)."""
        self._leaf_start = wp.array(self.scene.leaf_start, dtype=wp.int32, device=device)
        self._leaf_index = wp.array(self.scene.leaf_index, dtype=wp.int32, device=device)
        self.fallback = wp.zeros(V, dtype=wp.int32, device=device)
        """1 where the exponential diverged and the geometric-mean visibility was used (last update)."""
        self.used = wp.zeros(V, dtype=wp.int32, device=device)
        """Spheres that contributed at each vertex in the last update, shape (V,), int32."""
        self._blocker_points = [None] * len(trees)
        self._bone_transforms = None
        self._stats = {}

    def _load_tables(self):
        d = self.device
        t = sphere_tables(self.order, self.exp, self.tau)
        self.tables = t
        self._kz = zh_normalization_array(self.order, d)
        self._log = wp.array(t.log_blocker.astype(np.float32), dtype=float, device=d)
        self._ol = ol_table_arrays(self.order, d)
        self._products = product_table_arrays(self.order, d)
        self._ones = wp.array(np.ones((1, self.order), np.float32), dtype=float, device=d)
        # Per-receiver kernels are compiled per order with SH vectors in registers (fixed_kernels.py).
        self._fixed = shade_kernel_fixed(self.order)
        self._log_vec = wp.array(t.log_blocker.astype(np.float32), dtype=self._fixed.vec_zh, device=d)
        self._ff_vec = wp.array(t.form_factor.astype(np.float32), dtype=self._fixed.vec_zh, device=d)
        self._cos_vec = self._fixed.vec_zh(*clamped_cosine_zh(self.order).astype(np.float32).tolist())

    # -- command line ------------------------------------------------------------------------
    @classmethod
    def sweep(cls, quick: bool = False) -> list[dict]:
        base = {"spheres": 30, "levels": 3, "threshold": 0.5, "exp": "hyb"}
        if quick:
            return [base, {**base, "exp": "ol"}, {**base, "spheres": 60}]
        return [base, {**base, "exp": "ol"}, {**base, "exp": "series"}, {**base, "spheres": 15},
                {**base, "spheres": 60}, {**base, "threshold": 0.3}, {**base, "threshold": 0.8}]

    def _extra_knobs(self) -> dict:
        return {"blockers": self.num_blockers}

    def stats(self) -> dict:
        return dict(self._stats)

    # -- per frame ---------------------------------------------------------------------------
    def update(self, points=None, normals=None, blocker_points: list | None = None,
               bone_transforms: list | None = None) -> wp.array:
        """Recompute :attr:`visibility` and :attr:`transfer`.

        Args:
            points: Receiver positions (None: unchanged); normals recomputed when not given.
            normals: Optional receiver unit normals.
            blocker_points: Current vertices of each object in ``blockers`` (list aligned with it; None
                entries stay where they were). The receiver's own spheres follow ``points``.
            bone_transforms: Optional, per sphere-set object (own mesh first when ``self_shadow``, then
                ``blockers``), skinning transforms (J, 4, 4) for objects bound with :meth:`bind_bones`
                (their spheres then follow the bones, not the points), or None.
        """
        self._set_blockers(blocker_points, bone_transforms)
        return super().update(points, normals)

    def bind_bones(self, obj: int, joint_indices, joint_weights, num_joints: int, influences: int = 8) -> None:
        """Spheres of object ``obj`` (own mesh first when ``self_shadow``, then ``blockers``) follow skinning
        bones (:meth:`SphereScene.bind_bones`) whenever :meth:`update` gets its ``bone_transforms``."""
        self.scene.bind_bones(obj, joint_indices, joint_weights, num_joints, influences)

    def move(self, points=None, normals=None, blocker_points: list | None = None,
             bone_transforms: list | None = None) -> None:
        """Move receivers and spheres to the current frame without computing shadows (:meth:`update` minus
        the per-receiver shading): what :class:`~.reflections.SphereReflections` needs when another method
        shades the receivers' direct light. Arguments as :meth:`update`."""
        self._set_blockers(blocker_points, bone_transforms)
        if points is not None:
            self.set_points(points, normals)
        self._refit()
        wp.launch(fit_clusters, dim=self.clusters, inputs=[*self._members, self.points],
                  outputs=[self.cluster_centers, self.cluster_radii], device=self.device)

    def _set_blockers(self, blocker_points, bone_transforms=None) -> None:
        if bone_transforms is not None:
            if len(bone_transforms) != len(self.scene.trees):
                raise ValueError(f"expected {len(self.scene.trees)} bone transform entries (one per sphere-set "
                                 f"object), got {len(bone_transforms)}")
            self._bone_transforms = list(bone_transforms)
        if blocker_points is not None:
            if len(blocker_points) != self.num_blockers:
                raise ValueError(f"expected {self.num_blockers} blocker point sets, got {len(blocker_points)}")
            off = 1 if self.self_shadow else 0
            for i, b in enumerate(blocker_points):
                if b is not None:
                    self._blocker_points[off + i] = b

    def _refit(self) -> None:
        if self.self_shadow:
            self._blocker_points[0] = self.points
        self.scene.refit(self._blocker_points, self._bone_transforms)

    def _compute(self) -> None:
        d = self.device
        self._refit()
        wp.launch(fit_clusters, dim=self.clusters, inputs=[*self._members, self.points],
                  outputs=[self.cluster_centers, self.cluster_radii], device=d)
        ncut = self.shade_points(self.points, self.normals, self.cluster, self.cluster_centers, self.cluster_radii,
                                 self.used, self.fallback, self.visibility, self.transfer)
        sc = self.scene
        self._stats = {"cut_spheres_per_cluster": float(ncut) / self.clusters,
                       "leaf_spheres": int((sc.level == 0).sum()), "total_spheres": sc.num_spheres,
                       "clusters": self.clusters, "exp_fallbacks": int(self.fallback.numpy().sum())}

    def shade_points(self, points, normals, cluster, cluster_centers, cluster_radii, used, fallback, visibility,
                     transfer) -> int:
        """Sphere-set visibility and transfer of any receiver points against the current (refitted) spheres.

        Used for the mesh vertices and for the surface samples of the reflection pass.

        Args:
            points, normals: Receivers, shape (R,), vec3.
            cluster: Cluster of each receiver, shape (R,), int32.
            cluster_centers, cluster_radii: Cluster bounding spheres, shape (K,), vec3 / float32.
            used, fallback: Per-receiver counters, shape (R,), int32.
            visibility, transfer: Outputs, shape (R, N*N), float32.

        Returns:
            Number of cut entries (spheres summed over clusters).
        """
        d = self.device
        start, sph, clu = self.scene.select_cuts(cluster_centers.numpy().astype(np.float64),
                                                 cluster_radii.numpy().astype(np.float64), self.threshold)
        E = max(len(sph), 1)
        cut_start = wp.array(start, dtype=wp.int32, device=d)
        cut_sphere = wp.array(np.resize(sph, E) if len(sph) else np.zeros(1, np.int32), dtype=wp.int32, device=d)
        cut_cluster = wp.array(np.resize(clu, E) if len(clu) else np.zeros(1, np.int32), dtype=wp.int32, device=d)
        cut_ratio = wp.array(np.ones((E, self.order), np.float32), dtype=float, device=d)
        n2 = self.order * self.order
        sc = self.scene
        if len(sph) and self.ratios:
            buf = [wp.zeros((E, self.order), dtype=float, device=d)] + \
                [wp.zeros((E, n2), dtype=float, device=d) for _ in range(2)]
            wp.launch(compute_cut_ratios, dim=len(sph),
                      inputs=[cut_cluster, cut_sphere, cluster_centers, sc.centers, sc.radii,
                              self._leaf_start, self._leaf_index, self._log, self.tables.theta_step, self._ones,
                              self.order, self._kz, *buf],
                      outputs=[cut_ratio], device=d)
        t = self.tables
        wp.launch(self._fixed.shade, dim=points.shape[0],
                  inputs=[points, normals, cluster, sc.centers, sc.radii, cut_start, cut_sphere, cut_ratio,
                          self._log_vec, t.theta_step, self._cos_vec, self._fixed.kz, self._ol, self._products,
                          EXP_MODES[self.exp],
                          self.tau],
                  outputs=[used, fallback, visibility, transfer], device=d)
        self._cut = (cut_start, cut_sphere, cut_ratio)
        return len(sph)

    def spheres_used(self) -> np.ndarray:
        """Spheres that contributed at each vertex in the last update, shape (V,), int."""
        return self.used.numpy()

    # -- between objects ---------------------------------------------------------------------
    def shadow(self, transfer_in: wp.array, out: wp.array | None = None) -> wp.array:
        """Multiply another method's transfer (e.g. hemispherical-raster self-shadowing) by :attr:`visibility`.

        Call after :meth:`update`. ``T_i = ∫ y_i V_self cos · V_spheres`` is approximated by the SH product
        of the two (visibilities multiply, eq. 4.5); construct this method with ``self_shadow=False`` so
        the receiver's own geometry is not counted twice.

        Args:
            transfer_in: Transfer of the same vertices, shape (V, N*N), dtype float32.
            out: Optional output of the same shape (may not alias ``transfer_in``).

        Returns:
            ``out`` (allocated when None), shape (V, N*N).
        """
        V, n2 = self.mesh.num_vertices, self.order * self.order
        if tuple(transfer_in.shape) != (V, n2):
            raise ValueError(f"transfer_in must have shape ({V}, {n2}), got {tuple(transfer_in.shape)}")
        if out is None:
            out = wp.zeros((V, n2), dtype=float, device=self.device)
        wp.launch(multiply_transfer, dim=V, inputs=[transfer_in, self.visibility, self._products, self.order],
                  outputs=[out], device=self.device)
        return out
