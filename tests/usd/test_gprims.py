"""UsdGeom gprims and UsdPhysics colliders as DCCs write them (no warpshade: attribute but the cloth's kind)."""

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdPhysics

from warpshade.pipeline.cloth import ClothSimulation
from warpshade.usd import read_scene


def _hand_scene(path, collision_enabled=True):
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)  # a scene in metres (as Blender and Houdini author it)
    stage.SetTimeCodesPerSecond(24)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    n, size = 16, 1.6
    cloth = UsdGeom.Mesh.Define(stage, "/World/Cloth")
    cloth.CreatePointsAttr([Gf.Vec3f(-size / 2 + i * size / n, 1.3, -size / 2 + j * size / n)
                            for j in range(n + 1) for i in range(n + 1)])
    cloth.CreateFaceVertexCountsAttr([4] * (n * n))
    cloth.CreateFaceVertexIndicesAttr([v for j in range(n) for i in range(n) for v in
                                       (j * (n + 1) + i, (j + 1) * (n + 1) + i, (j + 1) * (n + 1) + i + 1, j * (n + 1) + i + 1)])
    cloth.GetPrim().CreateAttribute("warpshade:kind", Sdf.ValueTypeNames.String, custom=True).Set("cloth")
    cube = UsdGeom.Cube.Define(stage, "/World/Box")
    cube.CreateSizeAttr(1.0)
    UsdGeom.XformCommonAPI(cube).SetTranslate((0, 0.5, 0))
    api = UsdPhysics.CollisionAPI.Apply(cube.GetPrim())
    api.CreateCollisionEnabledAttr(collision_enabled)
    ground = UsdGeom.Mesh.Define(stage, "/World/Ground")
    ground.CreatePointsAttr([(-3, 0, -3), (3, 0, -3), (3, 0, 3), (-3, 0, 3)])
    ground.CreateFaceVertexCountsAttr([3, 3])
    ground.CreateFaceVertexIndicesAttr([0, 2, 1, 0, 3, 2])
    UsdPhysics.CollisionAPI.Apply(ground.GetPrim())
    UsdLux.DomeLight.Define(stage, "/World/Dome")
    for i, t in enumerate(("Cylinder", "Capsule", "Cone", "Plane")):
        g = getattr(UsdGeom, t).Define(stage, f"/World/Shapes/{t}")
        UsdGeom.XformCommonAPI(g).SetTranslate((3 + 2 * i, 1, 0))
    stage.GetRootLayer().Save()
    return read_scene(str(path))


def test_gprims_are_read_with_their_transforms(tmp_path):
    scene = _hand_scene(tmp_path / "s.usda")
    objs = {o.name: o for o in scene.objects}
    assert set(objs) >= {"/World/Cloth", "/World/Box", "/World/Ground", "/World/Shapes/Cylinder",
                         "/World/Shapes/Capsule", "/World/Shapes/Cone", "/World/Shapes/Plane"}
    box = objs["/World/Box"].mesh.points
    assert np.allclose(box.min(0), [-0.5, 0, -0.5]) and np.allclose(box.max(0), [0.5, 1, 0.5])
    # USD defaults: cylinder/cone radius 1 height 2 along Z, capsule radius 0.5 height 1 (+ caps)
    for name, half in (("Cylinder", (1, 1, 1)), ("Cone", (1, 1, 1)), ("Capsule", (0.5, 0.5, 1.0))):
        p = objs[f"/World/Shapes/{name}"].mesh.points
        centre = p.min(0) + np.ptp(p, axis=0) / 2
        assert np.allclose(np.ptp(p, axis=0) / 2, half, atol=2e-3), name
        assert np.allclose(centre[1:], [1, 0], atol=2e-3), name
    plane = objs["/World/Shapes/Plane"].mesh.points
    assert np.allclose(np.ptp(plane, axis=0), [2, 2, 0])


def test_physics_collision_api_marks_exact_colliders(tmp_path):
    objs = {o.name: o for o in _hand_scene(tmp_path / "s.usda").objects}
    assert objs["/World/Box"].params["collider"] == "box"
    assert np.allclose(objs["/World/Box"].params["box"]["half_extents"], 0.5)
    assert objs["/World/Ground"].params["collider"] == "ground"
    assert "collider" not in objs["/World/Shapes/Cone"].params
    off = {o.name: o for o in _hand_scene(tmp_path / "off.usda", collision_enabled=False).objects}
    assert "collider" not in off["/World/Box"].params  # physics:collisionEnabled = false


def test_cloth_lands_on_the_cube_and_the_ground(tmp_path):
    scene = _hand_scene(tmp_path / "s.usda")
    sim = ClothSimulation(scene)
    for f in range(36):
        pts = sim.advance(f, {})["/World/Cloth"]
    # resting on the box top (y = 1) and the ground (y = 0), each at the cloth thickness
    assert pts[:, 1].max() == pytest.approx(1.0, abs=0.03)
    assert pts[:, 1].min() >= -1e-3
    centre = np.linalg.norm(pts[:, [0, 2]], axis=1) < 0.3
    assert np.all(pts[centre, 1] > 0.99)
