"""A cloth dropped on a box (warpshade issue 19: a new user's first scene).

What it shows: a 2 m x 2 m cloth (default 41 x 41 vertices, 5 cm edges), horizontal 0.6 m above
a 1 m box standing on the floor, falls onto it and drapes: the middle lies on the top face, the
skirt hangs down the four sides and folds at the corners onto the floor. The box is an 8-vertex,
12-triangle mesh collider (``--box analytic``: the analytic box a ``Cube`` marked
``warpshade:collider = "box"`` reads as): its top corners carry the skirt's diagonal folds, held
by the corner contacts (a corner must not poke through a cloth triangle), its edges by the edge
contacts.

Success criteria (checked every frame, printed at the end): 0 intersecting triangle pairs
(cloth-cloth and cloth-collider, exact triangle tests) at the end of every frame; no vertex held by
the intersection guard for more than 30 steps (a held vertex is a spike: it stays where it was
while the cloth around it moves on); 99th-percentile edge strain below 40 % in the last frame.

Status: met (96 frames, 41 x 41): 0 intersecting pairs in every frame, no vertex held, last-frame
p99 strain 4.8 % (max 26.6 %) with the mesh box, 4.9 % (26.4 %) with the analytic box. Before the
mesh box's corners joined the corner contacts (c5e9570) the mesh box held vertices for 69 steps
(every step from the landing on), p99 11.6 %, max 97 %.

Run:  python sims/box_drop.py --frames 96 --out box_drop.usda
      (shaded under the default sky; --no-shade writes geometry only)
"""

from __future__ import annotations

import sys

import numpy as np
import trimesh

from _common import FPS, Recorder, parse
from warpshade.sim import ClothBuilder, ColliderSet, IntersectionCounter, XPBDSolver

SIZE, BOX, DROP = 2.0, 1.0, 0.6  # cloth width, box edge, drop height above the box [m]
HOLD_LIMIT, P99_LIMIT = 30, 0.40
"""Success criteria: longest guard hold [steps] and last frame's p99 edge strain."""


def main(argv=None) -> dict:
    def extra(ap):
        ap.add_argument("--grid", type=int, default=41, help="cloth vertices per side (default 41: 5 cm edges)")
        ap.add_argument("--box", choices=("mesh", "analytic"), default="mesh",
                        help="the box as an 8-vertex mesh collider (default) or the analytic box")

    args = parse(__doc__, argv, 96, extra)
    b = ClothBuilder()
    b.add_grid(args.grid, args.grid, SIZE, SIZE, origin=(-SIZE / 2, BOX + DROP, -SIZE / 2))
    model = b.finalize()
    box = trimesh.creation.box(extents=(BOX,) * 3)
    box_pts = np.asarray(box.vertices) + [0.0, BOX / 2, 0.0]
    col = ColliderSet()
    col.add_plane((0.0, 1.0, 0.0), 0.0)
    if args.box == "mesh":
        col.add_mesh(box_pts, np.asarray(box.faces), friction=0.5)
    else:
        col.add_box((0.0, BOX / 2, 0.0), (BOX / 2,) * 3, friction=0.5)
    solver = XPBDSolver(model, col)
    state = model.state()
    counter = IntersectionCounter(model.faces)

    rec = Recorder(args)
    cloth = rec.add("cloth", model.faces, state.points.numpy(), two_sided=True)
    rec.add("box", box.faces, box_pts)
    worst = 0
    for f in range(args.frames):
        solver.step(state, state, 1.0 / FPS)
        worst = max(worst, counter.self_pairs(state.points)[0] + counter.collider_pairs(state.points, col)[0])
        rec.frame(f, cloth, state.points.numpy())
    rec.close()
    x = state.points.numpy()
    res = {"max_intersections": worst, "p99_strain": float(np.percentile(model.edge_strain(x), 99)),
           "max_strain": float(model.edge_strain(x).max()), "longest_hold": solver.stats()["guard_longest_hold"]}
    ok = worst == 0 and res["longest_hold"] <= HOLD_LIMIT and res["p99_strain"] < P99_LIMIT
    print({k: round(v, 5) for k, v in res.items()}, "OK" if ok else "CRITERIA NOT MET")
    res["ok"] = ok
    return res


if __name__ == "__main__":
    sys.exit(0 if main()["ok"] else 1)
