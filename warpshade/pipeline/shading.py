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

from ..geometry.mesh import TriMesh
from ..geometry.normals import vertex_normals
from ..sh.zonal import clamped_cosine_zh, zh_rotate


def unoccluded_transfer(normals: np.ndarray, order: int) -> np.ndarray:
    """Transfer of an unshadowed vertex (docs/conventions.md §2): the clamped-cosine lobe rotated to the
    normal, ``sqrt(4π/(2l+1)) A_l y_lm(n)``.

    Returns:
        Shape (V, N*N), float32.
    """
    return zh_rotate(clamped_cosine_zh(order), normals).astype(np.float32)


@dataclass
class GroupSpec:
    """Objects shaded as one receiver mesh (they shadow each other) by one visibility method.

    Attributes:
        method: A ``warpshade.visibility.METHODS`` name, or None for unshadowed (analytic) transfer.
        knobs: Method keyword arguments.
        names: Object names, in order.
        meshes: Their rest meshes (topology fixed).
        albedos: Their albedos, linear RGB, shape (3,) each.
        moving: Whether each object moves (static objects keep their rest points).
        casts: Whether each object casts shadows (``warpshade:castsShadows``; empty: all do). An object
            that does not is a receiver only: its triangles block no light in any pass (not even its own).
        two_sided: Whether each object is shaded on both sides (:func:`is_two_sided`; empty: none is).
    """

    method: str | None
    knobs: dict
    names: list = field(default_factory=list)
    meshes: list = field(default_factory=list)
    albedos: list = field(default_factory=list)
    moving: list = field(default_factory=list)
    casts: list = field(default_factory=list)
    two_sided: list = field(default_factory=list)

    def blocker_faces(self) -> np.ndarray:
        """Triangles of the members that cast shadows, indexed into the merged group mesh, shape (F_c, 3), int32."""
        offsets = np.cumsum([0] + [m.num_vertices for m in self.meshes])
        casts = self.casts or [True] * len(self.meshes)
        parts = [m.faces + off for m, off, c in zip(self.meshes, offsets[:-1], casts) if c]
        return np.concatenate(parts).astype(np.int32) if parts else np.zeros((0, 3), np.int32)


TWO_SIDED_MODES = ("auto", "on", "off")
"""Values of the two-sided knob (``warpshade run --two-sided``, ``Pipeline(two_sided=...)``)."""


def is_two_sided(obj, mode: str = "auto") -> bool:
    """Whether a :class:`warpshade.scene.SceneObject` is shaded on both sides: ``"on"`` every object,
    ``"off"`` none, ``"auto"`` its ``two_sided`` (``warpshade:twoSided``) if set, else cloth only.

    Raises:
        ValueError: for a mode not in :data:`TWO_SIDED_MODES`.
    """
    if mode not in TWO_SIDED_MODES:
        raise ValueError(f"two-sided must be one of {', '.join(TWO_SIDED_MODES)}, got {mode!r}")
    if mode != "auto":
        return mode == "on"
    return bool(obj.two_sided) if obj.two_sided is not None else obj.kind == "cloth"


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

    def __init__(self, spec: GroupSpec, order: int, device: str, reuse: float | None = None):
        self.spec, self.order = spec, order
        self.offsets = np.cumsum([0] + [m.num_vertices for m in spec.meshes])
        faces = np.concatenate([m.faces + off for m, off in zip(spec.meshes, self.offsets[:-1])])
        self.rest = np.concatenate([m.points for m in spec.meshes])
        self.mesh = TriMesh(self.rest, faces, name=f"group[{', '.join(spec.names)}]")
        """Receivers: every member's vertices and triangles (normals come from all of them)."""
        self.blocker_faces = spec.blocker_faces()
        """Triangles that block light (members casting shadows), shape (F_c, 3), int32."""
        receivers_only = len(self.blocker_faces) < len(faces)
        self.any_moving = any(spec.moving)
        self.cached = None
        self.method = None
        if spec.method is not None and len(self.blocker_faces):
            from ..visibility import get_method

            # Members that cast no shadows keep their vertices (receivers, with the normals of their own
            # triangles, passed in update) but lose their triangles from the method's mesh, so every
            # method sees them as points that block nothing.
            mesh = self.mesh if not receivers_only else TriMesh(
                self.rest, self.blocker_faces, normals=self.mesh.normals, name=f"{self.mesh.name} casters")
            self.method = get_method(spec.method)(mesh, order=order, device=device, **spec.knobs)
        self.back_method = None
        self.back_rows = None
        """Group rows the back method receives at (None: all of them)."""
        self.two_sided = any(spec.two_sided)
        if self.two_sided and self.method is not None:
            self._build_back_method(type(self.method), order, device)
        if reuse is not None:  # temporal reuse (warpshade.visibility.reuse), both sides alike
            from ..visibility.reuse import with_reuse

            self.method, self.back_method = with_reuse(self.method, reuse), with_reuse(self.back_method, reuse)
        two = np.zeros(len(self.rest), dtype=bool)
        for k, t in enumerate(spec.two_sided):
            two[self.offsets[k]:self.offsets[k + 1]] = bool(t)
        self._two_rows, self._one_rows = np.flatnonzero(two).astype(np.int32), np.flatnonzero(~two)
        """Group rows of the two-sided members (the back pass's receivers) and of the others."""
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
                return TriMesh(np.concatenate([spec.meshes[k].points for k in ks]),
                               np.concatenate([spec.meshes[k].faces + o for k, o in zip(ks, offs[:-1])]), name=name)

            blockers = [k for k in range(len(spec.meshes)) if k not in two and casts[k]]
            self.back_rows = np.concatenate([np.arange(self.offsets[k], self.offsets[k + 1]) for k in two])
            occluders = [flipped(merged(blockers, f"{self.mesh.name} blockers"))] if blockers else []
            self.back_method = cls(flipped(merged(two, f"{self.mesh.name} two-sided")), order=order, device=device,
                                   occluders=occluders, **spec.knobs)
        else:
            self.back_method = cls(flipped(self.method.mesh), order=order, device=device, **spec.knobs)

    def update(self, geometry: dict) -> tuple:
        """Points (V, 3), transfer (V, N*N), unit normals (V, 3) and back-side transfer (V, N*N; None
        without two-sided members) of the group this frame."""
        if self.cached is not None and not self.any_moving:
            return self.cached  # nothing in the group moves: transfer computed once
        pts = np.concatenate([geometry[n] if mv else self.rest[a:b] for n, mv, a, b in
                              zip(self.spec.names, self.spec.moving, self.offsets[:-1], self.offsets[1:])])
        pts = pts.astype(np.float32)
        normals = None
        if self._faces is not None:  # normals from every member's triangles, blocking or not
            self._points.assign(pts)
            normals = vertex_normals(self._points, self._faces, out=self._normals)
        if self.method is not None:
            transfer = self.method.update(pts, normals).numpy().copy()  # the next update overwrites it
            normals = self.method.normals.numpy().copy()
        else:
            normals = normals.numpy().copy()
            transfer = unoccluded_transfer(normals, self.order)
        back = None
        if self.back_method is not None and self.back_rows is not None:
            back = np.zeros_like(transfer)  # rows of members shaded on one side stay unused
            rows = self.back_rows
            back[rows] = self.back_method.update(pts[rows], -normals[rows]).numpy()
        elif self.back_method is not None:  # on the whole group, computed at the two-sided members' rows only
            from ..visibility.reuse import update_rows

            back = update_rows(self.back_method, pts, -normals, self._two_rows).numpy().copy()
            back[self._one_rows] = 0.0  # rows of members shaded on one side stay unused
        elif self.two_sided:
            back = unoccluded_transfer(-normals, self.order)
        self.cached = (pts, transfer, normals, back)
        return self.cached


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

    def build_lights(self) -> list:
        """The :mod:`warpshade.lighting` objects this spec shades with."""
        from .lights import default_lights, light_from_spec

        if self.lights is not None:
            return list(self.lights)
        if not self.light_specs:
            return default_lights(self.up_axis)
        return [light_from_spec(s, self.up_axis) for s in self.light_specs]

    def build(self):
        """Build methods and lights; returns ``shade(frame, geometry) -> {name: (points, normals,
        colors, transfer or None)}``, for each two-sided object also ``{back_key(name): ...}`` (its back:
        the same points, negated normals, the back side's colours and transfer), plus the keys
        ``"_seconds"`` (time spent shading the frame) and, in the first result of this build,
        ``"_build_seconds"`` (method structures and lights)."""
        from ..lighting import lights_sh
        from ..radiance import exit_radiance

        t_build = time.perf_counter()
        groups = [_Group(g, self.order, self.device, self.reuse) for g in self.groups]
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
        # nothing moves and no light moves (rect lights included): the bounce of the first frame holds
        # for every frame
        frozen = (not any(g.any_moving for g in groups)
                  and not any(getattr(light, "motion", None) is not None for light in lights))
        area = _area_shading(self, groups, lights)
        # a second GEARS pass for the back sides (its own frame-0 cache when nothing moves)
        area_back = _area_shading(self, groups, lights) if area is not None and any(g.two_sided for g in groups) else None
        if area is not None:
            lights = [li for li in lights if not any(li is a for a in area.lights)]
        pending_build = [time.perf_counter() - t_build]  # reported once, with the first frame
        bounce_cache = {}

        def shade(frame: int, geometry: dict) -> dict:
            t0 = time.perf_counter()
            out = {"_build_seconds": pending_build.pop()} if pending_build else {}
            t = frame / self.fps
            frame_lights = [light.at_time(t) for light in lights]
            updated = [g.update(geometry) for g in groups]
            direct = []  # per object: (name, points, normals, radiance, transfer or None, albedo)
            area_e = None if area is None else area.irradiance(t, [u[0] for u in updated], [u[2] for u in updated])
            area_b = None if area_back is None else area_back.irradiance(
                t, [u[0] for u in updated], [-u[2] if g.two_sided else u[2] for g, u in zip(groups, updated)])
            for i, g in enumerate(groups):
                pts, transfer, normals, back = updated[i]
                if between is not None:
                    transfer = _shadow_by_others(between[i], i, pts, transfer, normals, updated, self.device)
                    if back is not None:
                        back = _shadow_by_others(between[i], i, pts, back, -normals, updated, self.device)
                distant, local = lights_sh(frame_lights, self.order, pts)
                sides = [(transfer, normals, area_e, "")] + ([(back, -normals, area_b, "back")] if back is not None else [])
                for k, (name, albedo) in enumerate(zip(g.spec.names, g.spec.albedos)):
                    a, b = g.offsets[k], g.offsets[k + 1]
                    for tr, nrm, e, side in sides:
                        if side and not g.spec.two_sided[k]:
                            continue
                        # clamped at 0: SH ringing behind bright lights must not make displayColor negative
                        rad = exit_radiance(tr[a:b], distant, albedo, None if local is None else local[a:b],
                                            device=self.device).numpy().copy()
                        if e is not None:  # GEARS-shadowed rect lights, (ρ/π) E (module .area)
                            rad += (albedo / np.pi * e[i][a:b]).astype(np.float32)
                        direct.append([back_key(name) if side else name, pts[a:b], nrm[a:b], rad,
                                       tr[a:b] if self.write_transfer else None, albedo])
            if bounce is not None:
                # One bounce (thesis §4.3): the reflectors' samples take the direct exit radiance just shaded
                # (every light, the group's own visibility method), the second pass sums sphere by sphere.
                # Back sides get a second bounce in which every two-sided object is its back side (flipped
                # normals, back-side radiance) and the others are as in the first.
                fronts = [d for d in direct if not isinstance(d[0], tuple)]
                backs = {d[0][1]: d for d in direct if isinstance(d[0], tuple)}
                passes = [("front", fronts, fronts)]
                if backs:
                    passes.append(("back", [backs.get(d[0], d) for d in fronts], [backs.get(d[0]) for d in fronts]))
                for key, seen, targets in passes:
                    e_r = bounce_cache.get(key)
                    if e_r is None:
                        e_r = bounce.update([d[1] for d in seen], [d[2] for d in seen], None,
                                            [d[5] for d in seen], exit_radiance=[d[3] for d in seen])
                    if frozen:
                        bounce_cache[key] = e_r
                    for k, d in enumerate(targets):
                        if d is not None:
                            # eq. 4.23: reflected exit radiance (ρ/π) E_R added to the shadowed direct one
                            d[3] += (np.asarray(d[5], dtype=np.float32) / np.float32(np.pi)) * bounce.slice(e_r, k)
            for name, pts, normals, rad, transfer, _ in direct:
                out[name] = (pts, normals, rad, transfer)
            wp.synchronize()
            out["_seconds"] = time.perf_counter() - t0
            return out

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
    from ..visibility.spheres.fitting import build_sphere_tree
    from ..visibility.spheres.method import SpheresTransfer

    # vertices of members that cast no shadows are in no triangle of blocker_faces: no sphere bounds them
    trees = [build_sphere_tree(g.rest, g.blocker_faces, device=device) if len(g.blocker_faces) else None
             for g in groups]
    out = []
    for i, g in enumerate(groups):
        others = [j for j in range(len(groups)) if j != i and trees[j] is not None]
        out.append((SpheresTransfer(g.mesh, order=order, device=device, self_shadow=False,
                                    blockers=[(trees[j], groups[j].rest) for j in others]), others) if others else None)
    return out


def _shadow_by_others(between, i: int, pts, transfer, normals, updated: list, device: str) -> np.ndarray:
    """Group ``i``'s ``transfer`` (one side: ``normals`` are that side's) times the visibility of the other
    casting groups' spheres this frame (``between``: its entry of :func:`_between_group_shadows`)."""
    if between is None:
        return transfer
    spheres, others = between
    spheres.update(pts, normals, blocker_points=[updated[j][0] for j in others])
    out = spheres.shadow(wp.array(transfer, dtype=float, device=device))
    return out.numpy().copy()


def back_key(name: str) -> tuple:
    """Key of an object's back side in a ``shade`` result (the front's key is ``name``)."""
    return ("back", name)


def group_objects(objects, method: str | None = None, knobs: dict | None = None,
                  default_knobs: dict | None = None, default_albedo=None, two_sided: str = "auto") -> list[GroupSpec]:
    """Group shaded objects by (method, knobs). A group none of whose members casts shadows
    (``casts_shadows`` False) gets method None: nothing in it blocks light, so its transfer is unoccluded.

    Args:
        objects: :class:`warpshade.scene.SceneObject` list.
        method: Override every object's method (``--method``), or None to use each object's.
        knobs: Knobs with ``method``.
        default_knobs: Method name -> knobs used when an object names a method but no knobs.
        default_albedo: Albedo (scalar or RGB) of objects whose material's albedo was not authored
            (``Material.albedo_authored``), or None to keep the material's default.
        two_sided: Which objects are shaded on both sides (:func:`is_two_sided`).
    """
    by_key: dict = {}
    for obj in objects:
        if not obj.shaded:
            continue
        if method is not None:
            name, kn = method, dict(knobs or {})
        else:
            name, kn = obj.method, dict(obj.knobs)
            if name is not None and not kn:
                kn = dict((default_knobs or {}).get(name, {}))
        key = (name, tuple(sorted(kn.items())))
        g = by_key.setdefault(key, GroupSpec(name, kn))
        g.names.append(obj.name)
        g.meshes.append(obj.mesh)
        albedo = obj.material.albedo
        if default_albedo is not None and not obj.material.albedo_authored:
            albedo = np.broadcast_to(np.asarray(default_albedo, dtype=np.float64), (3,))
        g.albedos.append(np.array(albedo, dtype=np.float64))
        g.moving.append(obj.kind != "static")
        g.casts.append(bool(obj.casts_shadows))
        g.two_sided.append(is_two_sided(obj, two_sided))
    for g in by_key.values():
        if g.method is not None and not any(g.casts):
            # nothing in the group blocks light (castsShadows false on every member): its own transfer is the
            # unoccluded one whatever the method; it stays a group of its own, so other groups' sphere sets
            # still shadow it
            g.method, g.knobs = None, {}
    return list(by_key.values())


__all__ = ["BACK_PASS_WITH_OCCLUDERS", "TWO_SIDED_MODES", "GroupSpec", "SceneShader", "back_key", "back_side_receivers", "flipped", "group_objects", "is_two_sided",
           "unoccluded_transfer"]
