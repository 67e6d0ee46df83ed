"""Ray-traced reference transfer: the ground truth every other method is measured against.

Monte-Carlo integration of the diffuse transfer of docs/conventions.md §2 with ``wp.Mesh`` BVH ray casts
(``wp.mesh_query_ray``): per vertex ``strata²`` stratified cosine-weighted directions (Shirley–Chiu
concentric map), fixed seed. Near the vertex, within a distance ``eps`` that scales with the receiver
(so a mesh scaled by 1e-4 or 1e4 gives the same transfer), the vertex's own surface blocks the rays that
start under it (it shadows the vertex where it folds up around it; a test on directions only, unchanged by
scale or rounding) and any other surface blocks where the ray enters its front; beyond that any hit but
one on the vertex's own surface blocks
(:func:`~.rays.trace_surface_ray`). Pushing the whole ray origin off along the normal
instead went through any surface the vertex rests on when the normal leans into it (a box standing on
a ground: its bottom vertices saw the sky below the ground and lost the sky above).

Error: stratified sampling of a smooth integrand converges faster than 1/sqrt(rays); visibility
edges make it about 1/sqrt(rays) in the worst case. At 4096 rays the relative L2 error of an
order-5 transfer is well under 1 % on Warp's bunny (measured in tests/visibility/test_reference.py).
"""

from __future__ import annotations

import math

import numpy as np
import warp as wp

from ...geometry.mesh import TriMesh
from ...sh.kernels import normalization_array
from ..base import TransferMethod
from ..knobs import Knob
from ..rays import local_origin
from .kernels import trace_transfer

RAYS_PER_LAUNCH = 1 << 19
"""Rays traced per kernel launch on the CPU: a transfer is cut into vertex blocks of about this many rays,
so that Ctrl-C, which Python answers between launches, waits about a second at most (Warp runs a CPU
launch on one thread; measured ~0.8e6 order-5 rays/s on a loaded 2-core machine). On a GPU the whole
mesh is one launch. Blocks change nothing in the result: each vertex keeps its index and random stream."""


class ReferenceTransfer(TransferMethod):
    """Ray-traced diffuse transfer.

    Args:
        mesh: Receiver mesh; it also occludes itself.
        order: SH order.
        device: Warp device.
        rays: Rays per vertex; rounded to the nearest square ``s*s`` for stratification (``knobs()``
            reports the count used).
        seed: Random seed (results are deterministic for a given seed).
        offset: Near-field distance ``eps`` of the rays, as a fraction of the receiver's bounding-box
            diagonal (default 1e-5): other surfaces within ``eps`` block where the ray enters their front
            (:func:`~.rays.trace_surface_ray`).
        occluders: Extra static meshes that cast shadows on ``mesh`` (they receive nothing).
    """

    name = "reference"
    KNOBS = (
        Knob("rays", int, "rays per vertex (rounded to a square)", minimum=1),
        Knob("seed", int, "random seed"),
        Knob("offset", float, "near-field distance of the rays (other surfaces this close block where entered from "
                              "the front), fraction of the receiver's bbox diagonal", minimum=0.0, attr="offset_rel"),
    )

    def __init__(self, mesh: TriMesh, order: int = 5, device: str = "cpu", rays: int = 1024, seed: int = 0,
                 offset: float = 1e-5, occluders: list[TriMesh] | None = None):
        super().__init__(mesh, order, device)
        if rays < 1:
            raise ValueError(f"rays must be >= 1, got {rays}")
        self.strata = max(1, int(round(math.sqrt(rays))))
        self.seed = int(seed)
        self.offset_rel = float(offset)
        self._k = normalization_array(self.order, device)
        occluders = occluders or []
        pts = [mesh.points] + [o.points for o in occluders]
        faces, base = [mesh.faces], mesh.num_vertices
        for o in occluders:
            faces.append(o.faces + base)
            base += o.num_vertices
        all_pts = np.concatenate(pts).astype(np.float32)
        self._occluder_points = all_pts[mesh.num_vertices:]
        self._scene_points = wp.array(all_pts, dtype=wp.vec3, device=device)
        self._scene_faces = wp.array(np.concatenate(faces).reshape(-1).astype(np.int32), dtype=wp.int32, device=device)
        self._bvh = wp.Mesh(points=self._scene_points, indices=self._scene_faces)

    @classmethod
    def sweep(cls, quick: bool = False) -> list[dict]:
        return [{"rays": n} for n in ((64, 256, 1024) if quick else (16, 64, 256, 1024, 4096))]

    @property
    def rays(self) -> int:
        """Rays per vertex as used (``strata²``)."""
        return self.strata * self.strata

    def _compute(self) -> None:
        n = self.mesh.num_vertices
        # rays are traced in coordinates about the scene's own origin (float32 resolves it as at the world origin)
        world = np.concatenate([self.points.numpy(), self._occluder_points])
        pts = (world.astype(np.float64) - local_origin(world)).astype(np.float32)
        self._scene_points.assign(pts)
        self._bvh.refit()
        recv = pts[:n]
        # offset scales with the receiver (scale invariance); rays reach past the whole scene
        diag = float(np.linalg.norm(recv.max(axis=0) - recv.min(axis=0))) or 1.0
        scene_diag = float(np.linalg.norm(pts.max(axis=0) - pts.min(axis=0))) or 1.0
        # vertex blocks of about RAYS_PER_LAUNCH rays: Python (Ctrl-C) runs between launches
        block = max(1, RAYS_PER_LAUNCH // self.rays) if str(self.device).startswith("cpu") else n
        for first in range(0, n, block):
            wp.launch(
                trace_transfer,
                dim=min(block, n - first),
                inputs=[self._bvh.id, self._scene_points, self.normals, self.strata, self.offset_rel * diag, 4.0 * scene_diag,
                        self.seed, self.order, self._k, first],
                outputs=[self.transfer],
                device=self.device,
            )
