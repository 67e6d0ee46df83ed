"""Helpers shared by test modules in different folders (imported as ``helpers``: ``tests/`` is on
``sys.path`` through its ``conftest.py``). Fixtures live in ``conftest.py``."""

from __future__ import annotations

import math
import os

import numpy as np
from pxr import Gf, Usd, UsdGeom

from warpshade.geometry import TriMesh
from warpshade.sh import sh_eval
from warpshade.usd import AnimationWriter

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
"""The repository's root folder."""

SHIPPED = os.path.join(REPO, "usd_scenes")
"""The shipped scenes' folder."""

DATA = os.path.join(REPO, "tests", "data")
"""Test data (real assets others wrote: ``data/newton``)."""

# --- a short run on a shipped cloth scene, for resume, fault and scheduler tests ---
SCENE = os.path.join(SHIPPED, "cloth_sphere.usda")  # cloth: the simulation must be replayed
FRAMES = 6
COMMON = ["--method", "reference", "--rays", "4", "--order", "2", "--chunk", "2", "--no-progress"]


def frames_of(path):
    """{prim: [(points, colors) per frame]} read back through USD (value clips resolved)."""
    stage = Usd.Stage.Open(str(path))
    out = {}
    for prim in stage.Traverse():
        if prim.IsA(UsdGeom.Mesh):
            m = UsdGeom.Mesh(prim)
            col = UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayColor")
            out[str(prim.GetPath())] = [(np.asarray(m.GetPointsAttr().Get(f)), np.asarray(col.Get(f)))
                                        for f in range(int(stage.GetStartTimeCode()), int(stage.GetEndTimeCode()) + 1)]
    return out


def assert_same_frames(a, b):
    assert a.keys() == b.keys()
    for prim in a:
        assert len(a[prim]) == len(b[prim]), prim
        for f, ((pa, ca), (pb, cb)) in enumerate(zip(a[prim], b[prim])):
            # same deterministic simulation and shading kernels, same seeds: bit-identical
            assert np.array_equal(pa, pb), f"{prim} frame {f}: points differ"
            assert np.array_equal(ca, cb), f"{prim} frame {f}: colours differ"


class InterruptingWriter(AnimationWriter):
    """Stands in for Ctrl-C arriving while frame ``at`` is being written."""

    def __init__(self, *a, at: int, **kw):
        super().__init__(*a, **kw)
        self.at = at

    def write_frame(self, frame, *a, **kw):
        if frame == self.at:
            raise KeyboardInterrupt
        super().write_frame(frame, *a, **kw)


def live_processes() -> dict[int, list[str]]:
    """``{pid: /proc/PID/stat fields after the command name}`` of every live (not zombie) process:
    fields[0] state, [1] ppid, [2] pgrp, [3] session."""
    out = {}
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as f:
                    fields = f.read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if fields[0] != "Z":
                out[int(d)] = fields
    return out


# Clamped-cosine zonal coefficients A_l (docs/conventions.md §2), independently from the Legendre integral
# 2π ∫_0^1 P_l(x) x dx · sqrt((2l+1)/4π).
def clamped_cosine_zh(order):
    out = []
    for l in range(order):
        p = np.polynomial.legendre.Legendre.basis(l).convert(kind=np.polynomial.Polynomial)
        integral = (p * np.polynomial.Polynomial([0, 1])).integ()
        val = 2 * np.pi * (integral(1.0) - integral(0.0)) * math.sqrt((2 * l + 1) / (4 * np.pi))
        out.append(val)
    return np.array(out)


def unoccluded_transfer(normals, order):
    """Transfer of vertices that see their whole hemisphere (no blocker), from the independent A_l above."""
    a = clamped_cosine_zh(order)
    scale = np.concatenate([[math.sqrt(4 * np.pi / (2 * l + 1)) * a[l]] * (2 * l + 1) for l in range(order)])
    return sh_eval(normals, order) * scale


def rel_err(t, ref):
    """Mean per-vertex error norm over the mean reference norm."""
    return float(np.linalg.norm(t - ref, axis=1).mean() / np.linalg.norm(ref, axis=1).mean())


def usd_grid(stage, path, n=6, y=0.0, size=2.0):
    """A flat n x n-vertex ``UsdGeom.Mesh`` of triangles at height ``y``, ``size`` across, centred on the Y axis."""
    mesh = UsdGeom.Mesh.Define(stage, path)
    xs = np.linspace(-size / 2, size / 2, n)
    mesh.CreatePointsAttr([Gf.Vec3f(float(x), y, float(z)) for z in xs for x in xs])
    faces = []
    for j in range(n - 1):
        for i in range(n - 1):
            a = j * n + i
            faces += [a, a + n, a + 1, a + 1, a + n, a + n + 1]
    mesh.CreateFaceVertexCountsAttr([3] * (len(faces) // 3))
    mesh.CreateFaceVertexIndicesAttr(faces)
    return mesh


def grid(n: int):
    """n x n vertices on [0, 1]² at y = 0, triangles facing +y (float32 points, int32 faces)."""
    x, y = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n))
    pts = np.stack([x.ravel(), np.zeros(n * n), y.ravel()], 1).astype(np.float32)
    i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1))
    v = (j * n + i).ravel()
    faces = np.concatenate([np.stack([v, v + n, v + 1], 1), np.stack([v + 1, v + n, v + n + 1], 1)])
    return pts, faces.astype(np.int32)


def level_bounds(level_points, level_faces, fine_points, fine_faces, start, mid, tris, offsets, outline=None):
    """NumPy oracle of a hemiraster hierarchy level's per-triangle bounds: for each triangle ``t`` of the level
    (points and faces in float64), standing for fine triangles ``tris[start[t]:start[t+1]]`` (primaries
    before ``mid[t]``, seam-cover extras after), the box of it and of every fine triangle it stands for,
    and its deviation: the largest distance of a primary fine vertex from its plane, at least the largest
    binding ``offsets`` of its corners, 1e-3 of its size, its whole size when it has no primary, and its
    ``outline`` deviation (the mesh boundary) when given. Returns ``(lo, hi, dev)``, (T, 3), (T, 3), (T,)."""
    lo, hi, dev = [], [], []
    for t, face in enumerate(level_faces):
        a, b, c = level_points[face]
        fine = fine_points[fine_faces[tris[start[t]:start[t + 1]]]].reshape(-1, 3)
        prim = fine_points[fine_faces[tris[start[t]:mid[t]]]].reshape(-1, 3)
        allp = np.concatenate([level_points[face], fine])
        lo.append(allp.min(axis=0))
        hi.append(allp.max(axis=0))
        nrm = np.cross(b - a, c - a)
        size = np.linalg.norm(np.stack([a, b, c]) - (a + b + c) / 3, axis=1).max()
        want = max(offsets[face].max(), np.abs((prim - a) @ nrm).max(initial=0.0) / np.linalg.norm(nrm), 1e-3 * size)
        if mid[t] == start[t]:
            want = max(want, size)
        if outline is not None:
            want = max(want, outline[t])
        dev.append(want)
    return np.array(lo), np.array(hi), np.array(dev)


def bumpy_grid(n=7, seed=0, name=None):
    """An open n x n sheet with folds and noise (a seeded random bump per vertex)."""
    rng = np.random.default_rng(seed)
    x, y = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n), indexing="ij")
    z = 0.25 * np.sin(5 * x) * np.cos(4 * y) + 0.05 * rng.normal(size=x.shape)
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    points = np.stack([x, y, z], -1).reshape(-1, 3)
    return TriMesh(points, faces) if name is None else TriMesh(points, faces, name=name)


def swaying_frames(mesh, first, count, up=2, across=1):
    """``count`` poses of ``mesh`` whose points from ``first`` on sway: +0.01 per frame along x and
    ``0.02 sin(0.7 f) cos(3 x_across)`` along axis ``up``; the points before ``first`` stay (so unmoved
    receivers keep a stored part from the second frame). float32."""
    out = []
    for f in range(count):
        p = mesh.points.copy()
        s = p[first:]
        s[:, 0] += 0.01 * f
        s[:, up] += 0.02 * np.sin(0.7 * f) * np.cos(3 * s[:, across])
        out.append(p.astype(np.float32))
    return out


def post_on_floor(dz: float = 0.0, shift: float = 0.0, seg: int = 24, rings: int = 9):
    """A floor (9 x 9 grid on [-2, 2]², z = 0, facing +z) and an open tube standing on it (radius 0.4, rings
    z = 0..2 of ``seg`` vertices, the lowest moved by ``dz``), the whole moved by ``shift``: one mesh, and the
    tube's base ring. Some base vertices lie on floor edges (x = 0), none on a floor vertex."""
    xs = np.linspace(-2.0, 2.0, 9)
    fx, fy = np.meshgrid(xs, xs)
    fp = np.stack([fx.ravel(), fy.ravel(), np.zeros(fx.size)], 1)
    ff = [(a, a + 1, a + 10) for j in range(8) for a in [j * 9 + i for i in range(8)]]
    ff += [(a, a + 10, a + 9) for j in range(8) for a in [j * 9 + i for i in range(8)]]
    t = np.linspace(0.0, 2.0 * np.pi, seg, endpoint=False)
    tp = np.array([(0.4 * np.cos(u), 0.25 + 0.4 * np.sin(u), z) for z in np.linspace(0.0, 2.0, rings) for u in t])
    tp[:seg, 2] += dz
    tf = [(k * seg + i, k * seg + (i + 1) % seg, (k + 1) * seg + (i + 1) % seg) for k in range(rings - 1) for i in range(seg)]
    tf += [(k * seg + i, (k + 1) * seg + (i + 1) % seg, (k + 1) * seg + i) for k in range(rings - 1) for i in range(seg)]
    pts = (np.concatenate([fp, tp]) + shift).astype(np.float32)
    faces = np.concatenate([np.array(ff), np.array(tf) + len(fp)]).astype(np.int32)
    return TriMesh(pts, faces), np.arange(len(fp), len(fp) + seg)
