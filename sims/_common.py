"""Shared plumbing of the sims/ scripts: argument parsing and USD output (not a sim itself)."""

from __future__ import annotations

import argparse
import os
import sys
import time

sys.path.insert(0, os.path.abspath(os.path.join(os.path.dirname(__file__), "..")))

import numpy as np  # noqa: E402

from warpshade.geometry import vertex_normals_np  # noqa: E402
from warpshade.usd import AnimationWriter  # noqa: E402

FPS = 60.0


def parse(doc: str, argv, frames: int, extra=None):
    """docs/conventions.md §5 arguments (--frames N --out PATH.usda) plus a script's own."""
    ap = argparse.ArgumentParser(description=doc.strip().split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter, epilog=doc)
    ap.add_argument("--frames", type=int, default=frames, help=f"frames at {FPS:g} fps (default {frames})")
    ap.add_argument("--out", required=True, help="output USD animation (.usda/.usdc/.usd)")
    if extra is not None:
        extra(ap)
    args = ap.parse_args(argv)
    if args.frames < 1:
        ap.error("--frames must be >= 1")
    return args


class Recorder:
    """Writes meshes frame by frame with angle-weighted vertex normals."""

    def __init__(self, path: str):
        self.writer = AnimationWriter(path, fps=FPS, up_axis="Y")
        self.faces: dict[str, np.ndarray] = {}
        self.t0 = time.perf_counter()

    def add(self, name: str, faces, points) -> str:
        n = self.writer.add_mesh(name, faces, points, shaded=False)
        self.faces[n] = np.asarray(faces)
        return n

    def frame(self, frame: int, name: str, points) -> None:
        pts = np.asarray(points, dtype=np.float64)
        self.writer.write_frame(frame, name, pts, vertex_normals_np(pts, self.faces[name]))

    def close(self) -> str:
        path = self.writer.close()
        print(f"wrote {path} ({time.perf_counter() - self.t0:.1f} s)")
        return path
