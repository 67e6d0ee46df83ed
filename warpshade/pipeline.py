"""The main job: simulate, shade and write a scene, one frame at a time (``warpshade run``).

Data flows one way (STYLE.md): per frame each object's positions come from the simulation (cloth),
from skinning or time samples (skinned, animated) or stay put (static); each *shading group* — the
objects that share a visibility method and its knobs — is one receiver mesh, so its members shadow
each other (with ``reference``: exactly, ray traced); the group's :class:`TransferMethod` updates the
SH transfer (CONTRACTS.md §2); exit radiance ``(ρ/π) Σ_i L_i T_i`` uses the lights' SH (world space);
the writer streams the frame out.

No ``pxr`` here: the scene arrives as a :class:`warpshade.scene.Scene` and the output goes to any
object with the :class:`warpshade.usd.AnimationWriter` methods.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
import warp as wp

from .geometry.mesh import TriMesh
from .geometry.normals import vertex_normals
from .scene import LightSpec, Scene, SceneError, SceneObject
from .sh.basis import check_order
from .sh.zonal import clamped_cosine_zh, zh_rotate

METHOD_PREFERENCE = ("hemiraster", "spheres", "disks", "reference")
"""Default visibility method: the first of these that is registered (fastest accurate first)."""

DEFAULT_KNOBS = {"reference": {"rays": 256}}
"""Knobs a run uses when the scene and the command line give none (reference: 256 rays ≈ 3.5 %
relative L2 error, measured in the README's reference section)."""

DEFAULT_ORDER = 4
"""SH order of a run unless the scene (``warpshade:order``) or ``--order`` says otherwise."""


def default_method() -> str:
    """The method a run uses when neither the scene nor the command line names one."""
    from .visibility import METHODS

    return next(m for m in METHOD_PREFERENCE if m in METHODS)


@dataclass
class RunReport:
    """What a run did and how long each stage took.

    Attributes:
        path: Output file.
        frames: Frames written.
        seconds: Wall time per stage [s]: ``load``, ``setup`` (method structures, simulation model,
            lights), ``simulate``, ``shade``, ``write``, ``total``.
        vertices: Shaded vertices per frame.
        groups: One line per shading group (method, knobs, objects).
    """

    path: str
    frames: int
    seconds: dict = field(default_factory=dict)
    vertices: int = 0
    groups: list = field(default_factory=list)


class _Group:
    """Objects shaded together by one visibility method (or unoccluded when ``method`` is None)."""

    def __init__(self, method: str | None, knobs: dict, objects: list[SceneObject], order: int, device: str):
        self.method_name, self.knobs, self.objects, self.order = method, knobs, objects, order
        self.offsets = np.cumsum([0] + [o.mesh.num_vertices for o in objects])
        faces = np.concatenate([o.mesh.faces + off for o, off in zip(objects, self.offsets[:-1])])
        points = np.concatenate([o.mesh.points for o in objects])
        name = f"group[{', '.join(o.name for o in objects)}]"
        self.mesh = TriMesh(points, faces, name=name)
        self.moving = any(o.kind != "static" for o in objects)
        self.method = None
        self.transfer_np = None
        if method is not None:
            from .visibility import get_method

            self.method = get_method(method)(self.mesh, order=order, device=device, **knobs)
        else:
            self._faces = wp.array(faces, dtype=wp.int32, device=device)
            self._points = wp.array(points, dtype=wp.vec3, device=device)
            self._normals = wp.zeros(len(points), dtype=wp.vec3, device=device)

    def update(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Transfer (V, N*N) and unit normals (V, 3) for the group's current points."""
        if self.transfer_np is not None and not self.moving:
            return self.transfer_np, self.normals_np  # nothing moved: reuse (static groups)
        if self.method is not None:
            self.transfer_np = self.method.update(points).numpy()
            self.normals_np = self.method.normals.numpy()
        else:
            self._points.assign(points)
            self.normals_np = vertex_normals(self._points, self._faces, out=self._normals).numpy()
            self.transfer_np = unoccluded_transfer(self.normals_np, self.order)
        return self.transfer_np, self.normals_np


def unoccluded_transfer(normals: np.ndarray, order: int) -> np.ndarray:
    """Transfer of an unshadowed vertex (CONTRACTS.md §2): the clamped-cosine lobe rotated to the
    normal, ``sqrt(4π/(2l+1)) A_l y_lm(n)``.

    Returns:
        Shape (V, N*N), float32.
    """
    return zh_rotate(clamped_cosine_zh(order), normals).astype(np.float32)


def exit_radiance(transfer: np.ndarray, albedo: np.ndarray, distant: np.ndarray,
                  local: np.ndarray | None = None) -> np.ndarray:
    """Lambertian exit radiance ``(ρ/π) Σ_i L_i T_i`` (CONTRACTS.md §2).

    Args:
        transfer: Shape (V, N*N).
        albedo: Linear RGB, shape (3,) or (V, 3).
        distant: Distant lights' SH, shape (N*N, 3).
        local: Per-vertex SH of local lights, shape (V, N*N, 3), or None.

    Returns:
        Linear RGB radiance, shape (V, 3), float32, clamped at 0 (SH ringing can dip below).
    """
    lit = transfer @ distant
    if local is not None:
        lit = lit + np.einsum("vi,vic->vc", transfer, local)
    return np.maximum(np.asarray(albedo) / math.pi * lit, 0.0).astype(np.float32)


def lights_for(scene: Scene) -> list:
    """The scene's lights as :mod:`warpshade.lighting` objects; the default sky if it has none."""
    try:
        from . import lighting
    except ImportError as exc:
        raise SceneError(f"{scene.source}: shading needs warpshade.lighting, which is not installed yet ({exc})") from None
    if not scene.lights:
        return [lighting.default_environment(up=scene.up_axis)]
    return [light_from_spec(spec, scene.up_axis) for spec in scene.lights]


def sky_light_specs(sky, image_path: str, up: str = "Y", height: int = 128) -> list[LightSpec]:
    """UsdLux descriptions of an analytic :class:`warpshade.lighting.Sky` for the output file: a
    DomeLight with the sky rendered to a lat-long image (written to ``image_path``) and a normalized
    DistantLight for the sun (the 0.53° disc is far smaller than a texel, so it is not in the image).
    """
    from .lighting import up_frame, write_image
    from .sh.projection import latlong_directions

    frame = up_frame(up)
    dirs = latlong_directions(height, 2 * height).reshape(-1, 3) @ frame.T  # map frame -> world
    sun = np.asarray(sky.sun_direction, dtype=np.float64)
    half = math.radians(0.53) / 2
    in_sun = dirs @ sun >= math.cos(half)
    if in_sun.any():  # a texel centre inside the disc: sample the sky just beside it instead
        perp = np.cross(sun, frame[:, 0] if abs(sun @ frame[:, 0]) < 0.9 else frame[:, 2])
        nudged = dirs[in_sun] + 0.03 * perp / np.linalg.norm(perp)
        dirs[in_sun] = nudged / np.linalg.norm(nudged, axis=1, keepdims=True)
    image = sky.radiance(dirs).reshape(height, 2 * height, 3)
    write_image(image_path, image)
    # the sun's frame: +Z towards the sun (a DistantLight shines along its -Z)
    x = np.cross(frame[:, 1], sun)
    x = x / np.linalg.norm(x) if np.linalg.norm(x) > 1e-9 else frame[:, 0]
    xf = np.eye(4)
    xf[:3, 0], xf[:3, 1], xf[:3, 2] = x, np.cross(sun, x), sun
    irradiance = np.asarray(sky.sun_radiance) * math.pi * math.sin(half) ** 2
    return [LightSpec("dome", "DefaultSky", texture=image_path, transform=np.eye(4) if up.upper() == "Y" else
                      np.block([[frame, np.zeros((3, 1))], [np.zeros((1, 3)), np.ones((1, 1))]])),
            LightSpec("distant", "DefaultSun", color=irradiance, normalize=True, angle=0.53, transform=xf)]


def light_from_spec(spec: LightSpec, up: str = "Y"):
    """A :mod:`warpshade.lighting` light from a UsdLux description (mapping documented in
    :mod:`warpshade.lighting.lights`: ``L = color · intensity · 2^exposure``; with ``normalize`` the
    power is independent of size, so radiance is divided by the emitting area, and a distant light
    gives irradiance)."""
    from . import lighting

    L = spec.radiance
    xf = spec.transform
    rot = xf[:3, :3] / np.maximum(np.linalg.norm(xf[:3, :3], axis=0), 1e-300)
    name = spec.name
    if spec.kind == "dome":
        if spec.texture:
            # UsdLux DomeLight (schema version 0, no poleAxis): the map's +Y pole is the dome prim's
            # +Y, so the prim's rotation alone orients it, whatever the stage's up axis.
            return lighting.EnvironmentMap.from_file(spec.texture, intensity=L, up="Y", rotation=rot, name=name)
        return lighting.ConstantEnvironment(radiance=L, name=name)
    if spec.kind == "distant":
        towards = xf[:3, 2]  # UsdLux: the light shines along its -Z
        if spec.normalize or spec.angle <= 0:
            return lighting.DirectionalLight(direction=towards, irradiance=L, angle=max(spec.angle, 0.0), name=name)
        return lighting.DirectionalLight.from_radiance(towards, L, angle=spec.angle, name=name)
    if spec.kind == "sphere":
        scale = float(np.cbrt(abs(np.linalg.det(xf[:3, :3]))))
        r = spec.radius * scale
        light = lighting.SphereLight(position=spec.position, radius=r,
                                     radiance=L / (4 * math.pi * r * r) if spec.normalize else L, name=name)
        return light.as_point() if spec.treat_as_point else light
    if spec.kind == "rect":
        u, v = xf[:3, 0] * spec.width / 2, xf[:3, 1] * spec.height / 2
        area = 4 * float(np.linalg.norm(np.cross(u, v)))
        return lighting.RectLight(center=spec.position, u=u, v=v, radiance=L / area if spec.normalize else L, name=name)
    raise SceneError(f"{spec.name}: light kind '{spec.kind}' is not supported")


CLOTH_PARAMS = {"density": "density", "stretchStiffness": "stretch_stiffness", "bendStiffness": "bend_stiffness"}
"""``warpshade:cloth:*`` attributes passed per piece to :meth:`warpshade.sim.ClothBuilder.add_mesh`."""
CLOTH_GLOBAL = {"damping": "damping", "thickness": "thickness"}
"""``warpshade:cloth:*`` attributes that are builder-wide (taken from the first cloth object)."""


class ClothSimulation:
    """Every cloth object of a scene in one :mod:`warpshade.sim` model, with the scene's colliders.

    Colliders (``warpshade:collider``): ``ground`` -> a plane at the mesh's mean height facing up;
    ``sphere`` -> the analytic sphere of a Sphere prim; ``mesh`` -> the triangle mesh. Pins
    (``warpshade:pinned``) are fixed; ``warpshade:wind`` on the default prim blows on all cloth.
    Frame 0 is the rest pose; each later frame advances one step of ``1/fps`` seconds.
    """

    def __init__(self, scene: Scene, device: str = "cpu"):
        try:
            from .sim import ClothBuilder, ClothControl, ColliderSet, XPBDSolver  # noqa: F401
        except ImportError as exc:
            name = next(o.name for o in scene.objects if o.kind == "cloth")
            raise SceneError(f"{scene.source}: {name} is cloth, and cloth needs warpshade.sim, which is not "
                             f"installed yet ({exc})") from None
        cloth = [o for o in scene.objects if o.kind == "cloth"]
        first = cloth[0].params.get("cloth", {})
        builder = ClothBuilder(**{k2: float(first[k]) for k, k2 in CLOTH_GLOBAL.items() if k in first})
        self.ranges = {}
        friction = float(first.get("friction", 0.5))
        for o in cloth:
            p = o.params.get("cloth", {})
            ids = builder.add_mesh(o.mesh.points, o.mesh.faces, name=o.name,
                                   **{k2: float(p[k]) for k, k2 in CLOTH_PARAMS.items() if k in p})
            if "pinned" in o.params and len(o.params["pinned"]):
                builder.pin(ids[o.params["pinned"]])
            self.ranges[o.name] = (int(ids[0]), int(ids[-1]) + 1)
        self.model = builder.finalize(device=device)
        up = np.array([0.0, 1.0, 0.0]) if scene.up_axis.upper() == "Y" else np.array([0.0, 0.0, 1.0])
        colliders = ColliderSet(device=device)
        for o in scene.objects:
            kind = o.params.get("collider")
            if kind is None or o.kind == "cloth":
                continue
            if kind == "ground":
                colliders.add_plane(normal=up, offset=float(np.mean(o.mesh.points @ up)), friction=friction)
            elif kind == "sphere" and "sphere" in o.params:
                colliders.add_sphere(o.params["sphere"]["center"], o.params["sphere"]["radius"], friction=friction)
            elif kind in ("mesh", "sphere"):
                if o.kind != "static":
                    raise SceneError(f"{o.name}: moving mesh colliders are not wired into the pipeline yet")
                colliders.add_mesh(o.mesh.points, o.mesh.faces, friction=friction)
            else:
                raise SceneError(f"{o.name}: warpshade:collider '{kind}' is not one of ground, sphere, mesh")
        gravity = tuple(-9.81 * up)
        self.solver = XPBDSolver(self.model, colliders, substeps=int(scene.settings.get("substeps", 8)),
                                 gravity=gravity, self_collision=bool(first.get("selfCollision", True)))
        self.control = self.model.control()
        if "wind" in scene.settings:
            self.control.set_wind(scene.settings["wind"])
        self.state = self.model.state()
        self.dt = 1.0 / scene.fps
        self._frame = 0
        self._points = self.state.points.numpy()

    def points(self, frame: int, name: str) -> np.ndarray:
        """Positions of cloth object ``name`` at ``frame`` (frames are produced in order), (V, 3)."""
        while self._frame < frame:
            self.solver.step(self.state, self.state, self.dt, self.control)
            self._frame += 1
            self._points = self.state.points.numpy()
        a, b = self.ranges[name]
        return self._points[a:b]


class Pipeline:
    """Simulate, shade and write one scene.

    Args:
        scene: The scene (from :func:`warpshade.usd.read_scene` or built in Python).
        frames: Frames to produce (default: the scene's).
        method: Visibility method for every shaded object (overrides the scene), or None.
        knobs: Method knobs (with ``method``).
        order: SH order (default: ``warpshade:order`` or :data:`DEFAULT_ORDER`).
        write_transfer: Also write ``primvars:warpshade:transfer`` (V × N*N floats per frame).
        lights: :mod:`warpshade.lighting` objects to use instead of the scene's.
        device: Warp device.
    """

    def __init__(self, scene: Scene, frames: int | None = None, method: str | None = None,
                 knobs: dict | None = None, order: int | None = None, write_transfer: bool | None = None,
                 lights: list | None = None, device: str = "cpu"):
        self.scene = scene
        self.frames = int(frames if frames is not None else scene.frames)
        if self.frames < 1:
            raise ValueError(f"frames must be >= 1, got {self.frames}")
        self.order = check_order(order if order is not None else scene.settings.get("order", DEFAULT_ORDER))
        self.write_transfer = bool(write_transfer if write_transfer is not None
                                   else scene.settings.get("writeTransfer", False))
        self.device = device
        self._method, self._knobs = method, dict(knobs or {})
        self._lights = lights
        self.report = None

    # -- setup ------------------------------------------------------------------------------
    def _groups(self) -> list[_Group]:
        by_key: dict = {}
        for obj in self.scene.objects:
            if not obj.shaded:
                continue
            if self._method is not None:
                name, knobs = self._method, self._knobs
            else:
                name, knobs = obj.method, obj.knobs
                if name is not None and not knobs:
                    knobs = DEFAULT_KNOBS.get(name, {})
            key = (name, tuple(sorted(knobs.items())))
            by_key.setdefault(key, (name, dict(knobs), []))[2].append(obj)
        return [_Group(n, k, objs, self.order, self.device) for n, k, objs in by_key.values()]

    def _simulators(self) -> dict:
        if not any(o.kind == "cloth" for o in self.scene.objects):
            return {}
        sim = ClothSimulation(self.scene, device=self.device)
        return {name: sim for name in sim.ranges}

    # -- run --------------------------------------------------------------------------------
    def run(self, writer, progress: bool = True) -> RunReport:
        """Produce every frame into ``writer`` (an :class:`warpshade.usd.AnimationWriter`-like object).

        The writer is closed on success and aborted (keeping complete frames) on error.
        """
        secs = dict.fromkeys(("setup", "simulate", "shade", "write"), 0.0)
        t0 = time.perf_counter()
        try:
            groups = self._groups()
            sims = self._simulators()
            lights = self._lights if self._lights is not None else lights_for(self.scene)
            names = {}
            for g in groups:
                for o in g.objects:
                    static = o.kind == "static"
                    names[o.name] = writer.add_mesh(
                        o.name, o.mesh.faces, points=o.mesh.points if static else None,
                        normals=o.mesh.normals if static else None,
                        albedo=o.material.albedo, roughness=o.material.roughness,
                        transfer_order=self.order if self.write_transfer else None)
            specs = self.scene.lights
            if not specs and self._lights is None:
                import os

                specs = sky_light_specs(lights[0], os.path.join(writer.asset_dir(), "default_sky.exr"),
                                        self.scene.up_axis)
            for spec in specs:
                writer.add_light(spec)
            wp.synchronize()
            secs["setup"] = time.perf_counter() - t0
            frames = range(self.frames)
            bar = None
            if progress:
                from tqdm import tqdm

                bar = tqdm(frames, desc="warpshade run", unit="frame", leave=True)
                frames = bar
            state = {o.name: o.mesh.points for o in self.scene.objects}
            for f in frames:
                t = time.perf_counter()
                for o in self.scene.objects:
                    if o.kind in ("animated", "skinned"):
                        state[o.name] = np.asarray(o.params["points_at"](f), dtype=np.float32)
                    elif o.kind == "cloth":
                        state[o.name] = sims[o.name].points(f, o.name)
                wp.synchronize()
                t1 = time.perf_counter()
                secs["simulate"] += t1 - t

                shaded = []
                for g in groups:
                    pts = np.concatenate([state[o.name] for o in g.objects])
                    transfer, normals = g.update(pts)
                    distant, local = _lights_sh(lights, self.order, pts, f / self.scene.fps)
                    for o, a, b in zip(g.objects, g.offsets[:-1], g.offsets[1:]):
                        rad = exit_radiance(transfer[a:b], o.material.albedo, distant,
                                            None if local is None else local[a:b])
                        shaded.append((o, state[o.name], normals[a:b], rad, transfer[a:b]))
                wp.synchronize()
                t2 = time.perf_counter()
                secs["shade"] += t2 - t1

                for o, pts, nrm, rad, tr in shaded:
                    static = o.kind == "static"
                    writer.write_frame(f, names[o.name], None if static else pts, None if static else nrm, rad,
                                       tr if self.write_transfer else None)
                secs["write"] += time.perf_counter() - t2
            if bar is not None:
                bar.close()
            t = time.perf_counter()
            path = writer.close()
            secs["write"] += time.perf_counter() - t
        except BaseException:
            writer.abort()
            raise
        secs["total"] = time.perf_counter() - t0
        self.report = RunReport(path=path, frames=self.frames, seconds=secs,
                                vertices=sum(g.mesh.num_vertices for g in groups),
                                groups=[f"{g.method_name or 'unoccluded'} {g.knobs or ''}: "
                                        f"{', '.join(o.name for o in g.objects)}" for g in groups])
        return self.report


def _lights_sh(lights, order: int, points: np.ndarray, t: float):
    """Distant SH (N*N, 3) and per-vertex local SH (V, N*N, 3) or None, for lights at time ``t`` [s]."""
    from .lighting import lights_sh

    lights = [light.at_time(t) for light in lights]
    return lights_sh(lights, order, points)
