"""Kinematic colliders: planes, spheres, capsules, boxes, cylinders, cones and animated triangle meshes.

A :class:`ColliderSet` is given to the solver. Move colliders between steps with the ``set_*``
methods (the new pose is where the collider is at the end of the next step; the solver sweeps
from the old pose to it across the substeps).
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..geometry.mesh import first_nonfinite, weld_indices
from . import collision_kernels as ck
from .kernels import apply_averaged_deltas, save_rows
from .launches import RecordedLaunches


def _vec(name: str, value, n: int = 3) -> np.ndarray:
    a = np.asarray(value, dtype=np.float64).reshape(-1)
    if a.shape != (n,) or not np.isfinite(a).all():
        raise ValueError(f"{name} must be {n} finite numbers, got {value}")
    return a


def _pos(name: str, value) -> float:
    v = float(value)
    if not np.isfinite(v) or v <= 0:
        raise ValueError(f"{name} must be finite and > 0, got {value}")
    return v


def _friction(value) -> float:
    v = float(value)
    if not np.isfinite(v) or v < 0:
        raise ValueError(f"friction must be finite and >= 0, got {value}")
    return v


CORNER_ANGLE_SUM = 290.0
"""[degrees] A closed mesh collider's convex vertex is a corner (a point the corner contacts hold)
when the angles of its faces there sum to less than this: a pointed tip such as a cone's apex (a
32-sided cone of half angle 22 degrees: 134) and a box's corner (270), not a vertex on a sharp
edge or a cylinder's rim (345-360) nor an icosahedron's (300), which the vertex and edge passes
hold. Without the box corners (the limit was 180), the corner of a mesh box poked through the
interior of a cloth triangle draped over it, which no vertex or edge contact pushes off, and the
intersection guard sent that triangle's vertices back every step for ever (docs/benchmarks/history.md)."""


def sharp_corners(points: np.ndarray, faces: np.ndarray, max_angle_sum: float = CORNER_ANGLE_SUM) -> tuple:
    """The pointed convex vertices of a closed, outward-wound triangle mesh (vertices welded as in
    :func:`weld_indices`): the angles of the faces at the vertex sum to less than
    ``max_angle_sum`` degrees, and the centroid of its neighbours lies behind it (opposite the sum
    of its faces' normals). Returns (vertex indices (K,), ring offsets (K + 1,), ring (R,)): the
    neighbours of corner k are ring[offsets[k]:offsets[k + 1]]."""
    pts = np.asarray(points, dtype=np.float64)
    f = weld_indices(pts)[np.asarray(faces, dtype=np.int64)]
    nrm = np.cross(pts[f[:, 1]] - pts[f[:, 0]], pts[f[:, 2]] - pts[f[:, 0]])
    ln = np.linalg.norm(nrm, axis=1)
    ok = ln > 0
    f, nrm = f[ok], nrm[ok] / ln[ok, None]
    vert = f.reshape(-1)
    face = np.repeat(np.arange(len(f)), 3)
    corner = np.tile(np.arange(3), len(f))
    e1 = pts[f[face, (corner + 1) % 3]] - pts[vert]
    e2 = pts[f[face, (corner + 2) % 3]] - pts[vert]
    cos = np.einsum("ij,ij->i", e1, e2) / (np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1))
    angle = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    order = np.argsort(vert, kind="stable")
    vert, face, angle = vert[order], face[order], angle[order]
    starts = np.flatnonzero(np.r_[True, vert[1:] != vert[:-1]])
    ends = np.r_[starts[1:], len(vert)]
    out, offsets, ring = [], [0], []
    for s0, s1 in zip(starts, ends):
        if angle[s0:s1].sum() >= max_angle_sum:
            continue
        v = int(vert[s0])
        nb = np.unique(f[face[s0:s1]].reshape(-1))
        nb = nb[nb != v]
        if (pts[nb].mean(axis=0) - pts[v]) @ nrm[face[s0:s1]].sum(axis=0) >= 0.0:
            continue  # the neighbours lie in front of it: not a convex tip
        out.append(v)
        ring.extend(nb.tolist())
        offsets.append(len(ring))
    return np.asarray(out, np.int64), np.asarray(offsets, np.int64), np.asarray(ring, np.int64)


class MeshCollider:
    """An animated triangle mesh: closed (or a union of overlapping closed parts), or an open sheet.

    Attributes:
        mesh: The Warp BVH mesh, points at the current substep.
        points_start: Points at the start of the step [m], shape (V,), dtype vec3.
        points_end: Points at the end of the step [m], shape (V,), dtype vec3.
        points_prev: Points at the previous substep [m], shape (V,), dtype vec3.
        faces: Triangles on the host, shape (F, 3), int32.
        friction: Coulomb coefficient.
        closed: Whether every edge has two faces. A closed mesh is a solid (winding-number
            inside test); an open one (a ground sheet) is a two-sided shell that vertices stay
            on their side of.
    """

    def __init__(self, points: np.ndarray, faces: np.ndarray, friction: float, device):
        pts = np.asarray(points, dtype=np.float32)
        self.faces = np.asarray(faces, dtype=np.int32)
        self._check(pts)
        if self.faces.ndim != 2 or self.faces.shape[1] != 3 or self.faces.min() < 0 or self.faces.max() >= len(pts):
            raise ValueError(f"mesh collider: faces must have shape (F, 3) with indices in 0..{len(pts) - 1}")
        self.friction = _friction(friction)
        self.points_start = wp.array(pts, dtype=wp.vec3, device=device)
        self.points_end = wp.array(pts, dtype=wp.vec3, device=device)
        self.points_prev = wp.array(pts, dtype=wp.vec3, device=device)
        self.indices = wp.array(self.faces.reshape(-1), dtype=wp.int32, device=device)
        self.mesh = wp.Mesh(points=wp.array(pts, dtype=wp.vec3, device=device), indices=self.indices)
        self._pending = None
        self._end_host = pts
        self.moving = False
        """Whether the mesh moves in the current step (its end pose differs from its start pose)."""
        # edge topology for edge-edge contact: each triangle's edges, their ends and faces (-1: border),
        # on the welded mesh (see weld_indices)
        f = weld_indices(pts)[self.faces.astype(np.int64)]
        directed = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
        und = np.sort(directed, axis=1)
        key = und[:, 0] * len(pts) + und[:, 1]
        uniq, inv = np.unique(key, return_inverse=True)
        tri_of = np.tile(np.arange(len(f)), 3)
        edge_faces = np.full((len(uniq), 2), -1, dtype=np.int64)
        order = np.argsort(inv, kind="stable")
        first = np.ones(len(order), dtype=bool)
        first[1:] = inv[order][1:] != inv[order][:-1]
        edge_faces[inv[order][first], 0] = tri_of[order][first]
        second = ~first
        edge_faces[inv[order][second], 1] = tri_of[order][second]
        self.tri_edges = wp.array(inv.reshape(3, -1).T.astype(np.int32), dtype=wp.int32, device=device)
        self.edge_verts = wp.array(np.stack([uniq // len(pts), uniq % len(pts)], 1).astype(np.int32),
                                   dtype=wp.int32, device=device)
        self.edge_faces = wp.array(edge_faces.astype(np.int32), dtype=wp.int32, device=device)
        self.closed = bool(len(edge_faces)) and bool((edge_faces[:, 1] >= 0).all())
        self.tri_sharp = wp.full((len(f), 3), -1, dtype=wp.int32, device=device)
        """Per triangle side, its edge's index when the edge is sharp and convex and met from this face,
        else -1 (:func:`~warpshade.sim.collision_kernels.mesh_sharp_edges`, for the pose in ``mesh.points``)."""
        self.edge_normals = wp.zeros((len(uniq), 2), dtype=wp.vec3, device=device)
        """The sharp convex edges' two faces' unit normals (for the pose in ``mesh.points``)."""
        self._sharp_posed = False  # whether tri_sharp and edge_normals are those of the pose in mesh.points
        corner, offsets, ring = sharp_corners(pts, self.faces) if self.closed else (np.zeros(0, np.int32),) * 3
        self.corner_vertices = wp.array(corner.astype(np.int32), dtype=wp.int32, device=device)
        """Pointed convex vertices (:func:`sharp_corners`: a cone's apex), whose poke through the cloth
        the corner contacts hold; none for an open mesh (a sheet has no inside)."""
        self.corner_ring_offsets = wp.array(np.asarray(offsets, np.int32), dtype=wp.int32, device=device)
        self.corner_ring = wp.array(np.asarray(ring, np.int32), dtype=wp.int32, device=device)

    def _check(self, pts):
        if pts.ndim != 2 or pts.shape[1] != 3:
            raise ValueError(f"mesh collider: points must have shape (V, 3), got {pts.shape}")
        v = first_nonfinite(pts)
        if v is not None:
            raise ValueError(f"mesh collider: vertex {v} is not finite")

    def set_points(self, points: np.ndarray) -> None:
        """Pose at the end of the next step [m], shape (V, 3) (same topology)."""
        pts = np.asarray(points, dtype=np.float32)
        if pts.shape != (self.points_end.shape[0], 3):
            raise ValueError(f"mesh collider: expected points of shape ({self.points_end.shape[0]}, 3), got {pts.shape}")
        self._check(pts)
        self._pending = pts


class ColliderSet:
    """Analytic shapes and mesh colliders, each with a thickness-independent friction coefficient.

    Args:
        device: Warp device, default ``"cpu"``.
    """

    def __init__(self, device: str = "cpu"):
        self.device = wp.get_device(device)
        self._kind: list[int] = []
        self._a: list[np.ndarray] = []
        self._b: list[np.ndarray] = []
        self._rot: list[np.ndarray] = []
        self._size: list[np.ndarray] = []
        self._friction: list[float] = []
        self.meshes: list[MeshCollider] = []
        self._dirty = True
        self._arrays = None
        self._recorded = RecordedLaunches(self.device)

    # -- building ---------------------------------------------------------------------------

    def _add(self, kind, a, b, rot, size, friction) -> int:
        self._kind.append(kind)
        self._a.append(a)
        self._b.append(b)
        self._rot.append(np.asarray(rot, dtype=np.float64))
        self._size.append(np.asarray(size, dtype=np.float64))
        self._friction.append(_friction(friction))
        self._dirty = True
        return len(self._kind) - 1

    def add_plane(self, normal=(0.0, 1.0, 0.0), offset: float = 0.0, friction: float = 0.5) -> int:
        """Half-space {x : n.x >= offset} (n normalised). Returns the shape index."""
        n = _vec("plane normal", normal)
        ln = np.linalg.norm(n)
        if ln == 0:
            raise ValueError("plane normal must be non-zero")
        n = n / ln
        return self._add(int(ck.SHAPE_PLANE), n * float(offset), n, (0, 0, 0, 1), (0, 0, 0), friction)

    def add_sphere(self, center, radius: float, friction: float = 0.5) -> int:
        """Solid sphere. Returns the shape index."""
        return self._add(int(ck.SHAPE_SPHERE), _vec("sphere center", center), np.zeros(3), (0, 0, 0, 1),
                         (_pos("sphere radius", radius), 0, 0), friction)

    def add_capsule(self, p0, p1, radius: float, friction: float = 0.5) -> int:
        """Solid capsule around segment p0-p1. Returns the shape index."""
        return self._add(int(ck.SHAPE_CAPSULE), _vec("capsule p0", p0), _vec("capsule p1", p1), (0, 0, 0, 1),
                         (_pos("capsule radius", radius), 0, 0), friction)

    def add_box(self, center, half_extents, rotation=(0.0, 0.0, 0.0, 1.0), friction: float = 0.5) -> int:
        """Solid oriented box; rotation is a quaternion (x, y, z, w). Returns the shape index."""
        he = _vec("box half_extents", half_extents)
        if (he <= 0).any():
            raise ValueError(f"box half_extents must be > 0, got {half_extents}")
        return self._add(int(ck.SHAPE_BOX), _vec("box center", center), np.zeros(3), self._quat(rotation), he,
                         friction)

    def add_cylinder(self, p0, p1, radius: float, friction: float = 0.5) -> int:
        """Solid cylinder with flat caps centred at p0 and p1 (sharp rims). Returns the shape index."""
        a, b = self._axis("cylinder", p0, p1)
        return self._add(int(ck.SHAPE_CYLINDER), a, b, (0, 0, 0, 1), (_pos("cylinder radius", radius), 0, 0), friction)

    def add_cone(self, base, apex, radius: float, friction: float = 0.5) -> int:
        """Solid cone: a flat disc of ``radius`` centred at ``base``, tapering to ``apex`` (sharp
        rim and apex). Returns the shape index."""
        a, b = self._axis("cone", base, apex)
        return self._add(int(ck.SHAPE_CONE), a, b, (0, 0, 0, 1), (_pos("cone radius", radius), 0, 0), friction)

    @staticmethod
    def _axis(what: str, p0, p1) -> tuple[np.ndarray, np.ndarray]:
        names = ("base", "apex") if what == "cone" else ("p0", "p1")
        a, b = _vec(f"{what} {names[0]}", p0), _vec(f"{what} {names[1]}", p1)
        if not np.linalg.norm(b - a) > 0:
            raise ValueError(f"{what} {names[0]} and {names[1]} must differ, got {p0} and {p1}")
        return a, b

    def add_mesh(self, points: np.ndarray, faces: np.ndarray, friction: float = 0.5) -> MeshCollider:
        """Animated triangle-mesh collider (move it with ``collider.set_points``)."""
        m = MeshCollider(points, faces, friction, self.device)
        self.meshes.append(m)
        return m

    @staticmethod
    def _quat(rotation) -> np.ndarray:
        q = _vec("rotation quaternion", rotation, 4)
        lq = np.linalg.norm(q)
        if lq == 0:
            raise ValueError("rotation quaternion must be non-zero")
        return q / lq

    # -- animation --------------------------------------------------------------------------

    def set_sphere(self, index: int, center) -> None:
        """Move sphere ``index`` (its centre at the end of the next step)."""
        self._a[self._shape(index, ck.SHAPE_SPHERE)] = _vec("sphere center", center)
        self._dirty = True

    def set_capsule(self, index: int, p0, p1) -> None:
        """Move capsule ``index``."""
        i = self._shape(index, ck.SHAPE_CAPSULE)
        self._a[i] = _vec("capsule p0", p0)
        self._b[i] = _vec("capsule p1", p1)
        self._dirty = True

    def set_cylinder(self, index: int, p0, p1) -> None:
        """Move cylinder ``index`` (its cap centres at the end of the next step)."""
        i = self._shape(index, ck.SHAPE_CYLINDER)
        self._a[i], self._b[i] = self._axis("cylinder", p0, p1)
        self._dirty = True

    def set_cone(self, index: int, base, apex) -> None:
        """Move cone ``index`` (its base centre and apex at the end of the next step)."""
        i = self._shape(index, ck.SHAPE_CONE)
        self._a[i], self._b[i] = self._axis("cone", base, apex)
        self._dirty = True

    def set_box(self, index: int, center, rotation=None) -> None:
        """Move box ``index``."""
        i = self._shape(index, ck.SHAPE_BOX)
        self._a[i] = _vec("box center", center)
        if rotation is not None:
            self._rot[i] = self._quat(rotation)
        self._dirty = True

    def _shape(self, index: int, kind) -> int:
        if not 0 <= index < len(self._kind) or self._kind[index] != int(kind):
            raise ValueError(f"collider {index} is not a shape of kind {int(kind)}")
        return index

    @property
    def shape_count(self) -> int:
        return len(self._kind)

    # -- used by the solver -----------------------------------------------------------------

    def end_pose_arrays(self) -> dict | None:
        """The analytic shapes' device arrays (``kind``, ``a_end``, ``b_end``, ``rot_end``, ``size``...)
        as posed at the end of the last step, or None without shapes."""
        if self._kind and self._arrays is None:
            self._upload_shapes()
        return self._arrays

    def begin_step(self) -> None:
        """Upload the end-of-step poses (the start poses are the previous step's end poses)."""
        self._upload_shapes()
        self._dirty = False
        for m in self.meshes:
            m.moving = m._pending is not None and not np.array_equal(m._pending, m._end_host)
            if m._pending is not None:
                m.points_end.assign(m._pending)
                m._end_host, m._pending = m._pending, None

    def _upload_shapes(self) -> None:
        if self._kind:
            if self._arrays is None or len(self._arrays["kind"]) != len(self._kind):
                d = self.device
                a = np.array(self._a, dtype=np.float32)
                b = np.array(self._b, dtype=np.float32)
                r = np.array(self._rot, dtype=np.float32)
                self._arrays = {
                    "kind": wp.array(np.array(self._kind, dtype=np.int32), dtype=wp.int32, device=d),
                    "a_start": wp.array(a, dtype=wp.vec3, device=d), "a_end": wp.array(a, dtype=wp.vec3, device=d),
                    "b_start": wp.array(b, dtype=wp.vec3, device=d), "b_end": wp.array(b, dtype=wp.vec3, device=d),
                    "rot_start": wp.array(r, dtype=wp.quat, device=d), "rot_end": wp.array(r, dtype=wp.quat, device=d),
                    "size": wp.array(np.array(self._size, dtype=np.float32), dtype=wp.vec3, device=d),
                    "friction": wp.array(np.array(self._friction, dtype=np.float32), dtype=wp.float32, device=d),
                }
                for key in ("a0", "a1", "b0", "b1"):
                    self._arrays[key] = wp.array(a if key[0] == "a" else b, dtype=wp.vec3, device=d)
                for key in ("r0", "r1"):
                    self._arrays[key] = wp.array(r, dtype=wp.quat, device=d)
            elif self._dirty:
                ar = self._arrays
                ar["a_end"].assign(np.array(self._a, dtype=np.float32))
                ar["b_end"].assign(np.array(self._b, dtype=np.float32))
                ar["rot_end"].assign(np.array(self._rot, dtype=np.float32))

    def end_step(self) -> None:
        """The end poses become the next step's start poses."""
        if self._arrays is not None:
            ar = self._arrays
            wp.copy(ar["a_start"], ar["a_end"])
            wp.copy(ar["b_start"], ar["b_end"])
            wp.copy(ar["rot_start"], ar["rot_end"])
        for m in self.meshes:
            wp.copy(m.points_start, m.points_end)

    def _launch(self, kernel, dim: int, inputs: list, outputs: list) -> None:
        """``wp.launch`` of the per-substep kernels through their recorded launches (:class:`RecordedLaunches`)."""
        self._recorded.launch(kernel, dim, inputs, outputs)

    def pose_substep(self, alpha0: float, alpha1: float) -> None:
        """Pose the colliders for the substep spanning fractions alpha0..alpha1 of the step."""
        if self._arrays is not None:
            ar = self._arrays
            self._launch(ck.pose_shapes, len(self._kind),
                         [ar["a_start"], ar["a_end"], ar["b_start"], ar["b_end"], ar["rot_start"], ar["rot_end"], alpha0,
                          alpha1], [ar["a0"], ar["a1"], ar["b0"], ar["b1"], ar["r0"], ar["r1"]])
        for m in self.meshes:
            self._launch(ck.interpolate_points, m.points_start.shape[0], [m.points_start, m.points_end, alpha0],
                         [m.points_prev])
            self._launch(ck.interpolate_points, m.points_start.shape[0], [m.points_start, m.points_end, alpha1],
                         [m.mesh.points])
            m.mesh.refit()
            m._sharp_posed = False
        if self.corner_count:
            self._corner_arrays()
            self._pose_corners("substep_start", self._corners_prev)
            self._pose_corners("substep", self._corners)

    @property
    def has_sharp_edges(self) -> bool:
        """Whether :meth:`collide_edges` has work: mesh colliders, boxes, cylinders or cones."""
        return bool(self.meshes) or any(k in self._SHARP for k in self._kind)

    @property
    def has_rims(self) -> bool:
        """Whether there are analytic cylinders or cones (sharp circular rims; their cloth triangles get
        :meth:`collide_shape_faces`)."""
        return any(k in self._FACE_PASS for k in self._kind)

    @property
    def smallest_rim(self) -> float | None:
        """Radius of the smallest analytic cylinder or cone [m], or None without one."""
        radii = [float(sz[0]) for k, sz in zip(self._kind, self._size) if k in self._FACE_PASS]
        return min(radii) if radii else None

    _SHARP = (int(ck.SHAPE_BOX), int(ck.SHAPE_CYLINDER), int(ck.SHAPE_CONE))
    """Analytic kinds with sharp edges (box edges, rims, apex)."""

    @property
    def has_round_shapes(self) -> bool:
        """Whether there are spheres or capsules (:meth:`collide_round_faces` has work)."""
        return any(k in (int(ck.SHAPE_SPHERE), int(ck.SHAPE_CAPSULE)) for k in self._kind)

    def collide_edges(self, thickness: float, inv_mass, edges, x, tris=None, x_prev=None, x_start=None) -> None:
        """Push cloth edges out of the mesh colliders' edges, the edges of boxes and the rims of
        cylinders and cones (sharp edges cutting between two cloth vertices), cloth triangles off
        the closed meshes' sharp edges (:func:`~warpshade.sim.collision_kernels.collide_mesh_edge_faces`:
        a triangle laid across a box's edge), and cloth triangles off the colliders' corners
        (:meth:`collide_corners`: box corners, cone apexes, sharp mesh vertices poking through a
        triangle's inside), corrections averaged per vertex. Given ``x_start`` (and tris), cloth triangles
        that cut into a cylinder or cone are pushed back the way they came since then
        (:meth:`collide_shape_faces`, those kinds only) before and after those passes: cloth held over a
        cone's flat base by its stretched edges otherwise slides round the rim within a step while the rim
        cuts its triangles, every vertex path outside the solid, and ends the step under it with no pair
        left for the guard; cloth draped over a cylinder's rim otherwise ends its steps with the rim
        through its triangles (the edge pass alone leaves it poking through a triangle's inside), and the
        guard holds it at the step's start while the cloth round it falls on.

        Args:
            thickness: Distance to keep [m].
            inv_mass: Inverse masses, shape (V,), dtype float32.
            edges: Cloth edges, shape (E, 2), dtype int32.
            x: Positions [m], shape (V,), dtype vec3, corrected in place.
            tris: Cloth triangles, shape (F, 3), dtype int32; None skips the triangle passes.
            x_prev: Positions at the start of the substep [m], for the corners' friction (None: none).
            x_start: Positions at the start of the step [m] (the solver's substeps) or None (no
                cone face pass).
        """
        if not self.has_sharp_edges:
            return
        faces = x_start is not None and tris is not None and self.has_rims
        if faces:
            self.collide_shape_faces(thickness, inv_mass, tris, x, x_start, self._FACE_PASS)
        n = x.shape[0]
        self._edge_accumulators(n)
        if self.has_sharp_shapes:
            ar = self._arrays
            self._launch(ck.collide_shape_edges, edges.shape[0],
                         [ar["kind"], ar["a1"], ar["b1"], ar["r1"], ar["size"], x, edges, inv_mass, thickness],
                         [self._edge_delta, self._edge_count])
        for m in self.meshes:
            self._launch(ck.collide_mesh_edges, edges.shape[0],
                         [m.mesh.id, m.mesh.points, m.indices, m.tri_edges, m.edge_verts, m.edge_faces, x, edges,
                          inv_mass, thickness], [self._edge_delta, self._edge_count])
        self._launch(apply_averaged_deltas, n, [], [self._edge_delta, self._edge_count, x])
        if tris is not None and self.has_closed_meshes:
            # cloth triangles off the closed meshes' sharp edges, a pass of its own (as the
            # corners': averaged with the edge corrections, the push would be diluted)
            for m in self.meshes:
                if m.closed and not m.moving:
                    if not m._sharp_posed:
                        self._launch(ck.mesh_sharp_edges, m.tri_sharp.shape[0],
                                     [m.mesh.points, m.indices, m.tri_edges, m.edge_verts, m.edge_faces],
                                     [m.edge_normals, m.tri_sharp])
                        m._sharp_posed = True
                    self._launch(ck.collide_mesh_edge_faces, tris.shape[0],
                                 [m.mesh.id, m.mesh.points, m.tri_sharp, m.edge_verts, m.edge_normals, x,
                                  tris, inv_mass, thickness], [self._edge_delta, self._edge_count])
            self._launch(apply_averaged_deltas, n, [], [self._edge_delta, self._edge_count, x])
        if tris is not None:
            # a pass of its own: averaged with the many small edge corrections a vertex near a
            # corner also gets, the corner's push would be diluted
            self.collide_corners(thickness, inv_mass, tris, x, x_prev)
        if faces:
            self.collide_shape_faces(thickness, inv_mass, tris, x, x_start, self._FACE_PASS)

    _FACE_PASS = (int(ck.SHAPE_CYLINDER), int(ck.SHAPE_CONE))
    """Kinds whose rims :meth:`collide_edges` also keeps out of the cloth triangles with
    :meth:`collide_shape_faces` (given ``x_start``; boxes not: on the forced hammock the pass on every
    sharp shape flipped outcomes case by case, docs/benchmarks/history.md)."""

    def limit_round_motion(self, fraction: float, thickness: float, inv_mass, x_prev, x) -> None:
        """Shorten each free vertex's move x_prev -> x over the substep to ``fraction`` of the radius
        of a sphere or capsule (posed by :meth:`pose_substep`) that the move passes within
        ``thickness`` of (:func:`~warpshade.sim.collision_kernels.limit_round_motion`)."""
        if not self.has_round_shapes:
            return
        ar = self._arrays
        self._launch(ck.limit_round_motion, x.shape[0],
                     [ar["kind"], ar["a1"], ar["b1"], ar["size"], float(fraction), float(thickness), inv_mass, x_prev],
                     [x])

    def limit_shape_motion(self, fraction: float, thickness: float, inv_mass, x_prev, x) -> None:
        """Shorten each free vertex's move x_prev -> x over the substep that enters a box, cylinder or
        cone (posed by :meth:`pose_substep`) to ``fraction`` of the chord its line cuts through the
        solid (:func:`~warpshade.sim.collision_kernels.limit_shape_motion`): the analytic
        counterpart of :meth:`limit_mesh_motion`."""
        if not self.has_sharp_shapes:
            return
        ar = self._arrays
        self._launch(ck.limit_shape_motion, x.shape[0],
                     [ar["kind"], ar["a1"], ar["b1"], ar["r1"], ar["size"], float(fraction), float(thickness),
                      inv_mass, x_prev], [x])

    @property
    def has_sharp_shapes(self) -> bool:
        """Whether there are boxes, cylinders or cones (:meth:`limit_shape_motion` has work)."""
        return any(k in self._SHARP for k in self._kind)

    def limit_mesh_motion(self, fraction: float, thickness: float, inv_mass, x_prev, x) -> None:
        """Shorten each free vertex's move x_prev -> x over the substep that enters a closed mesh
        collider (posed by :meth:`pose_substep`) to ``fraction`` of the chord its line cuts through
        the solid (:func:`~warpshade.sim.collision_kernels.limit_mesh_motion`): the mesh
        counterpart of :meth:`limit_round_motion`."""
        for m in self.meshes:
            if m.closed:
                self._launch(ck.limit_mesh_motion, x.shape[0],
                             [m.mesh.id, float(fraction), float(thickness), inv_mass, x_prev], [x])

    @property
    def has_closed_meshes(self) -> bool:
        """Whether there are closed mesh colliders (:meth:`limit_mesh_motion` has work)."""
        return any(m.closed for m in self.meshes)

    def collide_round_faces(self, thickness: float, inv_mass, tris, x, x_start) -> None:
        """Push cloth triangles that cut into a sphere or capsule (posed as at the end of the last
        substep) while their vertices are held outside (an edge drawn across it, or its dome
        poking through a stretched triangle) out to ``thickness``, on the side they were on at the
        start of the step (``x_start`` against the step's start pose;
        :func:`~warpshade.sim.collision_kernels.collide_round_faces`), corrections averaged per
        vertex. A triangle that stays out of the solid is left alone.

        Args:
            thickness: Distance to keep [m].
            inv_mass: Inverse masses, shape (V,), dtype float32.
            tris: Cloth triangles, shape (F, 3), dtype int32.
            x: Positions [m], shape (V,), dtype vec3, corrected in place.
            x_start: Positions at the start of the step [m]: the side each triangle came from.
        """
        if not self.has_round_shapes:
            return
        self._edge_accumulators(x.shape[0])
        ar = self._arrays
        self._launch(ck.collide_round_faces, tris.shape[0],
                     [ar["kind"], ar["a_start"], ar["b_start"], ar["a1"], ar["b1"], ar["size"], x_start, x, tris,
                      inv_mass, thickness], [self._edge_delta, self._edge_count])
        self._launch(apply_averaged_deltas, x.shape[0], [], [self._edge_delta, self._edge_count, x])

    FACE_SAMPLES = 24
    """Steps a side of the barycentric grid on which :meth:`collide_mesh_faces` tests a cloth
    triangle against a mesh (322 points besides the vertices; 6 steps missed the hammock's
    ball between the points of its 38 cm triangles)."""

    def collide_mesh_faces(self, thickness: float, inv_mass, tris, x, x_start) -> None:
        """Push cloth triangles that cut into a mesh collider (posed as at the end of the last substep)
        while their vertices are held outside, corrections averaged per vertex
        (:func:`~warpshade.sim.collision_kernels.collide_mesh_faces`, sampled on a grid of
        :attr:`FACE_SAMPLES` steps a side): the mesh counterpart of :meth:`collide_round_faces`. Out
        of a closed mesh to ``thickness``, their deepest point back the way it came since
        ``x_start``; through an open mesh, back to the side they were on at ``x_start`` against the
        step's start pose.

        Args:
            thickness: Distance to keep [m].
            inv_mass: Inverse masses, shape (V,), dtype float32.
            tris: Cloth triangles, shape (F, 3), dtype int32.
            x: Positions [m], shape (V,), dtype vec3, corrected in place.
            x_start: Positions at the start of the step [m]: where each triangle came from.
        """
        if not self.meshes:
            return
        self._edge_accumulators(x.shape[0])
        for m in self.meshes:
            self._launch(ck.collide_mesh_faces, tris.shape[0],
                         [m.mesh.id, m.points_start, m.indices, int(m.closed), int(m.moving), x_start, x, tris, inv_mass,
                          thickness, thickness + self.mesh_query_distance, self.FACE_SAMPLES],
                         [self._edge_delta, self._edge_count])
        self._launch(apply_averaged_deltas, x.shape[0], [], [self._edge_delta, self._edge_count, x])

    def collide_shape_faces(self, thickness: float, inv_mass, tris, x, x_start, kinds=None) -> None:
        """Push cloth triangles that cut into a box, cylinder or cone (posed as at the end of the last
        substep) while their vertices are held outside back the way they came since ``x_start``
        (judged against the step's start pose), corrections averaged per vertex
        (:func:`~warpshade.sim.collision_kernels.collide_shape_faces`, sampled on a grid of
        :attr:`FACE_SAMPLES` steps a side): the analytic counterpart of :meth:`collide_mesh_faces` for
        closed meshes. Arguments as there; ``kinds``: only the shapes of these kinds (``SHAPE_CONE`` and
        the like in :mod:`~warpshade.sim.collision_kernels`), None all."""
        if not self.has_sharp_shapes:
            return
        mask = sum(1 << int(k) for k in (self._SHARP if kinds is None else kinds))
        self._edge_accumulators(x.shape[0])
        ar = self._arrays
        self._launch(ck.collide_shape_faces, tris.shape[0],
                     [ar["kind"], ar["a_start"], ar["b_start"], ar["rot_start"], ar["a1"], ar["b1"], ar["r1"], ar["size"],
                      x_start, x, tris, inv_mass, thickness, self.FACE_SAMPLES, mask], [self._edge_delta, self._edge_count])
        self._launch(apply_averaged_deltas, x.shape[0], [], [self._edge_delta, self._edge_count, x])

    def _edge_accumulators(self, n: int) -> None:
        """The per-vertex correction sums of the edge and corner passes, for n cloth vertices."""
        if getattr(self, "_edge_delta", None) is None or self._edge_delta.shape[0] != n:
            self._edge_delta = wp.zeros(n, dtype=wp.vec3, device=self.device)
            self._edge_count = wp.zeros(n, dtype=wp.float32, device=self.device)

    # -- corners: box corners, cone apexes, sharp mesh vertices against cloth triangles ------

    CORNER_ROW = 64
    """Cloth triangles kept per corner (the nearest; more are counted in ``corner_overflow``)."""

    @property
    def corner_count(self) -> int:
        """Corners the corner contacts hold: 8 per box, 1 per cone, the sharp vertices of the mesh colliders."""
        key = (len(self._kind), len(self.meshes))
        if getattr(self, "_corner_count", (None, 0))[0] != key:
            box, cone = int(ck.SHAPE_BOX), int(ck.SHAPE_CONE)
            self._corner_count = (key, sum(8 if k == box else 1 if k == cone else 0 for k in self._kind)
                                  + sum(m.corner_vertices.shape[0] for m in self.meshes))
        return self._corner_count[1]

    def _pose_corners(self, pose: str, out) -> None:
        """Corner positions into `out` and their inward directions into ``self._corner_in``, the
        analytic shapes and meshes as posed at the step's ``"start"`` or ``"end"``, or the current
        substep's start (``"substep_start"``) or end (``"substep"``)."""
        d = self.device
        n_shape = 0
        if self._arrays is not None:
            ar = self._arrays
            lay = self._corner_layout
            n_shape = lay[0].shape[0]
            a, b, r = {"start": ("a_start", "b_start", "rot_start"), "end": ("a_end", "b_end", "rot_end"),
                       "substep_start": ("a0", "b0", "r0"), "substep": ("a1", "b1", "r1")}[pose]
            if n_shape:
                wp.launch(ck.shape_corners, dim=n_shape, inputs=[ar["kind"], ar[a], ar[b], ar[r], ar["size"], *lay],
                          outputs=[out, self._corner_in], device=d)
        off = n_shape
        for m in self.meshes:
            k = m.corner_vertices.shape[0]
            if k:
                pts = {"start": m.points_start, "end": m.points_end, "substep_start": m.points_prev,
                       "substep": m.mesh.points}[pose]
                wp.launch(ck.mesh_corners, dim=k, inputs=[pts, m.corner_vertices, m.corner_ring_offsets, m.corner_ring,
                                                         off], outputs=[out, self._corner_in], device=d)
            off += k

    def _corner_arrays(self) -> None:
        c, d = self.corner_count, self.device
        if getattr(self, "_corners", None) is not None and self._corners.shape[0] == c:
            return
        box, cone = int(ck.SHAPE_BOX), int(ck.SHAPE_CONE)
        shape = [s for s, k in enumerate(self._kind) for _ in range(8 if k == box else 1 if k == cone else 0)]
        local = [j for k in self._kind for j in range(8 if k == box else 1 if k == cone else 0)]
        self._corner_layout = (wp.array(np.asarray(shape, np.int32), dtype=wp.int32, device=d),
                               wp.array(np.asarray(local, np.int32), dtype=wp.int32, device=d))
        self._corners = wp.zeros(c, dtype=wp.vec3, device=d)
        self._corners_prev = wp.zeros(c, dtype=wp.vec3, device=d)
        fr = [self._friction[s] for s in shape] + [m.friction for m in self.meshes for _ in range(m.corner_vertices.shape[0])]
        self._corner_friction = wp.array(np.asarray(fr, np.float32), dtype=wp.float32, device=d)
        self._corner_start = wp.zeros(c, dtype=wp.vec3, device=d)
        self._corner_end = wp.zeros(c, dtype=wp.vec3, device=d)
        self._corner_in = wp.zeros(c, dtype=wp.vec3, device=d)
        self._corner_rows = None

    def detect_corner_contacts(self, x, v, tris, horizon: float, thickness: float) -> None:
        """Find the corners each cloth triangle may meet within `horizon` seconds and the side of
        the triangle each is on (:func:`~warpshade.sim.collision_kernels.find_corner_contacts`),
        the colliders posed from this step's start to its end (call after :meth:`begin_step`,
        with the cloth free of intersections, as the solver's intersection guard leaves it at the
        start of a step). A pair found at the previous detection keeps its side while the corner
        is under the triangle: a corner through the cloth is pushed back, however deep.

        Args:
            x: Positions [m], shape (V,), dtype vec3.
            v: Velocities [m/s], shape (V,), dtype vec3, or None (at rest).
            tris: Cloth triangles, shape (F, 3), dtype int32.
            horizon: Time the contacts must last [s] (the step).
            thickness: Distance to keep [m].
        """
        if not self.corner_count:
            return
        if self._kind and self._arrays is None:
            self._upload_shapes()
        self._corner_arrays()
        d, c, w = self.device, self.corner_count, self.CORNER_ROW
        rows = self._corner_rows
        if rows is None or rows["tris"] != tris.shape[0]:
            rows = self._corner_rows = {
                key: wp.zeros((c, w), dtype=dt, device=d)
                for key, dt in (("ids", wp.int32), ("sides", wp.float32), ("dists", wp.float32),
                                ("prev_ids", wp.int32), ("prev_sides", wp.float32))}
            rows["count"] = wp.zeros(c, dtype=wp.int32, device=d)
            rows["prev_count"] = wp.zeros(c, dtype=wp.int32, device=d)
            rows["tris"] = tris.shape[0]
            t = tris.numpy().reshape(-1)
            order = np.argsort(t, kind="stable")
            offsets = np.r_[0, np.cumsum(np.bincount(t, minlength=x.shape[0]))]
            rows["vt_offsets"] = wp.array(offsets.astype(np.int32), dtype=wp.int32, device=d)
            rows["vt_tris"] = wp.array((order // 3).astype(np.int32), dtype=wp.int32, device=d)
            self._corner_overflow = wp.zeros(1, dtype=wp.int32, device=d)
        if v is None:
            v = wp.zeros(x.shape[0], dtype=wp.vec3, device=d)
            self._pose_corners("substep", self._corner_start)
            wp.copy(self._corner_end, self._corner_start)
        else:
            self._pose_corners("start", self._corner_start)
            self._pose_corners("end", self._corner_end)
        wp.launch(save_rows, dim=c, inputs=[rows["count"], rows["ids"], rows["sides"]],
                  outputs=[rows["prev_count"], rows["prev_ids"], rows["prev_sides"]], device=d)
        wp.launch(ck.find_corner_contacts, dim=c,
                  inputs=[self._corner_start, self._corner_end, self._corner_in, x, v, tris, rows["vt_offsets"],
                          rows["vt_tris"], float(horizon),
                          float(thickness), rows["prev_ids"], rows["prev_sides"], rows["prev_count"]],
                  outputs=[rows["ids"], rows["sides"], rows["count"], rows["dists"], self._corner_overflow], device=d)

    @property
    def corner_overflow(self) -> int:
        """Corner-triangle pairs dropped so far because a triangle's row was full."""
        o = getattr(self, "_corner_overflow", None)
        return 0 if o is None else int(o.numpy()[0])

    def collide_corners(self, thickness: float, inv_mass, tris, x, x_prev=None) -> None:
        """Push cloth triangles off the collider corners found for them by
        :meth:`detect_corner_contacts` (box corners, cone apexes and sharp mesh vertices poking
        through their inside), the corners posed at the current substep's end, corrections
        averaged per vertex. Without a detection for these triangles, one is made from x at rest.

        Args:
            thickness: Distance to keep [m].
            inv_mass: Inverse masses, shape (V,), dtype float32.
            tris: Cloth triangles, shape (F, 3), dtype int32.
            x: Positions [m], shape (V,), dtype vec3, corrected in place.
            x_prev: Positions at the start of the substep [m] (for friction), or None (no friction).
        """
        if not self.corner_count:
            return
        self._corner_arrays()
        rows = self._corner_rows
        if rows is None or rows["tris"] != tris.shape[0]:
            self.detect_corner_contacts(x, None, tris, 0.0, thickness)
            rows = self._corner_rows
        n = x.shape[0]
        self._edge_accumulators(n)
        if x_prev is None:
            x_prev = self._no_prev if getattr(self, "_no_prev", None) is not None else wp.zeros(0, dtype=wp.vec3,
                                                                                                  device=self.device)
            self._no_prev = x_prev
        self._launch(ck.solve_corner_contacts, self.corner_count,
                     [self._corners, self._corners_prev, self._corner_friction, x, x_prev, tris, inv_mass, rows["ids"],
                      rows["sides"], rows["count"], float(thickness)], [self._edge_delta, self._edge_count])
        self._launch(apply_averaged_deltas, n, [], [self._edge_delta, self._edge_count, x])

    def collide(self, thickness: float, inv_mass, x_prev, x, passes: int = 1, since: str = "substep") -> None:
        """Project the vertices x out of every collider as posed by :meth:`pose_substep`,
        ``passes`` times (the same as as many calls).

        Args:
            thickness: Distance to keep from the surfaces [m].
            inv_mass: Inverse masses, shape (V,), dtype float32 (kinematic vertices are skipped).
            x_prev: Positions at the start of the substep [m], shape (V,), dtype vec3 (for friction).
            x: Positions [m], shape (V,), dtype vec3, corrected in place.
            passes: Projections (>= 1); without mesh colliders one launch runs them all.
            since: When the vertices were at x_prev, for the side of a moving open mesh they were
                on: ``"substep"`` (the start of the substep :meth:`pose_substep` posed), ``"start"``
                (the start of the step) or ``"end"`` (the mesh's current pose: x_prev is a state
                of this pose).
        """
        n = x.shape[0]
        shape_passes, rounds = (passes, 1) if not self.meshes else (1, passes)
        for _ in range(rounds):
            if self._arrays is not None:
                ar = self._arrays
                self._launch(ck.collide_shapes, n, [ar["kind"], ar["a0"], ar["a1"], ar["b0"], ar["b1"], ar["r0"],
                                                    ar["r1"], ar["size"], ar["friction"], thickness, shape_passes,
                                                    inv_mass, x_prev], [x])
            for m in self.meshes:
                ref = m.points_start if since == "start" else m.points_prev
                moved = int(m.moving and not m.closed and since != "end")
                self._launch(ck.collide_mesh, n, [m.mesh.id, m.points_prev, m.indices, int(m.closed),
                                                  thickness + self.mesh_query_distance, thickness, m.friction, inv_mass,
                                                  x_prev, ref, moved], [x])

    mesh_query_distance = 0.25
    """How far [m] beyond the thickness a vertex is still looked up against a mesh collider; a
    vertex deeper than this inside a mesh is not pushed out."""
