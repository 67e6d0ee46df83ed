"""Ray-traced one-bounce reference: the ground truth the sphere-set reflections are measured against.

``E_R(p) = ∫ L_o(hit(p, ω)) max(0, n_p·ω) dω`` (reflected irradiance, no albedo and no 1/π at the
receiver, the quantity :class:`~.reflections.SphereReflections` returns), by stratified
cosine-weighted rays against the real meshes (``wp.mesh_query_ray``). ``L_o`` is the exit radiance of
the surface that is hit, given per vertex (typically ``(ρ/π) L · T`` with ray-traced transfer
``T`` of :class:`~warpshade.visibility.reference.ReferenceTransfer`, i.e. shadowed direct light) and
interpolated barycentrically; back faces reflect nothing.
"""

from __future__ import annotations

import math

import numpy as np
import warp as wp

from ...geometry.mesh import TriMesh
from ..rays import local_origin
from .reflection_kernels import trace_bounce


def reflected_irradiance_reference(points, normals, meshes: list[TriMesh], exit_radiance: list[np.ndarray],
                                   rays: int = 1024, seed: int = 0, offset: float = 1e-5,
                                   device: str = "cpu") -> np.ndarray:
    """Ray-traced reflected irradiance at receivers.

    Args:
        points, normals: Receivers [m] and their unit normals, shape (R, 3).
        meshes: Every surface in the scene (reflectors and blockers; receivers' own meshes included).
        exit_radiance: Per mesh, linear RGB exit radiance of each vertex, shape (V_o, 3).
        rays: Rays per receiver (rounded to a square for stratification).
        seed: Random seed.
        offset: Near-field distance of the rays (:func:`~warpshade.visibility.rays.trace_surface_ray`),
            fraction of the scene's bounding-box diagonal.

    Returns:
        Reflected irradiance, shape (R, 3), float32.
    """
    if len(meshes) != len(exit_radiance):
        raise ValueError(f"{len(meshes)} meshes but {len(exit_radiance)} exit radiance arrays")
    pts, faces, rad, base = [], [], [], 0
    for m, r in zip(meshes, exit_radiance):
        r = np.asarray(r, dtype=np.float32)
        if r.shape != (m.num_vertices, 3):
            raise ValueError(f"{m.name}: exit radiance must have shape ({m.num_vertices}, 3), got {r.shape}")
        pts.append(m.points)
        faces.append(m.faces + base)
        rad.append(r)
        base += m.num_vertices
    allp = np.concatenate(pts).astype(np.float32)
    recv = np.asarray(points, dtype=np.float32)
    # a receiver at a mesh vertex is that vertex: its own triangles meet its rays only at their origin
    first = {}
    for i, row in enumerate(map(bytes, allp)):
        first.setdefault(row, i)
    ids = np.array([first.get(bytes(row), -1) for row in recv], dtype=np.int32)
    diag = float(np.linalg.norm(np.ptp(np.concatenate([allp, recv]), axis=0))) or 1.0
    # rays are traced about the scene's own origin (float32 resolves it there as at the world origin)
    origin = local_origin(np.concatenate([allp, recv]))
    allp = (allp.astype(np.float64) - origin).astype(np.float32)
    recv = (recv.astype(np.float64) - origin).astype(np.float32)
    bvh = wp.Mesh(points=wp.array(allp, dtype=wp.vec3, device=device),
                  indices=wp.array(np.concatenate(faces).reshape(-1).astype(np.int32), dtype=wp.int32, device=device),
                  velocities=wp.array(np.concatenate(rad), dtype=wp.vec3, device=device))
    strata = max(1, int(round(math.sqrt(rays))))
    out = wp.zeros(len(recv), dtype=wp.vec3, device=device)
    wp.launch(trace_bounce, dim=len(recv),
              inputs=[bvh.id, wp.array(recv, dtype=wp.vec3, device=device),
                      wp.array(np.asarray(normals, dtype=np.float32), dtype=wp.vec3, device=device),
                      wp.array(ids, dtype=int, device=device), strata,
                      offset * diag, 4.0 * diag, int(seed)],
              outputs=[out], device=device)
    return out.numpy()
