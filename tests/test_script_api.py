"""The Python scene API (warpshade.script): a scene built in a script is simulated, shaded and
written by the Pipeline, with visible contact shadows; geometry-only output shows the albedo; the
sims/ scripts shade by default; bad arguments are named."""

from __future__ import annotations

import os
import warnings
import subprocess
import sys

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, UsdShade

import warpshade as ws
from warpshade.scene import SceneWarning

from helpers import REPO

FRAMES = 30  # the cloth falls 0.3 m onto the box in ~15 frames (sqrt(2 * 0.3 / 9.81) s at 60 fps)


def _cloth_over_box():
    return ws.make_scene(
        ws.ground(size=2.0, resolution=33),
        ws.box(size=0.5),
        ws.cloth_grid(size=1.0, resolution=24, height=0.8),
        ws.sky(),
    )


def _colors(stage, name, t):
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath(f"/World/{name}"))
    pts = np.asarray(mesh.GetPointsAttr().Get(t), dtype=np.float64)
    col = np.asarray(UsdGeom.PrimvarsAPI(mesh).GetPrimvar("displayColor").Get(t), dtype=np.float64)
    return pts, col


@pytest.fixture(scope="module")
def draped(tmp_path_factory):
    out = str(tmp_path_factory.mktemp("script") / "cloth_box.usda")
    report = ws.run(_cloth_over_box(), out, frames=FRAMES)
    return report, Usd.Stage.Open(out)


def test_cloth_over_box_is_lit_with_contact_shadows(draped):
    report, stage = draped
    assert report.frames == FRAMES
    t = FRAMES - 1
    cloth, _ = _colors(stage, "Cloth", t)
    assert cloth[:, 1].max() < 0.56, "the cloth should rest on the 0.5 m box"  # top 0.5 + thickness + folds
    gp, gc = _colors(stage, "Ground", t)
    bp, bc = _colors(stage, "Box", t)
    for name, c in (("Ground", gc), ("Box", bc), ("Cloth", _colors(stage, "Cloth", t)[1])):
        assert np.isfinite(c).all() and c.mean() > 0.05, (name, c.mean(0))  # lit, not black
    lum = lambda c: c @ [0.2126, 0.7152, 0.0722]  # noqa: E731
    r = np.maximum(np.abs(gp[:, 0]), np.abs(gp[:, 2]))  # box-norm distance from the box's axis
    near = lum(gc[(r > 0.25) & (r < 0.33)])  # the ground ring at the box's foot, under the hanging cloth
    far = lum(gc[r > 0.85])
    assert near.size and far.size
    # measured: near/far 0.60 here (top/far 0.10); unoccluded ground (no shadows) gives exactly 1 (uniform colour)
    assert near.mean() < 0.8 * far.mean(), (near.mean(), far.mean())
    top = lum(bc[bp[:, 1] > 0.499])  # the box's top face, covered by the cloth
    # same normal and albedo as the far ground, so unoccluded it would match it; covered, it is far darker
    assert top.mean() < 0.5 * far.mean(), (top.mean(), far.mean())
    dome = [p for p in stage.Traverse() if p.GetTypeName() == "DomeLight"]
    assert dome, "the sky is written as a DomeLight"


def test_no_shade_writes_geometry_with_albedo(tmp_path):
    out = str(tmp_path / "geo.usda")
    scene = ws.make_scene(ws.ground(size=2.0, resolution=9, albedo=(0.2, 0.5, 0.3)),
                     ws.cloth_grid(size=0.5, resolution=6, height=0.3, albedo=0.6))
    ws.run(scene, out, frames=3, shade=False)
    stage = Usd.Stage.Open(out)
    for name, albedo in (("Ground", (0.2, 0.5, 0.3)), ("Cloth", (0.6, 0.6, 0.6))):
        for t in range(3):
            _, col = _colors(stage, name, t)
            np.testing.assert_allclose(col, np.broadcast_to(albedo, col.shape), atol=1e-6)
        prim = stage.GetPrimAtPath(f"/World/{name}")
        mat = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()[0]
        surf = UsdShade.Shader(stage.GetPrimAtPath(f"{mat.GetPath()}/PreviewSurface"))
        np.testing.assert_allclose(surf.GetInput("diffuseColor").Get(), albedo, atol=1e-6)
    p0, _ = _colors(stage, "Cloth", 0)
    p2, _ = _colors(stage, "Cloth", 2)
    assert p2[:, 1].mean() < p0[:, 1].mean()  # the same simulation runs: it falls


def test_pipeline_simulate_steps_frames():
    pipe = ws.script.pipeline(_cloth_over_box(), frames=4)
    heights = [geo["Cloth"][:, 1].mean() for _, geo in pipe.simulate()]
    assert len(heights) == 4 and heights[0] == pytest.approx(0.8) and heights[3] < heights[1]


@pytest.mark.parametrize("gravity", [(2.0, 0.0, 0.0), (0.0, 0.0, 0.0)])
def test_make_scene_gravity_moves_the_cloth(gravity):
    """``make_scene(gravity=)`` is the cloth's gravity (as a USD scene's PhysicsScene): a free cloth, nothing
    else in the scene, falls along it by 1/2 g t² to within the integrator's own error (a fraction 1/substeps
    of the fall: symplectic Euler over n substeps runs ahead by (1 + 1/n)/2 g t², measured 1.0625 x at n = 8),
    and floats without it."""
    substeps, fps = 8, 60.0
    scene = ws.make_scene(ws.cloth_grid(resolution=5, size=0.2), gravity=gravity, fps=fps, substeps=substeps)
    start = scene.object("Cloth").mesh.points.astype(np.float64).mean(axis=0)
    moved = np.array([geo["Cloth"].mean(axis=0) - start for _, geo in ws.script.pipeline(scene, frames=6).simulate()])
    t = np.arange(6) / fps  # simulate() gives the start pose first
    half = 0.5 * np.asarray(gravity)[None, :] * (t * t)[:, None]
    np.testing.assert_allclose(moved, half, atol=1e-6 + np.abs(half).max() / substeps)
    if not any(gravity):
        assert np.abs(moved).max() < 1e-6


def test_moving_mesh_from_a_generator(tmp_path):
    pts = np.array([[0, 0.2, 0], [1, 0.2, 0], [0, 0.2, -1.0]])
    frames = ({"Tri": pts + [0, 0.1 * f, 0]} for f in range(3))
    out = str(tmp_path / "gen.usda")
    ws.run(ws.make_scene(ws.ground(size=3.0, resolution=9), ws.mesh("Tri", pts, [[0, 1, 2]], moving=True)), out,
           frames=3, geometry=frames)
    p, c = _colors(Usd.Stage.Open(out), "Tri", 2)
    np.testing.assert_allclose(p, pts + [0, 0.2, 0], atol=1e-6)
    assert c.mean() > 0.05


def test_sims_script_writes_shaded_output_by_default(tmp_path):
    out = tmp_path / "drape.usda"
    proc = subprocess.run([sys.executable, os.path.join(REPO, "sims", "drape_sphere.py"), "--frames", "2",
                           "--grid", "8", "--out", str(out)], capture_output=True, text=True, timeout=600,
                          env={**os.environ, "PYTHONPATH": os.path.abspath(REPO)})
    assert proc.returncode == 0, proc.stderr
    stage = Usd.Stage.Open(str(out))
    _, col = _colors(stage, "cloth", 1)
    assert col.mean() > 0.05 and np.ptp(col[:, 1]) > 0.01  # lit, and shaded (not the constant albedo)
    mat = UsdShade.MaterialBindingAPI(stage.GetPrimAtPath("/World/cloth")).ComputeBoundMaterial()[0]
    assert mat.GetPath().name.endswith("_radiance")


@pytest.mark.parametrize("make, match", [
    (lambda: ws.cloth_grid(resolution=1), "resolution"),
    (lambda: ws.cloth_grid(size=-1.0), "size"),
    (lambda: ws.cloth_grid(resolution=4, pinned=[99]), "pinned vertex 99"),
    (lambda: ws.cloth_grid(resolution=4, pinned=[0.5]), "cloth 'Cloth': pinned: vertex indices must be integers"),
    (lambda: ws.box(size=0), "'Box': size"),
    (lambda: ws.box(center=(0, 1)), "'Box': center"),
    (lambda: ws.sphere(radius=-2), "radius"),
    (lambda: ws.capsule(radius=0), "'Capsule': radius"),
    (lambda: ws.cylinder(height=0), "'Cylinder': height"),
    (lambda: ws.cone(axis="W"), "'Cone': axis"),
    (lambda: ws.cylinder(axis=(0, 0, 0)), "'Cylinder': axis must not be zero"),
    (lambda: ws.ground(albedo=2.0), "albedo"),
    (lambda: ws.distant(direction=(0, 0, 0)), "direction"),
    (lambda: ws.make_scene(ws.box(), ws.box()), "two objects are named 'Box'"),
    (lambda: ws.make_scene(ws.box(), gravity=(0, float("nan"), 0)), "make_scene: gravity must be 3 finite numbers"),
    (lambda: ws.make_scene(ws.box(), substep=4), "make_scene: 'substep' is not a scene setting \\(did you mean "
     "'substeps'\\?\\)"),
    (lambda: ws.cloth_grid(resolution=4, attached=[0]), "attached and attach_to go together"),
    (lambda: ws.cloth_grid(resolution=4, attached=[16], attach_to="Bar"), "attached vertex 16 out of range"),
    (lambda: ws.make_scene(ws.cloth_grid(resolution=4, attached=[0], attach_to="Bar")),
     "cloth 'Cloth' is attached to 'Bar', which is not an object of the scene"),
    (lambda: ws.make_scene(ws.box(name="Bar"), ws.cloth_grid(resolution=4, attached=[0], attach_to="Bar")),
     "attached to 'Bar', which does not move"),
    (lambda: ws.run(ws.make_scene(ws.mesh("M", np.eye(3), [[0, 1, 2]], moving=True)), "x.usda", frames=1),
     "no geometry generator"),
    (lambda: ws.run(ws.make_scene(ws.sky(up="Z")), "x.usda", frames=1), "up axis"),
    # wrong types and shapes: each names its helper, object and argument (before: numpy's or float()'s own message,
    # or no error at all where the value was reshaped, truncated or ignored)
    (lambda: ws.cloth_grid(height="abc"), "cloth_grid 'Cloth': height must be a finite number, got 'abc'"),
    (lambda: ws.cloth_grid(center=(0, 0, 0)), "cloth_grid 'Cloth': center \\(X and Z\\) must be 2 finite numbers"),
    (lambda: ws.cloth_grid(resolution="8"), "cloth_grid 'Cloth': resolution must be an int >= 2 or two, got '8'"),
    (lambda: ws.cloth_grid(name=3), "cloth_grid: name must be a non-empty string, got 3"),
    (lambda: ws.cloth_grid(resolution=4, stiffness=3.0),
     "cloth 'Cloth': warpshade:cloth:stiffness is not a cloth attribute \\(did you mean 'bendStiffness'\\?\\)"),
    (lambda: ws.cloth_grid(resolution=4, density="x"), "cloth 'Cloth': warpshade:cloth:density must be a finite number"),
    (lambda: ws.cloth_grid(resolution=4, selfCollision="yes"), "warpshade:cloth:selfCollision must be a bool"),
    (lambda: ws.cloth_grid(resolution=4, iterations=2.5), "warpshade:cloth:iterations must be an integer"),
    (lambda: ws.ground(resolution=None), "ground 'Ground': resolution must be an int >= 2, got None"),
    (lambda: ws.ground(height="x"), "ground 'Ground': height must be a finite number"),
    (lambda: ws.sphere(albedo="red"), "sphere 'Sphere': albedo must be a number or RGB in \\[0, 1\\], got 'red'"),
    (lambda: ws.capsule(height="x"), "capsule 'Capsule': height must be a number > 0"),
    (lambda: ws.mesh("M", np.zeros((3, 4)), [[0, 1, 2]]), ("mesh 'M': points must be numbers of shape \\(V, 3\\), "
                                                           "got shape \\(3, 4\\)")),
    (lambda: ws.mesh("M", np.eye(3), [[0, 1, 2.5]]), "mesh 'M': faces must be integer vertex indices of shape"),
    (lambda: ws.mesh("M", np.eye(4, 3), [[0, 1, 2, 3]]), "mesh 'M': faces .* \\(triangles\\), got shape \\(1, 4\\)"),
    (lambda: ws.cloth("C", np.zeros((6, 2)), [[0, 1, 2]]), "cloth 'C': points must be numbers of shape \\(V, 3\\)"),
    (lambda: ws.sky(sun_elevation="x"), "sky: sun_elevation must be a finite number"),
    (lambda: ws.distant(intensity="x"), "distant 'Sun': intensity must be a finite number"),
    (lambda: ws.distant(angle=-1), "distant 'Sun': angle \\[degrees\\] must be a non-negative number"),
    (lambda: ws.dome(texture=3), "dome 'Dome': texture must be a file path"),
    (lambda: ws.make_scene(ws.box(), fps=0), "make_scene: fps must be a number > 0"),
    (lambda: ws.make_scene(ws.box(), fps=-24), "make_scene: fps must be a number > 0"),
    (lambda: ws.make_scene(ws.box(), frames=0), "make_scene: frames must be an int >= 1, got 0"),
    (lambda: ws.make_scene(ws.box(), frames=2.5), "make_scene: frames must be an int >= 1, got 2.5"),
    (lambda: ws.make_scene(ws.box(), up="X"), "make_scene: up must be 'Y' or 'Z', got 'X'"),
    (lambda: ws.make_scene(ws.box(), order="x"), "make_scene: order must be an int >= 1, got 'x'"),
    (lambda: ws.make_scene(ws.box(), wind=(1, 2)), "make_scene: wind \\[m/s\\] must be 3 finite numbers"),
    (lambda: ws.make_scene(ws.box(), reflections="yes"), "make_scene: reflections must be True or False"),
])
def test_bad_input_names_the_argument(tmp_path, monkeypatch, make, match):
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ValueError, match=match):
        make()


def test_scene_rejects_other_items():
    with pytest.raises(TypeError, match="item 1 is a str"):
        ws.make_scene(ws.box(), "sky")


def test_short_generator_names_the_frame(tmp_path):
    pts = np.array([[0, 0.2, 0], [1, 0.2, 0], [0, 0.2, -1.0]])
    with pytest.raises(ValueError, match="ended after 1 frames; the run needs frame 1"):
        ws.run(ws.make_scene(ws.mesh("Tri", pts, [[0, 1, 2]], moving=True)), str(tmp_path / "s.usda"), frames=3,
               geometry=[{"Tri": pts}])


EDGE = 0.05
"""Target edge of the tessellations compared [m]: several rings along the shapes' profiles below."""


def _usd_axial(shape, radius, height, axis, translate):
    """The USD reader's object for a Capsule/Cylinder/Cone gprim with PhysicsCollisionAPI."""
    from pxr import UsdPhysics

    from warpshade.usd.scene_io import scene_from_stage

    st = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(st, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(st, 1.0)
    g = getattr(UsdGeom, shape).Define(st, f"/World/{shape}")
    g.CreateRadiusAttr(radius)
    g.CreateHeightAttr(height)
    g.CreateAxisAttr(axis)
    UsdGeom.XformCommonAPI(g).SetTranslate(translate)
    UsdPhysics.CollisionAPI.Apply(g.GetPrim())
    g.GetPrim().CreateAttribute("warpshade:edgeLength", Sdf.ValueTypeNames.Float).Set(EDGE)
    return scene_from_stage(st, source="t.usda").objects[0]


@pytest.mark.parametrize("make, shape, axis", [(ws.capsule, "Capsule", "X"), (ws.cylinder, "Cylinder", "Y"),
                                               (ws.cone, "Cone", "Z")])
def test_axial_shapes_are_the_usd_readers_gprims(make, shape, axis):
    """ws.capsule/cylinder/cone make what the USD reader makes of the same gprim with
    PhysicsCollisionAPI: the same exact analytic collider and, for the same target edge, the same
    tessellation."""
    centre, r, h = (0.3, 0.7, -0.2), 0.2, 0.6
    obj = make(center=centre, radius=r, height=h, axis=axis, edge=EDGE)
    ref = _usd_axial(shape, r, h, axis, centre)
    kind = shape.lower()
    assert obj.params["collider"] == ref.params["collider"] == kind
    for key, value in ref.params[kind].items():
        np.testing.assert_allclose(obj.params[kind][key], value, atol=1e-12, err_msg=key)
    np.testing.assert_allclose(obj.mesh.points, ref.mesh.points, atol=1e-9)  # same build, same frame
    np.testing.assert_array_equal(obj.mesh.faces, ref.mesh.faces)
    assert "collider" not in make(collider=False).params


def test_axial_shapes_stand_on_the_ground_and_follow_any_axis():
    for make in (ws.capsule, ws.cylinder, ws.cone):
        assert make().mesh.points[:, 1].min() == pytest.approx(0.0, abs=1e-12), make.__name__
    d = np.array([1.0, 1.0, 0.0]) / np.sqrt(2)
    c = ws.cylinder(center=(0, 1, 0), radius=0.1, height=1.0, axis=d)
    np.testing.assert_allclose(c.params["cylinder"]["p1"] - c.params["cylinder"]["p0"], d, atol=1e-12)
    # every vertex of the tessellation is on the tilted cylinder's surface: on a cap or at the radius
    p = c.mesh.points - [0, 1, 0]
    along = p @ d
    radial = np.linalg.norm(p - along[:, None] * d, axis=1)
    tol = 2e-7  # TriMesh points are float32: half an ulp at 1.0 is 6e-8, at 1.2 (the top end) 1.2e-7
    on_cap = np.isclose(np.abs(along), 0.5, atol=tol)
    assert np.all(on_cap | np.isclose(radial, 0.1, atol=tol)) and np.all(np.abs(along) <= 0.5 + tol)


def test_cloth_drapes_on_a_script_cylinder_without_entering_it():
    """A cloth dropped across a horizontal ws.cylinder collides with the exact solid (distance to
    it from the NumPy formula below, not the solver's): no vertex inside the contact layer at any
    frame, and the cloth ends resting on it."""
    from warpshade.pipeline.cloth import ClothSimulation

    r, h = 0.15, 1.0
    scene = ws.make_scene(ws.cylinder(center=(0, 0.3, 0), radius=r, height=h, axis="X"),
                          ws.cloth_grid(size=0.6, resolution=12, height=0.5))
    sim = ClothSimulation(scene)
    assert sim.solver.colliders.shape_count == 1 and not sim.solver.colliders.meshes
    th = sim.model.thickness

    def signed_distance(x):  # capped cylinder along X through (0, 0.3, 0)
        q = x - [0, 0.3, 0]
        dr = np.linalg.norm(q[:, 1:], axis=1) - r
        da = np.abs(q[:, 0]) - h / 2
        outside = np.linalg.norm(np.stack([np.maximum(dr, 0), np.maximum(da, 0)], 1), axis=1)
        return outside + np.minimum(np.maximum(dr, da), 0)

    worst = np.inf
    for f in range(1, 31):  # 0.5 s: falls 0.05 m in 0.1 s, then drapes over the curve
        x = sim.advance(f, {})["Cloth"].astype(np.float64)
        worst = min(worst, signed_distance(x).min())
    assert worst >= th - 1e-5, (worst, th)  # 1e-5 m: float32 positions of size ~1 (1e-7) with margin
    # resting: edges are kept at the thickness, so a vertex rests up to the sagitta of a 0.055 m
    # edge on the 0.15 m radius (2.5 mm) above it; measured 2.2 mm
    assert (signed_distance(x) < th + 4e-3).sum() >= 3, "the cloth is not resting on the cylinder"


def test_a_cloth_attached_to_a_moving_mesh_follows_it():
    """``attached``/``attach_to``: the grid's back row keeps its rest offset from the nearest vertex of a bar
    that rises and slides (``points_at``), every frame, while the rest of the cloth hangs from it."""
    bar = np.array([[-0.6, 1.0, 0.55], [0.6, 1.0, 0.55], [0.0, 1.1, 0.55]])

    def bar_at(code):
        return bar + [0.1 * code / 6, 0.05 * code / 6, 0.0]

    row = np.arange(8)  # vertex (i, 0): the grid's row at z = +size/2 (cloth_grid's layout, j * nx + i)
    scene = ws.make_scene(ws.mesh("Bar", bar, [[0, 1, 2]], points_at=bar_at),
                          ws.cloth_grid(size=1.0, resolution=8, height=1.0, attached=row, attach_to="Bar"))
    rest = scene.object("Cloth").mesh.points[row]
    nearest = np.argmin(((rest[:, None] - bar[None]) ** 2).sum(-1), axis=1)
    assert np.allclose(rest[:, 2], 0.5)  # the row is the cloth's edge at z = +0.5
    for frame, points in ws.script.pipeline(scene, frames=6).simulate():
        # float32 positions of a metre-sized scene: a few ulps; 1e-5 m is ample
        np.testing.assert_allclose(points["Cloth"][row], bar_at(frame)[nearest] + rest - bar[nearest], atol=1e-5)
    assert points["Cloth"][-1, 1] < 1.0 - 0.01  # the free far edge has fallen (it hangs from the bar)


@pytest.mark.parametrize("normalize", [True, False])
def test_distant_light_intensity_is_irradiance_unless_unnormalized(tmp_path, normalize):
    """``ws.distant(intensity=E)`` lights a floor facing it with irradiance E (normalized, the default,
    as Blender writes a Sun), or with E pi sin^2(angle/2) when E is the disc's radiance (UsdLux's
    unnormalized light). Expected exit radiance rho E / pi times the SH order-4 truncation's gain for a
    (near-)delta light along the normal, sum_{l<4} A_l (2l+1) / (4 pi) with the clamped cosine's
    A_l = pi, 2pi/3, pi/4, 0: (1 + 2 + 1.25 + 0) / 4 = 1.0625. Tolerance 1e-4 relative: float32
    shading (measured 1.06249 / 1.0625)."""
    rho, e, angle = 0.5, 3.0, 0.53
    scene = ws.make_scene(ws.ground(size=2.0, resolution=9, albedo=(rho, rho, rho)),
                          ws.distant(direction=(0, -1, 0), intensity=e, angle=angle, normalize=normalize), frames=1)
    out = str(tmp_path / "sun.usda")
    ws.run(scene, out, frames=1)
    stage = Usd.Stage.Open(out)
    _, col = _colors(stage, "Ground", 0)
    irradiance = e if normalize else e * np.pi * np.sin(np.radians(angle) / 2) ** 2
    np.testing.assert_allclose(col, rho * irradiance / np.pi * 1.0625, rtol=1e-4)
    assert stage.GetPrimAtPath("/World/Lights/Sun").GetAttribute("inputs:normalize").Get() is normalize


def test_a_dim_unnormalized_sun_is_warned_of(tmp_path):
    """An unnormalized DistantLight of intensity 3 (the disc's radiance) gives an irradiance of 2e-4:
    the run warns, naming the light and the fix; a normalized one, or the UsdLux sun of 50000, does not."""
    def run(**kw):
        scene = ws.make_scene(ws.ground(size=2.0, resolution=5), ws.distant(**kw), frames=1)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            ws.run(scene, str(tmp_path / "sun.usda"), frames=1, shade=False)
        return [str(w.message) for w in caught if issubclass(w.category, SceneWarning)]

    dim = run(intensity=3.0, normalize=False)
    assert len(dim) == 1 and "Sun" in dim[0] and "inputs:normalize" in dim[0] and "irradiance of only 0.0002 " in dim[0]
    assert run(intensity=3.0) == []
    assert run(intensity=50000.0, normalize=False) == []


def test_moving_points_of_another_shape_name_the_mesh_and_frame(tmp_path):
    """Before: 'frames 0-1: shading failed: ValueError: operands could not be broadcast together ...'."""
    from warpshade.scene import SceneError

    tri = np.eye(3)
    with pytest.raises(SceneError, match="T: frame 1 \\(time code 1\\): points of shape \\(4, 3\\), but the mesh has 3 "
                                         "vertices"):
        ws.run(ws.make_scene(ws.mesh("T", tri, [[0, 1, 2]], moving=True)), str(tmp_path / "x.usda"), frames=2,
               geometry=[{"T": tri}, {"T": np.zeros((4, 3))}])


@pytest.mark.parametrize("make, error, match", [
    (lambda: ws.Pipeline(ws.make_scene(ws.box()), frames=1.5), ValueError, "frames must be an integer >= 1, got 1.5"),
    (lambda: ws.Pipeline(ws.make_scene(ws.box()), frames="2"), ValueError, "frames must be an integer >= 1, got '2'"),
    (lambda: ws.run("scene.usda", "x.usda", frames=1), TypeError,
     "ws.run \\(ws.script.pipeline\\): scene must be a Scene \\(warpshade.make_scene, or warpshade.usd.read_scene"),
    (lambda: ws.Pipeline("scene.usda"), TypeError, "Pipeline: scene must be a Scene"),
])
def test_run_arguments_of_the_wrong_type_are_named(tmp_path, monkeypatch, make, error, match):
    """Before: frames=1.5 ran 1 frame, frames='2' ran 2, a file name was "'str' object has no attribute 'objects'"."""
    monkeypatch.chdir(tmp_path)
    with pytest.raises(error, match=match):
        make()
