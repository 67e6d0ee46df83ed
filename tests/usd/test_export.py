"""warpshade export: a run's output as one self-contained .usdc or .usdz, opened with the sources gone."""

import os
import shutil
import subprocess
import sys

import numpy as np
import pytest
from pxr import Usd, UsdGeom, UsdLux

from helpers import REPO
from warpshade.usd.package import export



@pytest.fixture(scope="module")
def run_output(tmp_path_factory):
    """3 frames of the shipped default scene (its default sky is a DomeLight texture beside the frames)."""
    d = tmp_path_factory.mktemp("run")
    out = d / "out.usda"
    subprocess.run([sys.executable, "-m", "warpshade", "run", os.path.join(REPO, "usd_scenes", "default.usda"),
                    "--frames", "3", "--workers", "1", "--no-progress", "--out", str(out)],
                   check=True, capture_output=True, timeout=600)
    stage = Usd.Stage.Open(str(out))
    colors = {t: np.asarray(UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/World/Cloth")).GetPrimvar("displayColor").Get(t))
              for t in range(3)}
    return out, colors


def _dome_texture(stage):
    dome = next(UsdLux.DomeLight(p) for p in stage.Traverse() if p.IsA(UsdLux.DomeLight))
    return dome.GetTextureFileAttr().Get()


@pytest.mark.parametrize("ext", [".usdc", ".usdz"])
def test_export_stands_alone(run_output, tmp_path, ext):
    out, colors = run_output
    src = tmp_path / "src"
    shutil.copytree(out.parent, src)
    dst = tmp_path / "pack" / f"scene{ext}"
    dst.parent.mkdir()
    proc = subprocess.run([sys.executable, "-m", "warpshade", "export", str(src / "out.usda"), "-o", str(dst)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    shutil.rmtree(src)  # the export must not need the sources any more
    stage = Usd.Stage.Open(str(dst))
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0, 2)
    attr = UsdGeom.PrimvarsAPI(stage.GetPrimAtPath("/World/Cloth")).GetPrimvar("displayColor").GetAttr()
    assert attr.GetTimeSamples() == [0.0, 1.0, 2.0]
    for t, c in colors.items():
        assert np.array_equal(np.asarray(attr.Get(t)), c)  # baked from the clips, bit for bit
    texture = _dome_texture(stage)
    assert not os.path.isabs(texture.path)  # relative inside the export
    assert texture.resolvedPath and (ext == ".usdz" or os.path.isfile(texture.resolvedPath)), texture
    if ext == ".usdz":
        assert "[" in texture.resolvedPath  # resolved inside the package
    assert not [f for f in os.listdir(dst.parent) if ".partial" in f]


def test_a_usdz_is_a_scene_warpshade_run_reads(run_output, tmp_path):
    # an exported .usdz as a DCC would hand it over: its sky texture exists only inside the package
    out, _ = run_output
    pack = tmp_path / "scene.usdz"
    assert subprocess.run([sys.executable, "-m", "warpshade", "export", str(out), "-o", str(pack)],
                          capture_output=True, timeout=300).returncode == 0
    rerun = tmp_path / "again" / "rerun.usda"
    proc = subprocess.run([sys.executable, "-m", "warpshade", "run", str(pack), "--frames", "2", "--workers", "0",
                           "--method", "reference", "--rays", "16", "--order", "2", "--no-progress", "--out", str(rerun)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    stage = Usd.Stage.Open(str(rerun))
    texture = _dome_texture(stage)
    # the output carries its own copy beside its frames (the run's copy out of the package was temporary)
    assert os.path.isfile(texture.resolvedPath) and str(rerun.parent) in texture.resolvedPath, texture
    from pxr import Ar

    packed = Ar.GetResolver().OpenAsset(Ar.ResolvedPath(_dome_texture(Usd.Stage.Open(str(pack))).resolvedPath))
    assert open(texture.resolvedPath, "rb").read() == bytes(packed.GetBuffer())


def test_export_errors_name_the_file(run_output, tmp_path):
    out, _ = run_output
    with pytest.raises(ValueError, match="no such file"):
        export(str(tmp_path / "missing.usda"), str(tmp_path / "x.usdc"))
    with pytest.raises(ValueError, match="extension"):
        export(str(out), str(tmp_path / "x.abc"))
    with pytest.raises(ValueError, match="source itself"):
        export(str(out), str(out))
    with pytest.raises(ValueError, match="does not exist"):
        export(str(out), str(tmp_path / "nowhere" / "x.usdc"))
