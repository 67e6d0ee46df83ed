"""``warpshade:castsShadows = false`` in ``warpshade run``: the object receives shadows but blocks no light
in any pass (its own group's method, sphere sets between groups, GEARS rect lights), not even its own;
it still reflects light (one bounce). Ball (radius 0.5, centre 0.7 above the ground) over a ground grid."""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh

from warpshade.geometry import TriMesh
from warpshade.pipeline import Pipeline
from warpshade.planner import make_plan
from warpshade.scene import LightSpec, Material, Scene, SceneObject
from warpshade.visibility import METHODS

N = 21  # ground: N×N vertices on [-1.5, 1.5]² at y = 0, normals +y; vertex N*N//2 is the centre
CENTRE = N * N // 2
R, H = 0.5, 0.7  # ball radius and centre height [m]
GROUND_ALBEDO = 0.5
# Under a white dome of radiance 1 an unoccluded Lambertian vertex has exit radiance ρ (∫cos = π);
# the ball hides a cone of half-angle asin(R/H) from the centre vertex: sin²(asin(R/H)) of the irradiance.
UNSHADOWED = GROUND_ALBEDO
SHADOWED = GROUND_ALBEDO * (1 - (R / H) ** 2)


def ground_mesh() -> TriMesh:
    x = np.linspace(-1.5, 1.5, N)
    X, Z = np.meshgrid(x, x, indexing="ij")
    pts = np.stack([X.ravel(), np.zeros(N * N), Z.ravel()], 1)
    i = np.arange(N * N).reshape(N, N)
    faces = np.concatenate([np.stack([i[:-1, :-1], i[:-1, 1:], i[1:, 1:]], -1).reshape(-1, 3),
                            np.stack([i[:-1, :-1], i[1:, 1:], i[1:, :-1]], -1).reshape(-1, 3)])
    return TriMesh(pts, faces, name="ground")


def ball_mesh() -> TriMesh:
    ico = trimesh.creation.icosphere(subdivisions=2, radius=R)
    return TriMesh(np.asarray(ico.vertices) + (0.0, H, 0.0), np.asarray(ico.faces), name="ball")


def scene(ball_casts=True, ground_casts=True, ball_method="reference", ground_method="reference", lights=None):
    objs = [SceneObject("ground", ground_mesh(), method=ground_method, casts_shadows=ground_casts,
                        material=Material(albedo=np.full(3, GROUND_ALBEDO))),
            SceneObject("ball", ball_mesh(), method=ball_method, casts_shadows=ball_casts)]
    return Scene(objects=objs, frames=1, lights=lights or [LightSpec("dome", "sky")])


def shade(sc, **kw) -> tuple[dict, Pipeline]:
    """Exit radiance (R channel) per object of frame 0, and the pipeline."""
    pipe = Pipeline(sc, order=3, **kw)
    out = pipe.shader.build()(0, {})
    return {name: out[name][2][:, 0] for name in ("ground", "ball")}, pipe


def test_non_caster_leaves_the_ground_unshadowed_and_a_caster_darkens_it():
    off, pipe = shade(scene(ball_casts=False))
    assert [g.names for g in pipe.groups] == [["ground", "ball"]]  # still one group: the ball receives exactly
    # no blocker left above the ground: every reference ray escapes, and under a uniform dome only band 0
    # counts, so the estimate is exact up to float32 sums (measured 0.5000014)
    assert off["ground"][CENTRE] == pytest.approx(UNSHADOWED, rel=1e-5)
    assert np.allclose(off["ground"], UNSHADOWED, rtol=1e-5)
    on, _ = shade(scene(ball_casts=True))
    # analytic 0.2449; measured 0.2559 (the icosphere's faces lie inside the sphere, and 256 rays): 0.02
    assert on["ground"][CENTRE] == pytest.approx(SHADOWED, abs=0.02)
    # the ball is convex: its own triangles never shadowed it, so casting or not it gets the same shadow
    # from the ground (same rays; measured max difference 0 on this fixture)
    assert np.allclose(off["ball"], on["ball"], atol=1e-6)
    assert off["ball"].min() < 0.05  # its bottom faces the ground 0.2 below: dark


def test_non_caster_does_not_shadow_itself():
    # "casts no shadows" = invisible to shadow rays, its own included (RenderMan transmission off, Arnold
    # and Blender shadow visibility off). A ground that does not cast: the ball's underside sees the sky
    # below (a convex ball alone is exactly unoccluded: 0.8 grey, analytic), the ground still gets the
    # ball's shadow.
    res, _ = shade(scene(ground_casts=False))
    assert np.allclose(res["ball"], 0.8, rtol=1e-5)
    assert res["ground"][CENTRE] == pytest.approx(SHADOWED, abs=0.02)
    # a folded sheet (floor + wall, one mesh): casting, the floor vertex at the fold loses half its sky
    floor = ground_mesh()
    wall_pts = floor.points[:, [1, 0, 2]] * (1, 1, 1) + (-1.5, 1.5, 0)  # the x = -1.5 wall, y in [0, 3]
    folded = TriMesh(np.concatenate([floor.points, wall_pts]),
                     np.concatenate([floor.faces, floor.faces[:, ::-1] + len(floor.points)]), name="fold")
    fold_vertex = N // 2  # x = -1.5, z = 0: on the fold line
    for casts in (True, False):
        sc = Scene([SceneObject("ground", folded, method="reference", casts_shadows=casts,
                                material=Material(albedo=np.full(3, GROUND_ALBEDO)))], frames=1,
                   lights=[LightSpec("dome", "sky")])
        pipe = Pipeline(sc, order=3)
        rad = pipe.shader.build()(0, {})["ground"][2][:, 0]
        next_to_wall = N + N // 2  # one cell (0.15 m) from the wall: the 3 m wall hides ~half the sky
        if casts:
            assert rad[next_to_wall] < 0.8 * UNSHADOWED, rad[next_to_wall]
        else:
            assert np.allclose(rad, UNSHADOWED, rtol=1e-5), rad[[fold_vertex, next_to_wall]]


@pytest.mark.parametrize("method", sorted(METHODS))
def test_every_method_sees_a_non_caster_as_receiver_only(method):
    """The group's method gets the casters' triangles only; the non-caster's vertices receive (with the
    normals of their own triangles) and block nothing: the ground shades as if the ball were absent."""
    knobs = {"rays": 64} if method == "reference" else None
    alone = Scene([scene().objects[0]], frames=1, lights=[LightSpec("dome", "sky")])
    alone.objects[0].method = method
    base = Pipeline(alone, order=3, knobs=knobs, method=method).shader.build()(0, {})["ground"][2][:, 0]
    res, pipe = shade(scene(ball_casts=False), method=method, knobs=knobs)
    assert len(pipe.groups) == 1
    # same blocker triangles, same receivers' normals: measured max difference 0 for all four methods;
    # 1e-6 leaves room for float32 summation order only
    assert np.allclose(res["ground"], base, rtol=0, atol=1e-6), np.abs(res["ground"] - base).max()
    assert np.isfinite(res["ball"]).all() and (res["ball"] >= 0).all()
    # the ball's underside is shadowed by the ground through the group's method
    assert res["ball"].min() < 0.5 * 0.8


def test_between_groups_sphere_sets_skip_non_casters():
    # ground: unoccluded group of its own; ball: reference, a group with no caster, so unoccluded too
    res, pipe = shade(scene(ball_casts=False, ground_method=None))
    assert [(g.method, g.names) for g in pipe.groups] == [(None, ["ground"]), (None, ["ball"])]
    assert res["ground"][CENTRE] == pytest.approx(UNSHADOWED, rel=1e-6)  # no sphere set from the ball
    # the ground's spheres still shadow the ball's underside (measured 0.074)
    assert res["ball"].min() < 0.5 * 0.8
    on, _ = shade(scene(ball_casts=True, ground_method=None))
    # the sphere set of a casting ball darkens the centre (measured 0.151, analytic 0.245: sphere sets
    # over-shadow an open ground, docs/methods/spheres.md)
    assert on["ground"][CENTRE] < 0.7 * UNSHADOWED


def test_gears_rect_light_ignores_non_casters():
    from test_area_lights import A, H as LH, _scene, light, parallel_rect_phi

    lt = light()
    unshadowed = 0.5 / math.pi * parallel_rect_phi(A, A, LH) * lt.radiance
    shadowed = 0.5 / math.pi * (parallel_rect_phi(A, A, LH) - parallel_rect_phi(0.3125, 0.3125, LH)) * lt.radiance
    for lid_casts, plane_casts, expected in ((True, True, shadowed), (False, True, unshadowed),
                                             (False, False, unshadowed)):
        sc = _scene()
        sc.objects[1].casts_shadows = lid_casts
        sc.objects[0].casts_shadows = plane_casts
        pipe = Pipeline(sc, order=3, lights=[lt], area_lights="gears", between=None)
        rad = pipe.shader.build()(0, {})["plane"][2]
        # unblocked: the weighted visible share is exactly 1, so E is the exact Lambert irradiance
        # (float32 kernel vs float64 formula: 1e-6); blocked: as test_area_lights (measured 2e-5, 1e-3)
        assert rad[220] == pytest.approx(expected, rel=1e-6 if expected is unshadowed else 1e-3), (lid_casts,
                                                                                                  plane_casts)


def test_non_caster_still_reflects_light():
    # reflections: castsShadows is about shadow rays toward lights; a surface that casts no shadows is
    # still seen by indirect rays (it reflects light onto the ground, and its spheres occlude reflected light)
    added = {}
    for casts in (False, True):
        plain, _ = shade(scene(ball_casts=casts))
        bounce, _ = shade(scene(ball_casts=casts), reflections=True)
        added[casts] = bounce["ground"] - plain["ground"]
    # the grey ball's lit upper half is hidden from the ground; its dark underside still adds: measured +0.017
    assert added[False][CENTRE] > 0.01, added[False][CENTRE]
    # the bounce does not depend on the flag: the ball's exit radiance is the same either way (convex ball)
    assert np.allclose(added[False], added[True], atol=1e-5), np.abs(added[False] - added[True]).max()


def test_plan_costs_what_the_run_executes():
    sc = scene(ball_casts=False, ground_method=None)
    plan = make_plan(sc)
    run_groups = Pipeline(sc, order=3).groups
    assert [(g.method, g.names) for g in plan.groups] == [(g.method, g.names) for g in run_groups]
    ball = plan.object("ball")
    assert ball.method is None and ball.transfer == "none"
    ground_g, ball_g = plan.groups
    # the ground group is shadowed by no other group (the ball casts nothing); the ball's by the ground's spheres
    assert ground_g.seconds_between == 0.0 and ball_g.seconds_between > 0.0
    assert "sphere sets of shadow casters" in plan.structures
    nobody = scene(ball_casts=False, ground_casts=False, ground_method=None)
    assert "sphere sets of shadow casters" not in make_plan(nobody).structures
    # an unshaded object is no shadow caster in the run (docs/guide/quickstart.md, warpshade:shaded): nor in the plan
    collider = scene(ground_method=None)
    collider.objects[1].shaded = False
    collider.objects[1].kind = "animated"  # a moving caster would make the static ground re-shade every frame
    assert "sphere sets of shadow casters" not in make_plan(collider).structures
    assert make_plan(collider).object("ground").passes == []
    # in one group the method's blockers are the casters' triangles only
    one = make_plan(scene(ball_casts=False))
    assert one.groups[0].caster_triangles == ground_mesh().num_faces
    assert one.groups[0].triangles == ground_mesh().num_faces + ball_mesh().num_faces
    assert f"({ground_mesh().num_faces} of them cast shadows" in one.describe()


def test_cli_run_reads_casts_shadows_from_usd(tmp_path, capsys):
    from pxr import Sdf, Usd, UsdGeom

    from test_spheres_pipeline import _ball_on_ground  # ball radius 0.5 at 0.7 over a 21×21 ground
    from warpshade.cli import main

    path = _ball_on_ground(tmp_path / "scene.usda")
    st = Usd.Stage.Open(path)
    st.GetPrimAtPath("/World/ball").CreateAttribute("warpshade:castsShadows", Sdf.ValueTypeNames.Bool).Set(False)
    st.GetRootLayer().Save()
    out = tmp_path / "out.usda"
    assert main(["run", path, "--out", str(out), "--frames", "1", "--no-progress", "--workers", "0",
                 "--method", "reference", "--rays", "16", "--order", "2"]) == 0
    assert "casting no shadows: /World/ball" in capsys.readouterr().err
    stage = Usd.Stage.Open(str(out))
    col = np.asarray(UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/World/ground")).GetPrimvar("displayColor").Get(0))
    # the ground (albedo 0.5) is unoccluded everywhere: exact up to float32 whatever the ray count
    assert np.allclose(col, 0.5, rtol=1e-5), col.min()


def test_sphere_tree_leaves_out_vertices_in_no_triangle():
    from warpshade.visibility.spheres.fitting import build_sphere_tree

    ball = ball_mesh()
    extra = np.array([[5.0, 5.0, 5.0], [-3.0, 0.0, 1.0]])  # far away: any sphere bounding them would be huge
    alone = build_sphere_tree(ball.points, ball.faces, spheres=8, levels=2)
    padded = build_sphere_tree(np.concatenate([extra, ball.points]), ball.faces + len(extra), spheres=8, levels=2)
    assert np.allclose(padded.centers, alone.centers) and np.allclose(padded.radii, alone.radii)
    assert np.array_equal(padded.vert_index, alone.vert_index + len(extra))  # indices into the padded points
