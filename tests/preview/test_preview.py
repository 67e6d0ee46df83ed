"""Preview ray caster: barycentric colour interpolation, ground and sky, PNG and contact sheet output."""

from __future__ import annotations

import numpy as np
import pytest

from warpshade.cli import main
from warpshade.preview import Camera, contact_sheet, render, tonemap
from warpshade.usd import AnimationWriter

from helpers import grid  # the same tiny fixture


def test_barycentric_colors_and_background():
    # a triangle in the plane z = 0 seen head-on from +z; vertex colours red, green, blue
    pts = np.array([[-1, -1, 0], [1, -1, 0], [0, 1, 0]], np.float32)
    cols = np.eye(3, dtype=np.float32)
    cam = Camera(eye=np.array([0, 0, 5.0]), target=np.zeros(3), up=np.array([0, 1.0, 0]), fov=40)
    w = h = 101
    img = render([(pts, np.array([[0, 1, 2]]), cols)], cam, w, h, ground_height=-10.0)

    def pixel(p):  # project a point on z = 0 to its pixel (pinhole, square image)
        t = np.tan(np.radians(20))
        x = (p[0] / 5 / t + 1) / 2 * w - 0.5
        y = (1 - p[1] / 5 / t) / 2 * h - 0.5
        return img[int(round(y)), int(round(x))]

    centroid = pts.mean(0)
    assert np.allclose(pixel(centroid), 1 / 3, atol=0.02), pixel(centroid)
    # near vertex 0 (inside the triangle): mostly red, weights as barycentrics of the sampled point
    near0 = 0.9 * pts[0] + 0.05 * pts[1] + 0.05 * pts[2]
    assert np.allclose(pixel(near0), (0.9, 0.05, 0.05), atol=0.03), pixel(near0)
    near2 = 0.1 * pts[0] + 0.1 * pts[1] + 0.8 * pts[2]
    assert np.allclose(pixel(near2), (0.1, 0.1, 0.8), atol=0.03), pixel(near2)
    corner = img[0, 0]  # looking horizontally at a ground 10 units down: the top-left pixel is sky
    assert corner[2] > corner[0] > 0


def test_ground_plane_below_the_mesh():
    pts = np.array([[-1, 0.5, -1], [1, 0.5, -1], [0, 0.5, 1]], np.float32)
    cam = Camera(eye=np.array([0, 5.0, 0.01]), target=np.zeros(3), up=np.array([0, 1.0, 0]), fov=90)
    img = render([(pts, np.array([[0, 2, 1]]), np.ones((3, 3), np.float32))], cam, 64, 64)
    assert np.allclose(img[32, 32], 1.0)  # the mesh
    edge = img[2, 32]  # beyond the mesh, looking down: the ground plane (grey, not the sky's blue)
    assert 0 < edge[0] < 1 and edge[0] == pytest.approx(edge[2])


def test_tonemap_and_sheet_shapes():
    img = np.linspace(0, 2, 4 * 6 * 3).reshape(4, 6, 3)
    out = tonemap(img, exposure=1.0)
    assert out.dtype == np.uint8 and out[0, 0, 0] == 0 and out[-1, -1, -1] == 255
    sheet = contact_sheet([out] * 5, columns=2)
    assert sheet.shape == (3 * (4 + 2) + 2, 2 * (6 + 2) + 2, 3)


def test_preview_cli_writes_png(tmp_path):
    import imageio.v3 as iio

    pts, faces = grid(6)
    pts = (pts - (0.5, 0, 0.5)) * 2
    w = AnimationWriter(str(tmp_path / "anim.usda"), chunk=3)
    name = w.add_mesh("sheet", faces)
    for f in range(8):
        w.write_frame(f, name, pts + (0, 0.1 * f, 0), colors=np.full((36, 3), 0.1 + 0.1 * f))
    w.close()
    assert main([ "preview", str(tmp_path / "anim.usda"), "--frame", "3", "-o", str(tmp_path / "f.png"),
                 "--size", "80x60"]) == 0
    assert iio.imread(tmp_path / "f.png").shape == (60, 80, 3)
    assert main(["preview", str(tmp_path / "anim.usda"), "--contact-sheet", "0:7:1", "--columns", "4",
                 "-o", str(tmp_path / "sheet.png"), "--size", "40x30"]) == 0
    sheet = iio.imread(tmp_path / "sheet.png")
    assert sheet.shape == (2 * 32 + 2, 4 * 42 + 2, 3)
    # shared exposure: the later (brighter) frame's tile is brighter at its centre
    assert sheet[2 + 32 + 15, 2 + 3 * 42 + 20].mean() > sheet[2 + 15, 2 + 20].mean()


def test_preview_names_a_time_code_outside_the_animation(tmp_path, capsys):
    # a run keeps its input's time codes (here 101..104): frame 0 is no frame of it, and USD would
    # silently show the first sample there
    pts, faces = grid(4)
    w = AnimationWriter(str(tmp_path / "anim.usda"), chunk=2)
    name = w.add_mesh("sheet", faces)
    for f in range(101, 105):
        w.write_frame(f, name, pts + (0, 0.001 * f, 0), colors=np.full((16, 3), 0.5))
    w.close()
    for args in (["--frame", "0"], ["--contact-sheet", "0:3:1"], ["--contact-sheet", "101:110:3"]):
        assert main(["preview", str(tmp_path / "anim.usda"), *args, "-o", str(tmp_path / "f.png")]) != 0
        err = capsys.readouterr().err
        assert f"{args[0]}: time code" in err and "101..104" in err, err
        assert not (tmp_path / "f.png").exists()
    assert main(["preview", str(tmp_path / "anim.usda"), "--contact-sheet", "101:104:1", "-o",
                 str(tmp_path / "f.png"), "--size", "40x30"]) == 0


@pytest.mark.parametrize("size", ["0x10", "80x0", "-4x3"])
def test_preview_names_a_size_of_no_pixels(tmp_path, capsys, size):
    """Before: 'cannot write empty image' (0x10) after rendering, a ZeroDivisionError traceback (80x0), Warp's
    'Array shapes must be non-negative' (-4x3)."""
    pts, faces = grid(4)
    w = AnimationWriter(str(tmp_path / "anim.usda"), chunk=2)
    w.write_frame(0, w.add_mesh("sheet", faces), pts, colors=np.full((16, 3), 0.5))
    w.close()
    assert main(["preview", str(tmp_path / "anim.usda"), "-o", str(tmp_path / "f.png"), f"--size={size}"]) != 0
    assert f"--size '{size}': expected WxH, two whole numbers of pixels >= 1" in capsys.readouterr().err
    assert not (tmp_path / "f.png").exists()


def test_preview_of_a_scene_without_colours_says_it_is_not_an_output(tmp_path):
    """A user previewing the input scene instead of the run's output: before, one flat grey silhouette (cloth and
    floor alike) without a word."""
    import warnings

    from pxr import Usd, UsdGeom

    from warpshade.scene import SceneWarning

    pts, faces = grid(4)
    stage = Usd.Stage.CreateNew(str(tmp_path / "scene.usda"))
    mesh = UsdGeom.Mesh.Define(stage, "/World/Sheet")
    mesh.CreatePointsAttr(pts.tolist())
    mesh.CreateFaceVertexCountsAttr([3] * len(faces))
    mesh.CreateFaceVertexIndicesAttr(faces.ravel().tolist())
    stage.GetRootLayer().Save()
    w = AnimationWriter(str(tmp_path / "out.usda"), chunk=2)
    w.write_frame(0, w.add_mesh("sheet", faces), pts, colors=np.full((16, 3), 0.5))
    w.close()
    for name, warns in (("scene.usda", True), ("out.usda", False)):
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            assert main(["preview", str(tmp_path / name), "-o", str(tmp_path / "f.png"), "--size", "40x30"]) == 0
        said = [str(c.message) for c in caught if issubclass(c.category, SceneWarning)]
        assert any("no mesh has a displayColor" in m and "not an output of warpshade run" in m for m in said) == warns, said
