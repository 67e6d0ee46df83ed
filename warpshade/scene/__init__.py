"""Scene description shared by the USD reader, the planner and the pipeline (no ``pxr`` here).

The USD package turns a stage into a :class:`Scene`; the planner decides which passes each object
needs; the pipeline simulates, shades and writes. Keeping the description plain Python lets tests and
scripts build scenes without USD.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..geometry.mesh import TriMesh

def did_you_mean(name: str, known) -> str:
    """`` (did you mean 'x'?)`` with the closest of ``known`` to ``name``, or an empty string when none is close:
    the hint every unknown-name error and warning of a scene ends with."""
    import difflib

    close = difflib.get_close_matches(name, list(known), n=1)
    return f" (did you mean '{close[0]}'?)" if close else ""


class SceneError(ValueError):
    """Invalid scene input. The message names the file and the prim at fault."""


class SceneWarning(UserWarning):
    """Something in a scene file that warpshade ignores (an unsupported prim or input)."""


OBJECT_KINDS = ("static", "cloth", "skinned", "animated")
"""``static``: never moves; ``cloth``: simulated; ``skinned``: linear-blend skinned; ``animated``:
time-sampled points read from the file."""


DEFAULT_ALBEDO = (0.8, 0.8, 0.8)
"""Albedo (linear RGB) of an object whose scene gives none."""


@dataclass
class Material:
    """UsdPreviewSurface subset used for shading.

    Attributes:
        albedo: Diffuse reflectance, linear RGB in [0, 1], shape (3,) (default 0.8 grey).
        roughness: UsdPreviewSurface roughness in [0, 1]; < 1 makes the material glossy.
        albedo_authored: Whether the albedo came from the scene (a material's ``diffuseColor`` or a
            constant ``displayColor``); None: True when ``albedo`` was given. ``warpshade run --albedo``
            replaces only albedos that were not authored.
    """

    albedo: np.ndarray | None = None
    roughness: float = 1.0
    albedo_authored: bool | None = None

    def __post_init__(self):
        if self.albedo_authored is None:
            self.albedo_authored = self.albedo is not None
        if self.albedo is None:
            self.albedo = np.array(DEFAULT_ALBEDO)

    @property
    def glossy(self) -> bool:
        return self.roughness < 1.0


LIGHT_KINDS = ("dome", "distant", "sphere", "rect")
"""UsdLux light types warpshade reads and writes (DomeLight, DistantLight, SphereLight, RectLight)."""


@dataclass
class LightSpec:
    """A light as described in a scene file, before it becomes a :mod:`warpshade.lighting` object.

    Conventions follow UsdLux: radiance = ``color * intensity * 2**exposure`` (linear RGB); a
    distant light shines along ``-Z`` of its frame; a rect light lies in the frame's XY plane
    (``width`` along X, ``height`` along Y) and emits towards ``-Z``; a dome light's lat-long
    ``texture`` has +Y (in the dome's frame) at the top row.

    Attributes:
        kind: One of :data:`LIGHT_KINDS`.
        name: Prim path (for messages and as the output prim name).
        color: Linear RGB, shape (3,), float64.
        intensity: Scalar multiplier.
        exposure: Power-of-two multiplier (radiance scales by ``2**exposure``).
        transform: Light-to-world matrix acting on column vectors (``p_world = M @ [p, 1]``),
            shape (4, 4), float64.
        angle: Distant light: angular diameter [degrees].
        radius: Sphere light: radius [scene units].
        width: Rect light: size along the frame's X [scene units].
        height: Rect light: size along the frame's Y [scene units].
        texture: Dome light: absolute path of the lat-long environment image, or None for a
            uniform dome of ``color``.
        normalize: UsdLux ``inputs:normalize``: the power does not depend on the light's size
            (radiance is divided by the emitting area; a distant light then gives irradiance).
        treat_as_point: Sphere light: UsdLux ``treatAsPoint``.
        prim_path: Path of the input prim the light was read from (the output writes the light at
            that path, under its input ancestors), or None for a light built in Python (written
            under ``Lights`` of the output's default prim).
        prim_xforms: With ``prim_path``: the prim and its ancestors, root first, as
            :attr:`SceneObject.prim_xforms`.
        rotations: A distant or dome light whose transform is keyed: its rotation at each frame relative
            to ``transform`` (frame 0), shape (F, 3, 3), float64; None for a light that stands still.
    """

    kind: str
    name: str = "light"
    color: np.ndarray = field(default_factory=lambda: np.ones(3))
    intensity: float = 1.0
    exposure: float = 0.0
    transform: np.ndarray = field(default_factory=lambda: np.eye(4))
    angle: float = 0.53
    radius: float = 0.5
    width: float = 1.0
    height: float = 1.0
    texture: str | None = None
    normalize: bool = False
    treat_as_point: bool = False
    prim_path: str | None = None
    prim_xforms: tuple = ()
    rotations: np.ndarray | None = None

    def __post_init__(self):
        if self.kind not in LIGHT_KINDS:
            raise ValueError(f"{self.name}: unknown light kind '{self.kind}' (known: {', '.join(LIGHT_KINDS)})")
        self.color = np.asarray(self.color, dtype=np.float64).reshape(3)
        self.transform = np.asarray(self.transform, dtype=np.float64).reshape(4, 4)

    @property
    def radiance(self) -> np.ndarray:
        """Emitted radiance, linear RGB, shape (3,): ``color * intensity * 2**exposure``."""
        return self.color * self.intensity * 2.0 ** self.exposure

    @property
    def position(self) -> np.ndarray:
        """Origin of the light's frame in world space, shape (3,)."""
        return self.transform[:3, 3].copy()

    @property
    def direction(self) -> np.ndarray:
        """Unit world direction the light shines along (its frame's ``-Z``), shape (3,)."""
        d = -self.transform[:3, 2]
        n = np.linalg.norm(d)
        return d / n if n > 0 else np.array([0.0, -1.0, 0.0])


@dataclass
class SceneObject:
    """One mesh in the scene.

    Attributes:
        name: Prim path or name (used in messages and as the output prim name).
        mesh: Topology and rest pose (world space).
        kind: One of :data:`OBJECT_KINDS`.
        material: Shading parameters.
        method: Self-shadowing visibility method name (a key of ``warpshade.visibility.METHODS``),
            or None for no self-shadowing (unoccluded transfer).
        knobs: Keyword arguments for the method.
        casts_shadows: Whether the object blocks light (``warpshade:castsShadows``). False: it receives
            shadows but blocks no light toward any vertex, its own included, in every pass of a run
            (its group's visibility method, sphere sets between groups, GEARS rect lights); it still
            reflects light in the one-bounce pass (docs/guide/quickstart.md, "Objects that cast no shadows").
        shaded: Whether the object is shaded and written with colours.
        two_sided: Shade and write each side with its own transfer (``warpshade:twoSided``, docs/conventions.md
            §6); None: the run decides (on for cloth).
        params: Kind-specific settings (cloth material, pinned vertices, skinning data, animation
            samples...), as read from ``warpshade:`` attributes.
        prim_path: Path of the input prim the object was read from (the output writes the shaded
            mesh at that path), or None for an object built in Python (written at ``/World/<name>``).
        prim_xforms: With ``prim_path``: the prim and its ancestors, root first, as tuples
            ``(path, type name, local, resets, instance)`` (``local``: local-to-parent matrix acting on
            column vectors, shape (4, 4), float64, or None for a prim without a transform such as a Scope;
            ``resets``: the prim resets the transform stack; ``instance``: the prim is an instance, the
            object a mesh inside it). The output rebuilds this hierarchy. An entry of type
            ``PointInstancer`` that is not an ancestor names the instancer the object is an instance
            of: the output deactivates it.
    """

    name: str
    mesh: TriMesh
    kind: str = "static"
    material: Material = field(default_factory=Material)
    method: str | None = None
    knobs: dict[str, Any] = field(default_factory=dict)
    casts_shadows: bool = True
    shaded: bool = True
    two_sided: bool | None = None
    params: dict[str, Any] = field(default_factory=dict)
    prim_path: str | None = None
    prim_xforms: tuple = ()

    def __post_init__(self):
        if self.kind not in OBJECT_KINDS:
            raise ValueError(f"{self.name}: unknown object kind '{self.kind}' (known: {', '.join(OBJECT_KINDS)})")


@dataclass
class Scene:
    """Everything a run needs.

    Attributes:
        objects: Meshes.
        lights: Light descriptions (:class:`LightSpec`); the pipeline turns them into
            :mod:`warpshade.lighting` objects.
        frames: Number of frames to produce.
        fps: Frames per second.
        start_time: Time code of frame 0 (the input's ``startTimeCode``): frame ``f`` samples the
            input's animation at time code ``start_time + f`` and is written at that time code.
        up_axis: ``"Y"`` or ``"Z"``.
        meters_per_unit: Stage units.
        settings: Scene-wide ``warpshade:`` settings (SH order, reflections, max error...).
        source: File the scene came from, for messages.
        default_prim: The input's default prim path (the output's default prim), or None (``/World``).
        collision_only: Static colliders that are neither shaded nor written (UsdPhysics colliders
            with ``purpose`` guide or proxy, such as a character's collision twins).
        gravity: The cloth's gravity, a world vector [m/s²] (a UsdPhysics ``PhysicsScene``'s), or None
            for 9.81 m/s² down the up axis.
    """

    objects: list[SceneObject] = field(default_factory=list)
    lights: list[LightSpec] = field(default_factory=list)
    frames: int = 120
    fps: float = 60.0
    start_time: int = 0
    up_axis: str = "Y"
    meters_per_unit: float = 1.0
    settings: dict[str, Any] = field(default_factory=dict)
    source: str = "<scene>"
    default_prim: str | None = None
    collision_only: list[SceneObject] = field(default_factory=list)
    gravity: np.ndarray | None = None

    def object(self, name: str) -> SceneObject:
        for o in self.objects:
            if o.name == name:
                return o
        raise KeyError(f"{self.source}: no object named {name}")
