"""GEARS area-light soft shadows (Popescu): per-receiver k×k visibility masks by rasterizing blockers.

For every receiver vertex P the blocker triangles are projected from P onto the light's plane,
clipped to the part between P and the light, and scan-converted into a k×k bitmask of the light
(paper step 4). An acceleration grid (paper A.1–A.3) assigns to each receiver only the triangles
whose shadow volume's bounding box covers the receiver's grid cell; see
:func:`~warpshade.visibility.gears.kernels.bound_shadow_volumes` for why our bound is conservative
(never misses a blocker) where the paper's truncated one is not.
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ...geometry.mesh import TriMesh
from ..knobs import Knob
from .base import AreaVisibilityMethod, LightRect
from .kernels import (CULL_BATCH, add_counts, bound_shadow_volumes, count_cell_triangles, fill_cell_triangles,
                      fill_cells_in_order, iota, locate_receivers, rasterize_light_masks, triangle_corners)


class GearsVisibility(AreaVisibilityMethod):
    """GEARS visibility masks.

    Args:
        mesh, light, k, device, offset: see :class:`AreaVisibilityMethod`.
        grid: Acceleration grid resolution per side of the light (grid×grid cells); 0 assigns every
            triangle to every receiver (brute force, for testing). The paper found 128 best at
            ~1M pixel samples; for a few thousand vertices 8–16 is best (benchmarks/gears.py).
    """

    name = "gears"
    KNOBS = (Knob("grid", int, "acceleration grid cells per side (0 = every triangle for every vertex)",
                  minimum=0, maximum=1024),)

    def __init__(self, mesh: TriMesh, light: LightRect, k: int = 16, device: str = "cpu", offset: float = 1e-5,
                 grid: int = 16):
        if int(grid) != grid or grid < 0 or grid > 1024:
            raise ValueError(f"grid must be an integer in 0..1024 (0 = brute force), got {grid!r}")
        super().__init__(mesh, light, k, device, offset)
        self.grid = int(grid)
        n, f = mesh.num_vertices, mesh.num_faces
        self._cell_of = wp.zeros(n, dtype=int, device=device)
        self._tri_count = wp.zeros((n, 2), dtype=int, device=device)  # (tested by the cull, scan-converted)
        self._corners = wp.zeros(3 * f, dtype=wp.vec3, device=device)
        self._keep = wp.zeros((n, CULL_BATCH), dtype=int, device=device)
        self._cull = 1  # 0: scan-convert every candidate (tests check the cull drops nothing that sets a bit)
        self._boxes = wp.zeros((2 * f, 4), dtype=int, device=device)
        self._near = wp.zeros(2 * f, dtype=float, device=device)
        # CPU grid build: rows (triangle, side) sorted by near height (radix sort scratch: twice the rows)
        self._order_keys = wp.zeros(4 * max(1, f), dtype=float, device=device)
        self._order = wp.zeros(4 * max(1, f), dtype=int, device=device)
        g = max(1, self.grid)
        self._cell_count = wp.zeros(2 * g * g, dtype=int, device=device)
        self._cell_start = wp.zeros(2 * g * g, dtype=int, device=device)
        self._cell_fill = wp.zeros(2 * g * g, dtype=int, device=device)
        self._cell_end = wp.zeros(2 * g * g, dtype=int, device=device)
        # sort scratch: segmented_sort_pairs needs twice the pair count
        self._cell_tris = wp.zeros(2 * max(1, f), dtype=int, device=device)
        self._cell_keys = wp.zeros(2 * max(1, f), dtype=float, device=device)
        if self.grid == 0:
            self._cell_of.fill_(-2)
            self._cell_count.fill_(f)
            self._cell_tris = wp.array(np.arange(f, dtype=np.int32), dtype=int, device=device)
            self._cell_keys = wp.full(f, -np.inf, dtype=float, device=device)
        self._assigned = 0

    @classmethod
    def sweep(cls, quick: bool = False) -> list[dict]:
        """k (light samples per side) at the default grid, then the grid at the default k.

        Quick: k = 8 and 16 (the default) only. Full: k = 4, 8, 16, 32 and grid = 8, 32 (grid 0, brute
        force, is V×F work and only for testing).
        """
        if quick:
            return [{"k": 8, "grid": 16}, {"k": 16, "grid": 16}]
        return [{"k": k, "grid": 16} for k in (4, 8, 16, 32)] + [{"k": 16, "grid": g} for g in (8, 32)]

    def stats(self) -> dict:
        tc = self._tri_count.numpy()
        return {"triangles_tested_per_vertex": float(tc[:, 0].mean()), "triangles_tested_max": int(tc[:, 0].max()),
                "triangles_scanned_per_vertex": float(tc[:, 1].mean()),
                "grid_assignments": int(self._assigned)}

    def _build_grid(self, offset: float) -> None:
        """Bin receivers and triangles into the grid (paper A.1–A.3), one grid per side of the light."""
        lt = self.light
        c, nl = self.light_center(), lt.normal
        e1 = np.asarray(lt.u) / np.linalg.norm(lt.u)
        e2 = np.cross(nl, e1)
        pts = self._local_points.numpy().astype(np.float64) + offset * self.normals.numpy()
        rel = pts - c
        h = rel @ nl
        x, y = rel @ e1, rel @ e2
        g = self.grid
        lo = np.zeros((2, 2), dtype=np.float32)
        cell = np.ones(2, dtype=np.float32)
        height = np.zeros(2, dtype=np.float32)
        for side, sel in enumerate((h > 0.0, h < 0.0)):
            if not sel.any():
                continue
            x0, x1, y0, y1 = x[sel].min(), x[sel].max(), y[sel].min(), y[sel].max()
            size = max(x1 - x0, y1 - y0)
            size = size * (1.0 + 1e-6) if size > 0 else 1.0
            lo[side] = (x0, y0)
            cell[side] = size / g
            # the clip at this height is conservative: float32 rounding of receiver heights is covered
            height[side] = float(np.abs(h[sel]).max()) * (1.0 + 1e-5)
        dev = self.device
        grid_lo = wp.array(lo, dtype=float, device=dev)
        grid_cell = wp.array(cell, dtype=float, device=dev)
        side_height = wp.array(height, dtype=float, device=dev)
        cw, nlw = wp.vec3(*c), wp.vec3(*nl)
        e1w, e2w = wp.vec3(*e1), wp.vec3(*e2)
        wp.launch(locate_receivers, dim=self.mesh.num_vertices,
                  inputs=[self._local_points, self.normals, offset, cw, nlw, e1w, e2w, grid_lo, grid_cell, g],
                  outputs=[self._cell_of], device=dev)
        wp.launch(bound_shadow_volumes, dim=(self.mesh.num_faces, 2),
                  inputs=[self._local_points, self.faces, cw, wp.vec3(*lt.u), wp.vec3(*lt.v), nlw, e1w, e2w, side_height,
                          grid_lo, grid_cell, g],
                  outputs=[self._boxes, self._near], device=dev)
        self._cell_count.zero_()
        wp.launch(count_cell_triangles, dim=2 * self.mesh.num_faces, inputs=[self._boxes, g],
                  outputs=[self._cell_count], device=dev)
        wp.utils.array_scan(self._cell_count, self._cell_start, inclusive=False)
        total = int(self._cell_start.numpy()[-1] + self._cell_count.numpy()[-1])
        self._assigned = total
        if self._cell_tris.shape[0] < 2 * total:
            n = 2 * (int(total * 1.25) + 1)
            self._cell_tris = wp.zeros(n, dtype=int, device=dev)
            self._cell_keys = wp.zeros(n, dtype=float, device=dev)
        self._cell_fill.zero_()
        rows = 2 * self.mesh.num_faces
        if wp.get_device(dev).is_cpu:
            # one thread: sort the 2F rows by near height, then fill the cells in that order (sorted
            # lists without sorting the ~30 assignments per row; the segmented sort took 25-30 ms)
            wp.copy(self._order_keys, self._near, count=rows)
            wp.launch(iota, dim=rows, outputs=[self._order], device=dev)
            wp.utils.radix_sort_pairs(self._order_keys, self._order, rows)
            wp.launch(fill_cells_in_order, dim=1, inputs=[self._order, rows, self._boxes, g, self._near, self._cell_start],
                      outputs=[self._cell_fill, self._cell_tris, self._cell_keys], device=dev)
            return
        wp.launch(fill_cell_triangles, dim=rows, inputs=[self._boxes, g, self._near, self._cell_start],
                  outputs=[self._cell_fill, self._cell_tris, self._cell_keys], device=dev)
        if total > 0:
            wp.copy(self._cell_end, self._cell_start)
            wp.launch(add_counts, dim=self._cell_end.shape[0], inputs=[self._cell_count], outputs=[self._cell_end],
                      device=dev)
            wp.utils.segmented_sort_pairs(self._cell_keys, self._cell_tris, total, self._cell_start, self._cell_end)

    def _compute(self) -> None:
        offset = self._offset_abs()
        if self.grid > 0:
            self._build_grid(offset)
        c, u, v, nl = self.light_args()
        # dual axes: s = du·(X - c) recovers X = c + s u + t v for orthogonal u, v
        lt = self.light
        du = np.asarray(lt.u) / np.dot(lt.u, lt.u)
        dv = np.asarray(lt.v) / np.dot(lt.v, lt.v)
        wp.launch(triangle_corners, dim=(self.mesh.num_faces, 3), inputs=[self._local_points, self.faces],
                  outputs=[self._corners], device=self.device)
        wp.launch(rasterize_light_masks, dim=self.mesh.num_vertices,
                  inputs=[self._local_points, self.normals, self._corners, offset, c, u, v, wp.vec3(*du), wp.vec3(*dv), nl,
                          self.k, self._cell_of, self._cell_start, self._cell_count, self._cell_tris, self._cell_keys,
                          self._cull, self._keep],
                  outputs=[self.masks, self.visibility, self.form_factor, self._tri_count], device=self.device)
