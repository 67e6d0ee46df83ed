"""Time-sampled mesh animation written to USD (CONTRACTS.md §6).

Minimal writer: topology once at the default time, then per frame ``points``, ``normals``,
``extent`` and, when given, ``primvars:displayColor``. The file is written to a temporary path
beside the target and renamed on :meth:`AnimationWriter.close`, so an interrupted run never
leaves a half-written file at ``path``.
"""

from __future__ import annotations

import os
import re

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, Vt


def _prim_name(name: str) -> str:
    n = re.sub(r"[^A-Za-z0-9_]", "_", name)
    return n if n and not n[0].isdigit() else "_" + n


class AnimationWriter:
    """Write animated triangle meshes to a USD file.

    Args:
        path: Output file (``.usda``, ``.usdc`` or ``.usd``).
        fps: Frames per second; frame ``k`` is written at time code ``k``.
        up_axis: ``"Y"`` or ``"Z"``.
        meters_per_unit: Stage units.
    """

    def __init__(self, path: str, fps: float = 60.0, up_axis: str = "Y", meters_per_unit: float = 1.0):
        self.path = os.fspath(path)
        root, ext = os.path.splitext(self.path)
        self._tmp = f"{root}.partial{os.getpid()}{ext or '.usda'}"
        self.stage = Usd.Stage.CreateNew(self._tmp)
        UsdGeom.SetStageUpAxis(self.stage, UsdGeom.Tokens.y if up_axis.upper() == "Y" else UsdGeom.Tokens.z)
        UsdGeom.SetStageMetersPerUnit(self.stage, meters_per_unit)
        self.stage.SetTimeCodesPerSecond(fps)
        self.stage.SetFramesPerSecond(fps)
        world = UsdGeom.Xform.Define(self.stage, "/World")
        self.stage.SetDefaultPrim(world.GetPrim())
        self._meshes: dict[str, UsdGeom.Mesh] = {}
        self._first = None
        self._last = None

    def add_mesh(self, name: str, faces: np.ndarray, points: np.ndarray | None = None) -> str:
        """Declare a mesh; its topology is written once at the default time.

        Args:
            name: Prim name under ``/World`` (sanitised to a valid identifier).
            faces: Triangle indices, shape (F, 3), int.
            points: Optional rest positions, shape (V, 3), written at the default time.

        Returns:
            The prim name used.
        """
        pname = _prim_name(name)
        mesh = UsdGeom.Mesh.Define(self.stage, f"/World/{pname}")
        faces = np.asarray(faces, dtype=np.int32)
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(faces), 3, dtype=np.int32)))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(faces.reshape(-1)))
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        mesh.CreateOrientationAttr(UsdGeom.Tokens.rightHanded)
        if points is not None:
            pts = np.asarray(points, dtype=np.float32)
            mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(pts))
            mesh.CreateExtentAttr(UsdGeom.PointBased.ComputeExtent(Vt.Vec3fArray.FromNumpy(pts)))
        self._meshes[pname] = mesh
        return pname

    def write_frame(self, frame: int, name: str, points: np.ndarray, normals: np.ndarray | None = None,
                    colors: np.ndarray | None = None) -> None:
        """Write one frame of one mesh.

        Args:
            frame: Frame number (time code).
            name: A name returned by :meth:`add_mesh`.
            points: Positions, shape (V, 3).
            normals: Unit vertex normals, shape (V, 3), or None.
            colors: Linear RGB exit radiance per vertex, shape (V, 3), or None.
        """
        mesh = self._meshes[name]
        t = Usd.TimeCode(frame)
        pts = Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(points, dtype=np.float32))
        mesh.GetPointsAttr().Set(pts, t)
        mesh.GetExtentAttr().Set(UsdGeom.PointBased.ComputeExtent(pts), t)
        if normals is not None:
            attr = mesh.GetNormalsAttr()
            if not attr.HasAuthoredValue() and not attr.GetNumTimeSamples():
                mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
            attr.Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(normals, dtype=np.float32)), t)
        if colors is not None:
            pv = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("displayColor")
            if not pv:
                pv = UsdGeom.PrimvarsAPI(mesh).CreatePrimvar(
                    "displayColor", Sdf.ValueTypeNames.Color3fArray, UsdGeom.Tokens.vertex)
            pv.Set(Vt.Vec3fArray.FromNumpy(np.ascontiguousarray(colors, dtype=np.float32)), t)
        self._first = frame if self._first is None else min(self._first, frame)
        self._last = frame if self._last is None else max(self._last, frame)

    def close(self) -> str:
        """Set the time range, save, and atomically move the file into place. Returns the path."""
        if self._first is not None:
            self.stage.SetStartTimeCode(self._first)
            self.stage.SetEndTimeCode(self._last)
        self.stage.GetRootLayer().Save()
        del self.stage
        os.replace(self._tmp, self.path)
        return self.path

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self.close()
        else:  # leave any previous output untouched
            self.stage = None
            try:
                os.remove(self._tmp)
            except OSError:
                pass
        return False
