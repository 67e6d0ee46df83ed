"""Generate the pictures the README and the docs show (run it after a change that alters them).

What it makes:

* ``docs/images/default_contact_sheet.png``: ``warpshade run`` on the shipped default scene, then
  ``warpshade preview --contact-sheet`` of its frames (one camera, one exposure for all tiles).
* ``docs/images/pareto.png``: a copy of ``benchmarks/results/pareto.png`` (written by
  ``warpshade bench``), the speed/accuracy plot the method pages show.

Run:  python docs/make_pictures.py            (about 20 s on a 2-core machine)
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
IMAGES = os.path.join(ROOT, "docs", "images")


def warpshade(*args: str) -> None:
    """Run the CLI of this tree (``python -m warpshade``) and stop on failure."""
    env = dict(os.environ, PYTHONPATH=ROOT + os.pathsep + os.environ.get("PYTHONPATH", ""))
    subprocess.run([sys.executable, "-m", "warpshade", *args], check=True, env=env)


def main() -> int:
    os.makedirs(IMAGES, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "default_shaded.usda")
        warpshade("run", "--out", out, "--no-progress")
        warpshade("preview", out, "--contact-sheet", "0:119:17", "--columns", "4", "--size", "320x240",
                  "-o", os.path.join(IMAGES, "default_contact_sheet.png"))
    shutil.copyfile(os.path.join(ROOT, "benchmarks", "results", "pareto.png"), os.path.join(IMAGES, "pareto.png"))
    print(f"wrote {IMAGES}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
