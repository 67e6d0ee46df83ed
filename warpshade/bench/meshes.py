"""The benchmark's standard mesh set: procedural cloth and two-object frames, the simulation's skinned
character (:class:`warpshade.sim.figure.WalkingFigure`) and Warp's shipped meshes.

Each :class:`BenchMesh` has a rest pose (what a method builds its static structures from) and a
frame pose (what ``update(points)`` is timed and judged on). For rigid meshes the two coincide; the
cloth, character and two-object entries deform or move between rest and frame, so the benchmark
times a real per-frame update rather than a recomputation of the rest pose.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

import numpy as np

from .. import _cache
from .._atomic import replace_atomically
from ..geometry.mesh import TriMesh

BENCH_KIND = "bench"
"""Subdirectory of the per-user cache root (:func:`warpshade._cache.directory`) holding simulated benchmark meshes
and sequences by default."""


@dataclass
class BenchMesh:
    """One benchmark input.

    Attributes:
        name: Short name used in results (``cloth``, ``bunny``...).
        rest: Topology and rest pose.
        frame: Vertex positions of the judged frame [m], shape (V, 3), dtype float32.
        description: One line for ``results.md`` and the printed table.
        up: World up axis (``"Z"`` for the procedural meshes, ``"Y"`` for Warp's USD assets and the character), so the
            benchmark environments light every mesh from above.
        judged: Vertices whose errors are judged, bool shape (V,), or None for all. Methods still compute
            (and are timed on) every vertex; excluded are vertices no one can see (buried inside another
            closed part of the same mesh), whose true transfer is 0.
    """

    name: str
    rest: TriMesh
    frame: np.ndarray
    description: str = ""
    up: str = "Z"
    judged: np.ndarray | None = None

    @property
    def frame_mesh(self) -> TriMesh:
        """The judged frame as a mesh (same topology as :attr:`rest`)."""
        return TriMesh(self.frame, self.rest.faces, name=f"{self.name}-frame")


def grid(n: int, size: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Flat ``n``×``n`` vertex grid in the xy plane centred at the origin, normals +z.

    Returns:
        ``(points (n*n, 3) float32, faces (2*(n-1)**2, 3) int32)``.
    """
    u = np.linspace(-0.5 * size, 0.5 * size, n)
    x, y = np.meshgrid(u, u, indexing="xy")
    pts = np.stack([x.ravel(), y.ravel(), np.zeros(n * n)], axis=1)
    i = np.arange(n - 1)
    a = (i[None, :] + n * i[:, None]).ravel()
    faces = np.concatenate([np.stack([a, a + 1, a + n + 1], 1), np.stack([a, a + n + 1, a + n], 1)])
    return pts.astype(np.float32), faces.astype(np.int32)


def wrinkled_cloth(n: int = 64, seed: int = 7, compress: float = 0.85, name: str = "cloth") -> BenchMesh:
    """A 1 m square of cloth (rest: flat) crumpled into deep folds plus fine wrinkles (frame).

    Folds: three sinusoids of 9-17 cm wavelength and up to 6 cm amplitude with seeded directions
    and phases, modulated so some regions are nearly flat; the frame also compresses the sheet in x to
    ``compress`` of its width (as a draped cloth would), which deepens the folds' self-occlusion.
    """
    rng = np.random.default_rng(seed)
    pts, faces = grid(n)
    x, y = pts[:, 0].astype(np.float64), pts[:, 1].astype(np.float64)
    z = np.zeros_like(x)
    for k in range(3):
        ang = rng.uniform(0, np.pi)
        wl = rng.uniform(0.09, 0.17)
        ph = rng.uniform(0, 2 * np.pi)
        amp = rng.uniform(0.03, 0.06)
        env = 0.6 + 0.4 * np.cos(2 * np.pi * (x * rng.uniform(0.5, 1.5) + y * rng.uniform(0.5, 1.5)) + ph)
        z += amp * env * np.sin(2 * np.pi * (np.cos(ang) * x + np.sin(ang) * y) / wl + ph)
    z += 0.004 * np.sin(2 * np.pi * 25 * x + 1.3) * np.cos(2 * np.pi * 19 * y)
    frame = np.stack([compress * x, y, z], axis=1).astype(np.float32)
    return BenchMesh(name, TriMesh(pts, faces, name="wrinkled-cloth"), frame,
                     f"{n}x{n} cloth crumpled into 3 seeded folds + fine wrinkles, seed {seed}, "
                     f"{compress:g} compression (rest: flat)")


def draped_cloth(n: int = 64, frames: int = 60, cache_dir: str | None = _cache.USER) -> BenchMesh:
    """A 1 m square of cloth (rest: flat, 0.6 m up) dropped onto a 0.25 m ball on the floor and
    simulated for ``frames`` frames (:class:`~warpshade.sim.XPBDSolver`, 16 substeps at 60 frames/s):
    a dome over the ball with a skirt hanging in folds onto the floor. Deterministic (one CPU
    thread); the frame is cached in ``cache_dir`` (default ``<user cache root>/bench``,
    :func:`warpshade._cache.directory`; None: not cached). Y up; the ball and the floor are colliders only
    (not in the mesh).
    """
    cache_dir = _cache.resolve(cache_dir, BENCH_KIND)
    path = os.path.join(cache_dir, f"draped_cloth_n{n}_f{frames}.npz") if cache_dir else None
    if path and os.path.isfile(path):
        z = np.load(path)
        rest, faces, frame = z["rest"], z["faces"], z["frame"]
    else:
        from ..sim import ClothBuilder, ColliderSet, XPBDSolver

        b = ClothBuilder(bend_stiffness=2e-5)
        b.add_grid(n, n, 1.0, 1.0, origin=(-0.5, 0.6, -0.5))
        model = b.finalize()
        col = ColliderSet()
        col.add_plane((0.0, 1.0, 0.0), 0.0, friction=0.6)
        col.add_sphere(np.array([0.0, 0.25, 0.0]), 0.25, friction=0.4)
        solver = XPBDSolver(model, col, substeps=16)
        state = model.state()
        for _ in range(frames):
            solver.step(state, state, 1.0 / 60.0)
        rest = model.rest_points_np.astype(np.float32)
        faces = np.asarray(model.faces, dtype=np.int32)
        frame = state.points.numpy().astype(np.float32)
        if path:
            os.makedirs(cache_dir, exist_ok=True)
            replace_atomically(lambda tmp: np.savez(tmp, rest=rest, faces=faces, frame=frame), path)
    return BenchMesh("draped", TriMesh(rest, faces, name="draped-cloth"), frame,
                     f"{n}x{n} cloth dropped on a ball, {frames} simulated frames (rest: flat)", up="Y")


def _rotation(axis, angle: float) -> np.ndarray:
    a = np.asarray(axis, dtype=np.float64)
    a = a / np.linalg.norm(a)
    k = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return np.eye(3) + np.sin(angle) * k + (1 - np.cos(angle)) * k @ k


def character(t: float = 0.3) -> BenchMesh:
    """The simulation's skinned character (:class:`warpshade.sim.figure.WalkingFigure`, 1.8 m, 14 capsules
    on 11 joints, linear blend skinning by :class:`~warpshade.sim.skinning.LBSSkinner`) in mid-stride.

    Rest is the skeleton's bind pose (arms hanging close to the torso, legs straight); the frame is the
    pose at ``t`` seconds (default 0.3 s = a quarter gait cycle: thighs swung ±0.42 rad, arms ±0.35 rad,
    knees and elbows bent), skinned by the same Warp kernel ``warpshade run`` uses for skinned objects.
    Limbs overlap at the joints and the arms brush the torso (receivers touching blockers, the hard case
    for visibility). Y up.

    The body is a union of overlapping closed capsules, so 951 of its 2492 vertices lie inside another
    capsule (at the joints); their true transfer is 0 and no renderer shows them, so they are not judged
    (:attr:`BenchMesh.judged`): a vertex is buried when it is farther than 0.1 % of the radius inside
    an analytic capsule (:meth:`WalkingFigure.capsules`) other than its own.
    """
    from ..sim.figure import WalkingFigure, capsule_mesh

    fig = WalkingFigure()
    rest = TriMesh(fig.rest_points, fig.faces, name="walking-figure")
    frame = fig.points(t).astype(np.float32)
    caps = fig.capsules(t)
    # the body's vertices are the capsules' meshes in order (WalkingFigure builds them so)
    part = np.repeat(np.arange(len(caps)), [len(capsule_mesh(p0, p1, r)[0]) for p0, p1, r in caps])
    p = frame.astype(np.float64)
    buried = np.zeros(len(p), dtype=bool)
    for j, (p0, p1, r) in enumerate(caps):
        d = p1 - p0
        s = np.clip((p - p0) @ d / (d @ d), 0.0, 1.0)
        buried |= (part != j) & (np.linalg.norm(p - (p0 + s[:, None] * d), axis=1) < r * (1 - 1e-3))
    return BenchMesh("character", rest, frame,
                     f"skinned WalkingFigure (warpshade.sim) at t={t:g} s, mid-stride; "
                     f"{int(buried.sum())} vertices buried inside other capsules not judged", up="Y", judged=~buried)


def two_objects(ground_n: int = 48, torus_sections: int = 48) -> BenchMesh:
    """A torus floating above a 2 m ground grid, merged into one mesh (inter-object shadows).

    Rest: torus 0.5 m above the ground, axis vertical; frame: torus tilted 50° and lowered so its
    rim nearly touches the ground (receivers near blockers).
    """
    import trimesh

    gp, gf = grid(ground_n, size=2.0)
    t = trimesh.creation.torus(major_radius=0.35, minor_radius=0.12, major_sections=torus_sections,
                               minor_sections=torus_sections // 2)
    tv = np.asarray(t.vertices, dtype=np.float64)
    rest_t = tv + (0, 0, 0.5)
    frame_t = tv @ _rotation((1, 0.3, 0), np.radians(50)).T + (0.1, 0, 0.34)
    faces = np.concatenate([gf, np.asarray(t.faces) + len(gp)])
    rest = TriMesh(np.concatenate([gp, rest_t]), faces, name="torus-over-ground")
    frame = np.concatenate([gp, frame_t]).astype(np.float32)
    return BenchMesh("two-objects", rest, frame, "torus tilted over a ground grid (merged mesh)")


def warp_mesh(name: str) -> BenchMesh:
    """One of Warp's shipped meshes (``bunny``, ``bear``...) from ``warp/examples/assets``, rigid."""
    import warp as wp

    from ..usd.mesh_io import load_mesh

    path = os.path.join(os.path.dirname(wp.__file__), "examples", "assets", f"{name}.usd")
    m = load_mesh(path)
    return BenchMesh(name, m, m.points.copy(), f"Warp's {name}.usd", up="Y")


def standard_meshes(quick: bool = False) -> list[BenchMesh]:
    """The standard set: full — cloth 64², bunny, bear, character, two objects; quick — small versions.

    Quick keeps a deforming and a two-object input, both small (cloth 20², a 16² ground with a coarse
    torus), so the whole quick sweep stays under two minutes on a loaded machine.
    """
    if quick:
        return [wrinkled_cloth(20), two_objects(16, 16)]
    return [wrinkled_cloth(64), warp_mesh("bunny"), warp_mesh("bear"), character(), two_objects()]
