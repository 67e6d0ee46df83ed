"""Geometry: triangle meshes, validation, vertex normals."""

from .mesh import MeshError, TriMesh, closed_orientation, first_nonfinite, ulp_jitter, validate_mesh
from .normals import vertex_normals, vertex_normals_np

__all__ = ["MeshError", "TriMesh", "closed_orientation", "first_nonfinite", "ulp_jitter", "validate_mesh", "vertex_normals", "vertex_normals_np"]
