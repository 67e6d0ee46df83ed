"""What the planner saves on a scene with a static and a moving object.

What it shows: Warp's bear (static) next to a wrinkled cloth whose folds travel every frame (moving),
lit by a constant sky. Naive: every object's transfer and shading every frame. Planned (``make_plan``):
the bear's transfer and colours are computed once, the cloth's every frame. Both loops really run the
visibility method (``update``) and the re-dot; the script prints measured wall times and the planner's
own estimates.

Success criteria: planned time < naive time; the planned colours equal the naive ones bit for bit
(reuse must not change the picture).

How to run::

    python benchmarks/planner_savings.py [--frames 10] [--method disks] [--json PATH]

Numbers come from a shared, loaded machine; medians are not used here (each loop runs once after a
warm-up frame that absorbs kernel compilation).
"""

from __future__ import annotations

import argparse
import json
import time

import numpy as np


def cloth_frame(rest: np.ndarray, f: int) -> np.ndarray:
    """Cloth points of frame ``f``: travelling folds (4 cm amplitude, 0.2 m wavelength) on the flat grid."""
    p = rest.copy()
    p[:, 2] = 0.04 * np.sin(2 * np.pi * (p[:, 0] / 0.2 + 0.07 * f)) * np.cos(2 * np.pi * p[:, 1] / 0.35)
    return p


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frames", type=int, default=10)
    parser.add_argument("--method", default="disks")
    parser.add_argument("--json", default=None)
    args = parser.parse_args(argv)

    import warp as wp

    wp.config.quiet = True
    from warpshade.bench.environments import environments, radiance
    from warpshade.bench.meshes import grid, warp_mesh
    from warpshade.geometry import TriMesh
    from warpshade.planner import make_plan, naive_seconds
    from warpshade.scene import Scene, SceneObject
    from warpshade.visibility import get_method

    bear = warp_mesh("bear").rest
    cp, cf = grid(48, size=3.0)
    cp = cp[:, [0, 2, 1]] + (0.0, 6.0, 6.0)  # vertical sheet beside the bear (Y-up scene)
    cloth = TriMesh(cp, cf, name="cloth")
    # Self-shadowing only (the sheet hangs beside the bear, inter-object shadows off), so the bear's
    # transfer and colours are reusable; with casts_shadows=True the plan would recompute its shadow term.
    scene = Scene([SceneObject("bear", bear, "static", method=args.method, casts_shadows=False),
                   SceneObject("cloth", cloth, "cloth", method=args.method, casts_shadows=False)],
                  frames=args.frames, up_axis="Y")
    plan = make_plan(scene)
    light = environments(6, up="Y")["sky"]
    cls = get_method(args.method)
    order = plan.order

    def frames_points():
        for f in range(args.frames):
            q = cloth_frame(cp[:, [0, 2, 1]], f)[:, [0, 2, 1]]
            yield f, q

    def run(planned: bool):
        methods = {"bear": cls(bear, order=order), "cloth": cls(cloth, order=order)}
        for m in methods.values():  # warm-up: compile outside the timed loop
            m.update()
        colours, cache = [], {}
        t0 = time.perf_counter()
        for f, q in frames_points():
            out = {}
            for name, m in methods.items():
                op = plan.object(name)
                if name == "cloth":
                    m.update(q)
                elif not planned or "static" not in cache:
                    m.update()
                if planned and op.transfer == "once" and not op.passes:
                    if name not in cache:
                        cache[name] = radiance(m.transfer_numpy(), light)
                    out[name] = cache[name]
                    cache["static"] = True
                else:
                    out[name] = radiance(m.transfer_numpy(), light)
            colours.append(out)
        return time.perf_counter() - t0, colours

    t_naive, c_naive = run(False)
    t_plan, c_plan = run(True)
    same = all(np.array_equal(a[k], b[k]) for a, b in zip(c_naive, c_plan) for k in a)
    print(plan.describe())
    print(f"\nmeasured over {args.frames} frames ({args.method}, order {order}; shared loaded machine, one run each):")
    print(f"  naive   {t_naive:8.3f} s  ({t_naive / args.frames * 1e3:.1f} ms/frame)")
    print(f"  planned {t_plan:8.3f} s  ({t_plan / args.frames * 1e3:.1f} ms/frame)   saving {100 * (1 - t_plan / t_naive):.0f} %")
    print(f"  estimated by the planner: naive {naive_seconds(plan):.3f} s, planned {plan.seconds_total:.3f} s")
    print(f"  planned colours identical to naive: {same}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"frames": args.frames, "method": args.method, "naive_seconds": t_naive,
                       "planned_seconds": t_plan, "estimated_naive_seconds": naive_seconds(plan),
                       "estimated_planned_seconds": plan.seconds_total, "identical": same}, f, indent=2)
    return 0 if same else 1


if __name__ == "__main__":
    raise SystemExit(main())
