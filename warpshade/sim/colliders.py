"""Kinematic colliders: planes, spheres, capsules, boxes, cylinders, cones and animated triangle meshes.

A :class:`ColliderSet` is given to the solver. Move colliders between steps with the ``set_*``
methods (the new pose is where the collider is at the end of the next step; the solver sweeps
from the old pose to it across the substeps).
"""

from __future__ import annotations

import numpy as np
import warp as wp

from ..geometry.mesh import first_nonfinite
from . import collision_kernels as ck
from .kernels import apply_averaged_deltas


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


def weld_indices(points: np.ndarray) -> np.ndarray:
    """For each vertex, the first vertex at exactly the same position, shape (V,).

    DCC tools split a mesh's vertices along hard edges (a box exported with per-face normals has
    each face's own copy of its corners). Welded, the faces on both sides of such an edge are
    neighbours again, so the edge is a sharp edge between two faces, not two open borders, and a
    box made of separate faces is closed. Edge topology is fixed at construction: welded vertices
    are assumed to move together (as split copies of one vertex do)."""
    _, first, inverse = np.unique(np.asarray(points), axis=0, return_index=True, return_inverse=True)
    return first[inverse.reshape(-1)].astype(np.int64)


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
            if m._pending is not None:
                m.points_end.assign(m._pending)
                m._pending = None

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

    def pose_substep(self, alpha0: float, alpha1: float) -> None:
        """Pose the colliders for the substep spanning fractions alpha0..alpha1 of the step."""
        if self._arrays is not None:
            ar = self._arrays
            wp.launch(ck.pose_shapes, dim=len(self._kind),
                      inputs=[ar["a_start"], ar["a_end"], ar["b_start"], ar["b_end"], ar["rot_start"], ar["rot_end"],
                              alpha0, alpha1], outputs=[ar["a0"], ar["a1"], ar["b0"], ar["b1"], ar["r0"], ar["r1"]],
                      device=self.device)
        for m in self.meshes:
            wp.launch(ck.interpolate_points, dim=m.points_start.shape[0],
                      inputs=[m.points_start, m.points_end, alpha0], outputs=[m.points_prev], device=self.device)
            wp.launch(ck.interpolate_points, dim=m.points_start.shape[0],
                      inputs=[m.points_start, m.points_end, alpha1], outputs=[m.mesh.points], device=self.device)
            m.mesh.refit()

    @property
    def has_sharp_edges(self) -> bool:
        """Whether :meth:`collide_edges` has work: mesh colliders, boxes, cylinders or cones."""
        return bool(self.meshes) or any(k in self._SHARP for k in self._kind)

    _SHARP = (int(ck.SHAPE_BOX), int(ck.SHAPE_CYLINDER), int(ck.SHAPE_CONE))
    """Analytic kinds with sharp edges (box edges, rims, apex)."""

    def collide_edges(self, thickness: float, inv_mass, edges, x, tris=None) -> None:
        """Push cloth edges out of the mesh colliders' edges, the edges of boxes and the rims of
        cylinders and cones (sharp edges cutting between two cloth vertices), and cloth triangles
        off the corners of boxes (corners poking through a triangle's inside),
        corrections averaged per vertex.

        Args:
            thickness: Distance to keep [m].
            inv_mass: Inverse masses, shape (V,), dtype float32.
            edges: Cloth edges, shape (E, 2), dtype int32.
            x: Positions [m], shape (V,), dtype vec3, corrected in place.
            tris: Cloth triangles, shape (F, 3), dtype int32; None skips the box corners.
        """
        if not self.has_sharp_edges:
            return
        n = x.shape[0]
        if getattr(self, "_edge_delta", None) is None or self._edge_delta.shape[0] != n:
            self._edge_delta = wp.zeros(n, dtype=wp.vec3, device=self.device)
            self._edge_count = wp.zeros(n, dtype=wp.float32, device=self.device)
        if any(k in self._SHARP for k in self._kind):
            ar = self._arrays
            wp.launch(ck.collide_shape_edges, dim=edges.shape[0],
                      inputs=[ar["kind"], ar["a1"], ar["b1"], ar["r1"], ar["size"], x, edges, inv_mass, thickness],
                      outputs=[self._edge_delta, self._edge_count], device=self.device)
        for m in self.meshes:
            wp.launch(ck.collide_mesh_edges, dim=edges.shape[0],
                      inputs=[m.mesh.id, m.mesh.points, m.indices, m.tri_edges, m.edge_verts, m.edge_faces, x, edges,
                              inv_mass, thickness], outputs=[self._edge_delta, self._edge_count], device=self.device)
        wp.launch(apply_averaged_deltas, dim=n, inputs=[], outputs=[self._edge_delta, self._edge_count, x],
                  device=self.device)
        if tris is not None and int(ck.SHAPE_BOX) in self._kind:
            # a pass of its own: averaged with the many small edge corrections a vertex near a
            # corner also gets, the corner's push would be diluted
            ar = self._arrays
            wp.launch(ck.collide_box_corners, dim=tris.shape[0],
                      inputs=[ar["kind"], ar["a1"], ar["r1"], ar["size"], x, tris, inv_mass, thickness],
                      outputs=[self._edge_delta, self._edge_count], device=self.device)
            wp.launch(apply_averaged_deltas, dim=n, inputs=[], outputs=[self._edge_delta, self._edge_count, x],
                      device=self.device)

    def collide(self, thickness: float, inv_mass, x_prev, x) -> None:
        """Project the vertices x out of every collider as posed by :meth:`pose_substep`.

        Args:
            thickness: Distance to keep from the surfaces [m].
            inv_mass: Inverse masses, shape (V,), dtype float32 (kinematic vertices are skipped).
            x_prev: Positions at the start of the substep [m], shape (V,), dtype vec3 (for friction).
            x: Positions [m], shape (V,), dtype vec3, corrected in place.
        """
        n = x.shape[0]
        if self._arrays is not None:
            ar = self._arrays
            wp.launch(ck.collide_shapes, dim=n,
                      inputs=[ar["kind"], ar["a0"], ar["a1"], ar["b0"], ar["b1"], ar["r0"], ar["r1"], ar["size"],
                              ar["friction"], thickness, inv_mass, x_prev], outputs=[x], device=self.device)
        for m in self.meshes:
            wp.launch(ck.collide_mesh, dim=n,
                      inputs=[m.mesh.id, m.points_prev, m.indices, int(m.closed), thickness + self.mesh_query_distance,
                              thickness, m.friction, inv_mass, x_prev],
                      outputs=[x], device=self.device)

    mesh_query_distance = 0.25
    """How far [m] beyond the thickness a vertex is still looked up against a mesh collider; a
    vertex deeper than this inside a mesh is not pushed out."""
