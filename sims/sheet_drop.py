"""A free vertical sheet dropped edge-on onto the floor (issue 19: a cape that was not attached).

What it shows: a 0.8 m x 1 m sheet (25 x 31 vertices, 3.3 cm edges), hanging flat and vertical
with its lower edge 0.5 m above the floor, falls and lands on that edge at ~3 m/s, then crumples
into a pile; 24 fps, 8 substeps, ``guard_relax=8``, default settings otherwise. The landing
compresses the sheet in its own plane faster than one stretch sweep per substep can stop it, so
its lower rows fold over each other; the intersection guard sends the vertices of the triangles
that intersect back to their start of step, 13 cm above where their neighbours land, and
``guard_relax`` lets the free vertices around them follow.

Success criteria (checked every frame, printed at the end): 0 intersecting triangle pairs
(cloth-cloth and cloth-floor) at the end of every frame; no vertex below the floor; the largest
edge strain of the landing frames (1-12) below 100 %; the 99th-percentile edge strain of every
frame below 50 %; the guard's longest hold at most 48 steps (the whole run).

Status: the contact, landing and p99 criteria are met (0 pairs on every frame; landing max
strain 16.1 %, worst p99 13.6 %; at the solver's default ``guard_relax=0``: 366 % and 226 %). The
hold criterion is met only because the run is 48 frames long: from the settled pile on, the
guard sends a few vertices of the bottom rows back in every step and its longest hold grows by
one a step (27 at frame 48, 99 at frame 120; 84-103 with the sheet jittered by an ulp).
Measured (benchmarks/guard_holds.py; docs/benchmarks/history.md, "Guard holds that never
end"): the pairs are new every step (none at the step's start), the held state repeats
exactly, and from it the contact and floor projections alone (no gravity, stretch or bending)
still make new pairs; no fix yet.

Run:  python sims/sheet_drop.py --frames 48 --out sheet_drop.usda
      (shaded under the default sky; --no-shade writes geometry only)
"""

from __future__ import annotations

import sys

import numpy as np

from _common import Recorder, parse
from warpshade.sim import ClothBuilder, ColliderSet, IntersectionCounter, XPBDSolver

FPS = 24.0
NX, NY = 25, 31
WIDTH, HEIGHT, DROP = 0.8, 1.0, 0.5
LANDING = 12
"""Frames counted as the landing (the lower edge touches the floor in frame 8)."""
RELAX = 8
"""The solver's ``guard_relax``: stretch sweeps around the guard's reverts (without them the
landing frame's edges stretch to 366 %)."""


def sheet() -> tuple[np.ndarray, np.ndarray]:
    """The vertical sheet's vertices (V, 3) and triangles (F, 3): a grid in the xy plane, each
    cell split along the same diagonal (as a Blender grid exported as triangles)."""
    xs = np.linspace(-WIDTH / 2, WIDTH / 2, NX)
    ys = np.linspace(DROP, DROP + HEIGHT, NY)
    points = np.array([(x, y, 0.0) for y in ys for x in xs])
    faces = []
    for j in range(NY - 1):
        for i in range(NX - 1):
            a = j * NX + i
            faces += [(a, a + 1, a + NX + 1), (a, a + NX + 1, a + NX)]
    return points, np.array(faces)


def main(argv=None) -> dict:
    args = parse(__doc__, argv, 48, fps=FPS)
    b = ClothBuilder()
    b.add_mesh(*sheet())
    model = b.finalize()
    col = ColliderSet()
    col.add_plane((0.0, 1.0, 0.0), 0.0, friction=0.6)
    solver = XPBDSolver(model, col, substeps=8, guard_relax=RELAX)
    state = model.state()
    counter = IntersectionCounter(model.faces)

    rec = Recorder(args, fps=FPS)
    cloth = rec.add("cloth", model.faces, model.rest_points_np, two_sided=True)
    worst, lowest, landing_max, p99 = 0, np.inf, 0.0, 0.0
    for f in range(args.frames):
        solver.step(state, state, 1.0 / FPS)
        x = state.points.numpy()
        worst = max(worst, counter.self_pairs(state.points)[0] + counter.collider_pairs(state.points, col)[0])
        lowest = min(lowest, float(x[:, 1].min()))
        strain = model.edge_strain(x)
        if f < LANDING:
            landing_max = max(landing_max, float(strain.max()))
        p99 = max(p99, float(np.percentile(strain, 99)))
        rec.frame(f, cloth, x)
    rec.close()
    res = {"max_intersections": worst, "min_height": lowest, "landing_max_strain": landing_max,
           "max_p99_strain": p99, "longest_hold": solver.stats()["guard_longest_hold"]}
    ok = (worst == 0 and lowest > 0.0 and landing_max < 1.0 and p99 < 0.5 and res["longest_hold"] <= 48)
    print({k: round(v, 5) for k, v in res.items()}, "OK" if ok else "CRITERIA NOT MET")
    res["ok"] = ok
    return res


if __name__ == "__main__":
    sys.exit(0 if main()["ok"] else 1)
