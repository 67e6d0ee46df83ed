"""Shading one frame of a scene: shading groups, SH transfer, lights, exit radiance.

:class:`SceneShader` is a picklable :class:`warpshade.parallel.FrameShaderSpec`: it carries only
meshes, materials, method names and light descriptions; ``build()`` (once per worker, or once
inline) constructs the visibility methods and lights, and returns ``shade(frame, geometry)``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
import warp as wp

from ..geometry.mesh import TriMesh, fill_from_neighbours, mesh_edges
from ..geometry.normals import vertex_normals
from ..sh.zonal import unoccluded_transfer as sh_unoccluded_transfer
from .config import TWO_SIDED_MODES, GroupSpec, group_objects, is_two_sided


def unoccluded_transfer(normals: np.ndarray, order: int) -> np.ndarray:
    """:func:`warpshade.sh.unoccluded_transfer` as float32, the pipeline's transfer dtype: shape (V, N*N)."""
    return sh_unoccluded_transfer(normals, order).astype(np.float32)


BURIED = 5e-3
"""A vertex is buried when the DC coefficient of its transfer is at most this fraction of the unoccluded
one: (almost) no light reaches it from any direction (it lies under or inside a solid), so it is seen only
through the triangles it shares with visible vertices. Not zero: hemiraster's rasterization leaks a pixel or
two through the seams between a solid's triangles, one pixel of its default mask (32 across, about 804 on
the cosine-weighted disk) being 1.2e-3 of the unoccluded DC; 5e-3 is four such pixels, five of the reference
method's default 1024 rays, and a colour under 0.5 % of the unoccluded one, black to the eye either way."""


def buried_dc() -> float:
    """The DC coefficient at or below which a vertex is buried: :data:`BURIED` times the DC of the clamped
    cosine lobe (any normal, :mod:`warpshade.sh.zonal`)."""
    return BURIED * (np.sqrt(np.pi) / 2)


def fill_buried(transfer: np.ndarray, edges: np.ndarray, among: np.ndarray | None = None) -> np.ndarray:
    """``transfer`` (V, N*N) with its :data:`BURIED` rows (among the rows where the (V,) bool ``among`` is
    true, default all) given their non-buried
    neighbours' transfer over the mesh ``edges`` (:func:`~warpshade.geometry.mesh.fill_from_neighbours`):
    a buried vertex is black, and the triangles it shares with visible vertices would show a dark fringe
    around whatever buries it. Other rows are unchanged; a part with no non-buried vertex keeps its own."""
    buried = transfer[:, 0] <= buried_dc()
    if among is not None:
        buried &= among
    if not buried.any():
        return transfer
    return fill_from_neighbours(transfer, edges, buried)


BACK_PASS_WITH_OCCLUDERS = ("reference",)
"""Methods whose back-side pass may receive at the two-sided members alone, the other members blocking as
static ``occluders`` (:func:`back_side_receivers`)."""
# reference casts the same rays either way. hemiraster also takes occluders, but decimates and refines them
# apart from the receiver: on the default drape (frame 30, order 4, against reference at 1024 rays) its back
# side's mean |dT| was 1.1 % of the unoccluded T_0 that way and 0.63 % on the whole group (front: 0.47 %),
# for 30 % less time; it runs on the whole group.


def back_side_receivers(spec: GroupSpec) -> list[int] | None:
    """Members the back-side pass of a group receives at when it need not run on the whole group, else None.

    When the method is one of :data:`BACK_PASS_WITH_OCCLUDERS`, every member that is not two-sided is static
    and every two-sided member casts shadows, the back pass receives at the two-sided members only, the
    others blocking as occluders: it then costs in proportion to the two-sided vertices.
    """
    if spec.method not in BACK_PASS_WITH_OCCLUDERS or not any(spec.two_sided):
        return None
    casts = spec.casts or [True] * len(spec.meshes)
    two = [k for k, t in enumerate(spec.two_sided) if t]
    others_static = all(not mv for mv, t in zip(spec.moving, spec.two_sided) if not t)
    if others_static and len(two) < len(spec.meshes) and all(casts[k] for k in two):
        return two
    return None


def flipped(mesh: TriMesh) -> TriMesh:
    """``mesh`` seen from its back: the same points, reversed winding, negated normals."""
    return TriMesh(mesh.points, mesh.faces[:, ::-1].copy(), normals=-mesh.normals, name=f"{mesh.name} back")


class _Group:
    """A built :class:`GroupSpec`: the merged receiver mesh and its method.

    With two-sided members, a second instance of the method is built on the group mesh seen from its back
    (:func:`flipped`: every member's winding reversed, so the method's notion of front, near field and
    self-occlusion is the back's): its transfer is the hemisphere around the flipped normal, occluded by
    the same blockers. Only the two-sided members' rows of it are used (and, where the method allows, only
    they are computed: :meth:`_build_back_method`).
    """

    def __init__(self, spec: GroupSpec, order: int, device: str, reuse: float | None = None, origin=None):
        self.spec, self.order = spec, order
        self.origin = None if origin is None or not np.any(origin) else np.asarray(origin, dtype=np.float64)
        """Where the visibility methods' coordinates have their origin (:func:`~warpshade.visibility.rays.local_origin`
        of the scene's shaded objects, shared by every group of a build), or None for the world origin: float32
        coordinates resolve a scene to a fraction of their magnitude, and the methods work in float32."""
        self.offsets = np.cumsum([0] + [m.num_vertices for m in spec.meshes])
        faces = np.concatenate([m.faces + off for m, off in zip(spec.meshes, self.offsets[:-1])])
        self.rest = np.concatenate([m.points for m in spec.meshes])
        self.mesh = TriMesh(self.rest, faces, name=f"group[{', '.join(spec.names)}]")
        """Receivers: every member's vertices and triangles (normals come from all of them)."""
        self.edges = mesh_edges(faces)
        """Edges of every member's triangles (members share none): where :func:`fill_buried` fills."""
        self.blocker_faces = spec.blocker_faces()
        """Triangles that block light (members casting shadows), shape (F_c, 3), int32."""
        receivers_only = len(self.blocker_faces) < len(faces)
        self.any_moving = any(spec.moving)
        self.cached = None
        self.cached_back = None
        self.method = None
        if spec.method is not None and len(self.blocker_faces):
            from ..visibility import get_method

            # Members that cast no shadows keep their vertices (receivers, with the normals of their own
            # triangles, passed in update) but lose their triangles from the method's mesh, so every
            # method sees them as points that block nothing.
            mesh = (TriMesh(self.local(self.rest), faces, name=self.mesh.name) if self.origin is not None else
                    self.mesh) if not receivers_only else TriMesh(
                self.local(self.rest), self.blocker_faces, normals=self.mesh.normals, name=f"{self.mesh.name} casters")
            self.method = get_method(spec.method)(mesh, order=order, device=device, **spec.knobs)
        self.back_method = None
        self.back_rows = None
        """Group rows the back method receives at (None: all of them)."""
        self.two_sided = any(spec.two_sided)
        if self.two_sided and self.method is not None:
            self._build_back_method(type(self.method), order, device)
        for m, near_first in ((self.method, False), (self.back_method, True)):
            # every row it computes is filled where buried (update, update_back); a back side mostly lies on
            # what it faces (most of its receivers buried), a front mostly not
            if hasattr(m, "stop_when_dark"):
                m.stop_when_dark(buried_dc(), near_first=near_first)
        if reuse is not None:  # temporal reuse (warpshade.visibility.reuse), both sides alike
            from ..visibility.reuse import with_reuse

            self.method, self.back_method = with_reuse(self.method, reuse), with_reuse(self.back_method, reuse)
        two = np.zeros(len(self.rest), dtype=bool)
        for k, t in enumerate(spec.two_sided):
            two[self.offsets[k]:self.offsets[k + 1]] = bool(t)
        self._two_rows, self._one_rows = np.flatnonzero(two).astype(np.int32), np.flatnonzero(~two)
        """Group rows of the two-sided members (the back pass's receivers) and of the others."""
        self._two_sided = two
        """The same as a (V,) mask: where the back side is filled (:func:`fill_buried`)."""
        self._faces = None
        if self.method is None or receivers_only:
            self._faces = wp.array(faces, dtype=wp.int32, device=device)
            self._points = wp.array(self.rest, dtype=wp.vec3, device=device)
            self._normals = wp.zeros(len(self.rest), dtype=wp.vec3, device=device)

    def _build_back_method(self, cls, order: int, device: str) -> None:
        """The back-side method: on the two-sided members alone with the others as static occluders where
        :func:`back_side_receivers` allows it, else on the whole group."""
        spec = self.spec
        casts = spec.casts or [True] * len(spec.meshes)
        two = back_side_receivers(spec)
        if two is not None:
            def merged(ks, name):
                offs = np.cumsum([0] + [spec.meshes[k].num_vertices for k in ks])
                return TriMesh(self.local(np.concatenate([spec.meshes[k].points for k in ks])),
                               np.concatenate([spec.meshes[k].faces + o for k, o in zip(ks, offs[:-1])]), name=name)

            blockers = [k for k in range(len(spec.meshes)) if k not in two and casts[k]]
            self.back_rows = np.concatenate([np.arange(self.offsets[k], self.offsets[k + 1]) for k in two])
            occluders = [flipped(merged(blockers, f"{self.mesh.name} blockers"))] if blockers else []
            self.back_method = cls(flipped(merged(two, f"{self.mesh.name} two-sided")), order=order, device=device,
                                   occluders=occluders, **spec.knobs)
        else:
            self.back_method = cls(flipped(self.method.mesh), order=order, device=device, **spec.knobs)

    def local(self, points: np.ndarray) -> np.ndarray:
        """World ``points`` in the methods' coordinates (relative to :attr:`origin`; unchanged without one)."""
        if self.origin is None:
            return points
        return (np.asarray(points, dtype=np.float64) - self.origin).astype(np.asarray(points).dtype)

    def reset_reuse(self) -> None:
        """Temporal reuse forgets the frames seen (:meth:`~warpshade.visibility.reuse.TemporalReuse.reset`):
        the next frame computes every receiver, as the first one does."""
        for m in (self.method, self.back_method):
            if hasattr(m, "reset"):
                m.reset()

    def update(self, geometry: dict) -> tuple[bool, tuple]:
        """``(computed, (points (V, 3), transfer (V, N*N), unit normals (V, 3)))`` of the group this frame;
        ``computed`` is False when the first frame's result is reused (nothing in the group moves)."""
        if self.cached is not None and not self.any_moving:
            return False, self.cached  # nothing in the group moves: transfer computed once
        pts = np.concatenate([geometry[n] if mv else self.rest[a:b] for n, mv, a, b in
                              zip(self.spec.names, self.spec.moving, self.offsets[:-1], self.offsets[1:])])
        pts = pts.astype(np.float32)
        normals = None
        if self._faces is not None:  # normals from every member's triangles, blocking or not
            self._points.assign(pts)
            normals = vertex_normals(self._points, self._faces, out=self._normals)
        if self.method is not None:
            transfer = self.method.update(self.local(pts), normals).numpy().copy()  # the next update overwrites it
            normals = self.method.normals.numpy().copy()
            transfer = fill_buried(transfer, self.edges)
        else:
            normals = normals.numpy().copy()
            transfer = unoccluded_transfer(normals, self.order)
        self.cached = (pts, transfer, normals)
        self.cached_back = None
        return True, self.cached

    def update_back(self) -> tuple[bool, np.ndarray]:
        """``(computed, back-side transfer (V, N*N))`` at the points and normals of the last :meth:`update`
        (rows of members shaded on one side are zero when only the two-sided members are computed)."""
        if self.cached_back is not None:
            return False, self.cached_back
        pts, transfer, normals = self.cached
        if self.back_method is not None and self.back_rows is not None:
            back = np.zeros_like(transfer)  # rows of members shaded on one side stay unused
            rows = self.back_rows
            back[rows] = self.back_method.update(self.local(pts[rows]), -normals[rows]).numpy()
        elif self.back_method is not None:  # on the whole group, computed at the two-sided members' rows only
            from ..visibility.reuse import update_rows

            back = update_rows(self.back_method, self.local(pts), -normals, self._two_rows).numpy().copy()
            back[self._one_rows] = 0.0  # rows of members shaded on one side stay unused
        else:
            back = unoccluded_transfer(-normals, self.order)
        if self.back_method is not None:
            back = fill_buried(back, self.edges, self._two_sided)
        self.cached_back = back
        return True, back


PROBE_RECEIVERS = 256
"""Receivers :func:`probe_transfer` computes per side where the method can compute a subset."""


def probe_transfer(spec: GroupSpec, order: int, receivers: int = PROBE_RECEIVERS, device: str = "cpu",
                   seed: int = 0) -> dict:
    """Measured transfer seconds per frame of one shading group on its rest pose, as the run builds it.

    The group is built as :meth:`SceneShader.build` builds it (its method, and the back-side method of
    two-sided members). A method that can compute a subset of receivers (``compute_rows``) is timed on
    one receiver and on ``receivers`` random ones (the least of five runs each, after an untimed warm-up
    that loads the kernels); the per-receiver slope times the receiver count plus the one-receiver time
    is its frame (all of them timed where there are at most twice ``receivers``). Any other method is
    timed on one full update after a warm-up update. Process CPU time, like the run's per-pass timings.

    Returns:
        ``{"front": s, "back": s or None, "build": s, "sampled": n or None}``: front and back transfer
        seconds per frame, the seconds the group took to build (untimed warm-up excluded), and the
        receivers sampled per side (None: full updates).
    """
    t0 = time.process_time()
    g = _Group(spec, order, device)
    build = time.process_time() - t0
    pts = g.rest.astype(np.float32)
    rng = np.random.default_rng(seed)
    out = {"front": 0.0, "back": None, "build": build, "sampled": None}
    normals = None
    if g._faces is not None:  # normals from every member's triangles, as _Group.update
        g._points.assign(pts)
        normals = vertex_normals(g._points, g._faces, out=g._normals).numpy().copy()

    def seconds(run, repeats: int = 5) -> float:
        """Least process CPU time of ``repeats`` runs (this VM's speed drifts by up to 1.5x for tens of ms)."""
        best = float("inf")
        for _ in range(repeats):
            t = time.process_time()
            run()
            wp.synchronize_device(device)
            best = min(best, time.process_time() - t)
        return best

    def timed(method, p, n, rows) -> float:
        # compute_rows computes every receiver in glossy mode or with interpolation: time a full frame there
        subset = hasattr(method, "compute_rows") and getattr(method, "mode", "diffuse") == "diffuse" and not getattr(
            method, "interpolate", 0.0)
        if not subset:
            method.update(p, n)  # warm-up
            return seconds(lambda: method.update(p, n), repeats=1)
        sample = rows if len(rows) <= 2 * receivers else rng.choice(rows, size=receivers, replace=False)
        sample = np.asarray(sample, dtype=np.int32)
        out["sampled"] = len(sample)

        def rows_of(k):
            def run():
                method.set_points(p, n)
                method.compute_rows(sample[:k])
            return run

        rows_of(len(sample))()  # warm-up: kernels loaded, scratch touched
        if len(sample) == len(rows):  # few receivers: timed all, as the run computes them
            return seconds(rows_of(len(sample)))
        one, many = seconds(rows_of(1)), seconds(rows_of(len(sample)))
        return one + max(0.0, (many - one) / (len(sample) - 1)) * (len(rows) - 1)

    if g.method is None:
        return out
    out["front"] = timed(g.method, pts, normals, np.arange(len(pts), dtype=np.int32))
    if g.back_method is not None:
        n_front = g.method.normals.numpy().copy() if normals is None else normals
        if g.back_rows is not None:
            rows = g.back_rows
            out["back"] = timed(g.back_method, pts[rows], -n_front[rows], np.arange(len(rows), dtype=np.int32))
        else:
            out["back"] = timed(g.back_method, pts, -n_front, g._two_rows)
    return out


@dataclass(frozen=True)
class Pass:
    """One pass of a frame in the pass graph (:meth:`SceneShader.passes`): what the run executes and the
    planner costs.

    Attributes:
        kind: One of :data:`PASS_KINDS`.
        group: Index of the shading group it works on (None: all groups at once).
        every_frame: Recomputed every frame; False: computed on the first frame and reused after
            (nothing it depends on moves).
    """

    kind: str
    group: int | None = None
    every_frame: bool = True

    @property
    def key(self) -> str:
        """``kind`` or ``kind[group]``: how the run reports the pass (``RunReport.passes``)."""
        return self.kind if self.group is None else f"{self.kind}[{self.group}]"


PASS_KINDS = ("transfer", "back transfer", "area", "back area", "between", "back between", "lights", "radiance",
              "back radiance", "reflections", "back reflections")
"""Kinds of passes: a group's transfer (its method, or the unoccluded lobe) and its back side's; GEARS
rect lights over all groups (front, back); sphere-set shadows from the other groups (front, back); the
lights' SH at the group's points; exit radiance (front, back); the one-bounce reflections (front, back)."""


@dataclass
class SceneShader:
    """Picklable description of how a scene is shaded (a :class:`warpshade.parallel.FrameShaderSpec`).

    Attributes:
        groups: Shading groups.
        order: SH order.
        fps: Frames per second (light motion is evaluated at ``frame / fps`` seconds).
        light_specs: UsdLux descriptions; empty means the default sky.
        up_axis: Stage up axis (for the default sky).
        lights: Ready :mod:`warpshade.lighting` objects instead of ``light_specs`` (must be
            picklable to shade in worker processes).
        write_transfer: Return the transfer too.
        device: Warp device.
        between: Shadows between shading groups: ``"spheres"`` (each group is shadowed by sphere sets
            fitted to every other group's shadow casters, thesis §4.2; visibilities multiply with the
            group's own, eq. 4.5) or None (groups do not shadow each other). Objects inside one group
            always shadow each other through the group's method (except objects that cast no shadows).
        reflections: One bounce of diffuse reflection between all shaded objects (sphere sets, thesis
            §4.3): None (off) or keyword arguments of :class:`~.reflections.SceneReflections`
            (``{}`` for its defaults). Each object's reflected irradiance times its ``albedo/π`` is
            added to its shadowed direct exit radiance (eq. 4.23); the reflecting surfaces use the
            same albedos.
        area_lights: Rect lights: ``"gears"`` (exact irradiance with GEARS soft shadows from every
            group, :mod:`.area`) or ``"sh"`` (projected to SH like the other local lights).
        area_knobs: :class:`~.area.AreaLightShading` keyword arguments (k, grid, weighting).
        reuse: Temporal reuse tolerance [rad] of every group's transfer
            (:class:`warpshade.visibility.reuse.TemporalReuse`), or None (recomputed every frame).
    """

    groups: list
    order: int
    fps: float = 60.0
    light_specs: list = field(default_factory=list)
    up_axis: str = "Y"
    lights: list | None = None
    write_transfer: bool = False
    device: str = "cpu"
    between: str | None = "spheres"
    reflections: dict | None = None
    area_lights: str = "gears"
    area_knobs: dict = field(default_factory=dict)
    reuse: float | None = None

    @classmethod
    def from_config(cls, config, scene, lights: list | None = None, device: str = "cpu",
                    reuse: float | None = None) -> SceneShader:
        """The shader of a :class:`~.config.RunConfig` on ``scene`` (``lights``: objects replacing the scene's;
        ``reuse``: temporal reuse tolerance [rad], or None)."""
        return cls(config.groups, config.order, scene.fps, list(scene.lights), scene.up_axis, lights,
                   config.write_transfer, device, config.between, config.reflections, config.area_lights,
                   dict(config.area_knobs), reuse)

    def build_lights(self) -> list:
        """The :mod:`warpshade.lighting` objects this spec shades with."""
        from .lights import default_lights, light_from_spec

        if self.lights is not None:
            return list(self.lights)
        if not self.light_specs:
            return default_lights(self.up_axis)
        return [light_from_spec(s, self.up_axis, self.fps) for s in self.light_specs]

    def _described_lights(self) -> list:
        """The lights as given: :mod:`warpshade.lighting` objects or scene ``LightSpec`` s."""
        return list(self.lights) if self.lights is not None else list(self.light_specs)

    def rect_lights(self) -> list[str]:
        """Names of the rect lights this spec shades (the lights' or the scene's)."""
        from .area import is_area_light

        return [li.name for li in self._described_lights() if is_area_light(li) or getattr(li, "kind", None) == "rect"]

    def passes(self) -> list[Pass]:
        """The pass graph of a frame, in execution order: which passes :meth:`build`'s ``shade`` runs and
        which of them it reuses after the first frame. The planner costs this list
        (:func:`warpshade.planner.make_plan`); a run reports the passes it computed per frame."""
        groups = self.groups
        casting = [i for i, g in enumerate(groups) if len(g.blocker_faces())]
        moving = [any(g.moving) for g in groups]
        two = [any(g.two_sided) for g in groups]
        lights = self._described_lights()
        lights_move = any(getattr(li, "motion", None) is not None for li in lights)
        out = []
        for i, g in enumerate(groups):
            out.append(Pass("transfer", i, moving[i]))
            if two[i]:
                out.append(Pass("back transfer", i, moving[i]))
        if self.area_lights == "gears" and self.rect_lights():
            from .area import is_area_light

            rect_moves = any(getattr(li, "motion", None) is not None for li in lights
                             if is_area_light(li) or getattr(li, "kind", None) == "rect")
            again = any(moving) or rect_moves
            out.append(Pass("area", None, again))
            if any(two):
                out.append(Pass("back area", None, again))
        between = self.between == "spheres" and len(groups) > 1
        for i in range(len(groups)):
            if between and any(j != i for j in casting):
                out.append(Pass("between", i))
                if two[i]:
                    out.append(Pass("back between", i))
            out.append(Pass("lights", i))
            out.append(Pass("radiance", i))
            if two[i]:
                out.append(Pass("back radiance", i))
        if self.reflections is not None:
            again = any(moving) or lights_move
            out.append(Pass("reflections", None, again))
            if any(two):
                out.append(Pass("back reflections", None, again))
        return out

    def build(self):
        """Build methods and lights; returns ``shade(frame, geometry) -> {name: (points, normals,
        colors, transfer or None)}``, for each two-sided object also ``{back_key(name): ...}`` (its back:
        the same points, negated normals, the back side's colours and transfer), plus the keys
        ``"_seconds"`` (time spent shading the frame), ``"_passes"`` (``{Pass.key: seconds}`` of the
        passes of :meth:`passes` computed this frame, reused ones left out) and, in the first result of
        this build, ``"_build_seconds"`` (method structures and lights). With :attr:`reuse`, ``shade.reset()``
        makes the next frame compute every receiver, as the first one does (a chunk's start,
        :func:`warpshade.parallel.shade_frames`)."""
        from ..lighting import lights_sh
        from ..radiance import exit_radiance

        t_build = time.perf_counter()
        from ..visibility.rays import local_origin

        origin = local_origin(np.concatenate([m.points for g in self.groups for m in g.meshes]))
        groups = [_Group(g, self.order, self.device, self.reuse, origin) for g in self.groups]
        if self.between not in (None, "spheres"):
            raise ValueError(f"between-group shadows must be 'spheres' or None, got {self.between!r}")
        between = (_between_group_shadows(groups, self.order, self.device)
                   if self.between == "spheres" and len(groups) > 1 else None)
        bounce = None
        if self.reflections is not None:
            from .reflections import SceneReflections

            bounce = SceneReflections([m for g in groups for m in g.spec.meshes], self.order, self.device,
                                      **self.reflections)
        lights = self.build_lights()
        area = _area_shading(self, groups, lights)
        # a second GEARS pass for the back sides (its own frame-0 cache when nothing moves)
        area_back = _area_shading(self, groups, lights) if area is not None and any(g.two_sided for g in groups) else None
        if area is not None:
            lights = [li for li in lights if not any(li is a for a in area.lights)]
        pending_build = [time.perf_counter() - t_build]  # reported once, with the first frame
        bounce_cache = {}
        graph = self.passes()
        write_transfer, device, order = self.write_transfer, self.device, self.order

        def shade(frame: int, geometry: dict) -> dict:
            t0 = time.perf_counter()
            out = {"_build_seconds": pending_build.pop()} if pending_build else {}
            t = frame / self.fps
            frame_lights = [light.at_time(t) for light in lights]
            # per group: points, transfer, normals, back transfer (None: one-sided), lights' SH (distant, local)
            state = [[None, None, None, None, None] for _ in groups]
            area_e = {}  # "area" / "back area" -> per group (V_g, 3) irradiance
            direct = []  # per object: [name, points, normals, radiance, transfer or None, albedo]

            def run(p: Pass) -> bool:
                i = p.group
                if p.kind == "transfer":
                    computed, (pts, tr, nrm) = groups[i].update(geometry)
                    state[i][:3] = [pts, tr, nrm]
                    return computed
                if p.kind == "back transfer":
                    computed, state[i][3] = groups[i].update_back()
                    return computed
                if p.kind in ("area", "back area"):
                    shading = area if p.kind == "area" else area_back
                    computed = shading._cached is None
                    normals = [st[2] if p.kind == "area" or not g.two_sided else -st[2] for g, st in zip(groups, state)]
                    area_e[p.kind] = shading.irradiance(t, [st[0] for st in state], normals)
                    return computed
                if p.kind in ("between", "back between"):
                    pts, tr, nrm, back, _ = state[i]
                    if p.kind == "between":
                        state[i][1] = _shadow_by_others(between[i], i, pts, tr, nrm, state, device, groups[i].local)
                    else:
                        state[i][3] = _shadow_by_others(between[i], i, pts, back, -nrm, state, device,
                                                        groups[i].local)
                    return True
                if p.kind == "lights":
                    state[i][4] = lights_sh(frame_lights, order, state[i][0])
                    return True
                if p.kind in ("radiance", "back radiance"):
                    g = groups[i]
                    pts, tr, nrm, back, (distant, local) = state[i]
                    side = p.kind == "back radiance"
                    if side:
                        tr, nrm = back, -nrm
                    e = area_e.get("back area" if side else "area")
                    for k, (name, albedo) in enumerate(zip(g.spec.names, g.spec.albedos)):
                        if side and not g.spec.two_sided[k]:
                            continue
                        a, b = g.offsets[k], g.offsets[k + 1]
                        # clamped at 0: SH ringing behind bright lights must not make displayColor negative
                        rad = exit_radiance(tr[a:b], distant, albedo, None if local is None else local[a:b],
                                            device=device).numpy().copy()
                        if e is not None:  # GEARS-shadowed rect lights, (ρ/π) E (module .area)
                            rad += (albedo / np.pi * e[i][a:b]).astype(np.float32)
                        direct.append([back_key(name) if side else name, pts[a:b], nrm[a:b], rad,
                                       tr[a:b] if write_transfer else None, albedo])
                    return True
                if p.kind in ("reflections", "back reflections"):
                    # One bounce (thesis §4.3): the reflectors' samples take the direct exit radiance just shaded
                    # (every light, the group's own visibility method), the second pass sums sphere by sphere.
                    # Back sides get a second bounce in which every two-sided object is its back side (flipped
                    # normals, back-side radiance) and the others are as in the first.
                    fronts = [d for d in direct if not isinstance(d[0], tuple)]
                    if p.kind == "reflections":
                        seen, targets = fronts, fronts
                    else:
                        backs = {d[0][1]: d for d in direct if isinstance(d[0], tuple)}
                        seen, targets = [backs.get(d[0], d) for d in fronts], [backs.get(d[0]) for d in fronts]
                    key = "front" if p.kind == "reflections" else "back"
                    e_r = bounce_cache.get(key)
                    computed = e_r is None
                    if computed:
                        e_r = bounce.update([d[1] for d in seen], [d[2] for d in seen], None,
                                            [d[5] for d in seen], exit_radiance=[d[3] for d in seen])
                    if not p.every_frame:
                        bounce_cache[key] = e_r
                    for k, d in enumerate(targets):
                        if d is not None:
                            # eq. 4.23: reflected exit radiance (ρ/π) E_R added to the shadowed direct one
                            d[3] += (np.asarray(d[5], dtype=np.float32) / np.float32(np.pi)) * bounce.slice(e_r, k)
                    return computed
                raise ValueError(f"unknown pass {p.kind!r}")

            done = {}
            for p in graph:
                tp = time.perf_counter()
                if run(p):
                    done[p.key] = time.perf_counter() - tp
            for name, pts, normals, rad, transfer, _ in direct:
                out[name] = (pts, normals, rad, transfer)
            wp.synchronize()
            out["_passes"] = done
            out["_seconds"] = time.perf_counter() - t0
            return out

        if self.reuse is not None:  # temporal reuse keeps state: a chunk of frames starts afresh
            def reset():
                for g in groups:
                    g.reset_reuse()

            shade.reset = reset
        return shade


def _area_shading(spec: SceneShader, groups: list, lights: list):
    """The :class:`~.area.AreaLightShading` of a build, or None (``--area-lights sh`` or no rect light)."""
    from .area import AREA_MODES, AreaLightShading, split_area_lights

    if spec.area_lights not in AREA_MODES:
        raise ValueError(f"area lights must be one of {', '.join(AREA_MODES)}, got {spec.area_lights!r}")
    rect = split_area_lights(lights)[1]
    if spec.area_lights == "sh" or not rect:
        return None
    return AreaLightShading([g.mesh for g in groups], rect, static=not any(g.any_moving for g in groups),
                            device=spec.device, blocker_faces=[g.blocker_faces for g in groups], **spec.area_knobs)


def _between_group_shadows(groups: list, order: int, device: str) -> list:
    """Per group, ``(spheres, others)``: a :class:`~warpshade.visibility.spheres.SpheresTransfer` whose
    blockers are the sphere trees of the shadow casters of the groups ``others`` (every other group with
    one; each tree fitted once, on the group's rest pose), or None when no other group casts shadows."""
    from ..visibility import get_method
    from ..visibility.spheres.fitting import build_sphere_tree

    spheres = get_method("spheres")

    # vertices of members that cast no shadows are in no triangle of blocker_faces: no sphere bounds them
    # in the groups' common local coordinates (_Group.local), as their methods
    trees = [build_sphere_tree(g.local(g.rest), g.blocker_faces, device=device) if len(g.blocker_faces) else None
             for g in groups]
    out = []
    for i, g in enumerate(groups):
        others = [j for j in range(len(groups)) if j != i and trees[j] is not None]
        mesh = g.mesh if g.origin is None else TriMesh(g.local(g.rest), g.mesh.faces, name=g.mesh.name)
        out.append((spheres(mesh, order=order, device=device, self_shadow=False,
                            blockers=[(trees[j], groups[j].local(groups[j].rest)) for j in others]), others)
                   if others else None)
    return out


def _shadow_by_others(between, i: int, pts, transfer, normals, updated: list, device: str, local=None) -> np.ndarray:
    """Group ``i``'s ``transfer`` (one side: ``normals`` are that side's) times the visibility of the other
    casting groups' spheres this frame (``between``: its entry of :func:`_between_group_shadows`); ``local``
    maps world points to the groups' common coordinates (:meth:`_Group.local`)."""
    if between is None:
        return transfer
    spheres, others = between
    local = local or (lambda p: p)
    spheres.update(local(pts), normals, blocker_points=[local(updated[j][0]) for j in others])
    out = spheres.shadow(wp.array(transfer, dtype=float, device=device))
    return out.numpy().copy()


def back_key(name: str) -> tuple:
    """Key of an object's back side in a ``shade`` result (the front's key is ``name``)."""
    return ("back", name)


__all__ = ["BACK_PASS_WITH_OCCLUDERS", "BURIED", "buried_dc", "PROBE_RECEIVERS", "probe_transfer", "TWO_SIDED_MODES", "GroupSpec", "SceneShader", "back_key", "back_side_receivers", "fill_buried", "flipped", "group_objects", "is_two_sided",
           "unoccluded_transfer"]
