"""Receiver refinement: static meshes too coarse to carry per-vertex shadows get finer triangles.

Shading is per vertex, so a shadow can only fall where there are vertices: a 2-triangle ground
under a box shows no contact shadow at all. Static objects whose longest edge exceeds the
refinement edge are subdivided (every longer edge bisected at a shared midpoint, trimesh's
``subdivide_to_size``: no cracks) and the refined mesh is what the run shades and writes.
Simulated, skinned and animated meshes keep their topology (their vertices are the animation's).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..geometry.mesh import TriMesh
from ..scene import Scene, SceneError

EDGE_FRACTION = 1.0 / 12.0
"""Default refinement edge as a fraction of the scene's bounding-box diagonal ("auto"). Every
static mesh of the shipped scenes is finer than that already (their longest edges are at most
~0.066 of the diagonal), so they are unchanged; a 6 m two-triangle ground gets ~0.4 m edges."""


@dataclass
class Refined:
    """One refined object: its name and vertex count before and after."""

    name: str
    before: int
    after: int


def refinement_edge(scene: Scene, edge) -> float | None:
    """The refinement edge length [scene units] for ``edge``: ``"auto"`` (None means the same)
    -> the scene setting ``warpshade:refineEdge`` or :data:`EDGE_FRACTION` of the scene's
    diagonal; ``"off"``, 0 -> no refinement (None); a positive number -> itself."""
    if edge is None or edge == "auto":
        edge = scene.settings.get("refineEdge", "auto")
    if edge == "off" or edge == 0:
        return None
    if edge == "auto":
        points = np.concatenate([o.mesh.points for o in scene.objects]) if scene.objects else np.zeros((1, 3))
        diag = float(np.linalg.norm(np.ptp(points, axis=0)))
        return diag * EDGE_FRACTION if diag > 0 else None
    try:
        value = float(edge)
    except (TypeError, ValueError):
        raise SceneError(f"{scene.source}: receiver refinement edge must be a length > 0, 'auto' or 'off', "
                         f"got {edge!r}") from None
    if not np.isfinite(value) or value < 0:
        raise SceneError(f"{scene.source}: receiver refinement edge must be a length > 0, 'auto' or 'off', "
                         f"got {edge!r}")
    return value or None


def _longest_edge(mesh: TriMesh) -> float:
    tri = mesh.points[mesh.faces].astype(np.float64)
    return float(np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2).max()) if len(tri) else 0.0


def refine_receivers(scene: Scene, edge="auto") -> list[Refined]:
    """Subdivide, in place, every static object of ``scene`` whose longest edge exceeds the
    refinement edge (:func:`refinement_edge`). Idempotent: a refined scene is left as it is.

    Returns:
        The objects refined, with their vertex counts before and after.
    """
    length = refinement_edge(scene, edge)
    done = []
    if length is None:
        return done
    for obj in scene.objects:
        if obj.kind != "static" or _longest_edge(obj.mesh) <= length:
            continue
        import trimesh  # only when there is a mesh to refine (0.5 s with the SciPy modules it loads)

        points, faces = trimesh.remesh.subdivide_to_size(obj.mesh.points.astype(np.float64), obj.mesh.faces,
                                                         max_edge=length, max_iter=16)
        before = obj.mesh.num_vertices
        obj.mesh = TriMesh(points.astype(np.float32), faces.astype(np.int32), name=obj.mesh.name)
        done.append(Refined(obj.name, before, obj.mesh.num_vertices))
    return done


def describe(refined: list[Refined]) -> str:
    """One line per refined object, e.g. ``refined /World/Ground for shading: 4 -> 289 vertices``."""
    return "\n".join(f"  refined {r.name} for shading: {r.before} -> {r.after} vertices (+{r.after - r.before})"
                     for r in refined)
