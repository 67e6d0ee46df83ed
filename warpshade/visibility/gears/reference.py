"""Ray-traced area-light visibility: k×k stratified shadow rays per vertex (the ground truth for GEARS)."""

from __future__ import annotations

import warp as wp

from ...geometry.mesh import TriMesh
from ..knobs import Knob
from .base import AreaVisibilityMethod, LightRect
from .kernels import trace_light_masks


class RayVisibility(AreaVisibilityMethod):
    """One shadow ray per light cell (k×k per vertex) with ``wp.mesh_query_ray``.

    Args:
        mesh, light, k, device, offset: see :class:`AreaVisibilityMethod`.
        jitter: Jitter each ray inside its light cell (stratified sampling, the better estimator);
            False puts it at the cell centre, the same samples as the GEARS mask.
        seed: Random seed for the jitter.
    """

    name = "reference"
    KNOBS = (
        Knob("jitter", bool, "rays through light cell centres"),
        Knob("seed", int, "random seed of the jitter"),
    )

    def __init__(self, mesh: TriMesh, light: LightRect, k: int = 16, device: str = "cpu", offset: float = 1e-5,
                 jitter: bool = True, seed: int = 0):
        super().__init__(mesh, light, k, device, offset)
        self.jitter = bool(jitter)
        self.seed = int(seed)
        self._bvh = wp.Mesh(points=self._local_points, indices=self.faces.flatten())

    def stats(self) -> dict:
        return {"rays_per_vertex": self.k * self.k}

    def _compute(self) -> None:
        # rays are traced in coordinates about the scene's own origin (float32 resolves it as at the world origin)
        self._bvh.refit()
        c, u, v, nl = self.light_args()
        wp.launch(trace_light_masks, dim=self.mesh.num_vertices,
                  inputs=[self._bvh.id, self._local_points, self.normals, self._offset_abs(), c, u, v, nl, self.k,
                          int(self.jitter), self.seed],
                  outputs=[self.masks, self.visibility, self.form_factor], device=self.device)
