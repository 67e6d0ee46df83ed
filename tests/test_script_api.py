"""The Python scene API (warpshade.script): a scene built in a script is simulated, shaded and
written by the Pipeline, with visible contact shadows; geometry-only output shows the albedo; the
sims/ scripts shade by default; bad arguments are named."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
from pxr import Usd, UsdGeom, UsdShade

import warpshade as ws

REPO = os.path.join(os.path.dirname(__file__), "..")
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
    (lambda: ws.box(size=0), "'Box': size"),
    (lambda: ws.box(center=(0, 1)), "'Box': center"),
    (lambda: ws.sphere(radius=-2), "radius"),
    (lambda: ws.ground(albedo=2.0), "albedo"),
    (lambda: ws.distant(direction=(0, 0, 0)), "direction"),
    (lambda: ws.make_scene(ws.box(), ws.box()), "two objects are named 'Box'"),
    (lambda: ws.run(ws.make_scene(ws.mesh("M", np.eye(3), [[0, 1, 2]], moving=True)), "x.usda", frames=1),
     "no geometry generator"),
    (lambda: ws.run(ws.make_scene(ws.sky(up="Z")), "x.usda", frames=1), "up axis"),
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
