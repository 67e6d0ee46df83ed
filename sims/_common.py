"""Shared plumbing of the sims/ scripts: argument parsing and shaded USD output through
:func:`warpshade.run` (not a sim itself)."""

from __future__ import annotations

import argparse
import os
import sys
import time

sys.path.insert(0, os.path.abspath(os.path.join(os.path.dirname(__file__), "..")))

import numpy as np  # noqa: E402

import warpshade as ws  # noqa: E402

FPS = 60.0


def parse(doc: str, argv, frames: int, extra=None, fps: float = FPS):
    """docs/conventions.md §5 arguments (--frames N --out PATH.usda) plus a script's own; ``fps`` is the
    script's frame rate, for the help text."""
    ap = argparse.ArgumentParser(description=doc.strip().split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=doc)
    ap.add_argument("--frames", type=int, default=frames, help=f"frames at {fps:g} fps (default {frames})")
    ap.add_argument("--out", required=True, help="output USD animation (.usda/.usdc/.usd)")
    ap.add_argument("--no-shade", action="store_true",
                    help="write geometry only (each mesh bound to its albedo), not the shaded colours")
    if extra is not None:
        extra(ap)
    args = ap.parse_args(argv)
    if args.frames < 1:
        ap.error("--frames must be >= 1")
    # Warp started as quietly as warpshade's commands (no banner, no module-load lines): a script
    # simulates with its own solver before any Pipeline, which would start it so
    from warpshade.parallel.runtime import init_warp

    init_warp()
    return args


class Recorder:
    """Collects a script's meshes and their per-frame points, then shades and writes them with
    :func:`warpshade.run` (the script's own simulation gives the points; a mesh given no frame is static)."""

    def __init__(self, args, fps: float = FPS):
        self.path, self.shade, self.fps = args.out, not args.no_shade, float(fps)
        self.meshes: dict[str, tuple] = {}  # name -> (faces, rest points, two-sided)
        self.frames: list[dict] = []
        self.t0 = time.perf_counter()

    def add(self, name: str, faces, points, two_sided: bool = False) -> str:
        """Declare a mesh; ``two_sided`` for cloth: each side shaded with its own transfer and
        written as its own mesh (docs/guide/dcc.md), as ``warpshade run`` does for cloth."""
        self.meshes[name] = (np.asarray(faces), np.array(points, dtype=np.float64), bool(two_sided))
        return name

    def frame(self, frame: int, name: str, points) -> None:
        while len(self.frames) <= frame:
            self.frames.append({})
        self.frames[frame][name] = np.array(points, dtype=np.float32)

    def close(self) -> str:
        moving = set().union(*self.frames) if self.frames else set()
        objects = []
        for name, (faces, pts, two_sided) in self.meshes.items():
            objects.append(ws.mesh(name, pts, faces, moving=name in moving))
            objects[-1].two_sided = two_sided
        scene = ws.make_scene(*objects, fps=self.fps)
        report = ws.run(scene, self.path, frames=max(1, len(self.frames)), shade=self.shade, geometry=self.frames)
        what = "shaded" if self.shade else "geometry only"
        print(f"wrote {report.path} ({what}, {time.perf_counter() - self.t0:.1f} s)")
        return report.path
