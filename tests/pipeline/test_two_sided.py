"""Both sides of thin surfaces: each side shaded with its own transfer and written as its own single-sided mesh
(docs/conventions.md §6, "Two-sided surfaces")."""

from __future__ import annotations

import os

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom, UsdShade

from helpers import REPO, grid  # n x n vertices on [0, 1]² at y = 0, triangles facing +y
from warpshade.cli import main
from warpshade.geometry import TriMesh
from warpshade.pipeline import Pipeline, unoccluded_transfer
from warpshade.planner import make_plan
from warpshade.scene import LightSpec, Scene, SceneObject
from warpshade.usd import AnimationWriter, read_scene
from warpshade.usd.validate import validation_errors
from warpshade.usd.writer import BACK_SIDE_OF, back_side_path
from warpshade.visibility.reference import ReferenceTransfer


DEFAULT = os.path.join(REPO, "usd_scenes", "default.usda")


def _mesh_attr(stage, path, name, t):
    return np.asarray(UsdGeom.Mesh(stage.GetPrimAtPath(path)).GetPrim().GetAttribute(name).Get(t))


def _luminance(c):
    return np.asarray(c, dtype=np.float64) @ np.array([0.2126, 0.7152, 0.0722])


@pytest.fixture(scope="module")
def drape(tmp_path_factory):
    """The default scene's first 24 frames, shaded with its defaults (two-sided cloth)."""
    out = str(tmp_path_factory.mktemp("drape") / "drape.usda")
    Pipeline(read_scene(DEFAULT), frames=24).run(AnimationWriter(out), progress=False)
    return Usd.Stage.Open(out)


def test_drape_underside_is_darker_than_its_top(drape):
    # Under the default sky the top of the drape sees the sky, its underside the ball and the ground (no bounce
    # in the default run). Measured: the underside's mean luminance is below 2 % of the top's at these frames
    # (below 4 % once the drape has settled, frame 119); 0.5 leaves a
    # wide margin and still fails if both sides got one transfer (ratio 1).
    for t in (4, 12, 23):
        top = _luminance(_mesh_attr(drape, "/World/Cloth", "primvars:displayColor", t))
        under = _luminance(_mesh_attr(drape, "/World/Cloth_back", "primvars:displayColor", t))
        assert under.mean() < 0.5 * top.mean(), (t, under.mean(), top.mean())
        # vertex by vertex, too: measured, the top is brighter at every vertex at these frames (96 % at frame 119)
        assert np.mean(under < top) > 0.9, (t, np.mean(under < top))


def test_output_prims_have_the_documented_structure(drape):
    front = drape.GetPrimAtPath("/World/Cloth")
    back = drape.GetPrimAtPath(back_side_path("/World/Cloth"))
    assert back and back.GetPath() == Sdf.Path("/World/Cloth_back")
    assert back.GetParent() == front.GetParent()  # a sibling: the same parent transform
    fm, bm = UsdGeom.Mesh(front), UsdGeom.Mesh(back)
    assert fm.GetDoubleSidedAttr().Get() is False and bm.GetDoubleSidedAttr().Get() is False
    assert front.GetAttribute("warpshade:twoSided").Get() is True
    assert back.GetRelationship(BACK_SIDE_OF).GetTargets() == [front.GetPath()]
    ff = np.asarray(fm.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3)
    bf = np.asarray(bm.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3)
    assert np.array_equal(bf, ff[:, ::-1])  # reversed winding
    assert np.array_equal(np.asarray(bm.GetFaceVertexCountsAttr().Get()), np.asarray(fm.GetFaceVertexCountsAttr().Get()))
    from warpshade.usd.writer import BACK_SIDE_OFFSET

    # the back lies BACK_SIDE_OFFSET of the first frame's size behind the front, along its own normals
    off = BACK_SIDE_OFFSET * float(np.linalg.norm(np.ptp(np.asarray(fm.GetPointsAttr().Get(0)), axis=0)))
    for t in (0, 23):
        fp, bp = np.asarray(fm.GetPointsAttr().Get(t)), np.asarray(bm.GetPointsAttr().Get(t))
        bn = np.asarray(bm.GetNormalsAttr().Get(t))
        assert np.allclose(bn, -np.asarray(fm.GetNormalsAttr().Get(t)))
        assert np.allclose(bp, fp + off * bn, rtol=0, atol=1e-6)  # float32 rounding of unit-scale points
        assert np.allclose(np.asarray(bm.GetExtentAttr().Get(t)), np.asarray(fm.GetExtentAttr().Get(t)), rtol=0,
                           atol=off + 1e-6)
    fmat = UsdShade.MaterialBindingAPI(front).ComputeBoundMaterial()[0]
    bmat = UsdShade.MaterialBindingAPI(back).ComputeBoundMaterial()[0]
    assert fmat and bmat.GetPath() == fmat.GetPath()  # the radiance material reads each prim's displayColor
    assert UsdGeom.PrimvarsAPI(back).GetPrimvar("displayColor").GetInterpolation() == UsdGeom.Tokens.vertex
    # the other objects stay one double-sided mesh each
    assert UsdGeom.Mesh(drape.GetPrimAtPath("/World/Ground")).GetDoubleSidedAttr().Get() is True
    assert not drape.GetPrimAtPath("/World/Ground_back")
    assert validation_errors(drape) == []


def test_reshading_the_output_reads_the_front_once(drape, tmp_path):
    # re-shading a two-sided output: the back mesh is not another object, the front keeps warpshade:twoSided
    path = drape.GetRootLayer().realPath
    scene = read_scene(path)
    names = [o.name for o in scene.objects]
    assert "/World/Cloth_back" not in names and "/World/Cloth" in names
    assert scene.object("/World/Cloth").two_sided is True
    assert scene.object("/World/Ground").two_sided is None


def _flag(two_sided=True):
    """A vertical 9x9 sheet in the plane z = 0 whose triangles face +z, lit by a distant light shining along -z
    (UsdLux: along -Z of its frame), i.e. onto its front."""
    pts, faces = grid(9)
    pts = pts[:, [0, 2, 1]] * (1.0, 1.0, 0.0) + (0.0, 0.0, 0.0)  # (x, 0, z) -> (x, z, 0)
    faces = faces[:, ::-1].copy()  # the swap of y and z mirrors, so reverse the winding to face +z again
    mesh = TriMesh(pts, faces, name="flag")
    assert np.allclose(mesh.normals, (0.0, 0.0, 1.0), atol=1e-6)
    flag = SceneObject("flag", mesh, method=None, two_sided=two_sided)
    sun = LightSpec("distant", "sun", color=np.ones(3), intensity=3.0, angle=5.0, normalize=True)  # irradiance 3
    return Scene(objects=[flag], frames=1, lights=[sun])


def test_flag_lit_from_one_side_is_bright_on_that_side_and_dark_on_the_other(tmp_path):
    out = str(tmp_path / "flag.usda")
    Pipeline(_flag(), order=4).run(AnimationWriter(out), progress=False)
    stage = Usd.Stage.Open(out)
    lit = _luminance(_mesh_attr(stage, "/World/flag", "primvars:displayColor", 0))
    dark = _luminance(_mesh_attr(stage, "/World/flag_back", "primvars:displayColor", 0))
    # Front: irradiance 3 head-on, exit radiance about 0.8 / pi * 3 = 0.76. Back: the clamped cosine around -z
    # sees no light; what it gets is the order-4 SH truncation of the sun, analytically (a delta light, zonal
    # clamped-cosine coefficients A_0..A_3 = pi, 2pi/3, pi/4, 0): sum_l A_l (2l+1) P_l(cos) over l < 4 is
    # pi (1 + 2 + 5/4) at cos = 1 and pi (1 - 2 + 5/4) at cos = -1, a ratio of 1/17. The 5° disc changes
    # the band factors by < 0.5 %; 2 % tolerance. Both sides of one transfer would give a ratio of 1.
    assert lit.min() > 0.1
    assert np.allclose(dark / lit, 1.0 / 17.0, rtol=0.02), (dark / lit).max()
    # the back mesh's normals face away from the sun
    assert np.allclose(_mesh_attr(stage, "/World/flag_back", "normals", 0), (0.0, 0.0, -1.0), atol=1e-5)


def _sheet_over_ground(ground_moves=False):
    """A bumpy sheet above a ground plane (static, or "animated" in place), both occluding, as one
    reference-shaded group."""
    pts, faces = grid(9)
    pts = (pts - (0.5, 0.0, 0.5)) * 2.0
    bumpy = pts + np.stack([0 * pts[:, 0], 0.6 + 0.15 * np.sin(3 * pts[:, 0]) * np.cos(2 * pts[:, 2]), 0 * pts[:, 0]], 1)
    sheet = SceneObject("sheet", TriMesh(bumpy, faces), method="reference", knobs={"rays": 64}, two_sided=True)
    ground = SceneObject("ground", TriMesh(pts * 2.0, faces), method="reference", knobs={"rays": 64})
    if ground_moves:  # a moving member that is not two-sided: the back pass runs on the whole group
        ground.kind, ground.params = "animated", {"points_at": lambda t: (pts * 2.0).astype(np.float32)}
    return Scene(objects=[sheet, ground], frames=1, lights=[LightSpec("dome", "sky", color=(1.0, 1.0, 1.0))])


@pytest.mark.parametrize("ground_moves", [False, True], ids=["occluder-pass", "whole-group-pass"])
def test_back_side_transfer_is_the_front_transfer_of_the_flipped_surface(tmp_path, ground_moves):
    scene = _sheet_over_ground(ground_moves)
    sheet, ground = scene.objects
    out = str(tmp_path / "sheet.usda")
    Pipeline(scene, order=4, write_transfer=True, between=None).run(AnimationWriter(out), progress=False)
    stage = Usd.Stage.Open(out)
    back = _mesh_attr(stage, "/World/sheet_back", "primvars:warpshade:transfer", 0).reshape(-1, 16)
    front = _mesh_attr(stage, "/World/sheet", "primvars:warpshade:transfer", 0).reshape(-1, 16)
    # Independently: the reference method on the same two surfaces with every triangle's winding reversed (its
    # normals computed from those triangles), front transfer of its sheet rows.
    pts = np.concatenate([sheet.mesh.points, ground.mesh.points])
    faces = np.concatenate([sheet.mesh.faces, ground.mesh.faces + sheet.mesh.num_vertices])[:, ::-1]
    flipped = TriMesh(pts, faces)
    expected = ReferenceTransfer(flipped, order=4, rays=64).update().numpy()[:sheet.mesh.num_vertices]
    # Same rays (same seed and vertex order, normals equal to float rounding). With a static ground the run's
    # back pass receives at the sheet alone with the ground as an occluder, so its near-field distance (which
    # scales with the receiver) differs and a ray grazing an edge can fall the other way: measured, one vertex
    # of 81 differs, by one ray (pi/64 * |y_lm| < 0.05 at order 4); every other entry agrees to float32
    # rounding. With a moving ground the back pass runs on the whole flipped group, as here.
    diff = np.abs(back - expected).max(axis=1)
    assert np.sum(diff > 1e-4) <= 2, np.flatnonzero(diff > 1e-4)
    assert diff.max() < 0.05, diff.max()
    # and it is not the front's: the underside sees the ground, the top the sky
    assert back[:, 0].mean() < 0.5 * front[:, 0].mean()


def test_back_side_of_an_open_plane_is_the_flipped_cosine_lobe():
    # SH convention check (docs/conventions.md §2): nothing blocks a lone flat sheet, so its back-side transfer is
    # the clamped-cosine lobe about -n, sqrt(4π/(2l+1)) A_l y_lm(-n). Stratified 32x32 rays: measured max error
    # 7.5e-3 (coefficients up to 0.89); 1.5e-2 bounds it.
    pts, faces = grid(5)
    mesh = TriMesh(pts, faces)
    from warpshade.pipeline.shading import flipped

    t = ReferenceTransfer(flipped(mesh), order=4, rays=1024).update().numpy()
    assert np.allclose(t, unoccluded_transfer(np.tile((0.0, -1.0, 0.0), (len(pts), 1)), 4), atol=1.5e-2)


def test_the_knob_turns_it_off_and_on(tmp_path):
    # Pipeline argument: off
    out = str(tmp_path / "off.usda")
    Pipeline(_flag(), order=4, two_sided="off").run(AnimationWriter(out), progress=False)
    stage = Usd.Stage.Open(out)
    assert not stage.GetPrimAtPath("/World/flag_back")
    assert UsdGeom.Mesh(stage.GetPrimAtPath("/World/flag")).GetDoubleSidedAttr().Get() is True
    # auto: a static object is one-sided unless it asks
    pipe = Pipeline(_flag(two_sided=None), order=4)
    assert pipe.groups[0].two_sided == [False]
    # on: every object
    assert Pipeline(_flag(two_sided=None), order=4, two_sided="on").groups[0].two_sided == [True]
    with pytest.raises(ValueError, match="two_sided must be one of auto, on, off"):
        Pipeline(_flag(), two_sided="both")


def _usd_sheet(path, attr=None):
    """A scene file: a static sheet (with ``warpshade:twoSided`` = ``attr`` if given) under a dome."""
    stage = Usd.Stage.CreateNew(path)
    pts, faces = grid(5)
    m = UsdGeom.Mesh.Define(stage, "/World/Sheet")
    m.CreatePointsAttr(pts.tolist())
    m.CreateFaceVertexCountsAttr([3] * len(faces))
    m.CreateFaceVertexIndicesAttr(faces.reshape(-1).tolist())
    m.GetPrim().CreateAttribute("warpshade:method", Sdf.ValueTypeNames.Token).Set("none")
    if attr is not None:
        typ = Sdf.ValueTypeNames.Bool if isinstance(attr, bool) else Sdf.ValueTypeNames.String
        m.GetPrim().CreateAttribute("warpshade:twoSided", typ).Set(attr)
    from pxr import UsdLux

    UsdLux.DomeLight.Define(stage, "/World/Sky")
    stage.SetDefaultPrim(stage.GetPrimAtPath("/World"))
    stage.GetRootLayer().Save()
    return path


def test_scene_attribute_and_command_line(tmp_path, capsys):
    scene = _usd_sheet(str(tmp_path / "on.usda"), True)
    assert read_scene(scene).object("/World/Sheet").two_sided is True
    out = str(tmp_path / "o.usda")
    assert main(["run", scene, "--out", out, "--frames", "1", "--workers", "0", "--no-progress"]) == 0
    assert Usd.Stage.Open(out).GetPrimAtPath("/World/Sheet_back")
    assert "two-sided: /World/Sheet" in capsys.readouterr().err
    out2 = str(tmp_path / "o2.usda")
    assert main(["run", scene, "--out", out2, "--frames", "1", "--workers", "0", "--no-progress",
                 "--two-sided", "off"]) == 0
    assert not Usd.Stage.Open(out2).GetPrimAtPath("/World/Sheet_back")
    # an invalid value names the prim and the attribute
    bad = _usd_sheet(str(tmp_path / "bad.usda"), "yes")
    with pytest.raises(Exception, match=r"/World/Sheet: warpshade:twoSided must be a bool"):
        read_scene(bad)


def test_plan_prices_the_back_sides():
    scene = read_scene(DEFAULT)
    scene.settings["order"] = 4
    on = make_plan(scene)
    off = make_plan(scene, two_sided="off")
    g_on, g_off = on.groups[0], off.groups[0]
    assert g_on.two_sided == ["/World/Cloth"] and g_off.two_sided == []
    assert g_off.seconds_back == 0.0
    # hemiraster: the back pass runs on the whole group, at least the front's transfer cost
    assert g_on.seconds_back >= g_on.seconds_transfer > 0
    assert on.run_seconds_per_frame > off.run_seconds_per_frame
    assert "back sides" in on.describe()
    # reference with static ground and ball: the back pass receives at the cloth's 1089 of the group's 2820
    # vertices
    for o in scene.objects:
        o.method, o.knobs = "reference", {"rays": 256}
    g = make_plan(scene).groups[0]
    assert 0 < g.seconds_back < g.seconds_transfer


def test_reflections_light_the_underside(tmp_path):
    # With the one-bounce pass the drape's underside, facing the lit ground, receives reflected light of its
    # own (the back pass flips the two-sided objects' normals): its mean radiance rises (measured 18x at frame
    # 2; 1.5x fails if the back side got no bounce); the front's bounce is computed as before, so with and
    # without two-sided the front agrees to float32 rounding.
    outs = {}
    for name, kw in (("plain", {}), ("bounce", {"reflections": True}), ("bounce_off", {"reflections": True,
                                                                                      "two_sided": "off"})):
        out = str(tmp_path / f"{name}.usda")
        Pipeline(read_scene(DEFAULT), frames=3, **kw).run(AnimationWriter(out), progress=False)
        outs[name] = Usd.Stage.Open(out)
    under = {k: _luminance(_mesh_attr(s, "/World/Cloth_back", "primvars:displayColor", 2))
             for k, s in outs.items() if k != "bounce_off"}
    assert under["bounce"].mean() > 1.5 * under["plain"].mean(), (under["bounce"].mean(), under["plain"].mean())
    top = _mesh_attr(outs["bounce"], "/World/Cloth", "primvars:displayColor", 2)
    assert np.allclose(top, _mesh_attr(outs["bounce_off"], "/World/Cloth", "primvars:displayColor", 2), atol=1e-5)


def test_preview_shows_each_side_its_own_mesh(drape):
    # warpshade preview draws a back-side mesh's colours where a ray meets the back of its front's triangles
    from warpshade.cli.cmd_preview import _with_back_sides
    from warpshade.preview import Camera, render
    from warpshade.usd import ShadedStage

    stage = ShadedStage(drape.GetRootLayer().realPath)
    assert stage.back_sides() == {"/World/Cloth_back": "/World/Cloth"}
    shot = _with_back_sides(stage.frame(0), stage.back_sides())
    assert len(shot) == 3  # Ground, Ball, Cloth: the back mesh is drawn as the Cloth's back colours
    # a square facing +y, red on its front, blue on its back, seen from above and from below
    pts = np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], np.float32)
    faces = np.array([[0, 2, 1], [0, 3, 2]], np.int32)
    assert TriMesh(pts, faces).normals[0, 1] > 0.99
    red, blue = np.tile((1.0, 0.0, 0.0), (4, 1)), np.tile((0.0, 0.0, 1.0), (4, 1))
    for eye, want in (((0.0, 3.0, 0.01), red), ((0.0, -3.0, 0.01), blue)):
        img = render([(pts, faces, red, blue)], Camera(eye=np.array(eye), target=np.zeros(3), up=np.array((0.0, 1.0, 0.0)),
                                                       fov=30.0), 32, 32, ground_height=-10.0)
        assert np.allclose(img[16, 16], want[0], atol=1e-6), (eye, img[16, 16])
