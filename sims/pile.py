"""A long strip lowered onto the floor, folding onto itself into a pile of many layers.

What it shows: a 0.3 m x 2.4 m strip (default 10 x 80 vertices) hangs from its top edge, which
is lowered at 0.8 m/s while swinging 0.12 m back and forth; the strip buckles on the floor and
folds over itself layer after layer. Self-contact (vertex-triangle and edge-edge, with friction
between layers) and the per-vertex motion bounds keep the layers apart.

Success criteria (checked every frame, printed at the end): 0 intersecting triangle pairs
(cloth-cloth and cloth-floor) at the end of every frame; no vertex below the floor; at the end
(full run) a pile of at least 6 layers (cloth layers crossing the vertical line through the
pile's centre); 99th-percentile edge strain below 5 %.

Status: the contact criteria are met: 0 intersecting pairs on every frame of the full 180-frame
run, lowest vertex 5 mm above the floor, 11 layers at the end. Not met: p99 edge strain 13.4 % at
the end (criterion 5 %; the guard holds a few vertices of the layers in place for up to 49 steps,
and the edges around them stretch).

Run:  python sims/pile.py --frames 180 --out pile.usda
      (shaded under the default sky; --no-shade writes geometry only)
"""

from __future__ import annotations

import sys

import numpy as np

from _common import FPS, Recorder, parse
from warpshade.sim import ClothBuilder, ColliderSet, IntersectionCounter, XPBDSolver

LENGTH, WIDTH, TOP = 2.4, 0.3, 2.5


def top_offset(t: float) -> np.ndarray:
    """Displacement of the held edge at time t: down at 0.8 m/s to 0.15 m above the floor, swinging in x."""
    drop = min(0.8 * t, TOP - 0.15)
    return np.array([0.12 * np.sin(2 * np.pi * 1.2 * t), -drop, 0.0])


def layers_at(x: np.ndarray, faces: np.ndarray, p: np.ndarray) -> int:
    """Cloth triangles crossed by the vertical line through p (x, z)."""
    a, b, c = x[faces[:, 0]][:, [0, 2]], x[faces[:, 1]][:, [0, 2]], x[faces[:, 2]][:, [0, 2]]

    def cross(u, v, q):
        return (v[:, 0] - u[:, 0]) * (q[1] - u[:, 1]) - (v[:, 1] - u[:, 1]) * (q[0] - u[:, 0])

    s1, s2, s3 = cross(a, b, p), cross(b, c, p), cross(c, a, p)
    inside = ((s1 >= 0) & (s2 >= 0) & (s3 >= 0)) | ((s1 <= 0) & (s2 <= 0) & (s3 <= 0))
    return int(inside.sum())


def main(argv=None) -> dict:
    args = parse(__doc__, argv, 180, lambda ap: ap.add_argument("--grid", type=int, default=10))
    nu = args.grid
    nv = max(2, int(round(nu * LENGTH / WIDTH)))
    b = ClothBuilder(bend_stiffness=2e-5)
    ids = b.add_grid(nu, nv, WIDTH, LENGTH, origin=(-WIDTH / 2, TOP, 0.0), u_axis=(1, 0, 0), v_axis=(0, -1, 0))
    slots = b.attach(ids[0])
    model = b.finalize()
    col = ColliderSet()
    col.add_plane((0.0, 1.0, 0.0), 0.0, friction=0.6)
    solver = XPBDSolver(model, col)
    state, control = model.state(), model.control()
    counter = IntersectionCounter(model.faces)
    top_rest = model.rest_points_np[ids[0]].astype(np.float64)

    rec = Recorder(args)
    cloth = rec.add("cloth", model.faces, model.rest_points_np, two_sided=True)
    worst, lowest = 0, np.inf
    for f in range(args.frames):
        targets = np.empty_like(top_rest)
        targets[slots] = top_rest + top_offset((f + 1) / FPS)
        control.set_targets(targets)
        solver.step(state, state, 1.0 / FPS, control)
        x = state.points.numpy()
        worst = max(worst, counter.self_pairs(state.points)[0] + counter.collider_pairs(state.points, col)[0])
        lowest = min(lowest, float(x[:, 1].min()))
        rec.frame(f, cloth, x)
    rec.close()
    x = state.points.numpy()
    centre = np.median(x[x[:, 1] < 0.1][:, [0, 2]], axis=0) if (x[:, 1] < 0.1).any() else x[:, [0, 2]].mean(0)
    strain = model.edge_strain(x)
    res = {"max_intersections": worst, "min_height": lowest, "layers": layers_at(x, model.faces, centre),
           "p99_strain": float(np.percentile(strain, 99))}
    ok = (worst == 0 and lowest > 0.0 and res["p99_strain"] < 0.05 and (args.frames < 180 or res["layers"] >= 6))
    print({k: round(v, 5) for k, v in res.items()}, "OK" if ok else "CRITERIA NOT MET")
    res["ok"] = ok
    return res


if __name__ == "__main__":
    sys.exit(0 if main()["ok"] else 1)
