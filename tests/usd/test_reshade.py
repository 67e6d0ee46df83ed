"""Outputs never render black by accident; re-shading a warpshade output reads its true albedo."""

import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdShade

import helpers
from warpshade.cli.cmd_run import shipped_scene
from warpshade.pipeline import Pipeline
from warpshade.scene import SceneWarning
from warpshade.usd import AnimationWriter, read_scene
from warpshade.usd.writer import RADIANCE_MATERIAL_ATTR

FRAMES = 3
REPO = Path(helpers.REPO)


def _colors(stage, path, t):
    return np.asarray(UsdGeom.PrimvarsAPI(stage.GetPrimAtPath(path)).GetPrimvar("displayColor").Get(t))


def _surface(stage, path):
    mat, _ = UsdShade.MaterialBindingAPI(stage.GetPrimAtPath(path)).ComputeBoundMaterial()
    return mat, mat.ComputeSurfaceSource()[0]


def test_geometry_only_output_shows_the_albedo(tmp_path):
    out = tmp_path / "geo.usda"
    w = AnimationWriter(str(out), fps=24)
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 0, 1]], np.float32)
    w.add_mesh("Tri", [[0, 1, 2]], pts, albedo=[0.2, 0.4, 0.6], shaded=False)
    w.add_mesh("Plain", [[0, 1, 2]], pts, shaded=False)
    w.write_frame(0, "Tri", pts, None)
    w.write_frame(0, "Plain", pts, None)
    w.close()
    stage = Usd.Stage.Open(str(out))
    for path, rgb in (("/World/Tri", (0.2, 0.4, 0.6)), ("/World/Plain", (0.8, 0.8, 0.8))):
        mat, surf = _surface(stage, path)
        assert np.allclose(surf.GetInput("diffuseColor").Get(), rgb)
        assert not surf.GetInput("emissiveColor")  # nothing wired to a displayColor never written
        assert not mat.GetPrim().GetAttribute(RADIANCE_MATERIAL_ATTR)


def test_flag_sim_output_is_not_black(tmp_path):
    """sims/flag.py --no-shade (geometry only) binds materials whose diffuse is the flag's albedo, not black."""
    out = tmp_path / "flag.usda"
    script = REPO / "sims" / "flag.py"
    proc = subprocess.run([sys.executable, str(script), "--out", str(out), "--frames", "2", "--no-shade"],
                          capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    stage = Usd.Stage.Open(str(out))
    meshes = [p for p in stage.Traverse() if p.IsA(UsdGeom.Mesh)]
    assert meshes
    for p in meshes:
        _, surf = _surface(stage, p.GetPath())
        assert max(surf.GetInput("diffuseColor").Get()) > 0.05, p.GetPath()


def test_reshading_an_output_reproduces_its_colours(tmp_path):
    """Shade the default scene, then shade its output: the albedo comes from warpshade:albedo (not
    the radiance material's black diffuse), so the colours agree.

    They agree to the difference between the analytic default sky (first run) and the lat-long
    texture of it the output's DomeLight carries (second run): measured at most 0.0125 absolute
    (~2.5 % of the ground's radiance) on these frames; 0.02 leaves margin, while a black albedo
    would differ by the full radiance (0.16-0.73 mean).
    """
    first = tmp_path / "a.usda"
    second = tmp_path / "b.usda"
    scene = read_scene(shipped_scene())
    Pipeline(scene, frames=FRAMES, workers=1).run(AnimationWriter(str(first), fps=scene.fps), progress=False)
    again = read_scene(str(first))
    Pipeline(again, frames=FRAMES, workers=1).run(AnimationWriter(str(second), fps=again.fps), progress=False)
    a, b = Usd.Stage.Open(str(first)), Usd.Stage.Open(str(second))
    for path in ("/World/Ground", "/World/Ball", "/World/Cloth"):
        for t in range(FRAMES):
            ca, cb = _colors(a, path, t), _colors(b, path, t)
            assert ca.mean() > 0.1
            assert np.abs(ca - cb).max() < 0.02, (path, t)


def test_black_albedo_mesh_warns_with_cause(tmp_path):
    scene_path = tmp_path / "black.usda"
    stage = Usd.Stage.CreateNew(str(scene_path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    mesh = UsdGeom.Mesh.Define(stage, "/World/Floor")
    n = 4
    xs = np.linspace(-1, 1, n)
    pts = [Gf.Vec3f(float(x), 0.0, float(z)) for z in xs for x in xs]
    faces = []
    for j in range(n - 1):
        for i in range(n - 1):
            a = j * n + i
            faces += [a, a + n, a + 1, a + 1, a + n, a + n + 1]
    mesh.CreatePointsAttr(pts)
    mesh.CreateFaceVertexCountsAttr([3] * (len(faces) // 3))
    mesh.CreateFaceVertexIndicesAttr(faces)
    mat = UsdShade.Material.Define(stage, "/World/Looks/Black")
    surf = UsdShade.Shader.Define(stage, "/World/Looks/Black/Surface")
    surf.CreateIdAttr("UsdPreviewSurface")
    surf.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0, 0, 0))
    mat.CreateSurfaceOutput().ConnectToSource(surf.ConnectableAPI(), "surface")
    UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(mat)
    stage.GetRootLayer().Save()
    scene = read_scene(str(scene_path))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        Pipeline(scene, frames=1, workers=1).run(AnimationWriter(str(tmp_path / "o.usda"), fps=scene.fps),
                                                 progress=False)
    msgs = [str(w.message) for w in caught if issubclass(w.category, SceneWarning)]
    assert any("Floor" in m and "zero at every vertex" in m and "albedo is black" in m for m in msgs), msgs


def test_black_run_albedo_is_named_as_the_cause(tmp_path):
    """``albedo=0`` (``--albedo 0``) blackens objects without an authored albedo: the warning must blame
    the albedo, not missing light (the scene's own material is the default grey)."""
    scene_path = tmp_path / "grey.usda"
    stage = Usd.Stage.CreateNew(str(scene_path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    mesh = UsdGeom.Mesh.Define(stage, "/World/Floor")
    mesh.CreatePointsAttr([Gf.Vec3f(-1, 0, -1), Gf.Vec3f(1, 0, -1), Gf.Vec3f(-1, 0, 1), Gf.Vec3f(1, 0, 1)])
    mesh.CreateFaceVertexCountsAttr([3, 3])
    mesh.CreateFaceVertexIndicesAttr([0, 2, 1, 1, 2, 3])
    stage.GetRootLayer().Save()
    scene = read_scene(str(scene_path))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        Pipeline(scene, frames=1, workers=1, albedo=0.0).run(
            AnimationWriter(str(tmp_path / "o.usda"), fps=scene.fps), progress=False)
    msgs = [str(w.message) for w in caught if "zero at every vertex" in str(w.message)]
    assert msgs and all("albedo is black" in m and "--albedo" in m for m in msgs), msgs
