"""The main job: simulate, shade and write a scene, one frame at a time (``warpshade run``).

Data flows one way: per frame each object's positions come from the simulation (cloth,
:mod:`.cloth`), from skinning or time samples (skinned, animated) or stay put (static); each
*shading group* — the objects that share a visibility method and its knobs — is one receiver mesh,
so its members shadow each other (with ``reference``: exactly, ray traced); the group's
:class:`~warpshade.visibility.TransferMethod` updates the SH transfer (docs/conventions.md §2); exit
radiance ``(ρ/π) Σ_i L_i T_i`` uses the lights' SH (world space); the writer streams the frame out.
An object with ``casts_shadows`` False stays in its group as a receiver only: the method, the
between-group sphere sets and the GEARS pass get the casters' triangles alone.

Shading runs through :func:`warpshade.parallel.shade_frames` with a picklable
:class:`~.shading.SceneShader`: inline by default, or on worker processes / a Dask cluster
(``workers``, ``scheduler``) while this process keeps simulating; frames are written in order.

No ``pxr`` here: the scene arrives as a :class:`warpshade.scene.Scene` and the output goes to any
object with the :class:`warpshade.usd.AnimationWriter` methods.
"""

from __future__ import annotations

import os
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..geometry.mesh import closed_orientation, first_nonfinite
from ..scene import Scene, SceneError, SceneWarning
from .cloth import ClothSimulation, coincident_vertices
from .lights import default_lights, light_from_spec, sky_light_specs
from .refine import refine_receivers as refine
from ..visibility import METHOD_PREFERENCE, default_method
from .config import DEFAULT_ORDER, REUSE_AUTO, REUSE_CHUNK, RUN_KNOBS, RunConfig, resolve_reuse, resolve_run
from .shading import GroupSpec, SceneShader, back_key, unoccluded_transfer

DEFAULT_KNOBS = RUN_KNOBS
DIM_SUN = 0.01
"""An unnormalized DistantLight giving less irradiance than this is warned of: a white floor facing it
would shade to 0.003, black on screen; its author most likely meant the intensity as irradiance."""
"""Alias of :data:`.config.RUN_KNOBS` (knobs a run gives a method named with none)."""


@dataclass
class RunReport:
    """What a run did and how long each stage took.

    Attributes:
        path: Output file.
        frames: Frames written.
        seconds: Wall time per stage [s]: ``setup`` (simulation model, method structures and
            lights, built once per worker: summed),
            ``simulate``, ``shade`` (summed over frames; with workers it overlaps the others),
            ``write``, ``total`` (wall).
        vertices: Shaded vertices per frame.
        groups: One line per shading group (method, knobs, objects).
        resumed_from: First frame produced by this run (> 0 after ``--resume``).
        area_lights: How rect lights were shaded ("" when the scene has none).
        compiled: Whether Warp's kernel cache held no warpshade kernels at the start, so that the
            setup and the first frames' times include compiling them.
    """

    path: str
    frames: int
    seconds: dict = field(default_factory=dict)
    vertices: int = 0
    groups: list = field(default_factory=list)
    resumed_from: int = 0
    area_lights: str = ""
    passes: list = field(default_factory=list)
    frame_seconds: list = field(default_factory=list)
    compiled: bool = False


def check_output(scene: Scene, out: str) -> None:
    """Refuse an output path that is one of the scene's input files (the scene, a texture it uses):
    writing it would destroy the input.

    Raises:
        SceneError: naming both.
    """
    files = [scene.source] + [getattr(light, "texture", None) for light in scene.lights]
    target = os.path.realpath(out)
    for f in files:
        if f and os.path.exists(f) and os.path.realpath(f) == target:
            raise SceneError(f"output {out} is an input of the scene ({f}); choose another --out")


def warn_black_mesh(scene: Scene, name: str, frame: int, albedo=None) -> None:
    """Warn that mesh ``name`` got zero exit radiance at every vertex of ``frame``, with the likely cause.
    ``albedo`` is the albedo it was shaded with (default: its material's)."""
    obj = scene.object(name)
    if not np.any(obj.material.albedo if albedo is None else albedo):
        cause = ("its albedo is black (warpshade:albedo, the bound material's diffuseColor, or --albedo for "
                 "objects without one); set a non-black albedo")
    else:
        cause = ("no light reaches any of its vertices: every vertex is shadowed or faces away from every "
                 "light (flipped normals or winding?), or the lights give no light (intensity, exposure)")
    warnings.warn(f"{name}: frame {frame}: exit radiance is zero at every vertex: {cause}", SceneWarning, stacklevel=2)


class _SetupTicker:
    """Redraws a progress bar's "setting up" text every ``every`` seconds until :meth:`stop`: the seconds
    elapsed, against the planner's estimate when there is one (the bar's own count stays at 0 until the
    first frame, which can take minutes on a large scene)."""

    def __init__(self, bar, estimate: float | None, every: float = 1.0, compiling: bool = False):
        import threading

        self.bar, self.estimate, self.compiling, self.t0 = bar, estimate, compiling, time.monotonic()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._tick, args=(every,), name="warpshade-setup-ticker", daemon=True)
        self._thread.start()

    def text(self) -> str:
        elapsed = time.monotonic() - self.t0
        of = f" of ~{self.estimate:.0f} s estimated" if self.estimate else ""
        if self.compiling:  # the planner prices the work, not Warp compiling it on a first run
            of += (" + compiling Warp kernels (first run)" if of else ", compiling Warp kernels (first run)")
        return f"warpshade run: setting up, {elapsed:.0f} s{of}"

    def _tick(self, every: float) -> None:
        while not self._stop.wait(every):
            self.bar.set_description_str(self.text())  # tqdm redraws under its own lock

    def stop(self) -> None:
        if not self._stop.is_set():
            self._stop.set()
            self._thread.join()


def require_scene(scene, what: str) -> None:
    """A TypeError naming ``what`` unless ``scene`` is a :class:`~warpshade.scene.Scene` (a file name is not one)."""
    if not isinstance(scene, Scene):
        raise TypeError(f"{what}: scene must be a Scene (warpshade.make_scene, or warpshade.usd.read_scene of a file), "
                        f"got {type(scene).__name__} {scene!r:.60}")


class Pipeline:
    """Simulate, shade and write one scene.

    Args:
        scene: The scene (from :func:`warpshade.usd.read_scene` or built in Python).
        frames: Frames to produce (default: the scene's).
        method: Visibility method for every shaded object (overrides the scene): a name of
            :data:`warpshade.visibility.METHODS`, ``"none"`` for none (unoccluded transfer, no shadows, as
            ``warpshade:method = "none"`` and ``--method none``), or None for each object's own.
        knobs: Method knobs (with ``method``).
        order: SH order (default: ``warpshade:order`` or :data:`DEFAULT_ORDER`).
        write_transfer: Also write ``primvars:warpshade:transfer`` (V × N*N floats per frame).
        lights: :mod:`warpshade.lighting` objects to use instead of the scene's.
        workers: Shading worker processes (0: shade in this process).
        scheduler: Dask scheduler (``"local"``, ``tcp://HOST:PORT`` or ``tls://HOST:PORT``) instead of
            local processes.
        device: Warp device.
        between: Shadows between shading groups (objects with different methods or knobs):
            ``"spheres"`` (sphere sets, default) or None.
        reflections: One bounce of diffuse reflection between shaded objects (sphere sets, thesis
            §4.3): True (defaults), a dict of :class:`~.reflections.SceneReflections` keyword arguments,
            False, or None for the scene's ``warpshade:reflections`` (default off).
        albedo: Albedo (scalar or RGB) of objects whose scene gives none (no material ``diffuseColor``,
            no constant ``displayColor``); None keeps the default 0.8 grey.
        area_lights: Rect lights: ``"gears"`` (default: exact irradiance, GEARS soft shadows,
            :mod:`.area`) or ``"sh"`` (projected to SH).
        area_knobs: GEARS knobs (``k``, ``grid``, ``weighting``) for ``area_lights="gears"``.
        refine_receivers: Edge length [scene units] to which coarse static meshes are subdivided so
            shadows have vertices to fall on; ``"auto"`` (the scene's ``warpshade:refineEdge``, else
            1/12 of the scene's diagonal) or ``"off"``. The scene's objects are refined in place.
        security: ``distributed.Security`` for ``scheduler`` (TLS, :func:`warpshade.parallel.cluster.scheduler_security`).
        two_sided: Shade both sides of thin surfaces, each with its own transfer, and write each side as
            its own single-sided mesh (docs/conventions.md §6): ``"auto"`` (default: objects with
            ``warpshade:twoSided``, else cloth), ``"on"`` (every shaded object) or ``"off"``. A group with a
            two-sided member runs its visibility method a second time, on the group seen from the back.
        reuse: Temporal reuse: recompute a receiver's transfer only when geometry it sees moved by more
            than this angle [rad] since it was last computed (:mod:`warpshade.visibility.reuse`); None
            recomputes every frame; ``"auto"`` (default) is :data:`~.config.REUSE` where the groups'
            methods compute only the receivers due, else None (:func:`~.config.resolve_reuse`).
        reuse_chunk: With ``reuse``: frames per chunk (default :data:`~.config.REUSE_CHUNK`). Frames
            ``k*reuse_chunk`` on are shaded in order by one worker, the first computed in full, so the
            output depends on ``reuse_chunk``, not on ``workers``; ``--resume`` starts shading at the
            chunk's first frame and writes from where it resumes.
    """

    def __init__(self, scene: Scene, frames: int | None = None, method: str | None = None,
                 knobs: dict | None = None, order: int | None = None, write_transfer: bool | None = None,
                 lights: list | None = None, workers: int = 0, scheduler: str | None = None, device: str = "cpu",
                 between: str | None = "spheres", reflections: bool | dict | None = None, albedo=None,
                 area_lights: str = "gears", area_knobs: dict | None = None, refine_receivers="auto",
                 security=None, two_sided: str = "auto", reuse: float | str | None = REUSE_AUTO,
                 reuse_chunk: int | None = None):
        from ..parallel.runtime import init_warp, kernel_cache_holds_warpshade

        init_warp()  # a script's run starts as quietly as the CLI's (no banner, no CUDA-driver notice)
        self.compiles = not kernel_cache_holds_warpshade()
        """Whether Warp's kernel cache held no warpshade kernels when the pipeline was made: the run's
        setup then compiles them (a machine's first run; the progress bar and the report say so)."""
        require_scene(scene, "Pipeline")
        self.scene = scene
        self.refined = refine(scene, refine_receivers)
        """Static objects subdivided for shading (:mod:`warpshade.pipeline.refine`)."""
        n = frames if frames is not None else scene.frames
        if isinstance(n, (bool, np.bool_)) or not isinstance(n, (int, np.integer, float, np.floating)) or \
                not float(n).is_integer() or n < 1:
            raise ValueError(f"frames must be an integer >= 1, got {n!r}")
        self.frames = int(n)
        self.config = resolve_run(scene, method, knobs, order, between, reflections, area_lights, area_knobs,
                                  two_sided, albedo, write_transfer)
        """Everything the run decided before its first frame (:class:`~.config.RunConfig`)."""
        self.order, self.groups = self.config.order, self.config.groups
        self.write_transfer, self.reflections = self.config.write_transfer, self.config.reflections
        self.workers, self.scheduler, self.device = int(workers), scheduler, device
        self.security = security
        if not self.groups:
            raise SceneError(f"{scene.source}: no shaded object")
        self.reuse = resolve_reuse(reuse, [g.method for g in self.groups])
        """Temporal reuse tolerance [rad] of every group's transfer, or None (recomputed every frame)."""
        if reuse_chunk is not None and self.reuse is None:
            raise ValueError("reuse_chunk needs temporal reuse (reuse was None, or 'auto' with a method that "
                             "computes every receiver)")
        self.shader = SceneShader.from_config(self.config, scene, lights, device, self.reuse)
        self.chunk = None if self.reuse is None else int(REUSE_CHUNK if reuse_chunk is None else reuse_chunk)
        """Frames per chunk (:func:`warpshade.parallel.shade_frames`), or None without temporal reuse."""
        if self.chunk is not None and self.chunk < 1:
            raise ValueError(f"reuse chunk must be >= 1 frames, got {self.chunk}")
        self._check_lights()
        self._warn_static_scene(lights)
        self._warn_inward_meshes()
        self._warn_cut_cloth()
        from .area import area_lights_used

        self.area_lights, self.area_description = area_lights_used(self.shader)
        """How rect lights are shaded (``"gears"``, ``"sh"``; None without rect lights), and in words."""
        self.report = None

    def _warn_static_scene(self, lights) -> None:
        """Warn about a scene whose frames will all be alike, lights that give no light, and cloth that can only fall."""
        objects = self.scene.objects
        moving_lights = (any(getattr(light, "motion", None) is not None for light in (lights or []))
                         or any(getattr(spec, "rotations", None) is not None for spec in self.scene.lights))
        if self.frames > 1 and not moving_lights and all(o.kind == "static" for o in objects):
            warnings.warn(
                f"{self.scene.source}: nothing in the scene moves, so all {self.frames} frames are alike: "
                'mark a mesh to simulate with warpshade:kind = "cloth", animate points or xforms, or use '
                "--frames 1", SceneWarning, stacklevel=3)
        for spec in self.scene.lights:
            if not np.any(np.asarray(spec.color, dtype=np.float64) * spec.intensity * 2.0 ** spec.exposure):
                warnings.warn(
                    f"{spec.name}: this light gives no light (color x intensity x 2^exposure = 0): set "
                    "inputs:intensity and inputs:color above zero, or remove it", SceneWarning, stacklevel=3)
            elif spec.kind == "distant" and not spec.normalize and spec.angle > 0:
                e = float(np.max(light_from_spec(spec, self.scene.up_axis, self.scene.fps).irradiance))
                if e < DIM_SUN:
                    warnings.warn(
                        f"{spec.name}: an unnormalized DistantLight's intensity is the radiance of its "
                        f"{spec.angle:g}-degree disc, so intensity {spec.intensity:g} gives an irradiance of only "
                        f"{e:.2g} (a white floor facing it shades to {e / np.pi:.2g}): set inputs:normalize = 1 "
                        "to make the intensity the irradiance (as Blender writes a Sun), or raise it (50000 is a "
                        "sun)", SceneWarning, stacklevel=3)
        has_colliders = bool(self.scene.collision_only) or any(o.params.get("collider") for o in objects
                                                               if o.kind != "cloth")
        for o in objects:
            if o.kind != "cloth" or has_colliders:
                continue
            pinned = "pinned" in o.params and len(o.params["pinned"])
            if not pinned and "attached" not in o.params:
                warnings.warn(
                    f"{o.name}: cloth with neither pins (warpshade:pinned) nor an attachment, and the scene has "
                    "no collider (warpshade:collider on a prim): it falls freely; add a collider or pin vertices",
                    SceneWarning, stacklevel=3)

    def _warn_cut_cloth(self) -> None:
        """Warn about a cloth with vertices at the same position that share no triangle (a seam split by a DCC or
        an exporter): the simulation keeps them apart, so the cloth comes apart along the seam."""
        for o in self.scene.objects:
            if o.kind != "cloth":
                continue
            pair, count = coincident_vertices(o.mesh.points)
            if count:
                warnings.warn(f"{o.name}: {count} vertices of the cloth lie on others without sharing a triangle "
                              f"with them (first: vertices {pair[0]} and {pair[1]}): the cloth is cut there and will "
                              "come apart along the cut; if it is one piece, merge them (Blender: Merge by Distance)",
                              SceneWarning, stacklevel=3)

    def _warn_inward_meshes(self) -> None:
        """Warn about closed meshes wound inward: their normals point in, so they would shade black."""
        for o in self.scene.objects:
            if o.shaded and o.kind != "cloth" and closed_orientation(o.mesh.points, o.mesh.faces) < 0:
                warnings.warn(f"{o.name}: a closed mesh wound inward (its triangles face its inside), so its normals "
                              "point in and it shades black: reverse the winding of its faces", SceneWarning,
                              stacklevel=3)

    def _albedo_of(self, name: str) -> np.ndarray:
        """The albedo object ``name`` is shaded with (its material's, or the run's ``albedo``)."""
        return next(a for g in self.groups for n, a in zip(g.names, g.albedos) if n == name)

    def _check_lights(self) -> None:
        """Reject, before any work, a light whose emission or SH radiance does not fit in float32
        (it would shade to inf), naming the light."""
        if self.shader.lights is None and not self.shader.light_specs:
            return  # the default sky
        try:
            lights = self.shader.build_lights()
            from ..lighting import lights_sh

            lights_sh([li for li in lights if not li.local], self.order)
        except ValueError as exc:
            raise SceneError(f"{self.scene.source}: {exc}") from exc

    def _geometry(self, sims, secs, failure: list, start: int = 0):
        """Yield ``(frame, {name: points})`` for every moving object from ``start`` on, timing the simulation.

        Frames before ``start`` (already written by an interrupted run) are simulated, since the
        simulation is sequential and deterministic, but not shaded (with chunks, from the first frame of
        ``start``'s chunk on they are shaded, for the chunk to be as in a whole run, and not written).

        An error ends the iteration and is put in ``failure`` instead of being raised here, so the
        frames already in flight are still shaded and written before the run stops with it.
        """
        try:
            from ..parallel.frames import chunk_start

            first = chunk_start(start, self.chunk)
            for f, geo in self._geometry_frames(sims, secs):
                if f >= first:
                    yield f, geo
        except Exception as exc:  # noqa: BLE001 - re-raised by run() after the in-flight frames
            failure.append(exc)

    def _geometry_frames(self, sims, secs):
        driven = [o for o in self.scene.objects if o.kind in ("animated", "skinned")]
        for f in range(self.frames):
            t = time.perf_counter()
            code = self.scene.start_time + f  # points_at takes the input's time code
            geo = {o.name: np.asarray(o.params["points_at"](code), dtype=np.float32) for o in driven}
            for o in driven:  # before the cloth, which collides with them and hangs from them
                if geo[o.name].shape != (o.mesh.num_vertices, 3):
                    raise SceneError(f"{o.name}: frame {f} (time code {code:g}): points of shape {geo[o.name].shape}, "
                                     f"but the mesh has {o.mesh.num_vertices} vertices, (V, 3): a moving mesh keeps "
                                     "its vertices and faces in every frame (export a mesh whose vertex count does not "
                                     "change, e.g. with modifiers that change it applied)")
            if sims is not None:  # cloth after the bodies it collides with and hangs from
                geo.update(sims.advance(f, geo))
            for name, pts in geo.items():
                v = first_nonfinite(pts)
                if v is not None:
                    raise SceneError(f"{name}: frame {f} (time code {code:g}): vertex {v} is not finite "
                                     f"{pts[v].tolist()}")
            secs["simulate"] += time.perf_counter() - t
            yield f, geo

    def simulate(self):
        """Yield ``(frame, {name: points (V, 3) float32})`` for every moving object, frame by frame:
        the run's simulation and animation without shading (geometry-only output, stepping)."""
        sims = ClothSimulation(self.scene, self.device) if any(o.kind == "cloth" for o in self.scene.objects) else None
        yield from self._geometry_frames(sims, dict.fromkeys(("simulate",), 0.0))

    def run(self, writer, progress: bool = True, setup_estimate: float | None = None, pool=None) -> RunReport:
        """Produce every frame into ``writer`` (an :class:`warpshade.usd.AnimationWriter`-like object).

        The writer is closed on success and aborted (keeping complete frames) on error. A writer
        opened with ``resume=True`` on an interrupted output has ``resume_frame > 0``: the run then
        produces only the frames from there on (``--resume``). With ``progress``, a bar counts frames;
        until the first frame it says "setting up", with the seconds elapsed against
        ``setup_estimate`` [s] (the planner's) when given, redrawn every second. With ``pool`` (a
        :class:`~warpshade.parallel.WorkerPool` started earlier) the frames are shaded there instead of
        on ``workers`` new processes, and the run closes it.
        """
        from ..parallel import shade_frames

        if getattr(writer, "path", None):
            try:
                check_output(self.scene, writer.path)
            except SceneError:
                writer.abort()
                raise
        secs = dict.fromkeys(("setup", "simulate", "shade", "write"), 0.0)
        time0 = self.scene.start_time  # frame f is written at time code time0 + f
        resume = int(getattr(writer, "resume_frame", 0))  # a time code: first one not yet written
        start = max(0, resume - time0) if resume else 0
        t0 = time.perf_counter()
        bar = ticker = None
        try:
            if progress:  # the bar says "setting up" until the first frame (workers build their structures)
                from tqdm import tqdm

                bar = tqdm(total=self.frames, initial=min(start, self.frames), desc="warpshade run: setting up",
                           unit="frame")
                ticker = _SetupTicker(bar, setup_estimate, compiling=self.compiles)
            sims = ClothSimulation(self.scene, self.device) if any(o.kind == "cloth" for o in self.scene.objects) else None
            static = {o.name for o in self.scene.objects if o.kind == "static"}
            names = {}
            if self.scene.default_prim:
                writer.set_default_prim(self.scene.default_prim)
            for g in self.groups:
                for k, (name, mesh, albedo) in enumerate(zip(g.names, g.meshes, g.albedos)):
                    obj = self.scene.object(name)
                    names[name] = writer.add_mesh(
                        name, mesh.faces, points=mesh.points if name in static else None,
                        normals=mesh.normals if name in static else None, albedo=albedo,
                        roughness=obj.material.roughness, transfer_order=self.order if self.write_transfer else None,
                        prim_path=obj.prim_path, prim_xforms=obj.prim_xforms)
                    if g.two_sided and g.two_sided[k]:
                        names[back_key(name)] = writer.add_back_side(names[name])
            specs = list(self.scene.lights)
            if not specs:  # the analytic skies it shades with (the default one, or given as lights) as DomeLights
                from ..lighting import Sky

                skies = [li for li in (self.shader.lights if self.shader.lights is not None
                                       else default_lights(self.scene.up_axis)) if isinstance(li, Sky)]
                for i, sky in enumerate(skies):
                    specs += sky_light_specs(sky, os.path.join(writer.asset_dir(), f"default_sky{i or ''}.exr"),
                                             self.scene.up_axis)
            for spec in specs:
                writer.add_light(spec)
            secs["setup"] = time.perf_counter() - t0
            failure: list = []
            warned_black: set[str] = set()
            passes: list = []
            frame_seconds: list = []
            results = shade_frames(self.shader, self._geometry(sims, secs, failure, start), workers=self.workers,
                                   scheduler=self.scheduler, security=self.security, chunk=self.chunk, pool=pool)
            for f, res in results:
                if f < start:  # shaded for its chunk (--resume), written already
                    secs["setup"] += res.pop("_build_seconds", 0.0)
                    continue
                t = time.perf_counter()
                frame_seconds.append(res.pop("_seconds"))
                secs["shade"] += frame_seconds[-1]
                secs["setup"] += res.pop("_build_seconds", 0.0)
                passes.append(res.pop("_passes", {}))
                for name, (points, normals, colors, transfer) in res.items():
                    # docs/conventions.md §6: every shaded mesh has points, normals and extent time-sampled
                    # per frame, static ones included
                    writer.write_frame(time0 + f, names[name], points, normals, colors, transfer)
                    # a back side may be dark by right (cloth lying on a ground): only fronts are checked
                    if isinstance(name, str) and name not in warned_black and colors is not None and not np.any(colors):
                        warned_black.add(name)
                        warn_black_mesh(self.scene, name, f, self._albedo_of(name))
                secs["write"] += time.perf_counter() - t
                if bar is not None:
                    if bar.n == min(start, self.frames):
                        ticker.stop()
                        bar.set_description_str("warpshade run", refresh=False)
                    bar.update(1)
            if failure:
                raise failure[0]
            if bar is not None:
                if ticker is not None:
                    ticker.stop()
                bar.close()
            t = time.perf_counter()
            path = writer.close()
            secs["write"] += time.perf_counter() - t
        except BaseException:
            if bar is not None:
                if ticker is not None:
                    ticker.stop()
                bar.close()
            writer.abort()
            raise
        secs["total"] = time.perf_counter() - t0
        self.report = RunReport(path=path, frames=max(0, self.frames - start), seconds=secs, resumed_from=start,
                                vertices=sum(m.num_vertices for g in self.groups for m in g.meshes),
                                groups=[_group_line(g) for g in self.groups],
                                area_lights=self.area_description, passes=passes,
                                frame_seconds=frame_seconds, compiled=self.compiles)
        return self.report


def _group_line(g: GroupSpec) -> str:
    """One :attr:`RunReport.groups` line: method, knobs, objects, and which of them cast no shadows."""
    line = f"{g.method or 'unoccluded'} {g.label or ''}: {', '.join(g.names)}"
    quiet = [n for n, c in zip(g.names, g.casts) if not c]
    both = [n for n, t in zip(g.names, g.two_sided) if t]
    return (line + (f" (casting no shadows: {', '.join(quiet)})" if quiet else "")
            + (f" (two-sided: {', '.join(both)})" if both else ""))


__all__ = ["check_output", "DEFAULT_KNOBS", "DEFAULT_ORDER", "REUSE_CHUNK", "METHOD_PREFERENCE", "ClothSimulation", "GroupSpec", "Pipeline",
           "RUN_KNOBS", "RunConfig", "RunReport", "resolve_run", "SceneShader", "default_method", "light_from_spec", "sky_light_specs",
           "unoccluded_transfer"]
