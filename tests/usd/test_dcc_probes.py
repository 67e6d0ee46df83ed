"""Stages written the way DCCs write them, and what warpshade made of them before reading them right.

* Isaac Sim / Omniverse (Isaac Sim 4.x "Create > Physics > Physics Scene", "Ground Plane", a cube with
  "Rigid Body with Colliders Preset", an OmniPBR material from "Create > Material"): Z up, metres, a
  PhysicsScene, materials as MDL only (``outputs:mdl:surface`` -> ``OmniPBR.mdl``), a Camera. The OmniPBR
  colour was dropped (grey), the free rigid body stood still without a word, the camera warned.
* Blender 4.x and mayaUSD exports carry a Camera in nearly every scene: it warned as an unread prim.
* Houdini Solaris (a Scatter and an Instancer LOP of packed rocks): prototypes under the instancer as
  instanceable references to a rock file, Y up, frames from 1001 (tests/usd/test_point_instancer.py has the
  instancer's own cases); the instancer was skipped.
"""

import warnings

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics, UsdShade

from warpshade.scene import SceneWarning
from warpshade.usd.scene_io import OMNIPBR_ALBEDO, scene_from_stage


def _messages(stage):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = scene_from_stage(stage, source="probe.usda")
    return scene, [str(w.message) for w in caught if issubclass(w.category, SceneWarning)]


def _cube_mesh(stage, path, half, z):
    m = UsdGeom.Mesh.Define(stage, path)
    p = np.array([(-1, -1, -1), (1, -1, -1), (1, 1, -1), (-1, 1, -1), (-1, -1, 1), (1, -1, 1), (1, 1, 1), (-1, 1, 1)])
    m.CreatePointsAttr([Gf.Vec3f(*(q * half + (0, 0, z))) for q in p])
    m.CreateFaceVertexCountsAttr([4] * 6)
    m.CreateFaceVertexIndicesAttr([0, 3, 2, 1, 4, 5, 6, 7, 0, 1, 5, 4, 2, 3, 7, 6, 1, 2, 6, 5, 0, 4, 7, 3])
    return m


def isaac_stage(colour=(0.8, 0.1, 0.1), tint=None, texture=None, kinematic=False):
    st = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(st, "Z")
    UsdGeom.SetStageMetersPerUnit(st, 1.0)
    st.SetDefaultPrim(UsdGeom.Xform.Define(st, "/World").GetPrim())
    scene = UsdPhysics.Scene.Define(st, "/World/PhysicsScene")
    scene.CreateGravityDirectionAttr(Gf.Vec3f(0, 0, -1))
    scene.CreateGravityMagnitudeAttr(9.81)
    ground = UsdGeom.Mesh.Define(st, "/World/GroundPlane/Environment/Geometry")
    ground.CreatePointsAttr([(-5, -5, 0), (5, -5, 0), (5, 5, 0), (-5, 5, 0)])
    ground.CreateFaceVertexCountsAttr([4])
    ground.CreateFaceVertexIndicesAttr([0, 1, 2, 3])
    plane = UsdGeom.Plane.Define(st, "/World/GroundPlane/CollisionPlane")
    plane.CreateAxisAttr("Z")
    plane.CreatePurposeAttr("guide")
    UsdPhysics.CollisionAPI.Apply(plane.GetPrim())
    crate = UsdGeom.Xform.Define(st, "/World/Crate")
    _cube_mesh(st, "/World/Crate/geo", 0.25, 2.0)
    UsdPhysics.CollisionAPI.Apply(st.GetPrimAtPath("/World/Crate/geo"))
    body = UsdPhysics.RigidBodyAPI.Apply(crate.GetPrim())
    UsdPhysics.MassAPI.Apply(crate.GetPrim())
    if kinematic:
        body.CreateKinematicEnabledAttr(True)
    mat = UsdShade.Material.Define(st, "/World/Looks/OmniPBR")
    shader = UsdShade.Shader.Define(st, "/World/Looks/OmniPBR/Shader")
    shader.SetSourceAsset(Sdf.AssetPath("OmniPBR.mdl"), "mdl")
    shader.SetSourceAssetSubIdentifier("OmniPBR", "mdl")
    if colour is not None:
        shader.CreateInput("diffuse_color_constant", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*colour))
    if tint is not None:
        shader.CreateInput("diffuse_tint", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*tint))
    if texture is not None:
        shader.CreateInput("diffuse_texture", Sdf.ValueTypeNames.Asset).Set(Sdf.AssetPath(texture))
    shader.CreateInput("reflection_roughness_constant", Sdf.ValueTypeNames.Float).Set(0.7)
    mat.CreateSurfaceOutput("mdl").ConnectToSource(shader.ConnectableAPI(), "out")
    UsdShade.MaterialBindingAPI.Apply(st.GetPrimAtPath("/World/Crate/geo")).Bind(mat)
    UsdGeom.Camera.Define(st, "/World/Camera")
    return st


def test_isaac_stage():
    scene, msgs = _messages(isaac_stage())
    crate = scene.object("/World/Crate/geo")
    np.testing.assert_allclose(crate.material.albedo, (0.8, 0.1, 0.1), rtol=1e-6)  # OmniPBR's, not grey
    assert crate.material.roughness == pytest.approx(0.7)
    assert crate.params["collider"] == "box"
    np.testing.assert_allclose(scene.gravity, (0, 0, -9.81), rtol=1e-6)
    assert [o.params["collider"] for o in scene.collision_only] == ["ground"]  # the guide CollisionPlane
    rigid = [m for m in msgs if "RigidBodyAPI" in m]
    assert len(rigid) == 1 and rigid[0].startswith("probe.usda: /World/Crate: a dynamic rigid body"), msgs
    assert not any("Camera" in m for m in msgs), msgs
    assert len(msgs) == 1, msgs


def test_kinematic_body_is_meant_to_stay():
    _, msgs = _messages(isaac_stage(kinematic=True))
    assert msgs == []


def test_omnipbr_defaults_tint_and_texture():
    scene, _ = _messages(isaac_stage(colour=None))
    np.testing.assert_allclose(scene.object("/World/Crate/geo").material.albedo, OMNIPBR_ALBEDO)
    scene, _ = _messages(isaac_stage(colour=(0.5, 0.5, 0.5), tint=(1.0, 0.5, 0.0)))
    np.testing.assert_allclose(scene.object("/World/Crate/geo").material.albedo, (0.5, 0.25, 0.0))
    _, msgs = _messages(isaac_stage(texture="crate_albedo.png"))
    assert any("(OmniPBR) has a diffuse_texture, which warpshade does not read" in m for m in msgs), msgs


def test_another_mdl_still_warns():
    st = isaac_stage()
    UsdShade.Shader(st.GetPrimAtPath("/World/Looks/OmniPBR/Shader")).SetSourceAssetSubIdentifier("OmniGlass", "mdl")
    st.GetPrimAtPath("/World/Looks/OmniPBR/Shader").GetAttribute("info:mdl:sourceAsset").Set(Sdf.AssetPath("OmniGlass.mdl"))
    _, msgs = _messages(st)
    assert any("has no UsdPreviewSurface; default material used" in m for m in msgs), msgs


def test_houdini_instanced_packed_rocks(tmp_path):
    rock_file = tmp_path / "rock.usda"
    rock = Usd.Stage.CreateNew(str(rock_file))
    UsdGeom.SetStageUpAxis(rock, "Y")
    rock.SetDefaultPrim(UsdGeom.Xform.Define(rock, "/rock").GetPrim())
    _cube_mesh(rock, "/rock/mesh_0", 0.2, 0.0)
    rock.Save()
    st = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(st, "Y")
    UsdGeom.SetStageMetersPerUnit(st, 1.0)
    st.SetStartTimeCode(1001)
    st.SetEndTimeCode(1010)
    pi = UsdGeom.PointInstancer.Define(st, "/scatter/instancer1")
    proto = st.DefinePrim("/scatter/instancer1/Prototypes/rock", "Xform")
    proto.GetReferences().AddReference(str(rock_file))
    proto.SetInstanceable(True)
    pi.CreatePrototypesRel().SetTargets([proto.GetPath()])
    pi.CreatePositionsAttr().Set([Gf.Vec3f(-1, 0.2, 0), Gf.Vec3f(1, 0.2, 0)], 1001)
    pi.CreateProtoIndicesAttr().Set([0, 0], 1001)
    scene, msgs = _messages(st)
    assert msgs == []
    names = [o.name for o in scene.objects]
    assert names == [f"/scatter/instancer1_instances/instance_{i}/rock/mesh_0" for i in (0, 1)]
    np.testing.assert_allclose(scene.objects[1].mesh.points.mean(axis=0), (1, 0.2, 0), atol=1e-6)


def test_maya_catmull_clark_meshes_warn():
    """mayaUSD exports a mesh with ``subdivisionScheme = "catmullClark"`` unless told otherwise (Y up, cm):
    warpshade shades the control cage, and says so once for all such meshes; an authored ``none`` and an
    unauthored scheme (a hand-written stage) do not warn."""
    st = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(st, "Y")
    UsdGeom.SetStageMetersPerUnit(st, 0.01)
    st.SetDefaultPrim(UsdGeom.Xform.Define(st, "/group1").GetPrim())
    for name, scheme in (("pCube1", "catmullClark"), ("pCube2", "catmullClark"), ("pCube3", "none"), ("pCube4", None)):
        m = _cube_mesh(st, f"/group1/{name}/{name}Shape", 25.0, 0.0)
        if scheme is not None:
            m.CreateSubdivisionSchemeAttr(scheme)
    _, msgs = _messages(st)
    assert len(msgs) == 1, msgs
    assert msgs[0].startswith("probe.usda: /group1/pCube1/pCube1Shape, /group1/pCube2/pCube2Shape (2 meshes): "
                              "subdivisionScheme catmullClark, but warpshade shades and writes the control mesh")
