"""The wheel carries the shipped scenes, and ``warpshade.usd.shipped`` finds them once installed.

The wheel is built from a copy of the files a build reads (pyproject.toml, setup.py, README.md,
``warpshade/``, ``usd_scenes/``), so the checkout gets no ``build/`` or ``*.egg-info``; pip builds it
in its usual isolated environment (setuptools and wheel from the package index, as ``pip install .``
does). "Installed" is the wheel unpacked into a directory on ``PYTHONPATH``: that is exactly the
tree pip puts into site-packages.
"""

import filecmp
import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest

from warpshade.usd.shipped import shipped_scene, shipped_scenes_dir

REPO = Path(__file__).resolve().parents[1]
BUILD_INPUTS = ["pyproject.toml", "setup.py", "README.md", "warpshade", "usd_scenes"]
SCENES = sorted(p.name for p in (REPO / "usd_scenes").iterdir() if p.suffix in (".usda", ".exr"))


@pytest.fixture(scope="module")
def wheel(tmp_path_factory) -> Path:
    src = tmp_path_factory.mktemp("src")
    for name in BUILD_INPUTS:
        if (REPO / name).is_dir():
            shutil.copytree(REPO / name, src / name, ignore=shutil.ignore_patterns("__pycache__", "*.pyc"))
        else:
            shutil.copy2(REPO / name, src / name)
    dist = tmp_path_factory.mktemp("dist")
    proc = subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "-q", "-w", str(dist), str(src)],
                          capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, f"pip wheel failed:\n{proc.stdout}\n{proc.stderr}"
    (whl,) = dist.glob("warpshade-*.whl")
    return whl


def test_checkout_finds_the_repository_scenes():
    assert Path(shipped_scenes_dir()) == REPO / "usd_scenes"
    assert Path(shipped_scene()) == REPO / "usd_scenes" / "default.usda"
    assert Path(shipped_scene("rect_light.usda")) == REPO / "usd_scenes" / "rect_light.usda"


def test_unknown_scene_names_itself_and_the_shipped_ones():
    with pytest.raises(FileNotFoundError, match=r"no shipped scene 'nope\.usda' in .*default\.usda"):
        shipped_scene("nope.usda")


def test_wheel_contains_every_shipped_scene_and_the_planner_data(wheel):
    names = set(zipfile.ZipFile(wheel).namelist())
    missing = [s for s in SCENES if f"warpshade/usd_scenes/{s}" not in names]
    assert not missing, f"{wheel.name} lacks shipped scenes {missing}"
    for data in ("warpshade/data/pass_costs.json", "warpshade/data/frontier.json", "warpshade/usd/shipped.py"):
        assert data in names, f"{wheel.name} lacks {data}"
    assert not [n for n in names if n.startswith(("usd_scenes/", "tests/", "benchmarks/", "sims/"))], \
        "the wheel installs top-level folders besides warpshade/"


def test_installed_layout_finds_its_own_scenes(wheel, tmp_path):
    site = tmp_path / "site"
    zipfile.ZipFile(wheel).extractall(site)
    elsewhere = tmp_path / "elsewhere"  # a working directory with no usd_scenes/ near it
    elsewhere.mkdir()
    env = {**os.environ, "PYTHONPATH": str(site)}
    code = ("import warpshade.usd.shipped as s, warpshade.cli.cmd_run as r; "
            "print(s.__file__); print(s.shipped_scenes_dir()); print(r.shipped_scene())")
    proc = subprocess.run([sys.executable, "-c", code], cwd=elsewhere, env=env, capture_output=True, text=True,
                          timeout=120)
    assert proc.returncode == 0, proc.stderr
    module, folder, default = proc.stdout.split()
    assert Path(module).is_relative_to(site), f"imported {module}, not the unpacked wheel"
    assert Path(folder) == site / "warpshade" / "usd_scenes"
    assert Path(default) == site / "warpshade" / "usd_scenes" / "default.usda"
    for s in SCENES:
        assert filecmp.cmp(site / "warpshade" / "usd_scenes" / s, REPO / "usd_scenes" / s, shallow=False), s
