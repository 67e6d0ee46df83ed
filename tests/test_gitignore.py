"""The files a default `warpshade run` / `preview` writes in a checkout are ignored by git."""

import shutil
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]

DEFAULT_OUTPUTS = ["default_shaded.usda", "default_shaded_frames/run/chunk_000000.usdc",
                   "default_shaded_frames.lock", "sims/flag_shaded.usdc", "flag_shaded_usdc_frames/manifest.usda",
                   "default_shaded.png", "sheet.png"]


pytestmark = pytest.mark.skipif(shutil.which("git") is None or not (REPO / ".git").exists(),
                                reason="needs git and a git checkout (the rule is about the repository)")


@pytest.mark.parametrize("path", DEFAULT_OUTPUTS)
def test_default_outputs_are_ignored(path):
    proc = subprocess.run(["git", "check-ignore", "--no-index", "-q", path], cwd=REPO)
    assert proc.returncode == 0, f"{path} is not ignored by .gitignore"


def test_shipped_scenes_are_not_ignored():
    proc = subprocess.run(["git", "check-ignore", "--no-index", "-q", "usd_scenes/default.usda"], cwd=REPO)
    assert proc.returncode == 1
