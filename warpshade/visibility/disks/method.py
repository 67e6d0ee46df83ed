"""Disk-hierarchy anisotropic occlusion (Gong et al. 2006, with Bunnell's disk form factors).

Every vertex becomes a disk (position, normal, one-ring area) each frame; a binary spatial tree
over the rest pose (built once: median splits along the longest axis, the "bi-tree" of the paper
grouping nearby disks) gets parent disks averaged from their children every frame. Per receiver
vertex the tree is walked with level of detail by distance, and each disk's coverage is binned into
the paper's 16 hemisphere directions (eq. 5). Bunnell's two passes correct for overlapping occluders.
The binned occlusion becomes the SH diffuse transfer of docs/conventions.md §2, and gives visibility toward
directional, point and spot lights.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ...geometry.mesh import TriMesh, surface_neighbours
from ...sh.kernels import normalization_array, zh_normalization_array
from ...sh.zonal import clamped_cosine_zh
from ..base import TransferMethod
from ..knobs import Knob
from .kernels import (BINS, STACK, accumulate_disk_areas, accumulate_occlusion, combine_passes,
                      integrate_disk_transfer, lookup_light_visibility, merge_child_access, merge_child_disks,
                      set_leaf_access, set_leaf_disks)


def tie_groups(x: np.ndarray, tol: float) -> np.ndarray:
    """Rank of each value of ``x`` among its distinct values, values closer than ``tol`` to a neighbour counting
    as one (chains of such neighbours too), shape (len(x),) int64."""
    order = np.argsort(x, kind="stable")
    out = np.empty(len(x), np.int64)
    out[order] = np.concatenate([[0], np.cumsum(np.diff(x[order]) > tol)])
    return out


def build_disk_tree(points: np.ndarray) -> dict:
    """Binary tree over points by median splits along the longest bounding-box axis.

    Returns:
        ``left``, ``right`` (N,) int32 child indices (-1 for leaves), ``node_vertex`` (N,) int32
        (the vertex of a leaf, -1 otherwise), ``leaf_of_vertex`` (V,) int32, ``levels``: list of
        int32 arrays of internal nodes, deepest level first (the bottom-up update order), with
        N = 2V - 1 nodes and node 0 the root.
    """
    p = np.asarray(points, dtype=np.float64)
    nv = len(p)
    n_nodes = 2 * nv - 1
    left = np.full(n_nodes, -1, np.int32)
    right = np.full(n_nodes, -1, np.int32)
    node_vertex = np.full(n_nodes, -1, np.int32)
    depth = np.zeros(n_nodes, np.int32)
    next_id = 1
    todo = [(0, np.arange(nv))]
    while todo:
        node, idx = todo.pop()
        if len(idx) == 1:
            node_vertex[node] = idx[0]
            continue
        ext = p[idx].max(axis=0) - p[idx].min(axis=0)
        # ties (common on grid-like meshes) go to the lowest axis, with a tolerance so that float
        # rounding of a scaled copy of the mesh builds the same tree
        axis = int(np.flatnonzero(ext >= ext.max() * (1.0 - 1e-5))[0])
        # order along the axis, then the other two; coordinates equal up to rounding tie (exactly equal ones
        # on grid-like meshes stay tied when rounded differently), then the vertex index decides
        tol = 1e-6 * max(float(ext.max()), float(np.abs(p[idx]).max()))
        keys = [tie_groups(p[idx, (axis + k) % 3], tol) for k in (2, 1, 0)]
        order = idx[np.lexsort([idx] + keys)]
        half = len(order) // 2
        left[node], right[node] = next_id, next_id + 1
        depth[next_id] = depth[next_id + 1] = depth[node] + 1
        todo.append((next_id, order[:half]))
        todo.append((next_id + 1, order[half:]))
        next_id += 2
    leaf_of_vertex = np.empty(nv, np.int32)
    leaves = np.flatnonzero(node_vertex >= 0)
    leaf_of_vertex[node_vertex[leaves]] = leaves
    internal = np.flatnonzero(left >= 0)
    levels = [internal[depth[internal] == d].astype(np.int32) for d in range(int(depth.max()), -1, -1)]
    levels = [lv for lv in levels if len(lv)]
    if int(depth.max()) + 2 > STACK:
        raise ValueError(f"disk tree depth {int(depth.max())} exceeds the traversal stack ({STACK})")
    return {"left": left, "right": right, "node_vertex": node_vertex, "leaf_of_vertex": leaf_of_vertex,
            "levels": levels}


class DiskTransfer(TransferMethod):
    """Disk-hierarchy anisotropic occlusion turned into SH diffuse transfer.

    Args:
        mesh: Receiver mesh (also the occluder). Topology fixed; the tree is built on the rest pose.
        order: SH order.
        device: Warp device.
        lod: Level of detail: a tree node stands for its subtree when the receiver is farther than
            ``lod`` times the node's bounding radius (larger: more accurate, slower; >= 1).
        passes: 1 (single pass) or 2 (Bunnell's correction for overlapping occluders: mean of pass 1
            and a pass weighted by each occluder's own accessibility), or 0 = auto: 2 for two-sided
            disks (which double-count the front and back of a surface) and 1 for one-sided ones
            (which already under-estimate occlusion); measured on Warp's bunny and bear (docs/methods/disks.md).
        sides: ``"one"`` (disks occlude only from their front: right for closed surfaces, whose back
            faces hide behind front faces), ``"two"`` (cloth, open sheets) or ``"auto"`` (one for
            a closed mesh, two if the mesh has boundary edges).
        back_weight: Weight of disks seen from behind, in [0, 1]; overrides ``sides`` (one = 0,
            two = 1). Intermediate values help closed meshes with sharp concave corners, whose
            directions into the solid only back faces block (bear: 0.5 with 2 passes measured
            10.0 % error against 12.0 % one-sided; the smooth bunny is best at 0).
        samples: Bin quadrature: ``samples²`` directions per occluded bin for the SH integral.
    """

    name = "disks"
    KNOBS = (
        Knob("lod", float, "use a tree node when farther than LOD times its radius", minimum=1.0),
        Knob("passes", int, "1, 2 (Bunnell's overlap correction) or 0 = auto (2 if two-sided)", choices=(0, 1, 2)),
        Knob("sides", str, "disks occlude from one side (closed meshes) or both (cloth); auto: by boundary",
             choices=("auto", "one", "two")),
        Knob("samples", int, "SH quadrature: samples² directions per bin", minimum=1, maximum=16),
        Knob("back_weight", float, "weight of disks seen from behind, 0..1 (overrides --sides: one = 0, two = 1)",
             minimum=0.0, maximum=1.0, nullable=True),
    )

    def __init__(self, mesh: TriMesh, order: int = 5, device: str = "cpu", lod: float = 2.0, passes: int = 0,
                 sides: str = "auto", samples: int = 3, back_weight: float | None = None):
        super().__init__(mesh, order, device)
        if not lod >= 1.0:
            raise ValueError(f"lod must be >= 1 (node distance in bounding radii), got {lod}")
        if passes not in (0, 1, 2):
            raise ValueError(f"passes must be 0 (auto), 1 or 2, got {passes}")
        if sides not in ("one", "two", "auto"):
            raise ValueError(f"sides must be 'one', 'two' or 'auto', got {sides!r}")
        if int(samples) != samples or not 1 <= samples <= 16:
            raise ValueError(f"samples must be an integer in 1..16, got {samples!r}")
        self.lod = float(lod)
        if back_weight is not None and not 0.0 <= back_weight <= 1.0:
            raise ValueError(f"back_weight must be in [0, 1], got {back_weight}")
        self.sides = sides
        two_sided = (sides == "two") or (sides == "auto" and has_boundary(mesh.faces))
        self.back_weight = float(two_sided) if back_weight is None else float(back_weight)
        self.two_sided = self.back_weight > 0.0
        self.passes = int(passes) if passes else (2 if self.two_sided else 1)
        self.samples = int(samples)
        tree = build_disk_tree(mesh.points)
        n_nodes = len(tree["left"])
        dev = device
        self._left = wp.array(tree["left"], dtype=int, device=dev)
        self._right = wp.array(tree["right"], dtype=int, device=dev)
        self._node_vertex = wp.array(tree["node_vertex"], dtype=int, device=dev)
        self._leaf_of_vertex = wp.array(tree["leaf_of_vertex"], dtype=int, device=dev)
        # CSR edge adjacency: the contact rule leaves out disks of the receiver's own sheet (across a split rim too:
        # a box's side vertex at its base is not in contact with its own bottom face's copy of it)
        ring_start, ring = surface_neighbours(mesh.points, mesh.faces)
        self._ring_start = wp.array(ring_start, dtype=int, device=dev)
        self._ring = wp.array(ring, dtype=int, device=dev)
        self._levels = [wp.array(lv, dtype=int, device=dev) for lv in tree["levels"]]
        self.depth = len(self._levels)
        self.node_pos = wp.zeros(n_nodes, dtype=wp.vec3, device=dev)
        """Disk centres [m], shape (2V-1,), dtype vec3 (leaves are vertices, node 0 the root)."""
        self.node_nrm = wp.zeros(n_nodes, dtype=wp.vec3, device=dev)
        """Unit disk normals, shape (2V-1,), dtype vec3."""
        self.node_area = wp.zeros(n_nodes, dtype=float, device=dev)
        """Disk areas [m²], shape (2V-1,), dtype float32."""
        self._node_radius = wp.zeros(n_nodes, dtype=float, device=dev)
        self._node_coherence = wp.zeros(n_nodes, dtype=float, device=dev)
        self._node_cone = wp.zeros(n_nodes, dtype=float, device=dev)
        self._node_access = wp.zeros(n_nodes, dtype=float, device=dev)
        nv = mesh.num_vertices
        self._areas = wp.zeros(nv, dtype=float, device=dev)
        # per pass: unclamped bin occlusion and its u, v centroid sums
        self._occ1, self._cu1, self._cv1 = (wp.zeros((nv, BINS), dtype=float, device=dev) for _ in range(3))
        self._occ2, self._cu2, self._cv2 = (wp.zeros((nv, BINS), dtype=float, device=dev) for _ in range(3))
        self.centroid = wp.zeros((nv, BINS, 2), dtype=float, device=dev)
        """Occlusion-weighted centroid of each bin's occluders in the concentric square, shape (V, 16, 2)."""
        self.occlusion = wp.zeros((nv, BINS), dtype=float, device=dev)
        """Occluded fraction of each of the 16 direction bins, shape (V, 16), dtype float32, in [0, 1]."""
        self._visited = wp.zeros(nv, dtype=int, device=dev)
        self._k = normalization_array(self.order, dev)
        self._cosine_zh = wp.array(clamped_cosine_zh(self.order)[None, :].astype(np.float32), dtype=float, device=dev)
        self._kz = zh_normalization_array(self.order, dev)

    # -- command line ------------------------------------------------------------------------
    @classmethod
    def sweep(cls, quick: bool = False) -> list[dict]:
        if quick:
            return [{"lod": 1.5}, {}, {"lod": 4.0}]
        return [{"lod": 1.5}, {}, {"lod": 4.0}, {"lod": 8.0}, {"lod": 16.0}, {"passes": 2},
                {"back_weight": 0.5, "passes": 2}]

    def stats(self) -> dict:
        vis = self._visited.numpy()
        return {"disks_visited_per_vertex": float(vis.mean()), "disks_visited_max": int(vis.max()),
                "tree_depth": self.depth}

    # -- per frame ---------------------------------------------------------------------------
    def update_disks(self) -> None:
        """Leaf disks from the current points/normals, then parents bottom-up."""
        dev = self.device
        self._areas.zero_()
        wp.launch(accumulate_disk_areas, dim=self.mesh.num_faces, inputs=[self.points, self.faces],
                  outputs=[self._areas], device=dev)
        wp.launch(set_leaf_disks, dim=self.mesh.num_vertices,
                  inputs=[self.points, self.normals, self._areas, self._leaf_of_vertex],
                  outputs=[self.node_pos, self.node_nrm, self.node_area, self._node_radius, self._node_coherence,
                           self._node_cone],
                  device=dev)
        for level in self._levels:
            wp.launch(merge_child_disks, dim=level.shape[0], inputs=[level, self._left, self._right],
                      outputs=[self.node_pos, self.node_nrm, self.node_area, self._node_radius, self._node_coherence,
                           self._node_cone],
                      device=dev)

    def _occlusion_pass(self, use_access: bool, out: list) -> None:
        wp.launch(accumulate_occlusion, dim=self.mesh.num_vertices,
                  inputs=[self.points, self.normals, self._left, self._right, self._node_vertex, self._ring_start,
                          self._ring, self.node_pos,
                          self.node_nrm, self.node_area, self._node_radius, self._node_coherence, self._node_cone,
                          self._node_access,
                          int(use_access), self.lod, self.back_weight],
                  outputs=[*out, self._visited], device=self.device)

    def compute_occlusion(self) -> wp.array:
        """Fill :attr:`occlusion` (both passes) from the current points; returns it."""
        dev = self.device
        self.update_disks()
        self._occlusion_pass(False, [self._occ1, self._cu1, self._cv1])
        if self.passes > 1:
            wp.launch(set_leaf_access, dim=self.mesh.num_vertices, inputs=[self._occ1, self._leaf_of_vertex],
                      outputs=[self._node_access], device=dev)
            for level in self._levels:
                wp.launch(merge_child_access, dim=level.shape[0],
                          inputs=[level, self._left, self._right, self.node_area], outputs=[self._node_access],
                          device=dev)
            self._occlusion_pass(True, [self._occ2, self._cu2, self._cv2])
        wp.launch(combine_passes, dim=(self.mesh.num_vertices, BINS),
                  inputs=[self._occ1, self._cu1, self._cv1, self._occ2, self._cu2, self._cv2, self.passes],
                  outputs=[self.occlusion, self.centroid], device=dev)
        return self.occlusion

    def _compute(self) -> None:
        self.compute_occlusion()
        wp.launch(integrate_disk_transfer, dim=self.mesh.num_vertices,
                  inputs=[self.normals, self.occlusion, self.centroid, self._cosine_zh, self._kz, self.samples, self.order,
                          self._k],
                  outputs=[self.transfer], device=self.device)

    def light_visibility(self, direction=None, position=None) -> np.ndarray:
        """Per-vertex visibility toward a directional light (``direction``, pointing to the light) or a
        point/spot light (``position`` [m]) from the last :meth:`update`'s binned occlusion.

        A spot light's cone is part of its emission, not of visibility: use ``position``.

        Returns:
            Visibility in [0, 1], shape (V,), float32 (0 below a vertex's horizon).
        """
        if (direction is None) == (position is None):
            raise ValueError("give exactly one of direction (directional light) or position (point/spot light)")
        vec = np.asarray(direction if direction is not None else position, dtype=np.float64)
        if vec.shape != (3,) or not np.isfinite(vec).all():
            raise ValueError(f"light direction/position must be 3 finite numbers, got {vec.tolist()}")
        if direction is not None and not np.linalg.norm(vec) > 0:
            raise ValueError("light direction must be non-zero")
        out = wp.zeros(self.mesh.num_vertices, dtype=float, device=self.device)
        w = wp.vec3(*vec)
        wp.launch(lookup_light_visibility, dim=self.mesh.num_vertices,
                  inputs=[self.points, self.normals, self.occlusion, w, w, int(position is not None)],
                  outputs=[out], device=self.device)
        return out.numpy()


def has_boundary(faces: np.ndarray) -> bool:
    """True if some edge belongs to exactly one triangle (an open surface such as cloth)."""
    f = np.asarray(faces, dtype=np.int64)
    e = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    e = e[e[:, 0] != e[:, 1]]  # degenerate triangles' collapsed edges are not boundaries
    _, counts = np.unique(e[:, 0] * (int(f.max()) + 1) + e[:, 1], return_counts=True)
    return bool((counts == 1).any())
