"""A UsdPhysics ``PhysicsScene``'s gravity moves the cloth (Omniverse and Isaac write one in every
physics scene: ``physics:gravityDirection``, ``physics:gravityMagnitude`` in stage units per s², their
fallbacks (0, 0, 0) = down the up axis and -inf = Earth gravity, per the UsdPhysics schema)."""

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics

from warpshade.cli import main
from warpshade.pipeline.cloth import ClothSimulation
from warpshade.scene import SceneError
from warpshade.usd.scene_io import EARTH_GRAVITY, scene_from_stage

FPS, SUBSTEPS, FRAMES = 60, 8, 6  # 0.1 s of fall: 4.9 cm at Earth gravity, far from anything


def _stage(direction=None, magnitude=None, up="Z", scenes=1):
    """A Z-up centimetre stage as Omniverse writes one (metersPerUnit 0.01, a PhysicsScene beside the
    geometry): a 20 cm cloth about the origin, hanging in the XZ plane so that gravity along X or Z runs in its plane
    (a sheet moving edge-on feels no air drag or lift: its fall is free fall), nothing under it.
    ``direction``/``magnitude`` None: the attribute is not authored."""
    st = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(st, up)
    UsdGeom.SetStageMetersPerUnit(st, 0.01)
    st.SetTimeCodesPerSecond(FPS)
    world = UsdGeom.Xform.Define(st, "/World")
    st.SetDefaultPrim(world.GetPrim())
    world.GetPrim().CreateAttribute("warpshade:substeps", Sdf.ValueTypeNames.Int, custom=True).Set(SUBSTEPS)
    for k in range(scenes):
        physics = UsdPhysics.Scene.Define(st, f"/World/PhysicsScene{'' if k == 0 else k}")
        if direction is not None:
            physics.CreateGravityDirectionAttr(Gf.Vec3f(*direction))
        if magnitude is not None:
            physics.CreateGravityMagnitudeAttr(float(magnitude))
    n, size = 6, 20.0
    cloth = UsdGeom.Mesh.Define(st, "/World/Cloth")
    cloth.CreatePointsAttr([Gf.Vec3f(i * size / n - size / 2, 0.0, j * size / n - size / 2) for j in range(n + 1) for i in range(n + 1)])
    cloth.CreateFaceVertexCountsAttr([4] * (n * n))
    cloth.CreateFaceVertexIndicesAttr([v for j in range(n) for i in range(n) for v in
                                       (j * (n + 1) + i, j * (n + 1) + i + 1, (j + 1) * (n + 1) + i + 1,
                                        (j + 1) * (n + 1) + i)])
    cloth.GetPrim().CreateAttribute("warpshade:kind", Sdf.ValueTypeNames.String, custom=True).Set("cloth")
    return st


def _fall(stage):
    """The cloth's mean displacement [cm] at frames 1..FRAMES, and the scene."""
    scene = scene_from_stage(stage, source="physics.usda")
    sim = ClothSimulation(scene)
    rest = scene.object("/World/Cloth").mesh.points.astype(np.float64).mean(axis=0)
    return np.array([sim.advance(f, {})["/World/Cloth"].astype(np.float64).mean(axis=0) - rest
                     for f in range(1, FRAMES + 1)]), scene


def _free_fall(g_si):
    """Free fall from rest [cm] at frames 1..FRAMES as the solver integrates it (symplectic Euler, substeps of
    h = 1/(FPS SUBSTEPS): x_n = g h² n (n + 1) / 2), which is ½ g t² (1 + 1/n) at t = n h."""
    h = 1.0 / (FPS * SUBSTEPS)
    n = SUBSTEPS * np.arange(1, FRAMES + 1, dtype=np.float64)
    return 100.0 * np.asarray(g_si)[None, :] * (h * h * n * (n + 1) / 2)[:, None]


TOL = 1e-3
"""[cm] The solver's velocities are float32 differences of positions over a substep (4e-5 m in the first):
on this cloth about the origin they round to a few 1e-5 of the fall, measured 7e-5 cm off the integrator's
exact free fall at frame 6 (the same cloth 2 m up was 0.011 cm off, the float32 spacing at 2 m being 0.6 % of
that first move). 1e-3 cm is 0.02 % of the 4.9 cm fall: a gravity 1 % off, or along another axis, fails."""


@pytest.mark.parametrize("direction,magnitude,g_si", [
    ((0, 0, -1), 981.0, (0, 0, -9.81)),                         # authored, cm/s² on a cm stage
    (None, None, (0, 0, -EARTH_GRAVITY)),                       # both fallbacks: Earth gravity down the up axis
    ((0, 0, 0), -1.0, (0, 0, -EARTH_GRAVITY)),                  # zero vector, negative sentinel
    ((2, 0, 0), 1000.0, (10.0, 0, 0)),                          # sideways (normalized): the cloth falls along +X
    ((0, 0, -1), 162.0, (0, 0, -1.62)),                         # Moon gravity
])
def test_physics_scene_gravity_is_free_fall(direction, magnitude, g_si):
    moved, scene = _fall(_stage(direction, magnitude))
    np.testing.assert_allclose(scene.gravity, g_si, rtol=1e-6)
    expected = _free_fall(g_si)
    np.testing.assert_allclose(moved, expected, atol=TOL)
    # and ½ g t² within the integrator's own error, a fraction 1/n of it after n substeps
    t = np.arange(1, FRAMES + 1) / FPS
    half = 100.0 * 0.5 * np.asarray(g_si)[None, :] * (t * t)[:, None]
    np.testing.assert_allclose(moved, half, atol=TOL + np.abs(half).max() / SUBSTEPS)


def test_zero_gravity_cloth_floats():
    moved, scene = _fall(_stage((0, 0, -1), 0.0))
    np.testing.assert_array_equal(scene.gravity, np.zeros(3))
    assert np.abs(moved).max() < TOL


def test_no_physics_scene_is_earth_gravity_down():
    st = _stage(scenes=0)
    moved, scene = _fall(st)
    assert scene.gravity is None
    np.testing.assert_allclose(moved, _free_fall((0, 0, -9.81)), atol=TOL)


def test_y_up_default_direction():
    st = _stage(None, 500.0, up="Y")
    scene = scene_from_stage(st, source="y.usda")
    np.testing.assert_allclose(scene.gravity, (0, -5.0, 0), rtol=1e-6)


def test_two_physics_scenes():
    st = _stage((0, 0, -1), 981.0, scenes=2)  # the same gravity twice: fine
    np.testing.assert_allclose(scene_from_stage(st).gravity, (0, 0, -9.81), rtol=1e-6)
    UsdPhysics.Scene(st.GetPrimAtPath("/World/PhysicsScene1")).GetGravityMagnitudeAttr().Set(100.0)
    with pytest.raises(SceneError, match="PhysicsScenes /World/PhysicsScene and /World/PhysicsScene1 give "
                                         "different gravities"):
        scene_from_stage(st)
    st.GetPrimAtPath("/World/PhysicsScene1").SetActive(False)  # deactivated: not read
    np.testing.assert_allclose(scene_from_stage(st).gravity, (0, 0, -9.81), rtol=1e-6)


def test_bad_gravity_values():
    st = _stage((0, float("nan"), -1), 981.0)
    with pytest.raises(SceneError, match="/World/PhysicsScene: physics:gravityDirection"):
        scene_from_stage(st)
    st = _stage((0, 0, -1), float("inf"))
    with pytest.raises(SceneError, match="/World/PhysicsScene: physics:gravityMagnitude inf"):
        scene_from_stage(st)


def test_run_simulates_with_the_physics_scene_gravity(tmp_path):
    """``warpshade run`` end to end: the cloth of a stage whose PhysicsScene pulls along +X falls along +X in
    the written output."""
    src = tmp_path / "sideways.usda"
    _stage((1, 0, 0), 1000.0).Export(str(src))
    out = tmp_path / "out.usda"
    assert main(["run", str(src), "--out", str(out), "--frames", "4", "--method", "none", "--workers", "0",
                 "--refine-receivers", "off", "--no-progress"]) == 0
    stage = Usd.Stage.Open(str(out))
    cloth = UsdGeom.Mesh(stage.GetPrimAtPath("/World/Cloth"))
    start = int(stage.GetStartTimeCode())
    rest = np.asarray(cloth.GetPointsAttr().Get(start), dtype=np.float64).mean(axis=0)
    moved = np.array([np.asarray(cloth.GetPointsAttr().Get(start + f), dtype=np.float64).mean(axis=0) - rest
                      for f in range(1, 4)])
    np.testing.assert_allclose(moved, _free_fall((10.0, 0, 0))[:3], atol=TOL)
