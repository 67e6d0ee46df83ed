"""Read shaded frames back from an output file (for ``warpshade preview`` and tests)."""

from __future__ import annotations

import warnings

import numpy as np
from pxr import Usd, UsdGeom

from ..scene import SceneError, SceneWarning
from .mesh_io import triangulate, usd_error_message
from .writer import BACK_SIDE_OF


class ShadedStage:
    """An output stage opened for reading frames.

    Args:
        path: A file written by :class:`warpshade.usd.AnimationWriter` (or any stage with meshes).

    Attributes:
        up_axis: ``"Y"`` or ``"Z"``.
        start, end: Time-code range (``startTimeCode``/``endTimeCode``; 0, 0 if unset).
    """

    def __init__(self, path: str):
        self.path = str(path)
        try:
            self.stage = Usd.Stage.Open(self.path)
        except Exception as exc:  # pxr raises Tf.ErrorException
            raise SceneError(f"{path}: cannot open USD stage: {usd_error_message(exc)}") from exc
        if self.stage is None:
            raise SceneError(f"{path}: cannot open USD stage")
        self.up_axis = str(UsdGeom.GetStageUpAxis(self.stage))
        self.start = self.stage.GetStartTimeCode() if self.stage.HasAuthoredTimeCodeRange() else 0.0
        self.end = self.stage.GetEndTimeCode() if self.stage.HasAuthoredTimeCodeRange() else 0.0
        self._meshes = []
        for prim in self.stage.Traverse():
            if prim.IsA(UsdGeom.Mesh) and UsdGeom.Imageable(prim).ComputeVisibility() != UsdGeom.Tokens.invisible:
                m = UsdGeom.Mesh(prim)
                where = f"{self.path}:{prim.GetPath()}"
                faces = triangulate(np.asarray(m.GetFaceVertexCountsAttr().Get()),
                                    np.asarray(m.GetFaceVertexIndicesAttr().Get()), where)
                self._meshes.append((prim, m, faces))
        if not self._meshes:
            raise SceneError(f"{path}: no Mesh prim")
        if not any(UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayColor").HasAuthoredValue() for prim, _, _ in self._meshes):
            warnings.warn(f"{path}: no mesh has a displayColor, so every mesh is shown in one flat grey: this is not "
                          "an output of warpshade run (which writes the shaded colours there); preview the output",
                          SceneWarning, stacklevel=2)

    def moving(self) -> set[str]:
        """Paths of the meshes whose points differ between the first, middle and last frames
        (static meshes are time-sampled too, docs/conventions.md §6, so sampling alone says nothing)."""
        out = set()
        times = [Usd.TimeCode(t) for t in (self.start, 0.5 * (self.start + self.end), self.end)]
        for prim, m, _ in self._meshes:
            attr = m.GetPointsAttr()
            if not attr.ValueMightBeTimeVarying():
                continue
            first = np.asarray(attr.Get(times[0]))
            if any(not np.array_equal(first, np.asarray(attr.Get(t))) for t in times[1:]):
                out.add(str(prim.GetPath()))
        return out

    def back_sides(self) -> dict[str, str]:
        """Back-side meshes of a two-sided output (docs/conventions.md §6): back prim path -> front prim path."""
        out = {}
        for prim, _, _ in self._meshes:
            rel = prim.GetRelationship(BACK_SIDE_OF)
            targets = rel.GetTargets() if rel else []
            if targets:
                out[str(prim.GetPath())] = str(targets[0])
        return out

    def frame(self, frame: float) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray]]:
        """Every mesh at ``frame``: ``(prim path, points (V, 3) world, faces (F, 3), colors (V, 3))``.

        Colours are ``primvars:displayColor`` (vertex, or constant broadcast); grey when absent.
        """
        t = Usd.TimeCode(frame)
        out = []
        for prim, m, faces in self._meshes:
            pts = m.GetPointsAttr().Get(t)
            if pts is None:
                raise SceneError(f"{self.path}:{prim.GetPath()}: no points at frame {frame}")
            pts = np.asarray(pts, dtype=np.float64).reshape(-1, 3)
            xf = np.asarray(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(t), dtype=np.float64)
            pts = pts @ xf[:3, :3] + xf[3, :3]  # USD matrices act on row vectors
            pv = UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayColor")
            cols = pv.Get(t) if pv else None
            if cols is None or len(cols) == 0:
                cols = np.full((len(pts), 3), 0.5)
            else:
                cols = np.asarray(cols, dtype=np.float64).reshape(-1, 3)
                if len(cols) == 1:
                    cols = np.repeat(cols, len(pts), axis=0)
                elif len(cols) != len(pts):
                    raise SceneError(f"{self.path}:{prim.GetPath()}: displayColor has {len(cols)} values for "
                                     f"{len(pts)} points (only vertex or constant interpolation is previewed)")
            out.append((str(prim.GetPath()), pts.astype(np.float32), faces, cols.astype(np.float32)))
        return out
