"""Analytic colliders against their tessellated meshes: time per step and drape difference.

What it measures: a 24 x 24 cloth (0.8 m, self-collision off) dropped onto a capsule, a cylinder
and a cone, each once as the exact analytic shape (``ColliderSet.add_capsule/add_cylinder/
add_cone``) and once as the triangle mesh that ``warpshade.usd.scene_io`` would tessellate the
same gprim to (trimesh, 48 sections; ``add_mesh``). Per shape it prints the median wall time of a
solver step (after a warm-up that includes kernel compilation; the analytic and mesh runs are
interleaved, ``--repeats`` times), the largest distance between the two final drapes, and how
deep the mesh-collider drape's deepest vertex is inside the exact solid (negative: outside).

Run:  python benchmarks/colliders.py --frames 60 --repeats 3 --json colliders.json
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import sys
import time

import numpy as np

sys.path.insert(0, os.path.abspath(os.path.join(os.path.dirname(__file__), "..")))

from warpshade.sim import ClothBuilder, ColliderSet, XPBDSolver  # noqa: E402

DT = 1.0 / 60.0
RADIUS, HALF = 0.12, 0.15
CENTRE = np.array([0.0, 0.25, 0.0])
SHAPES = {  # name: axis of the shape (p0 -> p1)
    "capsule (axis X)": ("capsule", np.array([1.0, 0, 0])),
    "cylinder (axis Y)": ("cylinder", np.array([0.0, 1, 0])),
    "cylinder (axis X)": ("cylinder", np.array([1.0, 0, 0])),
    "cone (apex up)": ("cone", np.array([0.0, 1, 0])),
}


def _mesh(kind, axis):
    """The tessellation scene_io uses for the gprim (built along +Z, then turned to ``axis``)."""
    import trimesh

    if kind == "capsule":
        m = trimesh.creation.capsule(height=2 * HALF, radius=RADIUS, count=[48, 24])
    elif kind == "cylinder":
        m = trimesh.creation.cylinder(radius=RADIUS, height=2 * HALF, sections=48)
    else:
        m = trimesh.creation.cone(radius=RADIUS, height=2 * HALF, sections=48)
        m.apply_translation([0, 0, -HALF])
    z = np.array([0.0, 0, 1])
    v = np.cross(z, axis)
    if np.linalg.norm(v) < 1e-12:
        rot = np.eye(3)
    else:
        k = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])
        rot = np.eye(3) + k + k @ k / (1 + z @ axis)
    return np.asarray(m.vertices) @ rot.T + CENTRE, np.asarray(m.faces)


def _sd(kind, x, p0, p1):
    u = (p1 - p0) / np.linalg.norm(p1 - p0)
    length = np.linalg.norm(p1 - p0)
    h = (x - p0) @ u
    r = np.linalg.norm((x - p0) - h[:, None] * u, axis=1)
    if kind == "capsule":
        return np.hypot(r, h - np.clip(h, 0, length)) - RADIUS
    if kind == "cylinder":
        q = np.stack([r - RADIUS, np.abs(h - length / 2) - length / 2], 1)
        return np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(axis=1), 0)
    # cone: distance to the meridian triangle (0,0), (R,0), (0,L), signed
    q = np.stack([r, h], 1)
    tri = np.array([[-RADIUS, 0.0], [RADIUS, 0.0], [0.0, length]])
    d = []
    for i in range(3):
        a, b = tri[i], tri[(i + 1) % 3]
        t = np.clip((q - a) @ (b - a) / ((b - a) @ (b - a)), 0, 1)
        d.append(np.linalg.norm(q - (a + t[:, None] * (b - a)), axis=1))
    inside = (h >= 0) & (r / RADIUS + h / length <= 1)
    return np.where(inside, -np.min(d, 0), np.min(d, 0))


def _run(kind, axis, analytic, frames):
    col = ColliderSet()
    p0, p1 = CENTRE - HALF * axis, CENTRE + HALF * axis
    if analytic:
        {"capsule": col.add_capsule, "cylinder": col.add_cylinder, "cone": col.add_cone}[kind](p0, p1, RADIUS)
    else:
        col.add_mesh(*_mesh(kind, axis))
    b = ClothBuilder()
    b.add_grid(24, 24, 0.8, 0.8, origin=(-0.4, 0.55, -0.4))
    m = b.finalize()
    s = XPBDSolver(m, col, self_collision=False)
    st = m.state()
    times = []
    for _ in range(frames):
        t0 = time.perf_counter()
        s.step(st, st, DT)
        st.points.numpy()  # synchronise
        times.append(time.perf_counter() - t0)
    return statistics.median(times), st.points.numpy().astype(np.float64), m.thickness, (p0, p1)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--frames", type=int, default=60)
    ap.add_argument("--repeats", type=int, default=3)
    ap.add_argument("--json", default=None, help="write the rows to this file")
    args = ap.parse_args(argv)
    for kind, axis in SHAPES.values():  # warm-up: kernel compilation
        _run(kind, axis, True, 2)
        _run(kind, axis, False, 2)
    rows = []
    print(f"{'shape':20s} {'analytic ms/step':>17s} {'mesh ms/step':>13s} {'ratio':>6s} "
          f"{'max drape diff mm':>18s} {'mesh drape depth mm':>20s} {'analytic depth mm':>18s}")
    for name, (kind, axis) in SHAPES.items():
        ta, tm = [], []
        for _ in range(args.repeats):  # interleaved A/B
            a = _run(kind, axis, True, args.frames)
            ta.append(a[0])
            mm = _run(kind, axis, False, args.frames)
            tm.append(mm[0])
        p0, p1 = a[3]
        th = a[2]
        row = {"shape": name, "analytic_ms": 1e3 * statistics.median(ta), "mesh_ms": 1e3 * statistics.median(tm),
               "max_drape_diff_mm": 1e3 * float(np.linalg.norm(a[1] - mm[1], axis=1).max()),
               "mesh_depth_mm": 1e3 * float(th - _sd(kind, mm[1], p0, p1).min()),
               "analytic_depth_mm": 1e3 * float(th - _sd(kind, a[1], p0, p1).min())}
        rows.append(row)
        print(f"{name:20s} {row['analytic_ms']:17.2f} {row['mesh_ms']:13.2f} {row['mesh_ms'] / row['analytic_ms']:6.2f} "
              f"{row['max_drape_diff_mm']:18.1f} {row['mesh_depth_mm']:20.2f} {row['analytic_depth_mm']:18.3f}")
    print("depth: how far the deepest cloth vertex is inside the thickness layer around the exact solid "
          "(<= 0: outside it)")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"frames": args.frames, "repeats": args.repeats, "rows": rows}, f, indent=1)


if __name__ == "__main__":
    main()
