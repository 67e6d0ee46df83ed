"""Sphere sets on the device: several blocker objects' hierarchies in one array, refitted every frame.

:class:`SphereScene` concatenates the :class:`~.fitting.SphereTree` of each blocker object (global
sphere index = object offset + local index), moves every sphere with its object's current vertices
(kernels ``refit_spheres``/``bound_parents``), and chooses per receiver cluster the cut of eq. 4.8
(Ren et al.'s adaptive cut: a sphere whose maximum angular radius over the cluster exceeds the
threshold is replaced by its children).
"""

from __future__ import annotations

import numpy as np
import warp as wp

from .fitting import SphereTree
from .kernels import bound_parents, refit_spheres, refit_spheres_bones


def csr(lists):
    """Lists of indices in compressed rows: ``(start, index)``, int32, list ``i`` being
    ``index[start[i]:start[i + 1]]``; shapes (len(lists) + 1,) and (total,)."""
    start = np.zeros(len(lists) + 1, dtype=np.int32)
    start[1:] = np.cumsum([len(x) for x in lists])
    index = np.concatenate([np.asarray(x, dtype=np.int32) for x in lists]) if lists else np.zeros(0, np.int32)
    return start, index.astype(np.int32)


class SphereScene:
    """Blocker sphere hierarchies of several objects, on the device.

    Args:
        trees: One :class:`SphereTree` per blocker object.
        rest_points: Each object's rest-pose vertex positions [m], shape (V_o, 3) (the pose it was fitted in).
        device: Warp device.
    """

    def __init__(self, trees: list[SphereTree], rest_points: list[np.ndarray], device: str = "cpu"):
        if len(trees) != len(rest_points):
            raise ValueError(f"{len(trees)} sphere trees but {len(rest_points)} rest point sets")
        self.device = device
        self.trees = trees
        self.offsets = np.cumsum([0] + [t.num_spheres for t in trees])
        S = int(self.offsets[-1])
        self.num_spheres = S
        self.object = np.concatenate([np.full(t.num_spheres, i) for i, t in enumerate(trees)]) if trees else np.zeros(0)
        self.level = np.concatenate([t.level for t in trees]) if trees else np.zeros(0, int)
        parent = [np.where(t.parent >= 0, t.parent + o, -1) for t, o in zip(trees, self.offsets)]
        self.parent = np.concatenate(parent) if trees else np.zeros(0, int)
        self.children = [[] for _ in range(S)]
        for s, p in enumerate(self.parent):
            if p >= 0:
                self.children[p].append(s)
        self.child_start, self.child_index = csr(self.children)
        self.has_children = np.diff(self.child_start) > 0
        self.roots = np.flatnonzero(self.parent < 0)
        leaves = []
        for t, o in zip(trees, self.offsets):
            leaves += [(t.leaf_descendants(s) + o).tolist() for s in range(t.num_spheres)]
        self.leaf_start, self.leaf_index = csr(leaves)
        self.centers = wp.zeros(S, dtype=wp.vec3, device=device)
        """Current sphere centres [m], shape (S,), dtype vec3 (all objects, all levels)."""
        self.radii = wp.zeros(S, dtype=float, device=device)
        """Current sphere radii [m], shape (S,), dtype float32."""
        self.rotations = wp.zeros(S, dtype=wp.mat33, device=device)
        """Rotation of each sphere since the rest pose (Kabsch fit of its vertices), shape (S,), dtype mat33."""
        self._obj = []
        for t, o, rp in zip(trees, self.offsets, rest_points):
            rp = np.asarray(rp, dtype=np.float64)
            cent = np.array([rp[t.vertices_of(s)].mean(axis=0) for s in range(t.num_spheres)])
            spread = np.array([np.linalg.norm(rp[t.vertices_of(s)] - t.centers[s], axis=1).max()
                               for s in range(t.num_spheres)])
            tc, ti = csr([np.asarray(t.children(s)) for s in range(t.num_spheres)])
            levels = [wp.array(np.flatnonzero(t.level == lev).astype(np.int32), dtype=wp.int32, device=device)
                      for lev in range(1, t.num_levels)]
            self._obj.append(dict(
                start=wp.array(t.vert_start.astype(np.int32), dtype=wp.int32, device=device),
                index=wp.array(t.vert_index.astype(np.int32), dtype=wp.int32, device=device),
                rest=wp.array(rp.astype(np.float32), dtype=wp.vec3, device=device),
                centroid=wp.array(cent.astype(np.float32), dtype=wp.vec3, device=device),
                offset=wp.array((t.centers - cent).astype(np.float32), dtype=wp.vec3, device=device),
                radius=wp.array(t.radii.astype(np.float32), dtype=float, device=device),
                spread=wp.array(spread.astype(np.float32), dtype=float, device=device),
                child_start=wp.array(tc, dtype=wp.int32, device=device),
                child_index=wp.array(ti, dtype=wp.int32, device=device),
                levels=levels, lo=int(o), n=t.num_spheres, nv=len(rp)))
        self.refit([None] * len(trees))

    def bind_bones(self, obj: int, joint_indices, joint_weights, num_joints: int, influences: int = 8) -> None:
        """Let object ``obj``'s spheres follow skinning bones instead of their vertices (see :meth:`refit`).

        Each sphere takes the mean skinning weights of the vertices it was fitted to (its own vertices,
        ``SphereTree.vertices_of``) and is skinned like a vertex at its rest centre; its radius grows by
        the bound of kernel ``refit_spheres_bones`` so it keeps bounding those vertices (exactly for
        rigid bone transforms).

        Args:
            obj: Object index (order of ``trees``).
            joint_indices, joint_weights: The mesh's LBS influences, shape (V_o, K) (as
                :class:`warpshade.sim.LBSSkinner`; rest pose = the pose the tree was fitted in).
            num_joints: Number of joints J of the transforms that :meth:`refit` will get.
            influences: Most joints per sphere (a leaf whose vertices have more raises ValueError: its
                radius bound needs every joint; parents keep their strongest and are grown over their
                children by ``bound_parents``).
        """
        o, tree = self._obj[obj], self.trees[obj]
        idx = np.asarray(joint_indices, dtype=np.int64).reshape(o["nv"], -1)
        w = np.asarray(joint_weights, dtype=np.float64).reshape(o["nv"], -1)
        if idx.shape != w.shape or (idx < 0).any() or (idx >= num_joints).any() or not np.isfinite(w).all():
            raise ValueError(f"object {obj}: joint indices/weights must be ({o['nv']}, K) with indices in "
                             f"0..{num_joints - 1} and finite weights")
        tot = w.sum(axis=1, keepdims=True)
        if (tot <= 0).any():
            raise ValueError(f"object {obj}: vertex {int(np.flatnonzero(tot <= 0)[0])} has no joint influence")
        w = w / tot  # as LBSSkinner
        S, K = tree.num_spheres, min(int(influences), num_joints)
        sj, sw, sd = np.zeros((S, K), np.int32), np.zeros((S, K), np.float32), np.zeros((S, K), np.float32)
        for s in range(S):
            v = tree.vertices_of(s)
            dense = np.zeros((len(v), num_joints))  # per-vertex weight of every joint
            np.add.at(dense, (np.repeat(np.arange(len(v)), idx.shape[1]), idx[v].ravel()), w[v].ravel())
            mean = dense.mean(axis=0)
            used = np.flatnonzero(dense.max(axis=0) > 0)
            if tree.level[s] > 0:
                # parents: centre from their strongest joints; bound_parents then grows them over their
                # children, which bound the vertices
                used = used[np.argsort(-mean[used], kind="stable")[:K]]
                sj[s, :len(used)], sw[s, :len(used)] = used, mean[used] / mean[used].sum()
                continue
            if len(used) > K:
                raise ValueError(f"object {obj}: leaf sphere {s}'s vertices have {len(used)} joints, more than "
                                 f"influences={K}")
            sj[s, :len(used)], sw[s, :len(used)] = used, mean[used]
            sd[s, :len(used)] = np.abs(dense[:, used] - mean[used]).max(axis=0)
        d = self.device
        o["bones"] = dict(joint=wp.array(sj, dtype=wp.int32, device=d), weight=wp.array(sw, dtype=float, device=d),
                          spread=wp.array(sd, dtype=float, device=d),
                          center=wp.array(tree.centers.astype(np.float32), dtype=wp.vec3, device=d),
                          radius=wp.array(tree.radii.astype(np.float32), dtype=float, device=d), joints=int(num_joints))

    def refit(self, points: list, transforms: list | None = None) -> None:
        """Move every object's spheres with its vertices (None: keep that object at the rest pose), or, for
        objects bound with :meth:`bind_bones` and given ``transforms``, with its bones.

        Args:
            points: Per object, current vertex positions: a (V_o,) vec3 ``wp.array``, a (V_o, 3) array, or None.
            transforms: Optional, per object, skinning transforms (J, 4, 4) (column-vector convention of
                :class:`warpshade.sim.LBSSkinner`) or a (J,) mat44 ``wp.array``, or None.
        """
        transforms = transforms if transforms is not None else [None] * len(self._obj)
        for o, pts, xf in zip(self._obj, points, transforms):
            if xf is not None and "bones" in o:
                self._refit_bones(o, xf)
                continue
            if pts is None:
                pts = o["rest"]
            elif not isinstance(pts, wp.array):
                pts = np.asarray(pts, dtype=np.float32)
                if pts.shape != (o["nv"], 3):
                    raise ValueError(f"blocker points must have shape ({o['nv']}, 3), got {pts.shape}")
                pts = wp.array(pts, dtype=wp.vec3, device=self.device)
            lo, n = o["lo"], o["n"]
            c, r, rot = self.centers[lo:lo + n], self.radii[lo:lo + n], self.rotations[lo:lo + n]
            wp.launch(refit_spheres, dim=n,
                      inputs=[o["start"], o["index"], o["rest"], pts, o["centroid"], o["offset"], o["radius"],
                              o["spread"]],
                      outputs=[c, r, rot], device=self.device)
            for lev in o["levels"]:
                wp.launch(bound_parents, dim=lev.shape[0], inputs=[o["child_start"], o["child_index"], lev],
                          outputs=[c, r], device=self.device)

    def select_cuts(self, cluster_centers: np.ndarray, cluster_radii: np.ndarray, threshold: float,
                    objects: np.ndarray | None = None):
        """Per cluster, the spheres to use (eq. 4.8: θ_max = asin(r_s / (|x_s - x_c| - r_c))).

        Starting from the roots, a sphere whose θ_max exceeds ``threshold`` (or that overlaps the
        cluster's bounding sphere) is replaced by its children; leaves are always accepted.

        Args:
            objects: Optional boolean mask over objects; spheres of masked-out objects are skipped.

        Returns:
            ``(cut_start (K+1,), cut_sphere (E,), cut_cluster (E,))``, int32, grouped by cluster.
        """
        cen = self.centers.numpy().astype(np.float64)
        rad = self.radii.numpy().astype(np.float64)
        K = len(cluster_radii)
        roots = self.roots if objects is None else self.roots[objects[self.object[self.roots]]]
        kk = np.repeat(np.arange(K), len(roots))
        ss = np.tile(roots, K)
        out_k, out_s = [], []
        while len(ss):
            gap = np.linalg.norm(cen[ss] - cluster_centers[kk], axis=1) - cluster_radii[kk]
            with np.errstate(divide="ignore", invalid="ignore"):
                theta = np.where(gap > rad[ss], np.arcsin(np.clip(rad[ss] / np.maximum(gap, 1e-300), 0, 1)),
                                 0.5 * np.pi)
            down = (theta > threshold) & self.has_children[ss]
            out_k.append(kk[~down])
            out_s.append(ss[~down])
            kk, ss = kk[down], ss[down]
            cnt = self.child_start[ss + 1] - self.child_start[ss]
            kk = np.repeat(kk, cnt)
            ss = np.concatenate([self.child_index[self.child_start[s]:self.child_start[s + 1]] for s in ss]) \
                if len(ss) else np.zeros(0, np.int64)
        k = np.concatenate(out_k) if out_k else np.zeros(0, int)
        s = np.concatenate(out_s) if out_s else np.zeros(0, int)
        order = np.lexsort((s, k))
        k, s = k[order], s[order]
        start = np.zeros(K + 1, dtype=np.int32)
        start[1:] = np.cumsum(np.bincount(k, minlength=K))
        return start, s.astype(np.int32), k.astype(np.int32)

    def _refit_bones(self, o: dict, transforms) -> None:
        b = o["bones"]
        if not isinstance(transforms, wp.array):
            m = np.asarray(transforms, dtype=np.float32)
            if m.shape != (b["joints"], 4, 4) or not np.isfinite(m).all():
                raise ValueError(f"bone transforms must be finite, shape ({b['joints']}, 4, 4), got {m.shape}")
            transforms = wp.array(m, dtype=wp.mat44, device=self.device)
        lo, n = o["lo"], o["n"]
        c, r, rot = self.centers[lo:lo + n], self.radii[lo:lo + n], self.rotations[lo:lo + n]
        wp.launch(refit_spheres_bones, dim=n, inputs=[b["joint"], b["weight"], b["spread"], b["center"], b["radius"], transforms],
                  outputs=[c, r, rot], device=self.device)
        for lev in o["levels"]:
            wp.launch(bound_parents, dim=lev.shape[0], inputs=[o["child_start"], o["child_index"], lev],
                      outputs=[c, r], device=self.device)
