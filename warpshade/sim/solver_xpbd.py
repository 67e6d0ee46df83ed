"""XPBD cloth solver: orchestrates the kernels in :mod:`warpshade.sim.kernels` and
:mod:`warpshade.sim.collision_kernels`.

One :meth:`XPBDSolver.step` advances ``dt`` seconds in ``substeps`` substeps of ``iterations``
constraint sweeps each (small steps, Macklin et al. 2019: substeps buy more accuracy per cost than
iterations). Per substep: aerodynamic forces, symplectic-Euler prediction, attachments driven to
their interpolated targets, then per iteration: multi-scale stretch limits, coloured stretch and
bending sweeps, long-range tethers, a cap on moves that pass near a sphere or capsule
(:attr:`XPBDSolver.ROUND_MOVE`) or enter a closed mesh collider (:attr:`XPBDSolver.MESH_MOVE`),
self-contacts, colliders (last, so collider contacts hold at
the end of every substep);
finally velocities from positions. Self-contact candidates are found every ``contact_interval``
substeps with a swept-box BVH query; a detection is skipped when the one before it in the step
found no candidate and, moving the cloth on with its velocities, foresaw none for it. After the
last substep the intersection guard (``guard=True``) counts intersecting triangle pairs exactly
and sends the vertices of offending triangles back to their start-of-step positions (the free
vertices around them follow by stretch sweeps), growing the region until none is left, so
every step ends free of intersections when it started free of them; a vertex the contacts keep
pushing into an intersection is held where it was until a step frees it (see
:mod:`warpshade.sim.contact_kernels`).
"""

from __future__ import annotations

import math

import numpy as np
import warp as wp

from . import contact_kernels as ck
from . import kernels as k
from . import lane_kernels as lk
from .colliders import ColliderSet
from .intersections import IntersectionCounter
from .launches import RecordedLaunches, recorded
from .model import ClothModel, SimulationError, check_param
from .state import ClothControl, ClothState


class XPBDSolver:
    """Extended position-based dynamics for cloth.

    Args:
        model: The cloth.
        colliders: Kinematic colliders, or None.
        substeps: Substeps per :meth:`step` (>= 1).
        iterations: Constraint sweeps per substep (>= 1).
        gravity: Acceleration [m/s^2], (3,).
        drag: Linear velocity damping [1/s] (>= 0), applied as an exact exponential decay.
        air_density: [kg/m^3] (>= 0) for aerodynamic drag and lift; 0 disables aerodynamics.
        drag_coefficient, lift_coefficient: Flat-plate coefficients (>= 0).
        self_collision: Self-contact on/off (vertex-triangle, and edge-edge with ``edge_contact``).
        edge_contact: Edge-edge self-contact beside vertex-triangle.
        guard: The intersection guard: no step ends with intersecting triangle pairs (cloth-cloth
            and cloth-collider) that the reverts can remove (see :meth:`step`).
        self_friction: Coulomb coefficient between cloth layers (>= 0).
        contact_interval: Substeps between self-contact detections (>= 1; default 3: longer
            intervals let candidate lists and contact sides go stale in fast folding cloth).
        max_contacts: Most self-contact candidates kept per vertex and per edge (>= 1). The rows
            start at ``min(CONTACT_ROW_START, max_contacts)`` candidates and double whenever a
            detection finds more (the detection is then repeated, so no candidate is dropped);
            past ``max_contacts`` the nearest are kept and the rest counted in
            ``stats()["self_contact_overflow"]``.
        contact_iterations: Passes of self-contact and collider projection per iteration (>= 1).
        stretch_sweeps: Stretch sweeps per iteration (>= 1); the multipliers accumulate across
            them (XPBD iterations restricted to the stiffest constraints).
        relaxation: Over-relaxation of the stretch sweeps (0 < relaxation < 2; 1 = plain Gauss-Seidel).
        tethers: Long-range attachments to the nearest kinematic vertex (Kim et al. 2012).
        stretch_limits: The model's multi-scale stretch limits (``model.limit_pairs``), swept
            coarsest first before the edges in every iteration: they take out the stretch that one
            sweep per substep leaves along long free spans (cloth hanging from pins or over a
            collider's rim). A limit is skipped while either vertex is in contact (it has
            self-contact candidates, or the contact projections moved it in the last substep):
            a straight-line correction there fights the contacts (it would pull cloth through a
            layer or into a collider). Each moves a vertex by at most the thickness per sweep.
            They allow no stretch, so pieces soft enough to stretch under their own weight get
            none (:data:`~warpshade.sim.model.STIFF_STRAIN`).
        limit_sliding: With stretch limits, a limit is skipped only while either vertex has
            self-contact candidates; a vertex the contact projections moved in the last substep
            (a collider, or a layer it touches as a triangle or edge) takes its share of the
            correction without the component against that move, so the limit pulls it along the
            surface that pushed it rather than into it (draped cloth: the cap on a collider is
            then bounded too). None: :attr:`LIMIT_SLIDING`.
        limit_every_sweep: With stretch limits and ``stretch_sweeps`` > 1, the limits are swept
            before every stretch sweep, not only before the first, each sweep moving a vertex by at
            most 1/``stretch_sweeps`` of the limits' move (so an iteration's limits move a vertex as
            far as one sweep of them does). Gauss-Seidel leaves a residual stretch that grows with
            the weight a chain of edges carries; with the limits in every sweep, the long-range
            pairs take it out as often as the edges (cloth draped free over a sphere, with
            ``limit_sliding`` and 12 sweeps: at-rest p99 strain under 2 %). None:
            :attr:`LIMIT_EVERY_SWEEP`.
        stretch_chebyshev: Chebyshev semi-iterative acceleration of the stretch sweeps (Wang 2015):
            with ``stretch_sweeps`` > 1, every sweep after the first is extrapolated from the two
            iterates before it with the weights of an iteration whose spectral radius is this
            (0 <= stretch_chebyshev < 1; 0: off). It converges a long chain of edges carrying weight
            in fewer sweeps (cloth draped free over a sphere, with ``limit_sliding``,
            ``limit_every_sweep``, 4 sweeps and 0.8: at-rest p99 strain 1.5-3.0 % on 40-56 grids
            against 4.5 % without on 48); the extrapolated moves exceed the limits' move cap by up
            to the weight (omega_2 = 1.47 at 0.8), and 0.95 diverged on that drape. None:
            :attr:`STRETCH_CHEBYSHEV`.
        coarse_levels: Hierarchical stretch constraints (Müller 2008): with stretch limits, the
            model's first this many coarse levels (``model.hierarchy``; 0: off) are swept
            coarsest first at the start of every iteration, each level's unilateral distance
            constraints between its vertices (with its inverse masses; the limits' move cap and
            contact rules, ``limit_sliding`` included) and its vertices' moves then carried to the
            vertices it drops by their parents' weights
            (:func:`~warpshade.sim.kernels.prolong_moves`), so a correction moves a patch of cloth
            rather than two vertices. None: :attr:`COARSE_LEVELS`.
        held_contact_interval: ``contact_interval`` in a step that follows one where the guard sent
            vertices back (>= 1). The held vertices start it with their edges to the free cloth
            stretched, and the stretch sweeps pull them back within a substep, further than the
            velocities the detection sweeps the boxes by: at 1, the contacts are looked for in
            every substep of such a step. None: :attr:`HELD_CONTACT_INTERVAL`.
        follow_edge_sides: An edge-edge contact's stored side follows an orientation flip that
            continuous collision detection shows was no crossing (edges turning past parallel, or
            passing beside an end clear of the cloth there); off, a pair keeps the side it was
            found on while in contact. None: :attr:`FOLLOW_EDGE_SIDES`.
        aero_interval: Substeps between evaluations of the aerodynamic forces (>= 1); in between,
            the last evaluation's drag coefficients and lift forces are reused (drag stays
            implicit in the current velocity). None: :attr:`AERO_INTERVAL`.
        bend_interval: Substeps between bending sweeps (>= 1): the bending constraints are solved
            in every ``bend_interval``-th substep as an XPBD step of H = ``bend_interval`` substeps
            (compliance term alpha / H^2, and the correction changes the velocity by its
            displacement over H, not over the substep), so the bending stiffness is the same as
            H -> 0. None: :attr:`BEND_INTERVAL`.
        guard_relax: Stretch sweeps after each of the guard's reverts with the reverted vertices
            held, so the free vertices around them follow instead of their edges stretching
            (:meth:`_relax_around_reverted`; >= 0, 0: none). None: :attr:`GUARD_RELAX`.
        check_finite: Stop with :class:`SimulationError` when the state turns non-finite.

    Raises:
        ValueError: for an out-of-range parameter, naming it.
    """

    def __init__(self, model: ClothModel, colliders: ColliderSet | None = None, substeps: int = 6,
                 iterations: int = 1, gravity=(0.0, -9.81, 0.0), drag: float = 0.0, air_density: float = 1.2,
                 drag_coefficient: float = 0.8, lift_coefficient: float = 0.3, self_collision: bool = True,
                 contact_interval: int | None = None, max_contacts: int = 128,
                 tethers: bool = True, check_finite: bool = True, relaxation: float = 1.0,
                 contact_iterations: int = 2, stretch_sweeps: int = 1, edge_contact: bool = True,
                 guard: bool = True, self_friction: float = 0.3, stretch_limits: bool = True,
                 follow_edge_sides: bool | None = None, aero_interval: int | None = None,
                 bend_interval: int | None = None, limit_sliding: bool | None = None,
                 guard_relax: int | None = None, limit_every_sweep: bool | None = None,
                 held_contact_interval: int | None = None, stretch_chebyshev: float | None = None,
                 coarse_levels: int | None = None):
        if int(substeps) != substeps or substeps < 1:
            raise ValueError(f"substeps must be an integer >= 1, got {substeps}")
        if int(iterations) != iterations or iterations < 1:
            raise ValueError(f"iterations must be an integer >= 1, got {iterations}")
        self.model = model
        self.device = model.device
        self.colliders = colliders
        self.substeps = int(substeps)
        self.iterations = int(iterations)
        g = np.asarray(gravity, dtype=np.float64).reshape(-1)
        if g.shape != (3,) or not np.isfinite(g).all():
            raise ValueError(f"gravity must be 3 finite numbers, got {gravity}")
        self.gravity = tuple(float(c) for c in g)
        self.drag = check_param("drag", drag)
        self.air_density = check_param("air_density", air_density)
        self.drag_coefficient = check_param("drag_coefficient", drag_coefficient)
        self.lift_coefficient = check_param("lift_coefficient", lift_coefficient)
        self.self_collision = bool(self_collision)
        self.edge_contact = bool(edge_contact) and self.self_collision
        self.guard = bool(guard)
        self.follow_edge_sides = self.edge_contact and bool(
            self.FOLLOW_EDGE_SIDES if follow_edge_sides is None else follow_edge_sides)
        self.self_friction = check_param("self_friction", self_friction)
        ci = min(self.substeps, 3) if contact_interval is None else contact_interval
        if int(ci) != ci or ci < 1:
            raise ValueError(f"contact_interval must be an integer >= 1, got {contact_interval}")
        self.contact_interval = int(ci)
        hci = self.HELD_CONTACT_INTERVAL if held_contact_interval is None else held_contact_interval
        hci = self.contact_interval if hci is None else hci
        if int(hci) != hci or hci < 1:
            raise ValueError(f"held_contact_interval must be an integer >= 1, got {held_contact_interval}")
        self.held_contact_interval = int(hci)
        ai = self.AERO_INTERVAL if aero_interval is None else aero_interval
        if int(ai) != ai or ai < 1:
            raise ValueError(f"aero_interval must be an integer >= 1, got {aero_interval}")
        self.aero_interval = int(ai)
        bi = self.BEND_INTERVAL if bend_interval is None else bend_interval
        if int(bi) != bi or bi < 1:
            raise ValueError(f"bend_interval must be an integer >= 1, got {bend_interval}")
        self.bend_interval = int(bi)
        if int(max_contacts) != max_contacts or max_contacts < 1:
            raise ValueError(f"max_contacts must be an integer >= 1, got {max_contacts}")
        self.max_contacts = int(max_contacts)
        if int(contact_iterations) != contact_iterations or contact_iterations < 1:
            raise ValueError(f"contact_iterations must be an integer >= 1, got {contact_iterations}")
        self.contact_iterations = int(contact_iterations)
        if int(stretch_sweeps) != stretch_sweeps or stretch_sweeps < 1:
            raise ValueError(f"stretch_sweeps must be an integer >= 1, got {stretch_sweeps}")
        self.stretch_sweeps = int(stretch_sweeps)
        self.tethers = bool(tethers) and bool((model.tether_anchor.numpy() >= 0).any())
        self.stretch_limits = bool(stretch_limits) and len(model.limit_pairs_np) > 0
        if self.stretch_limits:
            # a limit moves a vertex by at most the contact thickness per sweep (a quarter of the
            # median edge without thickness), so a correction never jumps a vertex through a layer
            rest = model.edge_rest_length.numpy()
            self._limit_move = model.thickness if model.thickness > 0 else 0.25 * float(np.median(rest))
            # vertices the contact projections moved in the last substep (limits skip them)
            self._touched = wp.zeros(model.particle_count, dtype=wp.int32, device=model.device)
            self._x_before = wp.zeros(model.particle_count, dtype=wp.vec3, device=model.device)
        self.limit_sliding = self.stretch_limits and bool(
            self.LIMIT_SLIDING if limit_sliding is None else limit_sliding)
        self.limit_every_sweep = self.stretch_limits and bool(
            self.LIMIT_EVERY_SWEEP if limit_every_sweep is None else limit_every_sweep)
        if self.limit_sliding:
            # how the contact projections moved each vertex in the last substep
            self._pushed = wp.zeros(model.particle_count, dtype=wp.vec3, device=model.device)
        sc = self.STRETCH_CHEBYSHEV if stretch_chebyshev is None else stretch_chebyshev
        self.stretch_chebyshev = check_param("stretch_chebyshev", sc)
        if self.stretch_chebyshev >= 1.0:
            raise ValueError(f"stretch_chebyshev must be < 1 (a spectral radius), got {stretch_chebyshev}")
        if self.stretch_sweeps < 2:
            self.stretch_chebyshev = 0.0  # (one sweep: nothing to extrapolate)
        if self.stretch_chebyshev:
            # the last two iterates of the stretch sweeps
            self._cheb_last = wp.zeros(model.particle_count, dtype=wp.vec3, device=model.device)
            self._cheb_before = wp.zeros(model.particle_count, dtype=wp.vec3, device=model.device)
        cl = self.COARSE_LEVELS if coarse_levels is None else coarse_levels
        if int(cl) != cl or cl < 0:
            raise ValueError(f"coarse_levels must be an integer >= 0, got {coarse_levels}")
        self.coarse_levels = min(int(cl), len(model.hierarchy)) if self.stretch_limits and cl else 0
        if self.coarse_levels:
            self._coarse_before = wp.zeros(model.particle_count, dtype=wp.vec3, device=model.device)
            # a level's vertices in or beside self-contact (kernels.mark_parents)
            self._coarse_contacts = wp.zeros(model.particle_count, dtype=wp.int32, device=model.device)
            if not self.limit_sliding:  # (read by the kernels only when sliding)
                self._pushed = wp.zeros(1, dtype=wp.vec3, device=model.device)
        self.check_finite = bool(check_finite)
        gr = self.GUARD_RELAX if guard_relax is None else guard_relax
        if int(gr) != gr or gr < 0:
            raise ValueError(f"guard_relax must be an integer >= 0, got {guard_relax}")
        self.guard_relax = int(gr) if self.guard else 0
        self.relaxation = check_param("relaxation", relaxation, 0.0, False)
        if self.relaxation >= 2.0:
            raise ValueError(f"relaxation must be < 2 (successive over-relaxation diverges beyond), got {relaxation}")
        self.step_count = 0
        self.contact_overflow = 0
        self.guard_steps = 0
        self.guard_unresolved = 0
        self.collider_yields = 0
        self.guard_longest_hold = 0
        self.guard_vertices = 0

        v, f, d = model.particle_count, model.tri_count, self.device
        # the index tuples as one-dimensional arrays of vectors, as the per-substep kernels take them
        self._edge_ids = model.edges.view(wp.vec2i)
        self._hinge_ids = model.hinges.view(wp.vec4i)
        # on the CPU the stretch, stretch damping and bending sweeps solve LANES constraints of a
        # colour per thread (the same floats; None: the scalar kernels)
        self._edge_groups = self._lane_groups(model.edge_colors, self._edge_ids, model.edge_rest_length,
                                              model.edge_compliance)
        self._hinge_groups = self._lane_groups(model.hinge_colors, self._hinge_ids, model.hinge_rest_angle,
                                               model.hinge_compliance)
        self._tri_ids = model.tris.view(wp.vec3i)
        self._limit_ids = model.limit_pairs.view(wp.vec2i)
        self._x_prev = wp.zeros(v, dtype=wp.vec3, device=d)
        self._lift = wp.zeros(v, dtype=wp.vec3, device=d)
        self._air_drag = wp.zeros(v, dtype=wp.float32, device=d)
        self._edge_lambda = wp.zeros(model.edge_count, dtype=wp.float32, device=d)
        self._hinge_lambda = wp.zeros(max(model.hinge_count, 1), dtype=wp.float32, device=d)
        # the bending sweeps' displacement in their substep, and x before a sweep (bend_interval > 1;
        # see discount_moved)
        self._bend_moved = wp.zeros(v if self.bend_interval > 1 else 1, dtype=wp.vec3, device=d)
        self._bend_before = wp.zeros(v if self.bend_interval > 1 else 1, dtype=wp.vec3, device=d)
        self._attach_start = wp.zeros(max(model.attachment_count, 1), dtype=wp.vec3, device=d)
        self._first_bad = wp.zeros(1, dtype=wp.int32, device=d)
        self._x = wp.zeros(v, dtype=wp.vec3, device=d)
        self._v = wp.zeros(v, dtype=wp.vec3, device=d)
        self._cmd_cache = None
        self._recorded = RecordedLaunches(self.device)  # the detections' and checks' launches
        self._contacts_found = True
        """The last self-contact detection found a candidate (vertex-triangle or edge-edge)."""
        self._clear_ahead = False
        """The last detection found no candidate and foresaw none for the next one (see
        :func:`~warpshade.sim.kernels.find_self_contacts`), which is then skipped."""
        if self.self_collision:
            # triangle boxes swept over the contact interval, and over the next one too (the BVH's)
            self._tri_boxes = [wp.zeros(f, dtype=wp.vec3, device=d) for _ in range(4)]
            self._bvh = None
            self._near = wp.zeros(1, dtype=wp.int32, device=d)
            self._contact_count = wp.zeros(v, dtype=wp.int32, device=d)
            self._prev_count = wp.zeros(v, dtype=wp.int32, device=d)
            self._vt_rows = self._contact_rows(v, min(self.CONTACT_ROW_START, self.max_contacts))
            self._overflow = wp.zeros(1, dtype=wp.int32, device=d)
            self._delta = wp.zeros(v, dtype=wp.vec3, device=d)
            self._delta_count = wp.zeros(v, dtype=wp.float32, device=d)
            self._pad = wp.full(v, 0.5 * model.thickness, dtype=wp.float32, device=d)
            self._group_span = self.GROUP_SPAN * float(np.median(model.edge_rest_length.numpy()))
            self._query_boxes = [wp.zeros(v, dtype=wp.vec3, device=d) for _ in range(2)]  # the detection's look-up boxes
        if self.edge_contact:
            ne, mc = model.edge_count, self.max_contacts
            self._edge_boxes = [wp.zeros(ne, dtype=wp.vec3, device=d) for _ in range(4)]
            self._ebvh = None
            self._contact_ecount = wp.zeros(ne, dtype=wp.int32, device=d)
            self._prev_ecount = wp.zeros(ne, dtype=wp.int32, device=d)
            self._ee_rows = self._contact_rows(ne, min(self.CONTACT_ROW_START, mc))
            self._eactive = wp.zeros(ne, dtype=wp.int32, device=d)
        if self.guard:
            self._counter = IntersectionCounter(model.faces, d, keep=1)
            self._x_start = wp.zeros(v, dtype=wp.vec3, device=d)
            self._mark = wp.zeros(v, dtype=wp.int32, device=d)
            self._mark2 = wp.zeros(v, dtype=wp.int32, device=d)
            self._reverted = wp.zeros(v, dtype=wp.int32, device=d)
            self._streak = wp.zeros(v, dtype=wp.int32, device=d)
            self._streak_clear = True
            """Every vertex's streak is 0."""
            self._x_unguarded = wp.zeros(v, dtype=wp.vec3, device=d)
            self._held_w = wp.zeros(v, dtype=wp.float32, device=d)  # inv_mass, reverted vertices 0

    # ------------------------------------------------------------------------------------------

    def step(self, state_in: ClothState, state_out: ClothState, dt: float, control: ClothControl | None = None):
        """Advance ``dt`` seconds from ``state_in`` into ``state_out`` (they may be the same object).

        Args:
            state_in: State at the start of the step.
            state_out: Receives the state at the end of the step.
            dt: Step length [s] (> 0, finite).
            control: Attachment targets at the end of the step and wind; None keeps attachments in
                place and the air still.

        Raises:
            ValueError: for a bad ``dt``.
            SimulationError: when the state turns non-finite, naming the step and the vertex.

        With ``guard``, the step ends free of intersecting triangle pairs whenever ``state_in`` was
        free of them and the kinematic vertices and colliders alone do not make any (a vertex
        sent back to its start can only be in an intersection that moving kinematic geometry
        made); :meth:`stats` counts the steps where that failed.
        """
        dt = float(dt)
        if not math.isfinite(dt) or dt <= 0:
            raise ValueError(f"step {self.step_count}: dt must be finite and > 0, got {dt}")
        m, d = self.model, self.device
        x, v = self._x, self._v
        wp.copy(x, state_in.points)
        wp.copy(v, state_in.velocities)
        if self.guard:
            wp.copy(self._x_start, x)
        h = dt / self.substeps
        wind = wp.vec3(*(control.wind if control is not None else (0.0, 0.0, 0.0)))
        self._wind = wind
        cmds = self._commands(h, wind)
        if self.colliders is not None:
            self.colliders.begin_step()
            if self.colliders.corner_count:
                self.colliders.detect_corner_contacts(x, v, m.tris, dt, m.thickness)
        attach = m.attachment_count > 0 and control is not None
        if attach:
            wp.launch(k.gather_points, dim=m.attachment_count, inputs=[m.attachment_indices, x],
                      outputs=[self._attach_start], device=d)

        ci = self.contact_interval
        if self.guard and not self._streak_clear:
            ci = self.held_contact_interval  # the guard sent vertices back in the last step
        for s in range(self.substeps):
            if self.self_collision and s % ci == 0:
                if s > 0 and self._clear_ahead:
                    # the last detection found no candidate and, moving the cloth on with its
                    # velocities, foresaw none for this one: skipped (the one after it runs)
                    self._clear_ahead = False
                else:
                    nxt = s + ci  # the next detection's substep
                    horizon = h * (min(nxt, self.substeps) - s)
                    ahead = horizon + (h * (min(nxt + ci, self.substeps) - nxt)
                                       if nxt < self.substeps else 0.0)
                    if self._detect_self_contacts(x, v, horizon, ahead):
                        cmds = self._commands(h, wind)  # the contact rows grew: the recorded launches are stale
            if "aero" in cmds and s % self.aero_interval == 0:
                self._lift.zero_()
                self._air_drag.zero_()
                cmds["aero"].launch()
            cmds["predict"].launch()
            if attach:
                wp.launch(k.drive_attachments, dim=m.attachment_count,
                          inputs=[m.attachment_indices, self._attach_start, control.attachment_targets,
                                  (s + 1) / self.substeps], outputs=[x], device=d)
            if self.colliders is not None:
                self.colliders.pose_substep(s / self.substeps, (s + 1) / self.substeps)
            # XPBD multipliers restart every substep (Macklin et al. 2016, Alg. 1 line 4)
            self._edge_lambda.zero_()
            self._hinge_lambda.zero_()
            for _ in range(self.iterations):
                self._coarse_pass(cmds["coarse"], x)
                if self.stretch_chebyshev:
                    self._chebyshev_sweeps(cmds["sweeps"], x)
                else:
                    for c in cmds["stretch"]:
                        c.launch()
                if (s + 1) % self.bend_interval == 0:
                    if self.bend_interval > 1:
                        wp.copy(self._bend_before, x)
                    for c in cmds["bending"]:
                        c.launch()
                for c in cmds["tethers"]:
                    c.launch()
                if self.colliders is not None and self.colliders.has_round_shapes:
                    # moves into a ball or capsule shortened: its projection is right for short moves only
                    self.colliders.limit_round_motion(self.ROUND_MOVE, m.thickness, m.inv_mass, self._x_prev, x)
                if self.colliders is not None and self.colliders.has_closed_meshes:
                    # and moves into a closed mesh: its projection pushes out at the nearest surface
                    self.colliders.limit_mesh_motion(self.MESH_MOVE, m.thickness, m.inv_mass, self._x_prev, x)
                if self.colliders is not None and self.colliders.has_sharp_shapes:
                    # and into a box, cylinder or cone, as into a closed mesh
                    self.colliders.limit_shape_motion(self.MESH_MOVE, m.thickness, m.inv_mass, self._x_prev, x)
                if self.stretch_limits:
                    wp.copy(self._x_before, x)
                # contacts last and repeated: stacked contacts (cloth on cloth on the ground) need
                # more than one Jacobi pass to stop a fast layer within one substep
                if self._contacts_found or (self.colliders is not None and self.colliders.corner_count):
                    for _c in range(self.contact_iterations):
                        if self._contacts_found:  # (no candidate anywhere: the contact launches change nothing)
                            for c in cmds["contacts"]:
                                c.launch()
                        if self.colliders is not None:
                            self.colliders.collide(m.thickness, m.inv_mass, self._x_prev, x)
                            # collider corners (box corners, cone apexes, pointed mesh tips) against the cloth
                            self.colliders.collide_corners(m.thickness, m.inv_mass, m.tris, x, self._x_prev)
                elif self.colliders is not None:
                    # nothing between the collider passes: all of them in one call
                    self.colliders.collide(m.thickness, m.inv_mass, self._x_prev, x, self.contact_iterations)
            if self.colliders is not None and self.colliders.has_sharp_edges:
                # sharp collider edges and corners against cloth edges and triangles, then the
                # vertices again
                for _c in range(self.SHARP_PASSES):
                    self.colliders.collide_edges(m.thickness, m.inv_mass, m.edges, x, m.tris, self._x_prev,
                                                 self._x_start if self.guard else None)
                    self.colliders.collide(m.thickness, m.inv_mass, self._x_prev, x)
            if self.stretch_limits:
                cmds["moved"].launch()
            cmds["velocities"].launch()
            if "bend_velocity" in cmds and (s + 1) % self.bend_interval == 0:
                cmds["bend_velocity"].launch()
            for c in cmds["damping"]:
                c.launch()
            if self._contacts_found and "sides" in cmds:
                cmds["sides"].launch()

        if self.guard:
            self._guard_intersections(x, v, dt)
        if self.colliders is not None:
            self.colliders.end_step()
        if self.check_finite:
            self._check_finite(state_in, x, v)
        wp.copy(state_out.points, x)
        wp.copy(state_out.velocities, v)
        self.step_count += 1

    # ------------------------------------------------------------------------------------------

    def _commands(self, h: float, wind) -> dict:
        """Recorded launches for substep length h with `wind` set (recording once saves most of
        the Python overhead of ~400 launches per step; re-recorded when h changes or the contact
        rows grow)."""
        if self._cmd_cache is None or self._cmd_cache[0] != h:
            self._cmd_cache = (h, self._record_commands(h))
        cmds = self._cmd_cache[1]
        cmds["predict"].set_param_by_name("wind", wind)
        if "aero" in cmds:
            cmds["aero"].set_param_by_name("wind", wind)
        return cmds

    def _record_commands(self, h: float) -> dict:
        m, d = self.model, self.device
        x, v = self._x, self._v
        n = m.particle_count
        zero3 = wp.vec3(0.0, 0.0, 0.0)
        cmds: dict = {}
        if self.air_density > 0 and (self.drag_coefficient > 0 or self.lift_coefficient > 0):
            lanes = self._lanes(self._tri_ids)
            cmds["aero"] = wp.launch(lk.accumulate_aero_forces_lanes if lanes else k.accumulate_aero_forces,
                                     dim=(m.tri_count + lk.LANES - 1) // lk.LANES if lanes else m.tri_count,
                                     inputs=[x, v, self._tri_ids, zero3, self.air_density, self.drag_coefficient,
                                             self.lift_coefficient], outputs=[self._lift, self._air_drag],
                                     device=d, record_cmd=True)
        cmds["predict"] = wp.launch(k.predict_positions, dim=n,
                                    inputs=[x, v, m.inv_mass, self._lift, self._air_drag, zero3,
                                            wp.vec3(*self.gravity), self.drag, h],
                                    outputs=[self._x_prev, x, v], device=d, record_cmd=True)
        edge_batches, hinge_batches = self._batches(m.edge_colors), self._batches(m.hinge_colors)
        cons = []
        if self.stretch_limits:
            limit_move = self._limit_move / self.stretch_sweeps if self.limit_every_sweep else self._limit_move
        if self.limit_sliding:
            # (without self-collision no vertex has candidates: _touched stays 0 in this mode)
            cons.extend(wp.launch(k.solve_limits_sliding, dim=cnt,
                                  inputs=[self._limit_ids, m.limit_length, m.inv_mass, limit_move,
                                          self._contact_count if self.self_collision else self._touched,
                                          self._pushed, off], outputs=[x], device=d, record_cmd=True)
                        for off, cnt in self._batches(m.limit_colors))
        elif self.stretch_limits:
            cons.extend(wp.launch(k.solve_limits, dim=cnt, inputs=[self._limit_ids, m.limit_length, m.inv_mass,
                                                                   limit_move,
                                                                   self._contact_count if self.self_collision
                                                                   else self._touched, self._touched, off],
                                  outputs=[x], device=d, record_cmd=True)
                        for off, cnt in self._batches(m.limit_colors))
        eg = self._edge_groups
        if eg is not None:
            stretch = [wp.launch(lk.solve_stretch_lanes, dim=eg.shape[0],
                                 inputs=[eg, self._edge_ids, m.edge_rest_length, m.edge_compliance, m.inv_mass, h,
                                         self.relaxation], outputs=[self._edge_lambda, x], device=d, record_cmd=True)]
        else:
            stretch = [wp.launch(k.solve_stretch, dim=cnt,
                                 inputs=[self._edge_ids, m.edge_rest_length, m.edge_compliance, m.inv_mass, off, h,
                                         self.relaxation], outputs=[self._edge_lambda, x], device=d, record_cmd=True)
                       for off, cnt in edge_batches]
        # extra stretch sweeps: cheap (edges only, or edges and limits) and the stretch residual is
        # what shows as sag
        cmds["stretch"] = (cons + stretch) * self.stretch_sweeps if self.limit_every_sweep \
            else cons + stretch * self.stretch_sweeps
        # a bending sweep every bend_interval substeps is an XPBD step of H = bend_interval * h: the
        # velocity update after it keeps 1/bend_interval of the sweep's correction over h
        bi = self.bend_interval
        if self._hinge_groups is not None:
            cmds["bending"] = [wp.launch(lk.solve_bending_lanes, dim=self._hinge_groups.shape[0],
                                         inputs=[self._hinge_groups, self._hinge_ids, m.hinge_rest_angle,
                                                 m.hinge_compliance, m.inv_mass, h * bi],
                                         outputs=[self._hinge_lambda, x], device=d, record_cmd=True)]
        else:
            cmds["bending"] = [wp.launch(k.solve_bending, dim=cnt,
                                         inputs=[self._hinge_ids, m.hinge_rest_angle, m.hinge_compliance, m.inv_mass,
                                                 off, h * bi], outputs=[self._hinge_lambda, x], device=d,
                                         record_cmd=True)
                               for off, cnt in hinge_batches]
        if bi > 1:
            cmds["bending"].append(wp.launch(k.add_moved, dim=n, inputs=[x, self._bend_before],
                                             outputs=[self._bend_moved], device=d, record_cmd=True))
            cmds["bend_velocity"] = wp.launch(k.discount_moved, dim=n, inputs=[(1.0 - 1.0 / bi) / h],
                                              outputs=[self._bend_moved, v], device=d, record_cmd=True)
        cmds["tethers"] = []
        if self.tethers:
            cmds["tethers"].append(wp.launch(k.solve_tethers, dim=n,
                                             inputs=[m.tether_anchor.flatten(), m.tether_length.flatten(),
                                                     m.tether_anchor.shape[1], m.inv_mass],
                                             outputs=[x], device=d, record_cmd=True))
        if self.limit_sliding:
            cmds["moved"] = wp.launch(k.record_moved, dim=n, inputs=[self._x_before, x], outputs=[self._pushed],
                                      device=d, record_cmd=True)
        elif self.stretch_limits:
            cmds["moved"] = wp.launch(k.flag_moved, dim=n, inputs=[self._x_before, x], outputs=[self._touched], device=d,
                                      record_cmd=True)
        contacts = []
        if self.self_collision:
            contacts.append(wp.launch(k.solve_self_contacts, dim=n,
                                      inputs=[x, self._x_prev, m.inv_mass, m.tris, self._vt_rows["ids"], self._vt_rows["sides"],
                                              self._contact_count, m.thickness, self.self_friction],
                                      outputs=[self._delta, self._delta_count], device=d, record_cmd=True))
            if self.edge_contact:
                contacts.append(wp.launch(ck.solve_edge_contacts, dim=m.edge_count,
                                          inputs=[x, self._x_prev, m.inv_mass, m.edges, m.ring_offsets, m.ring, self._ee_rows["ids"],
                                                  self._ee_rows["sides"], self._contact_ecount, m.thickness,
                                                  self.self_friction,
                                                  self.SIDE_CROSSING_TOL * m.thickness if self.follow_edge_sides else -1.0],
                                          outputs=[self._delta, self._delta_count], device=d, record_cmd=True))
            contacts.append(wp.launch(k.apply_averaged_deltas, dim=n, inputs=[],
                                      outputs=[self._delta, self._delta_count, x], device=d, record_cmd=True))
            if self.follow_edge_sides:
                cmds["sides"] = self._side_update(self._x_prev, x, record_cmd=True)
        cmds["contacts"] = contacts
        cmds["velocities"] = wp.launch(k.update_velocities, dim=n, inputs=[x, self._x_prev, h], outputs=[v], device=d,
                                       record_cmd=True)
        damping = []
        if m.damping > 0 and eg is not None:
            damping.append(wp.launch(lk.damp_stretch_lanes, dim=eg.shape[0],
                                     inputs=[eg, self._edge_ids, m.edge_compliance, m.inv_mass, x, h, m.damping],
                                     outputs=[v], device=d, record_cmd=True))
        elif m.damping > 0:
            for off, cnt in edge_batches:
                damping.append(wp.launch(k.damp_stretch, dim=cnt,
                                         inputs=[self._edge_ids, m.edge_compliance, m.inv_mass, x, off, h, m.damping],
                                         outputs=[v], device=d, record_cmd=True))
        if m.bend_damping > 0:
            for off, cnt in hinge_batches:
                damping.append(wp.launch(k.damp_bending, dim=cnt,
                                         inputs=[self._hinge_ids, m.hinge_compliance, m.inv_mass, x, off, h,
                                                 m.bend_damping],
                                         outputs=[v], device=d, record_cmd=True))
        cmds["damping"] = damping
        out = {name: [recorded(c) for c in cmd] if isinstance(cmd, list) else recorded(cmd)
               for name, cmd in cmds.items()}
        # the coarse levels, coarsest first, one list of launches each
        out["coarse"] = [[c if c is None else recorded(c) for c in self._coarse_launches(lv, limit_move)]
                         for lv in (m.hierarchy[:self.coarse_levels][::-1] if self.coarse_levels else [])]
        if self.stretch_chebyshev:
            # the stretch launches sweep by sweep (the limits in every sweep with limit_every_sweep,
            # else in the first only)
            first = len(cons) + len(stretch)
            per_sweep = first if self.limit_every_sweep else len(stretch)
            out["sweeps"] = [out["stretch"][:first]] + [out["stretch"][i:i + per_sweep]
                                                        for i in range(first, len(out["stretch"]), per_sweep)]
        return out

    def _coarse_pass(self, levels: list, x) -> None:
        """The coarse levels' launches (:meth:`_coarse_launches`, coarsest level first; none with
        ``coarse_levels`` 0)."""
        for level in levels:
            wp.copy(self._coarse_before, x)
            mark, sweep = level[0], level[1:]
            if mark is not None:
                self._coarse_contacts.zero_()
                if self._contacts_found:  # (else no vertex has candidates)
                    mark.launch()
            for c in sweep:
                c.launch()

    def _coarse_launches(self, level: dict, limit_move: float) -> list:
        """Recorded launches of one coarse level (see ``coarse_levels``): the marking of its vertices
        in or beside self-contact (None without self-collision), its constraints' coloured sweep
        with the limits' kernel and rules (skipped at marked vertices), then the prolongation of
        its vertices' moves from ``_coarse_before``."""
        m, d, x = self.model, self.device, self._x
        contacts = self._contact_count if self.self_collision else self._touched
        marked = self._coarse_contacts if self.self_collision else contacts
        out = [wp.launch(k.mark_parents, dim=m.particle_count,
                         inputs=[level["offsets"], level["parents"], self._contact_count],
                         outputs=[self._coarse_contacts], device=d, record_cmd=True) if self.self_collision else None]
        sliding = self.limit_sliding
        kernel, rule = (k.solve_limits_sliding, self._pushed) if sliding else (k.solve_limits, self._touched)
        out += [wp.launch(kernel, dim=cnt, inputs=[level["pairs"], level["length"], level["inv_mass"], limit_move,
                                                   marked, rule, off], outputs=[x], device=d, record_cmd=True)
                for off, cnt in self._batches(level["colors"])]
        out.append(wp.launch(k.prolong_moves, dim=m.particle_count,
                             inputs=[level["offsets"], level["parents"], level["weights"], m.inv_mass, contacts,
                                     self._touched, self._pushed, int(sliding), self._coarse_before],
                             outputs=[x], device=d, record_cmd=True))
        return out

    def _chebyshev_sweeps(self, sweeps: list, x) -> None:
        """The stretch sweeps (one list of launches each) with ``stretch_chebyshev``'s acceleration:
        the first plain, every later one extrapolated (:func:`~warpshade.sim.kernels.chebyshev_step`)
        with the weights omega_2 = 2 / (2 - rho^2), omega_k+1 = 4 / (4 - rho^2 omega_k) (Wang 2015)."""
        last, before = self._cheb_last, self._cheb_before
        rho2 = self.stretch_chebyshev ** 2
        wp.copy(before, x)
        for c in sweeps[0]:
            c.launch()
        wp.copy(last, x)
        omega = 2.0 / (2.0 - rho2)
        for i, sweep in enumerate(sweeps[1:]):
            for c in sweep:
                c.launch()
            if i > 0:
                omega = 4.0 / (4.0 - rho2 * omega)
            wp.launch(k.chebyshev_step, dim=x.shape[0], inputs=[omega], outputs=[x, last, before], device=self.device)

    def _batches(self, colors: list) -> list:
        """Launch ranges (offset, count) of the coloured constraints: one range per colour on a GPU; on
        the CPU, where a launch runs its threads one after another in index order, one range over
        all colours (they are stored colour by colour), which gives bit-for-bit the same sweep
        with one launch instead of one per colour."""
        if not self.device.is_cpu or not colors:
            return list(colors)
        for (off, cnt), (nxt, _) in zip(colors, colors[1:]):
            assert off + cnt == nxt, "colours are stored contiguously"
        return [(colors[0][0], sum(cnt for _, cnt in colors))]

    def _lanes(self, *arrays) -> bool:
        """The lane kernels (:mod:`~warpshade.sim.lane_kernels`) apply: on the CPU, with contiguous arrays."""
        return self.device.is_cpu and all(a.is_contiguous for a in arrays)

    def _lane_groups(self, colors: list, ids, *per_constraint):
        """Groups (start, count) of at most :data:`~warpshade.sim.lane_kernels.LANES` constraints
        of one colour for the lane kernels where they apply; else None."""
        if not colors or not self._lanes(ids, *per_constraint, self.model.inv_mass):
            return None
        return lk.lane_groups(colors, self.device)

    SHARP_PASSES = 1
    """Passes per substep of the sharp-edge and corner projection (each followed by the vertices')."""

    CONTACT_ROW_START = 16
    """Candidates per vertex (and per edge) the contact rows start with; they grow on demand."""

    def _contact_rows(self, rows: int, width: int) -> dict:
        """Candidate rows (ids, sides, distances) of one contact kind and the previous
        detection's ids and sides, ``width`` per row."""
        d = self.device
        return {"ids": wp.zeros((rows, width), dtype=wp.int32, device=d),
                "sides": wp.zeros((rows, width), dtype=wp.float32, device=d),
                "dists": wp.zeros((rows, width), dtype=wp.float32, device=d),
                "prev_ids": wp.zeros((rows, width), dtype=wp.int32, device=d),
                "prev_sides": wp.zeros((rows, width), dtype=wp.float32, device=d)}

    def _find_candidates(self, kernel, dim: int, rows: dict, inputs: list, count, prev_count,
                         threads: int | None = None) -> tuple[dict, bool]:
        """Run a candidate search (`threads` threads, default `dim`) into the `dim` `rows` after
        saving the previous detection; while rows overflow and may still grow, double them and
        search again. Returns the rows used and whether they grew."""
        if self._contacts_found:
            self._recorded.launch(k.save_rows, dim, [count, rows["ids"], rows["sides"]],
                                  [prev_count, rows["prev_ids"], rows["prev_sides"]])
        else:  # every count is 0: the rows past them are never read
            prev_count.zero_()
        grew = False
        while True:
            before = int(self._overflow.numpy()[0])
            self._recorded.launch(kernel, dim if threads is None else threads,
                                  inputs + [rows["prev_ids"], rows["prev_sides"], prev_count],
                                  [rows["ids"], rows["sides"], count, rows["dists"], self._overflow, self._near])
            width = rows["ids"].shape[1]
            if int(self._overflow.numpy()[0]) == before or width >= self.max_contacts:
                return rows, grew
            self._overflow.fill_(before)  # nothing dropped: the search runs again with room for all
            wider = self._contact_rows(dim, min(2 * width, self.max_contacts))
            for key in ("prev_ids", "prev_sides"):
                grown = wider[key].numpy()
                grown[:, :width] = rows[key].numpy()
                wider[key].assign(grown)
            rows, grew = wider, True

    def _swept_bvh(self, bvh, kernel, prims, boxes: list, x, v, horizon: float, ahead: float):
        """Boxes of the triangles or edges `prims` swept over `horizon` and over `ahead` (>=
        horizon) into `boxes` (lower, upper, ahead lower, ahead upper) and the BVH over the `ahead`
        ones (built at the first detection from that detection's `horizon` boxes, refitted after:
        its leaf order, which orders the candidates, is fixed then). Returns the BVH and the
        `horizon` boxes."""
        n, launch = prims.shape[0], self._recorded.launch
        lo, hi, alo, ahi = boxes
        if bvh is None:
            launch(kernel, n, [x, v, prims, horizon, self._pad], [alo, ahi])
            bvh = wp.Bvh(alo, ahi)
            if ahead == horizon:
                return bvh, alo, ahi
        if ahead == horizon:
            launch(kernel, n, [x, v, prims, horizon, self._pad], [alo, ahi])
            bvh.refit()
            return bvh, alo, ahi
        launch(kernel, n, [x, v, prims, horizon, self._pad], [lo, hi])
        launch(kernel, n, [x, v, prims, ahead, self._pad], [alo, ahi])
        bvh.refit()
        return bvh, lo, hi

    def _detect_self_contacts(self, x, v, horizon: float, ahead: float | None = None) -> bool:
        """Candidate pairs for the next contact interval (`horizon` seconds); with `ahead` >
        horizon, the next detection comes after `horizon` seconds with horizon `ahead - horizon`,
        and ``_clear_ahead`` tells whether it would find none. True when the contact rows grew."""
        m = self.model
        ahead = horizon if ahead is None else max(ahead, horizon)
        self._near.zero_()
        # boxes of both sides padded: overlap <=> gap < thickness
        self._bvh, lower, upper = self._swept_bvh(self._bvh, k.compute_triangle_bounds, self._tri_ids, self._tri_boxes, x, v,
                                                  horizon, ahead)
        g = self.DETECTION_GROUP
        self._vt_rows, grew = self._find_candidates(
            k.find_self_contacts, m.particle_count, self._vt_rows,
            [self._bvh.id, x, m.rest_points, v, m.tris, m.ring_offsets, m.ring, horizon, ahead, lower, upper,
             self._pad, m.thickness, self._tri_boxes[2], self._tri_boxes[3], g, self._group_span, *self._query_boxes],
            self._contact_count, self._prev_count, threads=(m.particle_count + g - 1) // g)
        if self.edge_contact:
            ne = m.edge_count
            self._ebvh, elower, eupper = self._swept_bvh(self._ebvh, ck.compute_edge_bounds, self._edge_ids, self._edge_boxes,
                                                         x, v, horizon, ahead)
            wp.copy(self._eactive, m.edge_border)
            if m.hinge_count:
                self._recorded.launch(ck.mark_crease_edges, m.hinge_count,
                                      [x, self._hinge_ids, m.hinge_edge, self.CREASE_ANGLE], [self._eactive])
            self._ee_rows, egrew = self._find_candidates(
                ck.find_edge_contacts, ne, self._ee_rows,
                [self._ebvh.id, x, v, horizon, ahead, m.edges, self._eactive, elower, eupper, self._edge_boxes[2],
                 self._edge_boxes[3], m.thickness],
                self._contact_ecount, self._prev_ecount)
            grew = grew or egrew
        self._contacts_found = bool(self._contact_count.numpy().any()) or (
            self.edge_contact and bool(self._contact_ecount.numpy().any()))
        self._clear_ahead = ahead > horizon and not self._contacts_found and not self._near.numpy()[0]
        if grew:
            self._cmd_cache = None
        return grew

    DETECTION_GROUP = 4
    """Consecutive vertices that share one BVH query in the vertex-triangle detection when their
    look-up boxes lie within :attr:`GROUP_SPAN` rest edge lengths (the same candidates, in the
    same order, as one query each; see :func:`~warpshade.sim.kernels.find_self_contacts`)."""
    GROUP_SPAN = 8.0
    """How wide [median rest edge lengths] the box around a group's look-up boxes may be for one query."""
    CREASE_ANGLE = 0.25
    """Hinges bent by more than this [rad] make their edge a crease: edge-edge contact is looked
    for from border and crease edges (where two layers' edges can cross without a vertex
    meeting a triangle first). At 0.5 the edges of an accordion fold one strip wide were not yet
    creases when they crossed (the default scene's drape)."""
    GUARD_ROUNDS = 6
    """Rounds of the intersection guard that grow the reverted region by one ring each; the round
    after them reverts every free vertex."""
    def _guard_intersections(self, x, v, dt: float) -> None:
        """Send the vertices of intersecting triangles back to their start-of-step positions
        (colliders then push them out again, and the free vertices around them follow:
        :meth:`_relax_around_reverted`), growing the region a ring per round, all free
        vertices in the last round, until no pair is left that the step made. A cloth-cloth pair
        that also met at the start of the step (inherited from an earlier step) is left alone:
        sending vertices back to where it already existed cannot remove it. When even the last round leaves new
        intersections (made by kinematic vertices or colliders), the step is kept as the contacts
        left it (no vertex sent back), pushed off the colliders by extra passes if that frees it
        (:meth:`_push_off_sharp_edges`, :meth:`_push_off_contacts`, :meth:`_yield_to_colliders`),
        else counted in ``stats()["guard_unresolved"]``."""
        m, d, n = self.model, self.device, self.model.particle_count
        col = self.colliders
        self._reverted.zero_()
        self.guard_vertices = 0
        for r in range(self.GUARD_ROUNDS + 2):
            self._mark.zero_()
            # cloth-cloth pairs that met at the start of the step too are inherited: sending
            # vertices back to the start cannot remove them, so only new pairs are marked and
            # counted. Cloth-collider pairs are all marked: reverting them holds cloth that lies
            # across a sharp rim, which the rim's edge contact alone can throw off.
            found = self._new_pairs(x)
            if found == 0:
                break
            if r == 0:
                self.guard_steps += 1
                self.guard_vertices = -1
                wp.copy(self._x_unguarded, x)
            if r == self.GUARD_ROUNDS + 1:
                # kinematic vertices or colliders made the intersection: reverting does not remove
                # it, and holding vertices back while a collider or an attached edge moves on only
                # stretches the cloth, so the step stands as the contacts left it, pushed off the
                # colliders' sharp edges and corners by extra passes if that frees it
                wp.copy(x, self._x_unguarded)
                self._reverted.zero_()
                if not self._push_off_sharp_edges(x):
                    wp.copy(x, self._x_unguarded)
                    if not self._push_off_contacts(x, v, dt):
                        wp.copy(x, self._x_unguarded)
                        if not self._yield_to_colliders(x, v, dt):
                            self.guard_unresolved += 1
                            wp.copy(x, self._x_unguarded)
                break
            if r == self.GUARD_ROUNDS:
                self._mark.fill_(1)
            for _ in range(r):
                wp.copy(self._mark2, self._mark)
                wp.launch(ck.grow_mark, dim=m.edge_count, inputs=[m.edges, self._mark], outputs=[self._mark2], device=d)
                self._mark, self._mark2 = self._mark2, self._mark
            wp.launch(ck.revert_marked, dim=n, inputs=[self._mark, m.inv_mass, self._x_start],
                      outputs=[x, self._reverted], device=d)
            if col is not None:
                col.collide(m.thickness, m.inv_mass, self._x_start, x, since="start")
            if self.guard_relax:
                self._relax_around_reverted(x, dt)
        if self.guard_vertices:
            if self.follow_edge_sides and self._contacts_found:
                self._side_update(self._x_unguarded, x)
            wp.launch(ck.reverted_velocities, dim=n, inputs=[self._reverted, self._x_start, x, dt], outputs=[v],
                      device=d)
            if self.guard_relax:
                wp.launch(ck.moved_velocities, dim=n, inputs=[self._x_unguarded, self._x_start, x, dt], outputs=[v],
                          device=d)
            self.guard_vertices = int(self._reverted.numpy().sum())
        if self.guard_vertices or not self._streak_clear:  # (else every streak stays 0)
            wp.launch(ck.update_streaks, dim=n, inputs=[self._reverted], outputs=[self._streak], device=d)
        self._streak_clear = not self.guard_vertices
        if self.guard_vertices:
            self.guard_longest_hold = max(self.guard_longest_hold, int(self._streak.numpy().max()))

    AERO_INTERVAL = 1
    """Default of ``aero_interval`` (aerodynamics every substep)."""
    BEND_INTERVAL = 1
    """Default of ``bend_interval`` (bending every substep)."""
    FOLLOW_EDGE_SIDES = False
    """Default of ``follow_edge_sides`` (off; what it does to the scenes is measured in
    docs/benchmarks/index.md)."""
    LIMIT_SLIDING = False
    """Default of ``limit_sliding`` (off; what it does to the scenes is measured in
    docs/benchmarks/index.md)."""
    STRETCH_CHEBYSHEV = 0.0
    """Default of ``stretch_chebyshev`` (0: off; what it does to the scenes is measured in
    docs/benchmarks/history.md)."""
    COARSE_LEVELS = 0
    """Default of ``coarse_levels`` (0: off; measured in docs/benchmarks/history.md)."""
    LIMIT_EVERY_SWEEP = False
    """Default of ``limit_every_sweep`` (off: it acts only with ``stretch_sweeps`` > 1, which costs,
    and the stiffer solve left the guard holding cloth that falls and folds fast for long;
    measured in docs/benchmarks/history.md)."""
    SIDE_CROSSING_TOL = 1.0e-3
    """Edges that come within this fraction of the thickness of each other at a moment their four
    points are coplanar have passed through each other: an edge pair's stored side is kept across
    such a motion and follows a sign flip without one (:func:`contact_kernels.update_edge_sides`)."""

    HELD_CONTACT_INTERVAL = None
    """Default of ``held_contact_interval`` (None: ``contact_interval``; 1 ends most of the guard's
    holds with stiff solves but not sims/sheet_drop.py's, whose strain it raises: measured in
    docs/benchmarks/history.md)."""

    GUARD_RELAX = 0
    """Default of ``guard_relax`` (off: on by default (8 sweeps) it let 10 intersecting pairs through
    from frame 36 on in tests/test_hard_scenes.py's twist, which a guard step the attached
    edges made left unresolved; docs/benchmarks/history.md)."""

    def _relax_around_reverted(self, x, dt: float) -> None:
        """``guard_relax`` stretch sweeps (substep length, no over-relaxation) with the vertices
        the guard sent back held where it put them, then the colliders' vertex pass: the free
        vertices around a reverted region follow it instead of the edges between them stretching
        (a sheet landing edge-on at 3 m/s had reverted vertices 13 cm above their neighbours, edges
        at 3-4x their rest length). Moved vertices that then intersect are reverted by the next
        round; every vertex the guard moved then leaves with its mean velocity over the step
        (:func:`~warpshade.sim.contact_kernels.moved_velocities`)."""
        m, d = self.model, self.device
        wp.launch(ck.held_inv_mass, dim=m.particle_count, inputs=[self._reverted, m.inv_mass],
                  outputs=[self._held_w], device=d)
        for _ in range(self.guard_relax):
            self._edge_lambda.zero_()
            for off, cnt in self._batches(m.edge_colors):
                wp.launch(k.solve_stretch, dim=cnt,
                          inputs=[self._edge_ids, m.edge_rest_length, m.edge_compliance, self._held_w, off,
                                  dt / self.substeps, 1.0], outputs=[self._edge_lambda, x], device=d)
        if self.colliders is not None:
            self.colliders.collide(m.thickness, m.inv_mass, self._x_start, x, since="start")

    def _side_update(self, x_from, x_to, record_cmd: bool = False):
        """Launch (or record) :func:`contact_kernels.update_edge_sides` on the edge contact rows
        for the motion from x_from to x_to."""
        m = self.model
        return wp.launch(ck.update_edge_sides, dim=m.edge_count,
                         inputs=[x_from, x_to, m.edges, m.ring_offsets, m.ring, self._ee_rows["ids"], self._ee_rows["sides"],
                                 self._contact_ecount, self.SIDE_CROSSING_TOL * m.thickness],
                         device=self.device, record_cmd=record_cmd)

    PUSH_OFF_PASSES = 4
    """Extra sharp-edge and vertex passes the guard tries on a step whose intersections a moving
    collider made (a box's corner driven into the cloth faster than the substeps' contacts push
    it off) before it counts the step as unresolved."""

    def _push_off_sharp_edges(self, x) -> bool:
        """Run up to :attr:`PUSH_OFF_PASSES` passes of the colliders' edge and corner projection
        (each followed by the vertices') on x; True as soon as x has no new intersecting pair."""
        m, col = self.model, self.colliders
        if col is None or not col.has_sharp_edges:
            return False
        for _ in range(self.PUSH_OFF_PASSES):
            col.collide_edges(m.thickness, m.inv_mass, m.edges, x, m.tris)
            col.collide(m.thickness, m.inv_mass, self._x_unguarded, x, since="end")
            if self._new_pairs(x) == 0:
                return True
        return False

    ROUND_MOVE = 0.25
    """Longest move of a cloth vertex in one substep that passes near a sphere or capsule, as a
    fraction of its radius (their projections push a vertex out on the side it is nearest, so a
    vertex yanked past a ball's centre in one substep by a stretched edge would leave on the far
    side): :meth:`~warpshade.sim.colliders.ColliderSet.limit_round_motion`."""

    MESH_MOVE = 0.125
    """Longest move of a cloth vertex in one substep that enters a closed mesh collider, as a
    fraction of the chord its line cuts through the solid (the mesh counterpart of
    :attr:`ROUND_MOVE`: 0.25 of the radius is 0.125 of a chord through a ball's centre; the mesh's
    projection pushes a vertex out at the surface nearest to it, so one yanked past the middle of
    the solid would leave on the far side). Capping only the depth a move reaches (0.25 of the
    chord past the entry point) let issue 19's hammock at 17 x 17 vertices work its last vertex
    round the ball, substep by substep, and the cloth slip under it:
    :meth:`~warpshade.sim.colliders.ColliderSet.limit_mesh_motion`."""

    YIELD_PASSES = 16
    """Most passes of the colliders' own projections (cloth triangles off spheres, capsules and
    closed meshes, sharp edges and corners, vertices) the guard runs in each of its two tries on a
    step whose cloth-collider intersections nothing else removed (the cloth stretches over the
    collider instead of crossing it: :meth:`_yield_to_colliders`)."""

    def _yield_to_colliders(self, x, v, dt: float) -> bool:
        """Push the cloth out of the colliders with the colliders' projections alone (cloth
        triangles off spheres and capsules on the side they were on at the start of the step,
        off closed meshes back the way they came, sharp edges and corners, vertices), up to
        :attr:`YIELD_PASSES` passes: the cloth's own constraints do not take part, so a collider
        driven against pinned or attached cloth stretches it instead of crossing it. First from x
        as the contacts left it; when that leaves pairs, from the start of the step with every free
        vertex sent back (held, as the guard's reverts hold them: the colliders alone move the
        cloth in that step). After either try that leaves x clear of the colliders but with new
        cloth-cloth pairs (the pushes drove cloth into its own layers), the self-contact push-off
        on it (:meth:`_yield_self_pairs`). True (counted in ``stats()["collider_yields"]``) as soon
        as x has no new intersecting pair."""
        m, col = self.model, self.colliders
        if col is None or not (col.has_sharp_edges or col.has_round_shapes):
            return False
        if self._yield_passes(x, self._x_unguarded, "end") or self._yield_self_pairs(x, v, dt):
            return True
        wp.copy(x, self._x_unguarded)
        self._mark.fill_(1)
        wp.launch(ck.revert_marked, dim=m.particle_count, inputs=[self._mark, m.inv_mass, self._x_start],
                  outputs=[x, self._reverted], device=self.device)
        col.collide(m.thickness, m.inv_mass, self._x_start, x, since="start")
        if self._yield_passes(x, self._x_start, "start") or self._yield_self_pairs(x, v, dt):
            return True
        self._reverted.zero_()
        return False

    def _yield_self_pairs(self, x, v, dt: float) -> bool:
        """When the collider passes of :meth:`_yield_to_colliders` left x clear of the colliders but
        with new cloth-cloth pairs (the pushes drove cloth into its own layers), the self-contact and
        collider passes of :meth:`_push_off_contacts` on it; True (counted in
        ``stats()["collider_yields"]``) when they free it."""
        if self.colliders is None or self._counter.collider_pairs(x, self.colliders)[0]:
            return False
        if self._push_off_contacts(x, v, dt):
            self.collider_yields += 1
            return True
        return False

    def _yield_passes(self, x, x_prev, since: str) -> bool:
        """The passes of :meth:`_yield_to_colliders` on x (x_prev: the vertices' friction reference,
        at ``since`` as :meth:`~warpshade.sim.colliders.ColliderSet.collide` takes it)."""
        m, col = self.model, self.colliders
        for _ in range(self.YIELD_PASSES):
            col.collide_round_faces(m.thickness, m.inv_mass, m.tris, x, self._x_start)
            col.collide_mesh_faces(m.thickness, m.inv_mass, m.tris, x, self._x_start)
            col.collide_shape_faces(m.thickness, m.inv_mass, m.tris, x, self._x_start)
            col.collide_edges(m.thickness, m.inv_mass, m.edges, x, m.tris)
            col.collide(m.thickness, m.inv_mass, x_prev, x, since=since)
            if self._new_pairs(x) == 0:
                self.collider_yields += 1
                return True
        return False

    def _new_pairs(self, x) -> int:
        """Intersecting pairs of x that the step made (cloth-cloth pairs that met at the start of the
        step too are inherited and not counted; every cloth-collider pair is), their vertices marked
        in ``_mark``."""
        c = self._counter
        found = c.self_pairs(x, self._mark, self._x_start)[0] - c.inherited
        if self.colliders is not None:
            found += c.collider_pairs(x, self.colliders, self._mark)[0]
        return found

    def _push_off_contacts(self, x, v, dt: float) -> bool:
        """Find the self-contacts of x afresh and run up to :attr:`PUSH_OFF_PASSES` passes of the
        self-contact and collider projections on it; True as soon as x has no new intersecting
        pair (attached vertices driven into cloth that lies under them: the free cloth is pushed
        off them). The contact rows are left as the step left them."""
        if not self.self_collision:
            return False
        m, col = self.model, self.colliders
        saved = self._contact_memory()
        try:
            self._detect_self_contacts(x, v, 0.0)
            if not self._contacts_found:
                return False
            cmds = self._commands(dt / self.substeps, self._wind)
            for _ in range(self.PUSH_OFF_PASSES):
                for cmd in cmds["contacts"]:
                    cmd.launch()
                if col is not None:
                    col.collide(m.thickness, m.inv_mass, self._x_unguarded, x, since="end")
                if self._new_pairs(x) == 0:
                    return True
            return False
        finally:
            self._restore_contact_memory(saved)

    def _contact_memory(self) -> dict:
        """Copies of the self-contact rows and counts (what the next detection reads)."""
        out = {"vt": self._vt_rows, "vt_copy": {name: wp.clone(a) for name, a in self._vt_rows.items()},
               "count": wp.clone(self._contact_count), "prev_count": wp.clone(self._prev_count),
               "found": self._contacts_found, "overflow": wp.clone(self._overflow)}
        if self.edge_contact:
            out.update(ee=self._ee_rows, ee_copy={name: wp.clone(a) for name, a in self._ee_rows.items()},
                       ecount=wp.clone(self._contact_ecount), prev_ecount=wp.clone(self._prev_ecount))
        return out

    def _restore_contact_memory(self, saved: dict) -> None:
        for key, copy, attr in (("vt", "vt_copy", "_vt_rows"), ("ee", "ee_copy", "_ee_rows")):
            if key not in saved:
                continue
            if getattr(self, attr) is not saved[key]:  # the rows grew: back to the old arrays
                setattr(self, attr, saved[key])
                self._cmd_cache = None
            for name, a in saved[copy].items():
                wp.copy(saved[key][name], a)
        wp.copy(self._contact_count, saved["count"])
        wp.copy(self._prev_count, saved["prev_count"])
        if self.edge_contact:
            wp.copy(self._contact_ecount, saved["ecount"])
            wp.copy(self._prev_ecount, saved["prev_ecount"])
        self._contacts_found = saved["found"]
        wp.copy(self._overflow, saved["overflow"])

    def _first_nonfinite(self, x, v) -> int:
        n = self.model.particle_count
        self._first_bad.fill_(n)
        self._recorded.launch(k.find_nonfinite, n, [x, v], [self._first_bad])
        bad = int(self._first_bad.numpy()[0])
        return bad if bad < n else -1

    def _check_finite(self, state_in: ClothState, x, v) -> None:
        bad = self._first_nonfinite(x, v)
        if bad >= 0:
            p = x.numpy()[bad]
            vel = v.numpy()[bad]
            before = self._first_nonfinite(state_in.points, state_in.velocities)
            why = (f"; the input state was already non-finite at vertex {before}" if before >= 0 else "")
            raise SimulationError(f"step {self.step_count}: vertex {bad} became non-finite (position {p.tolist()}, "
                                  f"velocity {vel.tolist()}){why}; state_out was left unchanged")

    def stats(self) -> dict:
        """Counters: steps taken, self-contact candidates now, candidates dropped (overflow) so far."""
        out = {"steps": self.step_count, "substeps": self.substeps, "iterations": self.iterations,
               "edge_colors": len(self.model.edge_colors), "hinge_colors": len(self.model.hinge_colors)}
        if self.self_collision:
            out["self_contact_candidates"] = int(self._contact_count.numpy().sum())
            out["self_contact_overflow"] = int(self._overflow.numpy()[0])
            out["self_contact_row_width"] = int(self._vt_rows["ids"].shape[1])
        if self.edge_contact:
            out["edge_contact_candidates"] = int(self._contact_ecount.numpy().sum())
            out["edge_contact_row_width"] = int(self._ee_rows["ids"].shape[1])
        if self.guard:
            out["guard_steps"] = self.guard_steps
            out["guard_unresolved"] = self.guard_unresolved
            out["collider_yields"] = self.collider_yields
            out["guard_longest_hold"] = self.guard_longest_hold
        return out

    def knobs(self) -> dict:
        """Every solver setting as used."""
        return {"substeps": self.substeps, "iterations": self.iterations, "gravity": list(self.gravity),
                "drag": self.drag, "air_density": self.air_density, "drag_coefficient": self.drag_coefficient,
                "lift_coefficient": self.lift_coefficient, "self_collision": self.self_collision,
                "contact_interval": self.contact_interval, "held_contact_interval": self.held_contact_interval,
                "edge_contact": self.edge_contact,
                "follow_edge_sides": self.follow_edge_sides, "aero_interval": self.aero_interval,
                "bend_interval": self.bend_interval,
                "guard": self.guard, "guard_relax": self.guard_relax, "self_friction": self.self_friction,
                "max_contacts": self.max_contacts, "contact_iterations": self.contact_iterations,
                "stretch_sweeps": self.stretch_sweeps,
                "relaxation": self.relaxation, "tethers": self.tethers, "stretch_limits": self.stretch_limits,
                "limit_sliding": self.limit_sliding, "limit_every_sweep": self.limit_every_sweep,
                "stretch_chebyshev": self.stretch_chebyshev, "coarse_levels": self.coarse_levels,
                "check_finite": self.check_finite,
                "thickness": self.model.thickness, "damping": self.model.damping,
                "bend_damping": self.model.bend_damping}
