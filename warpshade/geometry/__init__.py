"""Geometry: triangle meshes, validation, vertex normals."""

from .mesh import MeshError, TriMesh, first_nonfinite, validate_mesh
from .normals import vertex_normals, vertex_normals_np

__all__ = ["MeshError", "TriMesh", "first_nonfinite", "validate_mesh", "vertex_normals", "vertex_normals_np"]
