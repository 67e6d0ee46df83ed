"""Cloth of a scene simulated with :mod:`warpshade.sim` (pxr-free)."""

from __future__ import annotations

import warnings

import numpy as np

from ..geometry.mesh import vertex_indices, weld_indices
from ..scene import Scene, SceneError, SceneWarning, did_you_mean

CLOTH_PARAMS = {"density": "density", "stretchStiffness": "stretch_stiffness", "bendStiffness": "bend_stiffness"}
"""``warpshade:cloth:*`` attributes passed per piece to :meth:`warpshade.sim.ClothBuilder.add_mesh`."""
CLOTH_GLOBAL = {"damping": "damping", "thickness": "thickness"}
"""``warpshade:cloth:*`` attributes that are builder-wide (taken from the first cloth object)."""
CLOTH_SOLVER = {"selfCollision": ("self_collision", bool), "edgeContact": ("edge_contact", bool),
                "guard": ("guard", bool), "selfFriction": ("self_friction", float),
                "iterations": ("iterations", int), "contactInterval": ("contact_interval", int),
                "contactIterations": ("contact_iterations", int), "maxContacts": ("max_contacts", int),
                "stretchSweeps": ("stretch_sweeps", int), "stretchLimits": ("stretch_limits", bool),
                "guardRelax": ("guard_relax", int), "limitSliding": ("limit_sliding", bool),
                "limitEverySweep": ("limit_every_sweep", bool), "heldContactInterval": ("held_contact_interval", int),
                "stretchChebyshev": ("stretch_chebyshev", float), "coarseLevels": ("coarse_levels", int)}
"""``warpshade:cloth:*`` attributes passed to :class:`warpshade.sim.XPBDSolver` (taken from the
first cloth object, as the solver is shared): attribute -> (keyword, type)."""
CLOTH_ATTRIBUTES = (*CLOTH_PARAMS, *CLOTH_GLOBAL, "friction", *CLOTH_SOLVER)
"""Every ``warpshade:cloth:*`` attribute (``ws.cloth(**material)`` keyword) a cloth reads."""


def check_cloth_attributes(values: dict, where: str, error=ValueError) -> None:
    """Raise ``error`` naming ``where`` and the attribute when a ``warpshade:cloth:*`` value of ``values``
    (name without the prefix -> value) is not one of :data:`CLOTH_ATTRIBUTES` (suggesting the closest) or
    is not of its type: a bool for the on/off ones, else a finite number (an integer for the counts)."""
    for key, value in values.items():
        if key not in CLOTH_ATTRIBUTES:
            raise error(f"{where}: warpshade:cloth:{key} is not a cloth attribute{did_you_mean(key, CLOTH_ATTRIBUTES)}"
                        f"; they are {', '.join(CLOTH_ATTRIBUTES)}")
        typ = CLOTH_SOLVER.get(key, (None, float))[1]
        if typ is bool:
            ok = isinstance(value, (bool, np.bool_)) or (isinstance(value, (int, np.integer)) and value in (0, 1))
        else:
            ok = isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_)) \
                and bool(np.isfinite(value)) and (typ is float or float(value).is_integer())
        if not ok:
            kind = {bool: "a bool", int: "an integer"}.get(typ, "a finite number")
            raise error(f"{where}: warpshade:cloth:{key} must be {kind}, got {value!r}")


def coincident_vertices(points: np.ndarray) -> tuple[tuple[int, int] | None, int]:
    """Vertices of a mesh at exactly the position of a lower-numbered one: the first such pair (lower, higher)
    and how many such vertices there are, ``(None, 0)`` when none. In a cloth, whose triangles may not be
    degenerate, two such vertices share no triangle: a seam a DCC or an exporter split, along which the cloth
    is cut."""
    partner = weld_indices(points)  # each vertex's lowest-numbered vertex at its position
    dup = np.flatnonzero(partner != np.arange(len(partner)))
    return ((int(partner[dup[0]]), int(dup[0])) if len(dup) else None), len(dup)


SUBSTEPS = 8
"""Solver substeps per frame when the scene does not set ``warpshade:substeps``."""
RIM_SUBSTEPS = 16
"""Substeps per frame when the scene does not set ``warpshade:substeps`` and has an analytic cylinder
or cone collider whose radius is under :data:`RIM_EDGES` cloth edges (the median rest length): at
:data:`SUBSTEPS` a sheet sliding over such a thin post hooks on its rim (edges spanning the cap are
pushed up by the rim's edge and face passes and lift their vertices above it while the cloth round
them slides off, edges past :data:`STRAIN_WARNING`); measured in docs/benchmarks/history.md, "Thin
posts under fine sheets"."""
RIM_EDGES = 4.0
"""A cylinder's or cone's radius, in cloth edges, under which the scene gets :data:`RIM_SUBSTEPS`
(a cap a few edges across). Measured on benchmarks/post_drape.py's posts: radii of 0.5-3 edges hook at
:data:`SUBSTEPS` and not at 16; at 5 edges (15 cm under 3 cm edges) 16 let the sheet slide off the cap
and fold on itself (more and longer cloth-cloth holds than at 8)."""


STRAIN_WARNING = 2.0
"""Edge strain (|xi - xj| / L - 1) past which a cloth is taken not to follow the scene: an edge at
three times its rest length, beyond anything a cloth takes (the worst edge of the shipped and
``sims/`` scenes reaches 1.15, in ``usd_scenes/cloth_table``'s fold). :class:`ClothSimulation`
warns once per cloth that passes it."""


def _attach_target(scene: Scene, cloth: str, path: str):
    """The object ``warpshade:attachTarget`` names: a relationship or a string (Blender writes strings), to the
    mesh or to a prim above exactly one mesh of the scene (the transform a DCC writes over its mesh)."""
    try:
        return scene.object(path)
    except KeyError:
        pass
    under = [o for o in scene.objects if o.name.startswith(path.rstrip("/") + "/")]
    if len(under) == 1:
        return under[0]
    if under:
        raise SceneError(f"{cloth}: warpshade:attachTarget '{path}' holds {len(under)} meshes "
                         f"({', '.join(o.name for o in under[:3])}{', ...' if len(under) > 3 else ''}): name one of them")
    raise SceneError(f"{cloth}: warpshade:attachTarget '{path}' is not a mesh of the scene nor a prim above one")


class ClothSimulation:
    """Every cloth object of a scene in one :mod:`warpshade.sim` model, with the scene's colliders.

    Colliders (``warpshade:collider``): ``ground`` -> a plane at the mesh's mean height facing up;
    ``sphere`` -> the analytic sphere of a Sphere prim (moved frame by frame when its transform is
    time-sampled and keeps it a sphere of one radius; else its tessellated mesh); ``box`` -> the oriented box of a Cube prim, or of a static Mesh that is a box
    (UsdPhysics PhysicsCollisionAPI on a Cube); ``capsule``, ``cylinder``, ``cone`` -> the exact
    analytic solid of a Capsule, Cylinder or Cone prim (the tessellated mesh when its transform
    does not keep the shape exact); ``mesh`` -> the triangle mesh, which may
    move (a skinned or animated body: its pose is passed every frame). Pins (``warpshade:pinned``)
    are fixed; attachments (``warpshade:attached`` vertices, ``warpshade:attachTarget`` a moving
    object) follow the target's nearest rest vertex with their rest offset (a cape on shoulders);
    ``warpshade:wind`` on the default prim blows on all cloth. Frame 0 is the rest pose; each later
    frame advances one step of ``1/fps`` seconds.

    The solver works in SI units: positions go in multiplied by the scene's ``meters_per_unit``
    and come out divided by it, so its SI parameters (gravity, the ``warpshade:cloth:*`` values,
    thickness and the colliders' query distances in metres) mean the same on a stage in
    centimetres as in metres (docs/conventions.md §8).
    """

    def __init__(self, scene: Scene, device: str = "cpu"):
        try:
            from ..sim import ClothBuilder, ColliderSet, XPBDSolver
        except ImportError as exc:
            name = next(o.name for o in scene.objects if o.kind == "cloth")
            raise SceneError(f"{scene.source}: {name} is cloth, and cloth needs warpshade.sim, which is not "
                             f"installed yet ({exc})") from None
        cloth = [o for o in scene.objects if o.kind == "cloth"]
        m = float(scene.meters_per_unit)  # [m per scene unit]
        if not np.isfinite(m) or m <= 0:
            raise SceneError(f"{scene.source}: metersPerUnit must be a length > 0, got {scene.meters_per_unit}")
        self.meters_per_unit = m
        for o in cloth:
            check_cloth_attributes(o.params.get("cloth", {}), f"{scene.source}: {o.name}", SceneError)
        first = cloth[0].params.get("cloth", {})
        self.attachments = []  # (target name, target vertex per slot (A,), rest offset (A, 3))
        self.moving_colliders = []  # (object name, MeshCollider)
        self.moving_spheres = []  # (shape index, centre [m] per frame (F, 3))
        globals_ = {k2: float(first[k]) for k, k2 in CLOTH_GLOBAL.items() if k in first}
        builder = ClothBuilder(**globals_)
        self.ranges = {}
        friction = float(first.get("friction", 0.5))
        for o in cloth:
            p = o.params.get("cloth", {})
            ids = builder.add_mesh(self._si(o.mesh.points), o.mesh.faces, name=o.name,
                                   **{k2: float(p[k]) for k, k2 in CLOTH_PARAMS.items() if k in p})
            if "pinned" in o.params and len(o.params["pinned"]):
                builder.pin(ids[vertex_indices(o.params["pinned"], len(ids), f"{o.name}: warpshade:pinned", SceneError)])
            if "attached" in o.params:
                self._attach(builder, scene, o, ids)
            self.ranges[o.name] = (int(ids[0]), int(ids[-1]) + 1)
        self.model = builder.finalize(device=device)
        up = np.array([0.0, 1.0, 0.0]) if scene.up_axis.upper() == "Y" else np.array([0.0, 0.0, 1.0])
        colliders = ColliderSet(device=device)
        for o in list(scene.objects) + list(scene.collision_only):
            kind = o.params.get("collider")
            if kind is None or o.kind == "cloth":
                continue
            if kind == "ground":
                colliders.add_plane(normal=up, offset=float(np.mean(o.mesh.points @ up)) * m, friction=friction)
            elif kind == "box" and "box" in o.params:
                b = o.params["box"]
                colliders.add_box(self._si(b["center"]), self._si(b["half_extents"]), b["rotation"], friction=friction)
            elif kind == "sphere" and "sphere" in o.params:
                colliders.add_sphere(self._si(o.params["sphere"]["center"]), float(o.params["sphere"]["radius"]) * m,
                                     friction=friction)
            elif kind == "sphere" and (path := self._sphere_path(scene, o)) is not None:
                centers, radius = path
                index = colliders.add_sphere(self._si(centers[0]), radius * m, friction=friction)
                self.moving_spheres.append((index, self._si(centers)))
            elif kind in ("capsule", "cylinder") and kind in o.params:
                c = o.params[kind]
                add = colliders.add_capsule if kind == "capsule" else colliders.add_cylinder
                add(self._si(c["p0"]), self._si(c["p1"]), float(c["radius"]) * m, friction=friction)
            elif kind == "cone" and "cone" in o.params:
                c = o.params["cone"]
                colliders.add_cone(self._si(c["base"]), self._si(c["apex"]), float(c["radius"]) * m, friction=friction)
            elif kind in ("mesh", "sphere", "box", "capsule", "cylinder", "cone"):
                mc = colliders.add_mesh(self._si(o.mesh.points), o.mesh.faces, friction=friction)
                if o.kind != "static":
                    self.moving_colliders.append((o.name, mc))
            else:
                raise SceneError(f"{o.name}: warpshade:collider '{kind}' is not one of ground, sphere, box, capsule, cylinder, cone, mesh")
        # [m/s²]: the solver works in metres; a PhysicsScene's gravity, else Earth's down the up axis
        gravity = tuple(-9.81 * up if scene.gravity is None else np.asarray(scene.gravity, dtype=np.float64))
        knobs = {}
        for k, (kw, typ) in CLOTH_SOLVER.items():
            if k in first:  # of its type: check_cloth_attributes above
                knobs[kw] = typ(first[k])
        try:
            rim = colliders.smallest_rim
            thin = rim is not None and rim < RIM_EDGES * float(np.median(self.model.edge_rest_length.numpy()))
            substeps = RIM_SUBSTEPS if thin else SUBSTEPS
            self.solver = XPBDSolver(self.model, colliders, substeps=int(scene.settings.get("substeps", substeps)),
                                     gravity=gravity, **knobs)
        except ValueError as exc:
            bad = [k for k, (kw, _) in CLOTH_SOLVER.items() if kw in knobs and str(exc).startswith(kw)]
            where = f"{cloth[0].name}: warpshade:cloth:{bad[0]}" if bad else "warpshade:substeps"
            raise SceneError(f"{scene.source}: {where}: {exc}") from None
        self.control = self.model.control()
        if "wind" in scene.settings:
            self.control.set_wind(scene.settings["wind"])
        self.state = self.model.state()
        self.dt = 1.0 / scene.fps
        self._frame = 0
        self._points = self.state.points.numpy()
        self.frames = scene.frames
        inv_rest2 = (1.0 / self.model.edge_rest_length.numpy().astype(np.float64) ** 2).astype(np.float32)
        inv_mass = self.model.inv_mass.numpy()
        edges = self.model.edges_np
        self._stretch = {}  # cloth name -> its edges' ends and 1 / rest length², kinematic vertices?, frames over, worst
        for name, (a, b) in self.ranges.items():
            mine = np.flatnonzero((edges[:, 0] >= a) & (edges[:, 0] < b))
            self._stretch[name] = {"ends": (edges[mine, 0].copy(), edges[mine, 1].copy()), "inv_rest2": inv_rest2[mine],
                                   "held": bool((inv_mass[a:b] == 0).any()), "frames": [], "worst": (0.0, -1),
                                   "warned": False, "guarded": False}

    @staticmethod
    def _sphere_path(scene: Scene, obj) -> tuple[np.ndarray, float] | None:
        """An animated Sphere's centre at every frame (F, 3) and its radius [scene units], or None
        (a mesh collider then) when its transform does not keep it a sphere of one radius at every frame."""
        sphere_at = obj.params.get("sphere_at")
        if sphere_at is None:
            return None
        poses = [sphere_at(scene.start_time + f) for f in range(max(scene.frames, 1))]
        if any(p is None for p in poses):
            return None
        radius = float(poses[0]["radius"])
        if any(abs(float(p["radius"]) - radius) > 1.0e-6 * radius for p in poses):
            return None
        return np.array([p["center"] for p in poses], dtype=np.float64), radius

    def _attach(self, builder, scene: Scene, obj, ids) -> None:
        target_name = obj.params.get("attachTarget")
        if target_name is None:
            raise SceneError(f"{obj.name}: warpshade:attached needs warpshade:attachTarget (a moving object)")
        target = _attach_target(scene, obj.name, str(target_name))
        verts = vertex_indices(obj.params["attached"], obj.mesh.num_vertices, f"{obj.name}: warpshade:attached",
                               SceneError)
        builder.attach(ids[verts])
        rest = obj.mesh.points[verts].astype(np.float64)
        tp = target.mesh.points.astype(np.float64)
        nearest = np.argmin(((rest[:, None, :] - tp[None, :, :]) ** 2).sum(-1), axis=1)
        self.attachments.append((target.name, nearest, self._si(rest - tp[nearest])))

    def advance(self, frame: int, geometry: dict) -> dict:
        """Step to ``frame`` (frames come in order) and return ``{cloth name: positions (V, 3)}``.

        Args:
            frame: Frame number.
            geometry: This frame's positions of the other moving objects (colliders and attachment
                targets), ``{name: (V, 3)}``.
        """
        while self._frame < frame:
            for name, mc in self.moving_colliders:
                mc.set_points(self._si(geometry[name]))  # pose at the end of this step
            for index, centers in self.moving_spheres:
                self.solver.colliders.set_sphere(index, centers[min(self._frame + 1, len(centers) - 1)])
            if self.attachments:
                self.control.set_targets(np.concatenate(
                    [self._si(geometry[name][idx]) + off for name, idx, off in self.attachments]))
            reverts = self.solver.guard_steps
            self.solver.step(self.state, self.state, self.dt, self.control)
            self._frame += 1
            self._points = self.state.points.numpy()
            self._watch_stretch(guarded=self.solver.guard_steps > reverts)
        return {name: self._scene_units(self._points[a:b]) for name, (a, b) in self.ranges.items()}

    def _watch_stretch(self, guarded: bool = False) -> None:
        """After a step: note each cloth's frames whose worst edge strain passes
        :data:`STRAIN_WARNING`, and warn once per cloth (a :class:`SceneWarning` naming it, the
        frames, the worst strain and the likely cause) when such a run of frames ends or at the
        scene's last frame. Costs one float32 pass over the edges in numpy (0.3 ms on a 64 x 64
        cloth's 12033 edges at a load average of 20). ``guarded``: the intersection guard acted in this step."""
        x = self._points
        last = self._frame >= self.frames - 1
        for name, w in self._stretch.items():
            if w["warned"] or not len(w["inv_rest2"]):
                continue
            d = x[w["ends"][0]] - x[w["ends"][1]]
            worst = float(np.sqrt((np.einsum("ij,ij->i", d, d) * w["inv_rest2"]).max())) - 1.0
            if worst > STRAIN_WARNING:
                w["frames"].append(self._frame)
                w["guarded"] = w["guarded"] or guarded
                if worst > w["worst"][0]:
                    w["worst"] = (worst, self._frame)
            if w["frames"] and (last or worst <= STRAIN_WARNING):
                w["warned"] = True
                warnings.warn(self._stretch_message(name, w), SceneWarning, stacklevel=4)

    def _stretch_message(self, name: str, w: dict) -> str:
        frames = w["frames"]
        span = f"frame {frames[0]}" if len(frames) == 1 else f"frames {frames[0]}-{frames[-1]}"
        col = self.solver.colliders
        colliders = col is not None and (col.shape_count > 0 or bool(col.meshes))
        if w["held"] and colliders:
            cause = ("a collider pushing it against its pinned or attached vertices (a moving collider cannot pass "
                     "cloth held on two sides without stretching it far)")
        elif w["held"]:
            cause = "its pinned or attached vertices pulling it apart"
        elif w["guarded"] and not self.solver.guard_relax:
            cause = ("the intersection guard undoing a fast impact: it puts back the vertices of a step that ended in "
                     "intersections while the cloth around them moves on (warpshade:cloth:guardRelax = 8 pulls that "
                     "cloth along)")
        else:
            cause = "a collider driving it faster than it can follow"
        unresolved = getattr(self.solver, "guard_unresolved", 0)
        left = (f"; {unresolved} steps so far ended with intersections the guard could not remove"
                if unresolved else "")
        return (f"{name}: the cloth cannot follow the scene: edges stretched past {STRAIN_WARNING + 1:.0f}x their rest "
                f"length in {span} (worst edge strain {w['worst'][0]:.0%} at frame {w['worst'][1]}); likely "
                f"{cause}{left}. Its shading there shows the stretch (docs/guide/cloth.md, 'When constraints conflict')")

    def _si(self, x):
        """Scene-unit lengths in metres (float64; unchanged values on a metre stage)."""
        x = np.asarray(x, dtype=np.float64)
        return x if self.meters_per_unit == 1.0 else x * self.meters_per_unit

    def _scene_units(self, x: np.ndarray) -> np.ndarray:
        """Solver positions [m] in scene units, as the solver's dtype (a copy)."""
        return x.copy() if self.meters_per_unit == 1.0 else (x / self.meters_per_unit).astype(x.dtype)
