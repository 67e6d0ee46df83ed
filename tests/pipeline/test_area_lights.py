"""Rect lights in ``warpshade run``: exact Lambert irradiance times GEARS visibility (pipeline/area.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from warpshade.geometry import TriMesh
from warpshade.lighting import RectLight
from warpshade.pipeline import Pipeline
from warpshade.pipeline.area import AreaLightShading
from warpshade.scene import LightSpec, Material, Scene, SceneObject
from warpshade.visibility.gears import LightRect, get_area_method

H, A = 2.0, 0.5  # light height [m] and half-size [m]
HB = 1.0  # blocker height [m]
# the blocker's shadow from the plane's centre reaches 0.3125 m = 10 of the 16 cells of a 16×16 mask
# (cell size 2A/16): edges on cell boundaries, so the mask's samples split the light exactly there
B = 0.3125 * HB / H


def light(**kw) -> RectLight:
    # u × v = +y, so the light emits along -(u × v) = -y, down onto the plane (UsdLux: one-sided)
    return RectLight(center=(0.0, H, 0.0), u=(0.0, 0.0, A), v=(A, 0.0, 0.0), radiance=(1.0, 2.0, 3.0), **kw)


def square(n: int, half: float, y: float) -> TriMesh:
    """n×n grid of [-half, half]² at height y, normals +y."""
    x, z = np.meshgrid(np.linspace(-half, half, n), np.linspace(-half, half, n))
    pts = np.stack([x.ravel(), np.full(n * n, y), z.ravel()], 1)
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1))
    v = (j * n + i).ravel()
    faces = np.concatenate([np.stack([v, v + n, v + 1], 1), np.stack([v + 1, v + n, v + n + 1], 1)])
    return TriMesh(pts, faces.astype(np.int32))


def parallel_rect_phi(half_x: float, half_y: float, h: float) -> float:
    """Projected solid angle of a rectangle centred over a receiver facing it at distance h: 4 corner
    rectangles, each the textbook differential-area-to-parallel-rectangle form factor times π
    (Howell's catalogue, C-11)."""
    x, y = half_x / h, half_y / h
    f = (x / math.sqrt(1 + x * x) * math.atan(y / math.sqrt(1 + x * x))
         + y / math.sqrt(1 + y * y) * math.atan(x / math.sqrt(1 + y * y))) / (2 * math.pi)
    return 4 * math.pi * f


# -- exact unshadowed irradiance (lighting.RectLight) -----------------------------------------------
def test_irradiance_matches_the_parallel_rectangle_formula_and_numpy_reference():
    lt = light()
    e = lt.irradiance_at([[0.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])[0]
    assert e == pytest.approx(parallel_rect_phi(A, A, H) * lt.radiance, rel=1e-6)  # float32 kernel: measured 2e-8
    rng = np.random.default_rng(3)
    pts = rng.normal(size=(200, 3)) * 1.5 + (0, 1.0, 0)
    nrm = rng.normal(size=(200, 3))
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    got, ref = lt.irradiance_at(pts, nrm), lt.irradiance_at_reference(pts, nrm)
    # float32 kernel vs float64 reference: measured 8e-8 of the largest value; bound 1e-5 (float32 sums
    # of a few atan2 terms with cancellation between edges)
    assert np.abs(got - ref).max() <= 1e-5 * np.abs(ref).max(), (pts, nrm)
    # partly below the horizon: clipping matters for some of these receivers, and the one-sided light
    # gives nothing above its plane
    assert (ref[pts[:, 1] > H] == 0).all() and (ref[pts[:, 1] < H] > 0).any()
    two = light(two_sided=True).irradiance_at(pts, nrm)
    assert (two[pts[:, 1] > H] > 0).any()


# -- GEARS path --------------------------------------------------------------------------------------
def _plane_and_blocker():
    return square(21, 1.0, 0.0), square(5, B, HB)


def _ray_traced_irradiance(meshes, points, normals, lt, seeds=4, k=32):
    """E = π L F by k×k jittered shadow rays per seed (the gears reference method), one-sided."""
    faces = np.concatenate([m.faces + o for m, o in zip(meshes, np.cumsum([0] + [m.num_vertices for m in meshes])[:-1])])
    rays = get_area_method("reference")(TriMesh(points, faces), LightRect.from_light(lt), k=k)
    ff = np.zeros(len(points))
    for s in range(seeds):
        rays.seed = s
        rays.update(points, normals)
        ff += rays.form_factor.numpy() / seeds
    front = (points - lt.center) @ lt.emit_normal > 0
    return math.pi * (ff * front)[:, None] * lt.radiance


def test_no_blocker_gives_the_exact_unshadowed_irradiance():
    plane = square(21, 1.0, 0.0)
    lt = light()
    area = AreaLightShading([plane], [lt])
    (e,) = area.irradiance(0.0, [plane.points], [plane.normals])
    phi = lt.projected_solid_angle(plane.points, plane.normals).numpy()
    # the weighted visible share of an unblocked vertex is exactly 1 (same sums over the same samples)
    assert np.array_equal(area.visibility[0].weighted_visibility().numpy(), np.ones(plane.num_vertices, np.float32))
    assert np.allclose(e, phi.astype(np.float64)[:, None] * lt.radiance, rtol=1e-7, atol=0)
    ref = lt.irradiance_at_reference(plane.points, plane.normals)
    assert np.abs(e - ref).max() <= 1e-5 * np.abs(ref).max()  # float32 vs float64 (measured 1.5e-7), as above


def test_blocker_darkens_by_the_expected_fraction():
    plane, lid = _plane_and_blocker()
    lt = light()
    area = AreaLightShading([plane, lid], [lt])
    e_plane, _ = area.irradiance(0.0, [plane.points, lid.points], [plane.normals, lid.normals])
    centre = 220  # the plane's middle vertex
    # analytic: the lid hides the centred 0.3125 m square of the light from the centre vertex
    expected = (parallel_rect_phi(A, A, H) - parallel_rect_phi(0.3125, 0.3125, H)) * lt.radiance
    # the mask's samples split the light exactly here, so only the cell-centre quadrature of the smooth
    # weights remains: measured 2e-5 relative (the paper's plain fraction of samples: 3.2 % off)
    assert e_plane[centre] == pytest.approx(expected, rel=1e-3)
    assert e_plane[centre, 0] < 0.7 * parallel_rect_phi(A, A, H)  # a real shadow, not a nick

    # every plane vertex against ray tracing (4 × 32×32 jittered rays; their own noise is ~0.1 %)
    pts = np.concatenate([plane.points, lid.points])
    nrm = np.concatenate([plane.normals, lid.normals])
    ref = _ray_traced_irradiance([plane, lid], pts, nrm, lt)[: plane.num_vertices]
    unshadowed = lt.irradiance_at(plane.points, plane.normals)
    shadowed = ref[:, 0] < 0.98 * unshadowed[:, 0]
    assert shadowed.sum() > 40, shadowed.sum()
    err = np.abs(e_plane[:, 0] - ref[:, 0]) / unshadowed[:, 0]
    # measured on this fixture (213 shadowed vertices): mean 0.75 %, max 2.2 % of the unshadowed
    # irradiance (penumbra vertices where a shadow edge crosses a mask row); tolerances ~1.6x that
    assert err[shadowed].mean() < 0.012 and err.max() < 0.035, (err[shadowed].mean(), err.max())
    # the paper's plain fraction of visible samples, measured mean 2.5 % here: the weighting matters
    plain = AreaLightShading([plane, lid], [lt], weighting="area")
    e_plain, _ = plain.irradiance(0.0, [plane.points, lid.points], [plane.normals, lid.normals])
    err_plain = np.abs(e_plain[:, 0] - ref[:, 0]) / unshadowed[:, 0]
    assert err_plain[shadowed].mean() > 2 * err[shadowed].mean()


def _scene(area_lights_kind="rect"):
    plane, lid = _plane_and_blocker()
    objs = [SceneObject("plane", plane, method=None, material=Material(albedo=np.array([0.5, 0.5, 0.5]))),
            SceneObject("lid", lid, method=None, material=Material(albedo=np.array([0.5, 0.5, 0.5])))]
    return Scene(objects=objs, frames=2, lights=[LightSpec(area_lights_kind, "/Panel")])


def test_pipeline_adds_gears_shadowed_rect_light_to_the_shading():
    from warpshade.usd import AnimationWriter  # noqa: F401 - the run's writer API; colours read from shade()

    lt = light()
    scene = _scene()
    colours = {}
    for mode in ("gears", "sh"):
        pipe = Pipeline(scene, order=3, lights=[lt], area_lights=mode, between=None)
        assert pipe.area_lights == mode
        out = pipe.shader.build()(0, {})
        colours[mode] = out["plane"][2]
    expected = 0.5 / math.pi * (parallel_rect_phi(A, A, H) - parallel_rect_phi(0.3125, 0.3125, H)) * lt.radiance
    # unoccluded transfer in the groups: the lid shadows the plane only through GEARS
    assert colours["gears"][220] == pytest.approx(expected, rel=1e-3)  # as in the test above
    assert colours["sh"][220, 0] > 1.3 * colours["gears"][220, 0]  # SH path: no shadow from another group


def test_cli_run_on_tiny_rect_light_scene(tmp_path, capsys):
    from pxr import Gf, UsdGeom, UsdLux

    from warpshade.cli import main
    from warpshade.usd import make_scenes as ms
    from warpshade.usd.validate import validation_errors

    path = str(tmp_path / "tiny_rect.usda")
    st = ms.new_stage(path, 3, doc="tiny rect-light scene")
    ms.ground(st, n=9), ms.cloth(st, n=9), ms.sphere(st)
    rect = UsdLux.RectLight.Define(st, "/World/Lights/Panel")
    rect.CreateWidthAttr(1.5), rect.CreateHeightAttr(1.0), rect.CreateIntensityAttr(8.0)
    rect.AddTranslateOp().Set(Gf.Vec3d(0.5, 2.5, 0.5))
    rect.AddRotateXOp().Set(-90.0)
    st.GetRootLayer().Save()
    import json

    # the plan lists the GEARS pass iff the run executes it (--area-lights gears, the default)
    for mode, listed in (("gears", True), ("sh", False)):
        assert main(["plan", path, "--area-lights", mode, "--json", str(tmp_path / f"{mode}.json")]) == 0
        plan = json.loads((tmp_path / f"{mode}.json").read_text())
        assert any("area-light visibility (GEARS)" in o["passes"] for o in plan["objects"]) == listed
        assert ("GEARS area-light structures" in plan["structures"]) == listed and (plan["seconds_area"] > 0) == listed
    capsys.readouterr()
    out = tmp_path / "out.usda"
    assert main(["run", path, "--out", str(out), "--no-progress", "--workers", "0", "--method", "reference",
                 "--rays", "4", "--order", "2"]) == 0
    assert "rect lights: GEARS soft shadows" in capsys.readouterr().err
    from pxr import Usd

    stage = Usd.Stage.Open(str(out))
    assert stage.GetRootLayer().customLayerData["warpshade:area_lights"] == "gears"
    for prim in ("/World/Ground", "/World/Cloth"):
        col = np.asarray(UsdGeom.PrimvarsAPI(stage.GetPrimAtPath(prim)).GetPrimvar("displayColor").Get(2))
        assert np.isfinite(col).all() and col.max() > 0, prim
    assert validation_errors(out) == []


def test_non_orthogonal_rect_light_names_the_light_and_the_way_out():
    plane = square(3, 1.0, 0.0)
    skew = RectLight(center=(0, 2, 0), u=(0.0, 0.0, 0.5), v=(0.5, 0.0, 0.2), name="/Skewed")
    with pytest.raises(ValueError, match=r"/Skewed.*--area-lights sh"):
        AreaLightShading([plane], [skew])


@pytest.mark.parametrize("mode", ["gears", "sh"])
def test_plan_lists_gears_iff_the_run_uses_it(mode):
    from warpshade.planner import make_plan

    for scene, has_rect in ((_scene(), True), (_scene("sphere"), False)):
        for o in scene.objects:  # one moving object, so per-frame passes exist
            o.kind = "static"
        scene.objects[1].kind = "animated"
        scene.objects[1].params["points_at"] = lambda f, p=scene.objects[1].mesh.points: p
        plan = make_plan(scene, area_lights=mode)
        runs = Pipeline(scene, area_lights=mode).area_lights == "gears"
        assert runs == (has_rect and mode == "gears")
        listed = any("area-light visibility (GEARS)" in o.passes for o in plan.objects)
        assert listed == runs and ("GEARS area-light structures" in plan.structures) == runs
        assert (plan.seconds_area > 0) == runs
        if runs:  # costed at the run's light samples (--area-k)
            assert make_plan(scene, area_lights=mode, area_k=32).seconds_area > plan.seconds_area


def test_static_scene_computes_the_pass_once_unless_the_light_moves():
    from warpshade.lighting import spin

    plane, lid = _plane_and_blocker()
    args = ([plane.points, lid.points], [plane.normals, lid.normals])
    still = AreaLightShading([plane, lid], [light()], static=True)
    first = still.irradiance(0.0, *args)
    assert still.irradiance(1.0, *args) is first  # nothing moves: frame 0's result is reused
    spun = AreaLightShading([plane, lid], [light().with_motion(spin((0, 1, 0), 90.0))], static=True)
    a, b = spun.irradiance(0.0, *args)[0], spun.irradiance(0.5, *args)[0]
    # the light turns 45° about the vertical through the centre: off-centre vertices see it change
    assert not np.allclose(a, b)


@pytest.mark.parametrize("blockers", [True, False])
@pytest.mark.parametrize("far", [1e3, 1e4])
def test_far_from_the_origin_the_irradiance_is_the_origins(blockers, far):
    """A 2 cm plane under a 1 cm light 2 cm up, moved ``far`` units: vertex by vertex the irradiance at the origin
    for the same float32 positions (so that only the shading's own rounding can differ). The unshadowed term was
    computed in world coordinates with the light's centre rounded to float32 there: max 0.06 % (1e3) and 1.9 %
    (1e4) of the largest irradiance apart, with or without blockers; now in the coordinates GEARS traces in
    (``rays.local_origin``)."""
    scale, shift = 0.01, np.array([far, far, -far])
    plane, lid = _plane_and_blocker()
    world = [(m.points * scale + shift).astype(np.float32) for m in (plane, lid)]
    local = [w.astype(np.float64) - shift for w in world]  # the same positions about the origin (exact)
    normals = [TriMesh(p, m.faces).normals for p, m in zip(local, (plane, lid))]
    count = 2 if blockers else 1

    def irradiance(points, offset):
        lt = light()
        lt = RectLight(center=lt.center * scale + offset, u=lt.u * scale, v=lt.v * scale, radiance=lt.radiance)
        meshes = [TriMesh(p, m.faces) for p, m in zip(points, (plane, lid))][:count]
        area = AreaLightShading(meshes, [lt], blocker_faces=None if blockers else [np.zeros((0, 3), int)])
        return area.irradiance(0.0, [m.points for m in meshes], normals[:count])[0]

    e0, e = irradiance(local, 0.0), irradiance(world, shift)
    assert e0[:, 0].max() > 0.1  # lit (Φ = 0.23 sr unshadowed at the plane's centre)
    # measured identical at 1e3 and 1e4; float32 rounding of the light's centre relative to the scene's local
    # origin (~6e-8 of the scene's size) would move it by ~1e-5 relative
    assert np.abs(e - e0).max() <= 1e-4 * np.abs(e0).max()
