"""Reading triangle meshes from USD files (this package is the only one that imports ``pxr``)."""

from __future__ import annotations

import os
import re

import numpy as np
from pxr import Usd, UsdGeom

from ..geometry.mesh import MeshError, TriMesh


_TF_ERROR = re.compile(r"Error in '[^']*' at line \d+ in file [^:]* : '(.*?)'\s*(?=\n\s*Error in |\Z)", re.S)


def usd_error_message(exc: BaseException) -> str:
    """The most specific line of a pxr ``Tf.ErrorException``: the first error that names a place in a
    file (a parse error's ``FILE:LINE:COLUMN: ...``), else the last error, without pxr's C++ namespaces."""
    text = str(exc).strip()
    errors = [m.group(1).strip() for m in _TF_ERROR.finditer(text)] or [text.splitlines()[-1].strip() if text else ""]
    placed = [e for e in errors if re.search(r":\d+:\d+: ", e)]
    return re.sub(r"pxrInternal_[A-Za-z0-9_]*?__pxrReserved__::", "", (placed or errors[-1:])[0])


def open_stage(path: str) -> Usd.Stage:
    """Open a USD stage, turning USD's errors into a :class:`MeshError` that names the file."""
    try:
        stage = Usd.Stage.Open(path)
    except Exception as exc:  # pxr raises Tf.ErrorException
        raise MeshError(f"{path}: cannot open USD stage: {usd_error_message(exc)}") from exc
    if stage is None:
        raise MeshError(f"{path}: cannot open USD stage")
    return stage


def triangulate(counts: np.ndarray, indices: np.ndarray, name: str, holes=None) -> np.ndarray:
    """Fan-triangulate polygons given USD ``faceVertexCounts`` and ``faceVertexIndices``.

    Args:
        holes: The mesh's ``holeIndices``: polygons that are holes (not drawn, not simulated), dropped.

    Returns:
        Triangle indices, shape (F, 3), int32. Polygons with fewer than 3 corners are dropped.

    Raises:
        MeshError: if the counts do not add up to the number of indices.
    """
    counts = np.asarray(counts, dtype=np.int64)
    indices = np.asarray(indices, dtype=np.int64)
    if counts.sum() != len(indices):
        raise MeshError(f"{name}: faceVertexCounts sum to {counts.sum()} but there are "
                        f"{len(indices)} faceVertexIndices")
    starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
    if holes is not None and len(holes):
        holes = np.asarray(holes, dtype=np.int64)
        bad = holes[(holes < 0) | (holes >= len(counts))]
        if len(bad):
            raise MeshError(f"{name}: holeIndices {int(bad[0])} is not a face (the mesh has {len(counts)})")
        keep = np.ones(len(counts), dtype=bool)
        keep[holes] = False
        counts = np.where(keep, counts, 0)  # a hole becomes a polygon of no corner: dropped below
    tris = []
    for n in np.unique(counts):
        if n < 3:
            continue
        s = starts[counts == n]
        for k in range(1, n - 1):
            tris.append(np.stack([indices[s], indices[s + k], indices[s + k + 1]], axis=1))
    if not tris:
        return np.zeros((0, 3), dtype=np.int32)
    # keep polygons in file order so triangle order is stable across runs
    order = np.concatenate([np.flatnonzero(counts == n).repeat(n - 2) for n in np.unique(counts) if n >= 3])
    tri = np.concatenate(tris)
    return tri[np.argsort(order, kind="stable")].astype(np.int32)


def outward_faces(faces: np.ndarray, prim, linear: np.ndarray) -> np.ndarray:
    """Triangles of a mesh prim wound counter-clockwise seen from outside in world space, as warpshade
    reads normals (right-handed): reversed when the prim's ``orientation`` is ``leftHanded``, and again
    when its world transform mirrors (``linear``, the 3x3 part, has a negative determinant), as renderers
    flip the winding of mirrored meshes. Otherwise the normals would point in and the mesh shade black.

    Args:
        faces: Triangles in the prim's own winding, shape (F, 3).
        prim: The ``UsdGeom.Mesh`` (or other gprim) prim; its ``orientation`` is read.
        linear: Its local-to-world linear part (either convention: the determinant is the same).
    """
    left = UsdGeom.Gprim(prim).GetOrientationAttr().Get() == UsdGeom.Tokens.leftHanded
    mirrored = float(np.linalg.det(np.asarray(linear, dtype=np.float64)[:3, :3])) < 0.0
    faces = np.asarray(faces)
    return np.ascontiguousarray(faces[:, [0, 2, 1]]) if left != mirrored else faces


def read_usd_mesh(path: str, prim_path: str | None = None, time=None):
    """Read one mesh prim as world-space triangles.

    Args:
        path: USD file.
        prim_path: Prim to read; default the first ``UsdGeom.Mesh`` in traversal order.
        time: Time code (default: the default time).

    Returns:
        ``(points (V, 3) float32 [world units], faces (F, 3) int32, name)``.
    """
    stage = open_stage(path)
    if prim_path is not None:
        prim = stage.GetPrimAtPath(prim_path)
        if not prim or not prim.IsValid():
            raise MeshError(f"{path}: no prim at {prim_path}")
        if not prim.IsA(UsdGeom.Mesh):
            raise MeshError(f"{path}: prim {prim_path} is a {prim.GetTypeName() or 'typeless prim'}, not a Mesh")
    else:
        prim = next((p for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)), None)
        if prim is None:
            raise MeshError(f"{path}: no Mesh prim in the stage")
    name = f"{path}:{prim.GetPath()}"
    t = Usd.TimeCode.Default() if time is None else Usd.TimeCode(time)
    mesh = UsdGeom.Mesh(prim)
    pts = mesh.GetPointsAttr().Get(t)
    counts = mesh.GetFaceVertexCountsAttr().Get(t)
    idx = mesh.GetFaceVertexIndicesAttr().Get(t)
    if pts is None or counts is None or idx is None:
        raise MeshError(f"{name}: mesh lacks points, faceVertexCounts or faceVertexIndices")
    points = np.asarray(pts, dtype=np.float64).reshape(-1, 3)
    xf = np.asarray(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(t), dtype=np.float64)
    # USD matrices act on row vectors: p' = [p, 1] @ M
    points = points @ xf[:3, :3] + xf[3, :3]
    faces = outward_faces(triangulate(np.asarray(counts), np.asarray(idx), name, mesh.GetHoleIndicesAttr().Get(t)),
                          prim, xf)
    return points.astype(np.float32), faces, name


def load_mesh(path: str | os.PathLike, prim: str | None = None) -> TriMesh:
    """Load a triangle mesh from USD (``.usd/.usda/.usdc``), OBJ, PLY or STL.

    USD: the first ``UsdGeom.Mesh`` prim in traversal order, or ``prim``; points are transformed
    to world space and n-gons are fan-triangulated. OBJ/PLY/STL: read with trimesh without
    reordering vertices (STL, which stores unshared corners, has its vertices merged).

    (Here, at the file boundary, rather than in :mod:`warpshade.geometry`: only :mod:`warpshade.usd` imports pxr.)

    Raises:
        MeshError: for a missing or unreadable file, a missing prim or invalid geometry.
    """
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise MeshError(f"{path}: no such file")
    ext = os.path.splitext(path)[1].lower()
    if ext in (".usd", ".usda", ".usdc", ".usdz"):
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
