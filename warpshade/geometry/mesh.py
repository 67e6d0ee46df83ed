"""Triangle meshes: loading, validation and vertex normals.

Shapes follow one notation everywhere: V vertices, F triangles.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from .normals import vertex_normals_np


class MeshError(ValueError):
    """Invalid mesh input. The message names the file (and prim, vertex or face) at fault."""


@dataclass
class TriMesh:
    """A triangle mesh on the host.

    Attributes:
        points: Vertex positions [m], shape (V, 3), dtype float32.
        faces: Triangle vertex indices, shape (F, 3), dtype int32.
        normals: Unit vertex normals (angle-weighted), shape (V, 3), dtype float32.
        name: Where the mesh came from (file and prim), for error messages.
    """

    points: np.ndarray
    faces: np.ndarray
    normals: np.ndarray = None
    name: str = "<mesh>"
    info: dict = field(default_factory=dict)

    def __post_init__(self):
        self.points = np.ascontiguousarray(self.points, dtype=np.float32)
        self.faces = np.ascontiguousarray(self.faces, dtype=np.int32)
        validate_mesh(self.points, self.faces, self.name)
        if self.normals is None:
            self.normals = vertex_normals_np(self.points, self.faces).astype(np.float32)
        else:
            self.normals = np.ascontiguousarray(self.normals, dtype=np.float32)

    @property
    def num_vertices(self) -> int:
        return len(self.points)

    @property
    def num_faces(self) -> int:
        return len(self.faces)

    def bbox_diagonal(self) -> float:
        """Length of the axis-aligned bounding-box diagonal [m]."""
        return float(np.linalg.norm(self.points.max(axis=0) - self.points.min(axis=0)))


def validate_mesh(points: np.ndarray, faces: np.ndarray, name: str = "<mesh>") -> None:
    """Check shapes, finiteness and index ranges.

    Degenerate (zero-area or repeated-index) triangles are allowed: they carry no area and are
    ignored by normals and visibility.

    Raises:
        MeshError: naming ``name`` and the first offending vertex or face.
    """
    if points.ndim != 2 or points.shape[1] != 3:
        raise MeshError(f"{name}: points must have shape (V, 3), got {points.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3:
        raise MeshError(f"{name}: faces must have shape (F, 3), got {faces.shape}")
    if len(points) == 0 or len(faces) == 0:
        raise MeshError(f"{name}: empty mesh ({len(points)} vertices, {len(faces)} triangles)")
    bad = ~np.isfinite(points).all(axis=1)
    if bad.any():
        v = int(np.flatnonzero(bad)[0])
        raise MeshError(f"{name}: vertex {v} has a non-finite position {points[v].tolist()} "
                        f"({int(bad.sum())} such vertices)")
    out = (faces < 0) | (faces >= len(points))
    if out.any():
        f = int(np.flatnonzero(out.any(axis=1))[0])
        raise MeshError(f"{name}: face {f} has vertex index out of range 0..{len(points) - 1}: "
                        f"{faces[f].tolist()}")


def load_mesh(path: str | os.PathLike, prim: str | None = None) -> TriMesh:
    """Load a triangle mesh from USD (``.usd/.usda/.usdc``), OBJ, PLY or STL.

    USD: the first ``UsdGeom.Mesh`` prim in traversal order, or ``prim``; points are transformed
    to world space and n-gons are fan-triangulated. OBJ/PLY/STL: read with trimesh without
    reordering vertices (STL, which stores unshared corners, has its vertices merged).

    Raises:
        MeshError: for a missing or unreadable file, a missing prim or invalid geometry.
    """
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise MeshError(f"{path}: no such file")
    ext = os.path.splitext(path)[1].lower()
    if ext in (".usd", ".usda", ".usdc", ".usdz"):
        from ..usd.mesh_io import read_usd_mesh  # only the usd package imports pxr

        points, faces, name = read_usd_mesh(path, prim)
        return TriMesh(points, faces, name=name)
    if ext in (".obj", ".ply", ".stl", ".off", ".glb", ".gltf"):
        if prim is not None:
            raise MeshError(f"{path}: --prim applies to USD files only")
        import trimesh

        try:
            tm = trimesh.load(path, force="mesh", process=False)
        except Exception as exc:  # trimesh raises many types for malformed files
            raise MeshError(f"{path}: cannot read mesh: {exc}") from exc
        if ext == ".stl":
            tm.merge_vertices()
        return TriMesh(np.asarray(tm.vertices), np.asarray(tm.faces), name=path)
    raise MeshError(f"{path}: unsupported mesh format '{ext}' (use .usd/.usda/.usdc, .obj, .ply or .stl)")
