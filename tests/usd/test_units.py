"""Stage units: cloth on a stage in centimetres behaves as the same cloth in metres
(docs/conventions.md §8), and a stage without ``metersPerUnit`` is centimetres, with a warning."""

import warnings

import numpy as np
import pytest
from pxr import Gf, Sdf, Usd, UsdGeom, UsdPhysics

from warpshade.pipeline.cloth import ClothSimulation
from warpshade.scene import SceneWarning
from warpshade.usd.scene_io import scene_from_stage

FRAMES = 30  # 0.5 s at 60 fps: the cloth swings down from its pinned edge onto the box and the ground


def _stage(mpu):
    """A 0.8 m cloth (12 x 12 quads) 0.5 m up, pinned along one edge, over a 0.4 m Cube collider
    on a 2-triangle ground,
    sizes in metres authored in stage units (``mpu`` None: metersPerUnit left unauthored, the
    numbers those of a centimetre stage)."""
    u = 100.0 if mpu is None else 1.0 / mpu  # stage units per metre
    st = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(st, UsdGeom.Tokens.y)
    if mpu is not None:
        UsdGeom.SetStageMetersPerUnit(st, mpu)
    st.SetTimeCodesPerSecond(60)
    world = UsdGeom.Xform.Define(st, "/World")
    st.SetDefaultPrim(world.GetPrim())
    n, size = 12, 0.8
    cloth = UsdGeom.Mesh.Define(st, "/World/Cloth")
    cloth.CreatePointsAttr([Gf.Vec3f(*(np.array([-size / 2 + i * size / n, 0.5, -size / 2 + j * size / n]) * u))
                            for j in range(n + 1) for i in range(n + 1)])
    cloth.CreateFaceVertexCountsAttr([4] * (n * n))
    cloth.CreateFaceVertexIndicesAttr([v for j in range(n) for i in range(n) for v in
                                       (j * (n + 1) + i, (j + 1) * (n + 1) + i, (j + 1) * (n + 1) + i + 1,
                                        j * (n + 1) + i + 1)])
    cloth.GetPrim().CreateAttribute("warpshade:kind", Sdf.ValueTypeNames.String, custom=True).Set("cloth")
    cloth.GetPrim().CreateAttribute("warpshade:pinned", Sdf.ValueTypeNames.IntArray, custom=True).Set(
        [j * (n + 1) for j in range(n + 1)])  # the x = -0.4 m edge: the cloth swings down onto the box's edge
    cloth.GetPrim().CreateAttribute("warpshade:cloth:selfCollision", Sdf.ValueTypeNames.Bool, custom=True).Set(False)
    cube = UsdGeom.Cube.Define(st, "/World/Box")
    cube.CreateSizeAttr(0.4 * u)
    UsdGeom.XformCommonAPI(cube).SetTranslate((0.1 * u, 0.2 * u, 0))
    UsdPhysics.CollisionAPI.Apply(cube.GetPrim())
    ground = UsdGeom.Mesh.Define(st, "/World/Ground")
    ground.CreatePointsAttr([Gf.Vec3f(*(np.array(p) * u)) for p in [(-2, 0, -2), (2, 0, -2), (2, 0, 2), (-2, 0, 2)]])
    ground.CreateFaceVertexCountsAttr([3, 3])
    ground.CreateFaceVertexIndicesAttr([0, 2, 1, 0, 3, 2])
    UsdPhysics.CollisionAPI.Apply(ground.GetPrim())
    return st


def _drape(mpu):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = scene_from_stage(_stage(mpu), source=f"mpu{mpu}.usda")
    sim = ClothSimulation(scene)
    for f in range(1, FRAMES + 1):
        x = sim.advance(f, {})["/World/Cloth"]
    return x.astype(np.float64), [str(w.message) for w in caught if issubclass(w.category, SceneWarning)]


@pytest.fixture(scope="module")
def metres():
    return _drape(1.0)


@pytest.fixture(scope="module")
def centimetres():
    return _drape(0.01)


def test_a_centimetre_stage_drapes_as_the_same_scene_in_metres(metres, centimetres):
    xm, warned_m = metres
    xc, warned_c = centimetres
    # the metre drape itself: swung down from the pinned edge onto the box (top 0.4 m, x from
    # -0.1 to 0.3 m), some vertices resting the cloth thickness (5 mm) above its top
    on_top = (xm[:, 0] > -0.1) & (xm[:, 0] < 0.3) & (np.abs(xm[:, 1] - 0.405) < 3e-3)
    assert on_top.sum() >= 3, xm
    # The solver runs in metres either way; the centimetre input differs only by float32 rounding
    # (points x100, then x0.01: <= 1 ulp). This drape is sensitive to that, most where the cloth
    # slides off the box's edge: 8 runs of the metre scene with every cloth coordinate moved by
    # -1, 0 or +1 ulp at random (seed 0) differed from it by 0.9-21.8 mm RMS (max over vertices
    # 6.1-64.5 mm) after 30 frames; the centimetre stage differs by 21.1 mm RMS (61.3 mm max).
    # Bounds: 1.25x the largest jitter figures. Taking the SI numbers as centimetres (the
    # behaviour before stage units were applied) was 62 mm RMS off.
    d = np.linalg.norm(xc * 0.01 - xm, axis=1)
    assert np.sqrt(np.mean(d ** 2)) < 27e-3 and d.max() < 0.081, (np.sqrt(np.mean(d ** 2)), d.max())
    assert not [w for w in warned_m + warned_c if "metersPerUnit" in w]


def test_unauthored_meters_per_unit_is_centimetres_and_warns(centimetres):
    xc, _ = centimetres
    xu, warned = _drape(None)
    # UsdGeom's fallback (0.01) as Blender reads it: the same drape as the authored centimetre stage
    np.testing.assert_array_equal(xu, xc)
    units = [w for w in warned if "metersPerUnit is not authored" in w]
    assert len(units) == 1, warned
    # names the file, the size the cloth is simulated at and the fix; the cloth's diagonal is 0.8 * sqrt 2 m
    assert units[0].startswith("mpuNone.usda:") and f"{0.8 * 2 ** 0.5:.3g} m across" in units[0], units[0]
    assert "SetStageMetersPerUnit(stage, 1.0)" in units[0]


def test_unauthored_units_without_cloth_do_not_warn():
    """Units change nothing but the cloth: shading is scale-free, so a static stage is quiet."""
    st = _stage(None)
    st.GetPrimAtPath("/World/Cloth").GetAttribute("warpshade:kind").Set("static")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene_from_stage(st, source="static.usda")
    assert not [w for w in caught if "metersPerUnit" in str(w.message)]
