"""Stages with a PointInstancer as Houdini's Solaris writes a scatter (shared by the instancer tests)."""

from __future__ import annotations

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdPhysics, Vt

ROCK = np.array([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0), (-1, -1, 2), (1, -1, 2), (1, 1, 2), (-1, 1, 2)],
                dtype=np.float64) * 10.0  # a 20 cm box standing on its base [cm]
ROCK_FACES = [(0, 3, 2, 1), (4, 5, 6, 7), (0, 1, 5, 4), (1, 2, 6, 5), (2, 3, 7, 6), (3, 0, 4, 7)]
TREE = np.array([(-5, -5, 0), (5, -5, 0), (5, 5, 0), (-5, 5, 0), (0, 0, 60)], dtype=np.float64)  # a 60 cm pyramid
TREE_FACES = [(0, 3, 2, 1), (0, 1, 4), (1, 2, 4), (2, 3, 4), (3, 0, 4)]

POSITIONS = np.array([(0, 0, 0), (60, 0, 0), (-60, 20, 0), (0, 70, 0), (40, -50, 0)], dtype=np.float64)
ANGLES = np.array([0.0, 30.0, 90.0, 45.0, 180.0])  # about +Z [degrees]
SCALES = np.array([(1, 1, 1), (1.5, 1.5, 1.5), (1, 2, 0.5), (1, 1, 1), (0.5, 0.5, 0.5)], dtype=np.float64)
PROTO_INDICES = [0, 1, 0, 1, 0]
IDS = [10, 11, 12, 13, 14]


def _mesh(stage, path, pts, faces, colour):
    m = UsdGeom.Mesh.Define(stage, path)
    m.CreatePointsAttr([Gf.Vec3f(*p) for p in pts])
    m.CreateFaceVertexCountsAttr([len(f) for f in faces])
    m.CreateFaceVertexIndicesAttr([i for f in faces for i in f])
    m.CreateDisplayColorAttr([Gf.Vec3f(*colour)])
    return m


def quat_z(deg):
    """Rotation about +Z as a GfQuath (real first), as the instancer's ``orientations`` hold it."""
    a = np.radians(deg) / 2
    return Gf.Quath(float(np.cos(a)), Gf.Vec3h(0.0, 0.0, float(np.sin(a))))


def scatter_stage(time_sampled=False, collider=False):
    """A Z-up centimetre stage: a 4 m ground, a sun, and ``/World/scatter/instancer1``: a PointInstancer with
    prototypes ``rock`` (an Xform over a Mesh box, translated 5 cm up: its own transform, applied under every
    instance) and ``tree`` (a Mesh pyramid) under a ``Prototypes`` Scope, five instances (``positions``,
    ``orientations`` as quath, ``scales``, ``protoIndices``, ``ids``), instance id 13 hidden by ``invisibleIds``.
    As Houdini's Solaris writes a Scatter and Instancer LOP: the prototypes under the instancer, the arrays written
    as time samples at frame 1 (``time_sampled``: positions keyed at frames 1 and 11, rising 1 cm a frame).
    ``collider``: PhysicsCollisionAPI on the ``rock`` prototype's root."""
    st = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(st, UsdGeom.Tokens.z)
    UsdGeom.SetStageMetersPerUnit(st, 0.01)
    st.SetTimeCodesPerSecond(24)
    st.SetStartTimeCode(1)
    st.SetEndTimeCode(4)
    world = UsdGeom.Xform.Define(st, "/World")
    st.SetDefaultPrim(world.GetPrim())
    _mesh(st, "/World/ground", [(-200, -200, 0), (200, -200, 0), (200, 200, 0), (-200, 200, 0)], [(0, 1, 2, 3)],
          (0.5, 0.5, 0.5))
    sun = UsdLux.DistantLight.Define(st, "/World/sun")
    sun.CreateIntensityAttr(3.0)
    sun.CreateNormalizeAttr(True)
    UsdGeom.XformCommonAPI(sun).SetRotate((30, 0, 20))
    scatter = UsdGeom.Xform.Define(st, "/World/scatter")
    UsdGeom.XformCommonAPI(scatter).SetTranslate((10, 0, 0))
    pi = UsdGeom.PointInstancer.Define(st, "/World/scatter/instancer1")
    UsdGeom.Scope.Define(st, "/World/scatter/instancer1/Prototypes")
    rock = UsdGeom.Xform.Define(st, "/World/scatter/instancer1/Prototypes/rock")
    UsdGeom.XformCommonAPI(rock).SetTranslate((0, 0, 5))
    _mesh(st, "/World/scatter/instancer1/Prototypes/rock/mesh_0", ROCK, ROCK_FACES, (0.6, 0.5, 0.4))
    _mesh(st, "/World/scatter/instancer1/Prototypes/tree", TREE, TREE_FACES, (0.2, 0.6, 0.2))
    if collider:
        UsdPhysics.CollisionAPI.Apply(rock.GetPrim())
    pi.CreatePrototypesRel().SetTargets([rock.GetPath(), Sdf.Path("/World/scatter/instancer1/Prototypes/tree")])
    one = Usd.TimeCode(1)
    positions = pi.CreatePositionsAttr()
    positions.Set(Vt.Vec3fArray.FromNumpy(POSITIONS.astype(np.float32)), one)
    if time_sampled:
        positions.Set(Vt.Vec3fArray.FromNumpy((POSITIONS + (0, 0, 10)).astype(np.float32)), Usd.TimeCode(11))
    pi.CreateOrientationsAttr().Set([quat_z(a) for a in ANGLES], one)
    pi.CreateScalesAttr().Set(Vt.Vec3fArray.FromNumpy(SCALES.astype(np.float32)), one)
    pi.CreateProtoIndicesAttr().Set(PROTO_INDICES, one)
    pi.CreateIdsAttr().Set(IDS, one)
    pi.CreateInvisibleIdsAttr().Set([13], one)
    return st
