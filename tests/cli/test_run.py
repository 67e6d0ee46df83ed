"""The main job, ``warpshade run``: end to end on shipped scenes with few frames; shading checks."""

from __future__ import annotations

import math
import os
import shlex
import sys

import numpy as np
import pytest
from pxr import Usd, UsdGeom, UsdLux

from helpers import REPO, grid  # the same tiny fixture
from warpshade.cli import main
from warpshade.pipeline import Pipeline, unoccluded_transfer
from warpshade.radiance import exit_radiance
from warpshade.scene import LightSpec, Scene, SceneObject
from warpshade.geometry import TriMesh
from warpshade.usd import AnimationWriter, read_scene
from warpshade.usd.validate import validation_errors


SCENES = os.path.join(REPO, "usd_scenes")


def test_unoccluded_transfer_matches_contract_constants():
    # docs/conventions.md §2: T_lm = sqrt(4π/(2l+1)) A_l y_lm(n); for n = +z only m = 0 terms survive and
    # y_l0(+z) = sqrt((2l+1)/4π), so T_l0 = A_l.
    t = unoccluded_transfer(np.array([[0.0, 0.0, 1.0]]), 5)[0]
    a = [math.sqrt(math.pi) / 2, math.sqrt(math.pi / 3), math.sqrt(5 * math.pi) / 8, 0.0, -math.sqrt(math.pi) / 16]
    assert np.allclose([t[l * (l + 1)] for l in range(5)], a, atol=1e-6)
    assert np.allclose(np.delete(t, [l * (l + 1) for l in range(5)]), 0, atol=1e-6)


def test_unshadowed_plane_under_uniform_sky_has_albedo_radiance():
    # A uniform environment of radiance L gives irradiance πL on any unoccluded surface, so the exit
    # radiance is ρL (analytic); order 2 represents a constant exactly.
    t = unoccluded_transfer(np.array([[0.0, 1.0, 0.0], [0.6, 0.8, 0.0]]), 2)
    sh = np.zeros((4, 3))
    sh[0] = np.array([1.0, 2.0, 3.0]) * math.sqrt(4 * math.pi)
    rad = exit_radiance(t, sh, np.array([0.5, 0.5, 0.25])).numpy()
    assert np.allclose(rad, [[0.5, 1.0, 0.75]] * 2, rtol=1e-5)


def _plane_scene(method):
    pts, faces = grid(9)  # 9x9 vertices on [-1, 1]² at y = 0; vertex 40 is the centre
    pts = (pts - (0.5, 0, 0.5)) * 2
    ground = SceneObject("ground", TriMesh(pts, faces), method=method)
    blocker = SceneObject("lid", TriMesh(pts * 0.3 + (0, 0.2, 0), faces), method=method, kind="animated",
                          params={"points_at": lambda f: (pts * 0.3 + (0, 0.2 + 0.1 * f, 0)).astype(np.float32)})
    return Scene(objects=[ground, blocker], frames=3, lights=[LightSpec("dome", "sky", color=(1.0, 1.0, 1.0))])


def test_objects_in_one_group_shadow_each_other(tmp_path):
    scene = _plane_scene("reference")
    report = Pipeline(scene, order=3, knobs=None).run(AnimationWriter(str(tmp_path / "o.usda")), progress=False)
    assert report.frames == 3 and len(report.groups) == 1
    stage = Usd.Stage.Open(str(tmp_path / "o.usda"))
    for prim in ("/World/ground", "/World/lid"):  # docs/conventions.md §6: every shaded mesh, static or not
        m = UsdGeom.Mesh(stage.GetPrimAtPath(prim))
        for attr in (m.GetPointsAttr(), m.GetNormalsAttr(), m.GetExtentAttr()):
            assert attr.GetTimeSamples() == [0.0, 1.0, 2.0], (prim, attr.GetName())
    col = np.asarray(UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/World/ground")).GetPrimvar("displayColor").Get(0))
    centre, corner = col[40, 0], col[0, 0]
    # under a white dome of radiance 1 an open vertex gets ρ·1 = 0.8
    # (a uniform light needs band 0 only, so the order does not matter); the lid (0.025 sr seen
    # from the corner) and 256-ray noise stay within 5 %. The centre sits under the lid: its
    # 56° half-angle blocks sin²(56°) ≈ 69 % of the irradiance.
    assert corner == pytest.approx(0.8, rel=0.05)
    assert centre == pytest.approx(0.8 * (1 - math.sin(math.atan(1.5)) ** 2), abs=0.08)
    # the lid moves up over time: the centre brightens
    later = np.asarray(UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/World/ground")).GetPrimvar("displayColor").Get(2))
    assert later[40, 0] > centre


@pytest.mark.parametrize("scene", ["skinned_arm.usda", "dome_texture.usda"])
def test_run_shipped_scenes_write_their_lights(tmp_path, scene):
    out = tmp_path / "out.usda"
    assert main(["run", os.path.join(SCENES, scene), "--frames", "2", "--out", str(out), "--no-progress",
                 "--workers", "0", "--method", "reference", "--rays", "4", "--write-transfer", "--order", "3"]) == 0
    stage = Usd.Stage.Open(str(out))
    lights = [p for p in stage.Traverse() if p.HasAPI(UsdLux.LightAPI)]
    assert {p.GetName() for p in lights} == {l.name.split("/")[-1] for l in read_scene(os.path.join(SCENES, scene)).lights}
    mesh = next(p for p in stage.Traverse() if p.IsA(UsdGeom.Mesh))
    tr = UsdGeom.PrimvarsAPI(mesh).GetPrimvar("warpshade:transfer")
    assert tr.GetElementSize() == 9 and len(tr.Get(1)) == 9 * len(UsdGeom.Mesh(mesh).GetPointsAttr().Get(1))
    assert validation_errors(out) == []


def test_failing_run_keeps_complete_frames(tmp_path):
    scene = _plane_scene(None)
    rest = scene.objects[0].mesh.points.copy()  # the lid's own topology (the plane may be refined for shading)

    def points_at(f):
        if f == 5:
            raise RuntimeError("animation source lost at frame 5")
        return rest * 0.3 + (0, 0.2 + 0.1 * f, 0)

    scene.objects[1].params["points_at"] = points_at
    scene.frames = 8
    with pytest.raises(RuntimeError, match="frame 5"):
        Pipeline(scene, order=2).run(AnimationWriter(str(tmp_path / "o.usda"), chunk=2), progress=False)
    stage = Usd.Stage.Open(str(tmp_path / "o.usda"))
    lid = UsdGeom.Mesh(stage.GetPrimAtPath("/World/lid"))
    assert lid.GetPointsAttr().GetTimeSamples() == [0.0, 1.0, 2.0, 3.0, 4.0]
    assert stage.GetEndTimeCode() == 4
    assert validation_errors(tmp_path / "o.usda") == []


def test_scene_without_lights_gets_the_default_sky(tmp_path):
    scene = _plane_scene("none")
    scene.lights = []
    for o in scene.objects:
        o.method = None
    out = tmp_path / "o.usda"
    Pipeline(scene, order=3).run(AnimationWriter(str(out), chunk=2), progress=False)
    stage = Usd.Stage.Open(str(out))
    dome = UsdLux.DomeLight(stage.GetPrimAtPath("/World/Lights/DefaultSky"))
    tex = dome.GetTextureFileAttr().Get().resolvedPath
    assert tex and os.path.isfile(tex)
    col = np.asarray(UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/World/ground")).GetPrimvar("displayColor").Get(1))
    # the default sky is normalized so an open white upward surface has luminance 1: albedo 0.8
    # (unshadowed here) gives a luminance near 0.8
    lum = col @ np.array([0.2126, 0.7152, 0.0722])
    assert np.allclose(lum, 0.8, rtol=0.05), lum[:5]
    assert validation_errors(out) == []


def test_cli_errors_are_one_line(tmp_path, capsys):
    assert main(["run", str(tmp_path / "nope.usda"), "--no-progress"]) == 1
    assert "nope.usda: no such scene file" in capsys.readouterr().err
    assert main(["run", os.path.join(SCENES, "skinned_arm.usda"), "--rays", "4", "--no-progress"]) == 1
    assert "need --method" in capsys.readouterr().err
    assert main(["run", os.path.join(SCENES, "skinned_arm.usda"), "--method", "reference", "--bogus", "1"]) == 1
    assert "unknown option(s) for method 'reference': --bogus" in capsys.readouterr().err
    assert main(["preview", str(tmp_path / "nope.usda"), "-o", str(tmp_path / "x.png")]) == 1
    assert "nope.usda: cannot open USD stage" in capsys.readouterr().err


def test_scene_shader_pickles_for_worker_processes():
    """--workers ships the SceneShader to worker processes: it must pickle (no pxr objects, no closures)."""
    import pickle

    scene = read_scene(os.path.join(SCENES, "skinned_arm.usda"))
    shader = Pipeline(scene, method="reference", knobs={"rays": 4}, order=2).shader
    clone = pickle.loads(pickle.dumps(shader))
    assert [g.names for g in clone.groups] == [g.names for g in shader.groups]
    shade = clone.build()
    tube = scene.object("/World/Arm/Tube")
    out = shade(3, {tube.name: tube.params["points_at"](3)})
    assert set(out) == {"/World/Ground", "/World/Arm/Tube", "_seconds", "_build_seconds", "_passes"}
    assert np.allclose(out[tube.name][0], tube.params["points_at"](3))


@pytest.mark.parametrize("scene", ["rect_light.usda", "cloth_sphere.usda", "flag_wind.usda", "cloth_table.usda",
                                   "cape_walker.usda"])
def test_run_cloth_scenes(tmp_path, scene):
    out = tmp_path / "out.usda"
    assert main(["run", os.path.join(SCENES, scene), "--frames", "3", "--out", str(out), "--no-progress",
                 "--workers", "0", "--method", "reference", "--rays", "4", "--order", "3"]) == 0
    stage = Usd.Stage.Open(str(out))
    cloth = [o.name for o in read_scene(os.path.join(SCENES, scene)).objects if o.kind == "cloth"]
    for name in cloth:
        pts = UsdGeom.Mesh(stage.GetPrimAtPath("/World/" + name.split("/")[-1])).GetPointsAttr()
        assert not np.array_equal(np.asarray(pts.Get(0)), np.asarray(pts.Get(2))), f"{name} must move"
    assert validation_errors(out) == []
def test_run_default_scene_few_frames(tmp_path, capsys):
    out = tmp_path / "default_out.usda"
    assert main(["run", "--frames", "3", "--out", str(out), "--no-progress", "--method", "reference",
                 "--rays", "16"]) == 0
    printed = capsys.readouterr()
    assert printed.out.strip() == str(out.resolve())
    assert "simulate" in printed.err and "shade" in printed.err and "write" in printed.err
    from warpshade.parallel import default_workers

    # with worker processes the setup and shade figures are sums over them, which can exceed the total: said so
    assert ("(setup and shade are summed over the" in printed.err) == (default_workers() > 0)
    # reference recomputes every receiver whenever one is due: no temporal reuse by default, and said so
    assert "temporal reuse: off" in printed.err
    stage = Usd.Stage.Open(str(out))
    assert stage.GetRootLayer().customLayerData["warpshade:reuse"].startswith("off")
    assert stage.GetEndTimeCode() == 2
    cloth = UsdGeom.Mesh(stage.GetPrimAtPath("/World/Cloth"))
    p0, p2 = (np.asarray(cloth.GetPointsAttr().Get(f)) for f in (0, 2))
    assert p2[:, 1].mean() < p0[:, 1].mean(), "the cloth must fall"
    col = np.asarray(UsdGeom.PrimvarsAPI(cloth).GetPrimvar("displayColor").Get(1))
    assert col.shape == (33 * 33, 3) and np.isfinite(col).all() and col.max() > 0
    assert validation_errors(out) == []




@pytest.mark.parametrize("flags,bar", [([], False), (["--progress"], True), (["--no-progress"], False)])
def test_progress_bar_only_on_a_terminal_unless_asked(tmp_path, capsys, flags, bar):
    """Redirected to a log (capsys: not a terminal) the run draws no progress bar, whose redraws would pile
    up in the file, unless ``--progress`` asks for it."""
    out = tmp_path / "o.usda"
    assert main(["run", "--frames", "1", "--out", str(out), "--method", "reference", "--rays", "8", *flags]) == 0
    err = capsys.readouterr().err
    assert ("warpshade run: setting up" in err) == bar
    assert "simulate" in err  # the summary is printed either way


def test_progress_follows_the_terminal_by_default(monkeypatch):
    import argparse

    from warpshade.cli.cmd_run import add_arguments, show_progress

    parser = argparse.ArgumentParser()
    add_arguments(parser)
    for tty in (True, False):
        monkeypatch.setattr(sys.stderr, "isatty", lambda tty=tty: tty)
        assert show_progress(parser.parse_args([])) is tty
        assert show_progress(parser.parse_args(["--progress"])) is True
        assert show_progress(parser.parse_args(["--no-progress"])) is False
    with pytest.raises(SystemExit):
        parser.parse_args(["--progress", "--no-progress"])


@pytest.mark.parametrize("cached", [False, True])
def test_run_says_when_its_setup_compiles_warp_kernels(tmp_path, capsys, monkeypatch, cached):
    """A first run with an empty kernel cache spends a minute compiling: the run says so before its setup and
    under its timings (which include it); with the kernels cached it says nothing of the kind."""
    import warpshade.parallel.runtime as runtime

    monkeypatch.setattr(runtime, "kernel_cache_holds_warpshade", lambda: cached)
    out = tmp_path / "out.usda"
    assert main(["run", "--frames", "2", "--out", str(out), "--no-progress", "--workers", "0", "--method",
                 "reference", "--rays", "16"]) == 0
    err = capsys.readouterr().err
    assert ("holds no warpshade kernels: this first run compiles them" in err) == (not cached)
    assert ("(this run compiled Warp's kernels" in err) == (not cached)


def test_kernel_cache_check_counts_compiled_warpshade_modules_only(tmp_path, monkeypatch):
    """Lock files, build directories still being written and other programs' modules are not compiled
    warpshade kernels; a finished module directory is (names as Warp 1.19 writes them)."""
    import warp as wp

    from warpshade.parallel.runtime import init_warp, kernel_cache_holds_warpshade

    init_warp()
    monkeypatch.setattr(wp.config, "kernel_cache_dir", str(tmp_path))
    assert not kernel_cache_holds_warpshade()
    for name in ("wp_warpshade.geometry.normals_e65b463.lock", "wp_warpshade.geometry.normals_e65b463_p81_t1407",
                 "wp_test_hemiraster_e065bc9", "wp_warp.sim_0a1b2c3"):
        (tmp_path / name).mkdir()
        assert not kernel_cache_holds_warpshade(), name
    (tmp_path / "wp_warpshade.geometry.normals_e65b463").mkdir()
    assert kernel_cache_holds_warpshade()
    monkeypatch.setattr(wp.config, "kernel_cache_dir", str(tmp_path / "missing"))
    assert not kernel_cache_holds_warpshade()


def test_setup_ticker_says_it_compiles():
    from warpshade.pipeline import _SetupTicker

    class Bar:
        def set_description_str(self, text):
            pass

    for estimate in (None, 6.0):
        quiet, first = _SetupTicker(Bar(), estimate), _SetupTicker(Bar(), estimate, compiling=True)
        try:
            assert "compiling" not in quiet.text() and "compiling Warp kernels (first run)" in first.text()
            assert ("of ~6 s estimated" in first.text()) == (estimate is not None)
        finally:
            quiet.stop(), first.stop()


def test_reuse_option_takes_an_angle_off_or_auto():
    import argparse

    from warpshade.cli.cmd_run import parse_reuse
    from warpshade.pipeline.config import REUSE_AUTO

    assert parse_reuse("2") == 2.0 and parse_reuse("0") == 0.0
    assert parse_reuse("off") is None and parse_reuse("OFF") is None and parse_reuse("auto") == REUSE_AUTO
    for bad in ("-1", "nan", "sometimes"):
        with pytest.raises(argparse.ArgumentTypeError):
            parse_reuse(bad)


def test_groups_with_different_methods_shadow_each_other_through_spheres(tmp_path):
    """Objects shaded by different methods form separate groups; sphere sets carry shadows between them."""

    def ground_colours(between, name):
        scene = _plane_scene("reference")
        scene.objects[0].method = None  # ground: unshadowed transfer of its own, lid: reference
        out = tmp_path / f"{name}.usda"
        report = Pipeline(scene, order=3, between=between).run(AnimationWriter(str(out)), progress=False)
        assert len(report.groups) == 2
        stage = Usd.Stage.Open(str(out))
        return np.asarray(UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/World/ground")).GetPrimvar("displayColor").Get(0))

    alone = ground_colours(None, "none")
    assert alone[40, 0] == pytest.approx(0.8, rel=1e-4)  # no shadow from the lid without between-group shadows
    shadowed = ground_colours("spheres", "spheres")
    # the lid's 56° half-angle blocks sin²(56°) of the irradiance at the centre (analytic, as in the
    # one-group test above); the lid's sphere set is an approximation: measured 0.243 vs 0.246 analytic,
    # the one-group test's 0.08 tolerance applies
    assert shadowed[40, 0] == pytest.approx(0.8 * (1 - math.sin(math.atan(1.5)) ** 2), abs=0.08)
    assert shadowed[0, 0] == pytest.approx(0.8, rel=0.05)  # the corner sees the lid at 0.025 sr


def test_the_preview_command_printed_runs_as_printed(tmp_path, capsys):
    # the run's last lines suggest a preview command to copy: with a space in the output's path it must
    # still be one command the shell splits right
    out = tmp_path / "my renders" / "arm's take.usda"
    assert main(["run", os.path.join(SCENES, "skinned_arm.usda"), "--frames", "2", "--out", str(out), "--no-progress",
                 "--workers", "0", "--method", "reference", "--rays", "4", "--order", "2"]) == 0
    line = next(x for x in capsys.readouterr().err.splitlines() if x.strip().startswith("preview: "))
    words = shlex.split(line.strip()[len("preview: "):])
    assert words[:2] == ["warpshade", "preview"] and words[2] == str(out)
    assert main(words[1:] + ["--size", "32x24"]) == 0
    assert (out.parent / "arm's take.png").is_file()
