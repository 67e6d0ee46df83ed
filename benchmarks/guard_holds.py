"""Counters for the intersection guard's holds on sims/sheet_drop.py's settled pile (issue 19).

Three measurements, each printed as a table (``--json`` writes them):

* ``steps``: per step, the guard's round-0 count (new cloth-cloth pairs, inherited ones, cloth-floor
  pairs), the pairs the state had at the step's start, the vertices sent back and the longest streak.
* ``switch``: the scene run to ``--switch-frame`` (inside the hold), one solver setting changed, then 30
  more frames: does the hold end, and does a new one start?
* ``seeds``: the scene with its cloth coordinates jittered by an ulp (``cloth.Jittered``), per seed.

Run:  python benchmarks/guard_holds.py --frames 120 --seeds 5 --json benchmarks/results/guard_holds.json
"""

from __future__ import annotations

import argparse
import contextlib
import io
import json
import os
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
sys.path.insert(0, os.path.join(HERE, "..", "sims"))

import cloth  # noqa: E402
import sheet_drop  # noqa: E402
import warp as wp  # noqa: E402

from warpshade.sim import ClothBuilder, ColliderSet, IntersectionCounter, XPBDSolver  # noqa: E402

SWITCHES = {
    "none": {},
    "contact_iterations=8": {"contact_iterations": 8},
    "iterations=4": {"iterations": 4},
    "substeps=16": {"substeps": 16},
    "self_friction=0": {"self_friction": 0.0},
    "guard_relax=0": {"guard_relax": 0},
    "gravity=0": {"gravity": (0.0, 0.0, 0.0)},
    "contacts only": {"gravity": (0.0, 0.0, 0.0), "stretch_limits": False, "edge_compliance": 1.0e3,
                      "hinge_compliance": 1.0e6},
}
"""Solver settings switched inside the hold (attributes of the running solver; the recorded launches are
re-recorded). "contacts only": no gravity, and edges and hinges so compliant (1e3 m/N, 1e6 1/(N m)) that
stretch and bending move nothing: only the contact, floor and guard passes act."""


class CountingSolver(XPBDSolver):
    """The solver with the guard's round-0 counts kept per step (outside the step's own arithmetic: the
    counts read copies of the positions)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self.rows = []
        self._probe = IntersectionCounter(self.model.faces)

    def _guard_intersections(self, x, v, dt):
        c, col = self._probe, self.colliders
        new = c.self_pairs(x, None, self._x_start)[0]
        inherited = c.inherited
        floor = c.collider_pairs(x, col)[0]
        at_start = c.self_pairs(self._x_start)[0] + c.collider_pairs(self._x_start, col)[0]
        super()._guard_intersections(x, v, dt)
        self.rows.append({"step": self.step_count, "new_pairs": new - inherited, "inherited": inherited,
                          "floor_pairs": floor, "pairs_at_start": at_start, "reverted": self.guard_vertices,
                          "streak": int(self._streak.numpy().max())})


def scene(solver_class=XPBDSolver):
    """sims/sheet_drop.py's sheet, floor and solver, and the sheet's first state."""
    b = ClothBuilder()
    b.add_mesh(*sheet_drop.sheet())
    model = b.finalize()
    col = ColliderSet()
    col.add_plane((0.0, 1.0, 0.0), 0.0, friction=0.6)
    return model, col, solver_class(model, col, substeps=8, guard_relax=sheet_drop.RELAX), model.state()


def run(model, col, solver, state, frames: int) -> dict:
    """Step `frames` frames from `state`; the worst frame's pairs and the largest edge strain."""
    counter = IntersectionCounter(model.faces)
    worst, strain = 0, 0.0
    for _ in range(frames):
        solver.step(state, state, 1.0 / sheet_drop.FPS)
        worst = max(worst, counter.self_pairs(state.points)[0] + counter.collider_pairs(state.points, col)[0])
        strain = max(strain, float(model.edge_strain(state.points.numpy()).max()))
    return {"max_pairs": worst, "max_strain": strain}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--frames", type=int, default=120)
    ap.add_argument("--switch-frame", type=int, default=60)
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--json")
    args = ap.parse_args(argv)
    wp.config.log_level = wp.LOG_WARNING
    wp.init()
    out = {}

    model, col, solver, state = scene(CountingSolver)
    run(model, col, solver, state, args.frames)
    out["steps"] = solver.rows
    print("sheet_drop, every step (the guard's round 0):")
    print(f"{'step':>5}{'new pairs':>10}{'inherited':>10}{'floor':>6}{'at start':>9}{'reverted':>9}{'streak':>7}")
    for r in solver.rows[::max(1, len(solver.rows) // 20)]:
        print(f"{r['step']:>5}{r['new_pairs']:>10}{r['inherited']:>10}{r['floor_pairs']:>6}{r['pairs_at_start']:>9}"
              f"{r['reverted']:>9}{r['streak']:>7}")

    out["switch"] = {}
    print(f"\nsettings switched at frame {args.switch_frame}, then 30 frames:")
    print(f"{'switch':<22}{'streak before':>14}{'first clean step':>17}{'streak after':>13}{'longest new':>12}"
          f"{'max pairs':>10}{'max strain':>11}")
    for name, change in SWITCHES.items():
        model, col, solver, state = scene(CountingSolver)
        run(model, col, solver, state, args.switch_frame)
        before = solver.rows[-1]["streak"] if solver.rows else 0
        for key, value in change.items():
            if key.endswith("_compliance"):
                array = getattr(model, key)
                array.fill_(value)
            else:
                setattr(solver, key, value)
        solver._cmd_cache = None
        n0 = len(solver.rows)
        res = run(model, col, solver, state, 30)
        after = solver.rows[n0:]
        clean = next((r["step"] - args.switch_frame for r in after if r["reverted"] == 0), None)
        runs, cur = [], 0
        for r in after:
            cur = cur + 1 if r["reverted"] else 0
            runs.append(cur)
        first_free = next((i for i, r in enumerate(after) if r["reverted"] == 0), len(after))
        longest_new = max(runs[first_free:], default=0)
        row = {"streak_before": before, "first_clean_step": clean, "streak_after": after[-1]["streak"],
               "longest_new_hold": longest_new, **res}
        out["switch"][name] = row
        print(f"{name:<22}{before:>14}{str(clean):>17}{row['streak_after']:>13}{longest_new:>12}{res['max_pairs']:>10}"
              f"{res['max_strain']:>10.1%}")

    out["seeds"] = {}
    print(f"\njittered by an ulp, {args.frames} frames:")
    print(f"{'seed':>5}{'longest hold':>13}{'guard steps':>12}{'max pairs':>10}{'max strain':>11}")
    for seed in range(args.seeds):
        with cloth.Jittered(seed), contextlib.redirect_stdout(io.StringIO()):
            model, col, solver, state = scene()
            res = run(model, col, solver, state, args.frames)
        row = {"longest_hold": solver.guard_longest_hold, "guard_steps": solver.guard_steps, **res}
        out["seeds"][seed] = row
        print(f"{seed:>5}{row['longest_hold']:>13}{row['guard_steps']:>12}{row['max_pairs']:>10}{row['max_strain']:>10.1%}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(out, f, indent=1, default=lambda o: o.item() if isinstance(o, np.generic) else str(o))
    return 0


if __name__ == "__main__":
    sys.exit(main())
