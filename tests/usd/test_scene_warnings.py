"""Scenes as users write them: warnings that name the prim and the fix; guide/proxy purpose not shaded."""

import glob
import os
import warnings

import numpy as np
import pytest
from helpers import usd_grid as _grid
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux

from warpshade.pipeline import Pipeline
from warpshade.scene import SceneWarning
from warpshade.usd import read_scene


def _scene(tmp_path, build):
    path = tmp_path / "scene.usda"
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)  # in metres (unauthored is centimetres and warns)
    build(stage)
    stage.GetRootLayer().Save()
    return read_scene(str(path))


def _warnings_of(scene, frames):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        Pipeline(scene, frames=frames, workers=1)
    return [str(w.message) for w in caught if issubclass(w.category, SceneWarning)]


def test_nothing_moves_warns(tmp_path):
    scene = _scene(tmp_path, lambda st: _grid(st, "/World/Floor"))
    msgs = _warnings_of(scene, frames=4)
    assert any("nothing in the scene moves" in m and "warpshade:kind" in m for m in msgs), msgs
    assert not any("nothing in the scene moves" in m for m in _warnings_of(scene, frames=1))


def _cloth(stage):
    cloth = _grid(stage, "/World/Cloth", y=1.0)
    cloth.GetPrim().CreateAttribute("warpshade:kind", Sdf.ValueTypeNames.String, custom=True).Set("cloth")
    return cloth


def test_cloth_without_pins_or_colliders_warns(tmp_path):
    scene = _scene(tmp_path, _cloth)
    msgs = _warnings_of(scene, frames=3)
    assert any(m.startswith("/World/Cloth") and "falls freely" in m for m in msgs), msgs
    assert not any("nothing in the scene moves" in m for m in msgs)


def test_cloth_with_a_collider_does_not_warn(tmp_path):
    def build(stage):
        _cloth(stage)
        floor = _grid(stage, "/World/Floor")
        floor.GetPrim().CreateAttribute("warpshade:collider", Sdf.ValueTypeNames.String, custom=True).Set("ground")

    msgs = _warnings_of(_scene(tmp_path, build), frames=3)
    assert not any("falls freely" in m for m in msgs), msgs


@pytest.mark.parametrize("purpose", ["guide", "proxy"])
def test_guide_and_proxy_prims_are_not_shaded(tmp_path, purpose):
    def build(stage):
        _grid(stage, "/World/Body/visuals/Floor")
        twin = _grid(stage, "/World/Body/collisions/Floor", y=0.01)
        UsdGeom.Imageable(stage.DefinePrim("/World/Body/collisions", "Xform")).CreatePurposeAttr(purpose)
        assert UsdGeom.Imageable(twin).ComputePurpose() == purpose

    scene = _scene(tmp_path, build)
    assert [o.name for o in scene.objects] == ["/World/Body/visuals/Floor"]


def test_dark_light_warns_with_its_name(tmp_path):
    def build(stage):
        _grid(stage, "/World/Floor")
        UsdLux.DistantLight.Define(stage, "/World/Sun").CreateIntensityAttr(0.0)
        UsdLux.DomeLight.Define(stage, "/World/Sky").CreateIntensityAttr(1.0)

    msgs = _warnings_of(_scene(tmp_path, build), frames=1)
    assert any(m.startswith("/World/Sun") and "gives no light" in m for m in msgs), msgs
    assert not any(m.startswith("/World/Sky") for m in msgs), msgs


def _read_warnings(tmp_path, build):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        _scene(tmp_path, build)
    return [str(w.message) for w in caught if issubclass(w.category, SceneWarning)]


def test_unmarked_sheet_that_looks_like_cloth_warns(tmp_path):
    def build(stage, kind=None, n=9):
        _grid(stage, "/World/Floor", n=2, size=4.0)
        sheet = _grid(stage, "/World/Sheet", n=n, y=1.0)
        if kind:
            sheet.GetPrim().CreateAttribute("warpshade:kind", Sdf.ValueTypeNames.String, custom=True).Set(kind)

    msgs = _read_warnings(tmp_path, build)
    cloth_like = [m for m in msgs if "looks like cloth" in m]
    assert len(cloth_like) == 1 and cloth_like[0].split(": ")[0].endswith(":/World/Sheet"), msgs
    assert 'warpshade:kind = "cloth"' in cloth_like[0] and "81 vertices" in cloth_like[0]
    # marked static on purpose, or too coarse to be a cloth (a 3 x 3 grid): no warning
    assert not any("looks like cloth" in m for m in _read_warnings(tmp_path, lambda st: build(st, kind="static")))
    assert not any("looks like cloth" in m for m in _read_warnings(tmp_path, lambda st: build(st, n=3)))


def test_fine_floor_below_everything_does_not_look_like_cloth(tmp_path):
    def build(stage):
        _grid(stage, "/World/Floor", n=20, size=4.0)  # 400 vertices, open and flat, but the lowest
        UsdGeom.Cube.Define(stage, "/World/Box").AddTranslateOp().Set(Gf.Vec3d(0.0, 1.0, 0.0))

    assert not any("looks like cloth" in m for m in _read_warnings(tmp_path, build))


@pytest.mark.parametrize("name, value, message", [
    ("rays", -5, "warpshade:knobs:rays: must be >= 1, got -5"),
    ("bogus", 3, "warpshade:knobs:bogus: reference has no knob 'bogus'"),
])
def test_invalid_scene_knob_names_the_prim_and_attribute(tmp_path, name, value, message):
    from warpshade.scene import SceneError

    def build(stage):
        prim = _cloth(stage).GetPrim()
        prim.CreateAttribute("warpshade:method", Sdf.ValueTypeNames.String, custom=True).Set("reference")
        prim.CreateAttribute(f"warpshade:knobs:{name}", Sdf.ValueTypeNames.Int, custom=True).Set(value)

    with pytest.raises(SceneError) as err:
        _scene(tmp_path, build)
    assert f"scene.usda:/World/Cloth: {message}" in str(err.value)


def _with_world(attrs, world_type="Xform"):
    def build(stage):
        world = stage.DefinePrim("/World", world_type)
        stage.SetDefaultPrim(world)
        for name, (type_name, value) in attrs.items():
            world.CreateAttribute(f"warpshade:{name}", type_name, custom=True).Set(value)
        _grid(stage, "/World/Floor")
    return build


def test_unknown_scene_setting_on_the_default_prim_warns_with_the_closest(tmp_path):
    # a typo on the default prim was ignored without a word (the run took 120 frames, not 10)
    build = _with_world({"frams": (Sdf.ValueTypeNames.Int, 10), "order": (Sdf.ValueTypeNames.Int, 3)})
    msgs = _read_warnings(tmp_path, build)
    hits = [m for m in msgs if "warpshade:frams" in m]
    assert len(hits) == 1, msgs
    assert "scene.usda:/World" in hits[0] and "did you mean 'frames'" in hits[0] and "ignored" in hits[0]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scene = _scene(tmp_path, build)
    assert scene.settings["order"] == 3 and "frams" not in scene.settings and scene.frames == 120
    # an object mark on the default prim is no scene setting either (object marks stop below the default prim)
    msgs = _read_warnings(tmp_path, _with_world({"kind": (Sdf.ValueTypeNames.String, "cloth")}))
    assert any("warpshade:kind" in m and "not a scene setting" in m for m in msgs), msgs


def test_known_scene_settings_and_shipped_scenes_do_not_warn(tmp_path):
    from helpers import REPO

    from warpshade.usd.scene_io import SCENE_KEYS

    values = {"frames": 3, "fps": 24.0, "order": 3, "method": "disks", "writeTransfer": False, "substeps": 4,
              "reflections": False, "refineEdge": 0.1, "edgeLength": 0.2, "graded": True, "wind": Gf.Vec3f(1, 0, 0),
              "max_error": 0.05}
    assert set(values) == set(SCENE_KEYS)
    types = {bool: Sdf.ValueTypeNames.Bool, int: Sdf.ValueTypeNames.Int, float: Sdf.ValueTypeNames.Float,
             str: Sdf.ValueTypeNames.String}
    attrs = {k: (types.get(type(v), Sdf.ValueTypeNames.Float3), v) for k, v in values.items()}
    msgs = _read_warnings(tmp_path, _with_world(attrs))
    assert not [m for m in msgs if "scene setting" in m], msgs
    shipped = sorted(glob.glob(os.path.join(REPO, "usd_scenes", "*.usda")))
    assert len(shipped) >= 8
    for path in shipped:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            read_scene(path)
        assert not [w for w in caught if "scene setting" in str(w.message) or "object attribute" in str(w.message)], path


def test_unknown_object_attribute_warns_with_the_closest(tmp_path):
    # a typo on an object was ignored without a word: the ground did not collide, the cloth fell through
    def build(stage):
        world = stage.DefinePrim("/World", "Xform")
        stage.SetDefaultPrim(world)
        floor = _grid(stage, "/World/Floor", n=2, size=4.0).GetPrim()
        floor.CreateAttribute("warpshade:colider", Sdf.ValueTypeNames.Token, custom=True).Set("ground")
        cloth = _cloth(stage).GetPrim()
        cloth.CreateAttribute("warpshade:stifnes", Sdf.ValueTypeNames.Float, custom=True).Set(2.0)
        cloth.CreateAttribute("warpshade:frames", Sdf.ValueTypeNames.Int, custom=True).Set(3)
        group = stage.DefinePrim("/World/Props", "Xform")  # a typo on a group above two meshes: one warning
        group.CreateAttribute("warpshade:castShadows", Sdf.ValueTypeNames.Bool, custom=True).Set(False)
        _grid(stage, "/World/Props/A", y=0.5)
        _grid(stage, "/World/Props/B", y=0.7)

    msgs = [m for m in _read_warnings(tmp_path, build) if "object attribute" in m]
    assert len(msgs) == 4, msgs
    by = {m.split("scene.usda:")[1].split(" is not")[0]: m for m in msgs}
    assert "did you mean 'collider'?" in by["/World/Floor: warpshade:colider"]
    assert "ignored" in by["/World/Cloth: warpshade:stifnes"]
    assert "author it on the default prim" in by["/World/Cloth: warpshade:frames"]
    assert "did you mean 'castsShadows'?" in by["/World/Props: warpshade:castShadows"]


def test_every_object_attribute_and_a_run_output_read_back_do_not_warn(tmp_path):
    from warpshade.usd import AnimationWriter
    from warpshade.usd.scene_io import OBJECT_ATTRIBUTES
    from warpshade.usd.shipped import shipped_scene

    def build(stage):
        floor = _grid(stage, "/World/Floor", n=2, size=4.0).GetPrim()
        floor.CreateAttribute("warpshade:collider", Sdf.ValueTypeNames.Token, custom=True).Set("ground")
        cloth = _cloth(stage).GetPrim()
        for name in ("method", "shaded", "castsShadows", "twoSided"):
            assert name in OBJECT_ATTRIBUTES
        cloth.CreateAttribute("warpshade:method", Sdf.ValueTypeNames.Token, custom=True).Set("none")
        for name in ("shaded", "castsShadows", "twoSided"):
            cloth.CreateAttribute(f"warpshade:{name}", Sdf.ValueTypeNames.Bool, custom=True).Set(True)
        cloth.CreateAttribute("warpshade:pinned", Sdf.ValueTypeNames.IntArray, custom=True).Set([0, 5])
        cloth.CreateAttribute("warpshade:cloth:density", Sdf.ValueTypeNames.Float, custom=True).Set(0.2)
        cloth.CreateAttribute("warpshade:albedo", Sdf.ValueTypeNames.Color3f, custom=True).Set(Gf.Vec3f(0.5, 0.5, 0.5))

    assert not [m for m in _read_warnings(tmp_path, build) if "object attribute" in m]
    # a run's output carries warpshade:albedo, transferOrder, twoSided and the back side's backSideOf
    out = tmp_path / "out.usda"
    scene = read_scene(shipped_scene())
    Pipeline(scene, frames=1, workers=1, write_transfer=True).run(AnimationWriter(str(out), fps=scene.fps),
                                                                  progress=False)
    stage = Usd.Stage.Open(str(out))
    written = {p.GetName() for prim in stage.Traverse() for p in prim.GetAuthoredPropertiesInNamespace("warpshade")}
    assert {"warpshade:albedo", "warpshade:transferOrder", "warpshade:twoSided", "warpshade:backSideOf"} <= written
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        read_scene(str(out))
    assert not [str(w.message) for w in caught if "object attribute" in str(w.message)]
def _split_cloth(stage):
    """A cloth whose grid is cut down its middle column as an exporter splits a seam: that column's vertices are
    duplicated (same positions) and the right half's triangles use the copies."""
    n = 6
    cloth = _cloth(stage)
    pts = list(cloth.GetPointsAttr().Get())
    faces = np.array(cloth.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3)
    column = [j * n + n // 2 for j in range(n)]
    copy = {v: len(pts) + k for k, v in enumerate(column)}
    right = np.array([min(pts[v][0] for v in tri) >= pts[n // 2][0] - 1e-9 for tri in faces])
    faces[right] = np.vectorize(lambda v: copy.get(int(v), int(v)))(faces[right])
    cloth.CreatePointsAttr(pts + [pts[v] for v in column])
    cloth.CreateFaceVertexIndicesAttr(faces.ravel().tolist())
    _grid(stage, "/World/Floor").GetPrim().CreateAttribute("warpshade:collider", Sdf.ValueTypeNames.Token).Set("ground")


def test_a_cloth_cut_along_duplicate_points_warns(tmp_path):
    """Before: the cloth came apart along the seam without a word (seen draping a 12 x 12 grid over a ball)."""
    msgs = _warnings_of(_scene(tmp_path, _split_cloth), frames=2)
    assert any(m.startswith("/World/Cloth: 6 vertices of the cloth lie on others without sharing a triangle") and
               "(first: vertices 3 and 36)" in m and "Merge by Distance" in m for m in msgs), msgs


@pytest.mark.parametrize("attr, typ, value, message", [
    ("stiffness", Sdf.ValueTypeNames.Float, 3.0, ("warpshade:cloth:stiffness is not a cloth attribute "
                                                  "\\(did you mean 'bendStiffness'\\?\\)")),
    ("selfCollision", Sdf.ValueTypeNames.String, "yes", "warpshade:cloth:selfCollision must be a bool, got 'yes'"),
    ("density", Sdf.ValueTypeNames.String, "0.2", "warpshade:cloth:density must be a finite number, got '0.2'"),
])
def test_a_bad_cloth_attribute_names_the_prim_and_attribute(tmp_path, attr, typ, value, message):
    """Before: an unknown warpshade:cloth:* attribute was ignored without a word, and a string one was a bare
    float() error or (a bool) taken as true."""
    def build(stage):
        _cloth(stage).GetPrim().CreateAttribute(f"warpshade:cloth:{attr}", typ, custom=True).Set(value)
    from warpshade.scene import SceneError

    with pytest.raises(SceneError, match="scene.usda: /World/Cloth: " + message):
        next(Pipeline(_scene(tmp_path, build), frames=2, workers=1).simulate())


@pytest.mark.parametrize("attr, value, message", [
    ("shaded", "false", "scene.usda:/World/Cloth: warpshade:shaded must be a bool \\(true or false\\), got 'false'"),
    ("castsShadows", "no", "scene.usda:/World/Cloth: warpshade:castsShadows must be a bool"),
])
def test_an_on_off_mark_that_is_a_string_is_an_error(tmp_path, attr, value, message):
    """Before: a string 'false' was taken as true (bool('false')), without a word."""
    from warpshade.scene import SceneError

    def build(stage):
        _cloth(stage).GetPrim().CreateAttribute(f"warpshade:{attr}", Sdf.ValueTypeNames.String, custom=True).Set(value)

    with pytest.raises(SceneError, match=message):
        _scene(tmp_path, build)


@pytest.mark.parametrize("fps, tcps, message", [
    (0.0, None, "scene.usda:/World: warpshade:fps must be a number of frames per second > 0, got 0"),
    (-24.0, None, "warpshade:fps must be a number of frames per second > 0, got -24"),
    (None, 0.0, "scene.usda: timeCodesPerSecond must be a number of frames per second > 0, got 0"),
])
def test_a_frame_rate_that_is_not_positive_is_an_error(tmp_path, fps, tcps, message):
    """Before: warpshade:fps = 0 was a ZeroDivisionError traceback in the cloth simulation, -24 'step 0: dt must be
    finite and > 0'."""
    from warpshade.scene import SceneError

    def build(stage):
        _cloth(stage)
        stage.SetDefaultPrim(stage.GetPrimAtPath("/World"))
        if fps is not None:
            stage.GetPrimAtPath("/World").CreateAttribute("warpshade:fps", Sdf.ValueTypeNames.Float, custom=True).Set(fps)
        if tcps is not None:
            stage.SetTimeCodesPerSecond(tcps)

    with pytest.raises(SceneError, match=message):
        _scene(tmp_path, build)
