"""Gprims with sharp edges shade each face up to its rims (a Cube's 12 rims, a Cylinder's and a
Cone's cap rims), as a renderer draws them: a rim vertex shared by two faces got one normal between
them and shaded like neither face, a dark or bright seam along every rim (dotted, at the
tessellation's alternating rim triangles)."""

import numpy as np
import pytest
from pxr import Gf, Usd, UsdGeom, UsdLux

import warpshade.script as ws
from warpshade.usd import read_scene

FACE_TOL = {"hemiraster": 0.01, "reference": 0.05}
"""Largest allowed difference between a flat face's corner values and its centre value (radiance,
the lit faces are 0.13-0.45 here). Measured on this scene: hemiraster at most 0.0002 (an unoccluded
vertex's transfer is the clamped cosine, the same at every vertex of a face), the reference at most
0.031 (its ray sampling's noise). With the rim vertices shared, corners differed from their face's
centre by up to 0.37 (hemiraster and reference alike: the normals were wrong, not the visibility)."""


def _scene(path):
    """A scaled Cube (a table), a Cylinder and a Cone turned base-up, 20 m apart (no shadows on each
    other), under one distant light of irradiance 2 from above, in front and to the +x side."""
    st = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(st, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(st, 1.0)
    st.SetStartTimeCode(1)
    st.SetEndTimeCode(1)
    cube = UsdGeom.Xformable(UsdGeom.Cube.Define(st, "/World/Table").GetPrim())
    cube.AddTranslateOp().Set(Gf.Vec3d(0, 0.4, 0))
    cube.AddScaleOp().Set(Gf.Vec3f(1.2, 0.8, 0.8))
    for name, schema, x, turn in (("Cylinder", UsdGeom.Cylinder, 20.0, 0.0), ("Cone", UsdGeom.Cone, -20.0, 180.0)):
        g = schema.Define(st, f"/World/{name}")
        g.CreateAxisAttr("Y")
        g.CreateRadiusAttr(0.4)
        g.CreateHeightAttr(0.8)
        xf = UsdGeom.Xformable(g.GetPrim())
        xf.AddTranslateOp().Set(Gf.Vec3d(x, 0.4, 0))
        xf.AddRotateXOp().Set(turn)  # the cone's base up, in the light
    sun = UsdLux.DistantLight.Define(st, "/World/Sun")
    sun.CreateIntensityAttr(2.0)
    sun.CreateNormalizeAttr(True)
    UsdGeom.Xformable(sun.GetPrim()).AddRotateXYZOp().Set(Gf.Vec3f(-60, 30, 0))  # towards it: (0.25, 0.87, 0.43)
    st.GetRootLayer().Save()
    return read_scene(str(path))


@pytest.mark.parametrize("method", sorted(FACE_TOL))
def test_flat_faces_shade_alike_up_to_their_rims(tmp_path, method):
    out = str(tmp_path / "out.usda")
    ws.run(_scene(tmp_path / "s.usda"), out, frames=1, method=method, workers=0)
    stage = Usd.Stage.Open(out)
    checked = []
    for name in ("Table", "Cylinder", "Cone"):
        mesh = UsdGeom.Mesh(stage.GetPrimAtPath(f"/World/{name}"))
        p = np.array(mesh.GetPointsAttr().Get(1), dtype=np.float64)
        f = np.array(mesh.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3)
        colour = UsdGeom.PrimvarsAPI(mesh.GetPrim()).GetPrimvar("displayColor")
        assert colour.GetInterpolation() == UsdGeom.Tokens.vertex and mesh.GetNormalsInterpolation() == "vertex"
        value = np.array(colour.Get(1))[:, 0]
        normals = np.array(mesh.GetNormalsAttr().Get(1), dtype=np.float64)
        fn = np.cross(p[f[:, 1]] - p[f[:, 0]], p[f[:, 2]] - p[f[:, 0]])
        fn /= np.linalg.norm(fn, axis=1, keepdims=True)
        lo, hi = p.min(0), p.max(0)
        for axis in range(3):
            for sign in (-1.0, 1.0):
                e = np.eye(3)[axis] * sign
                corners = np.unique(f[fn @ e > 1 - 1e-6])  # every corner of the face's triangles, rims too
                if not len(corners):
                    continue  # a cylinder's and a cone's sides are not flat
                centre = (lo + hi) / 2
                centre[axis] = hi[axis] if sign > 0 else lo[axis]
                mid = corners[np.argmin(np.linalg.norm(p[corners] - centre, axis=1))]
                where = f"{method} {name} face {'+-'[sign < 0]}{'xyz'[axis]}"
                np.testing.assert_allclose(normals[corners], np.broadcast_to(e, (len(corners), 3)), atol=1e-6,
                                           err_msg=where)
                np.testing.assert_allclose(value[corners], value[mid], atol=FACE_TOL[method], err_msg=where)
                checked.append((where, value[mid]))
    lit = [w for w, v in checked if v > 0.1]
    # the Cube's +x, +y, +z faces, the Cylinder's top cap and the Cone's base face the light
    assert len(checked) == 9 and len(lit) == 5, checked
