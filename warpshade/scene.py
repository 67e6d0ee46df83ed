"""Scene description shared by the USD reader, the planner and the pipeline (no ``pxr`` here).

The USD package turns a stage into a :class:`Scene`; the planner decides which passes each object
needs; the pipeline simulates, shades and writes. Keeping the description plain Python lets tests and
scripts build scenes without USD.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .geometry.mesh import TriMesh

OBJECT_KINDS = ("static", "cloth", "skinned", "animated")
"""``static``: never moves; ``cloth``: simulated; ``skinned``: linear-blend skinned; ``animated``:
time-sampled points read from the file."""


@dataclass
class Material:
    """UsdPreviewSurface subset used for shading.

    Attributes:
        albedo: Diffuse reflectance, linear RGB in [0, 1], shape (3,).
        roughness: UsdPreviewSurface roughness in [0, 1]; < 1 makes the material glossy.
    """

    albedo: np.ndarray = field(default_factory=lambda: np.array([0.8, 0.8, 0.8]))
    roughness: float = 1.0

    @property
    def glossy(self) -> bool:
        return self.roughness < 1.0


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
        casts_shadows: Whether the object shadows other objects.
        shaded: Whether the object is shaded and written with colours.
        params: Kind-specific settings (cloth material, pinned vertices, skinning data, animation
            samples...), as read from ``warpshade:`` attributes.
    """

    name: str
    mesh: TriMesh
    kind: str = "static"
    material: Material = field(default_factory=Material)
    method: str | None = None
    knobs: dict[str, Any] = field(default_factory=dict)
    casts_shadows: bool = True
    shaded: bool = True
    params: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self):
        if self.kind not in OBJECT_KINDS:
            raise ValueError(f"{self.name}: unknown object kind '{self.kind}' (known: {', '.join(OBJECT_KINDS)})")


@dataclass
class Scene:
    """Everything a run needs.

    Attributes:
        objects: Meshes.
        lights: Light objects from :mod:`warpshade.lighting` (environment, directional, sphere, rect...).
        frames: Number of frames to produce.
        fps: Frames per second.
        up_axis: ``"Y"`` or ``"Z"``.
        meters_per_unit: Stage units.
        settings: Scene-wide ``warpshade:`` settings (SH order, reflections, max error...).
        source: File the scene came from, for messages.
    """

    objects: list[SceneObject] = field(default_factory=list)
    lights: list[Any] = field(default_factory=list)
    frames: int = 120
    fps: float = 60.0
    up_axis: str = "Y"
    meters_per_unit: float = 1.0
    settings: dict[str, Any] = field(default_factory=dict)
    source: str = "<scene>"

    def object(self, name: str) -> SceneObject:
        for o in self.objects:
            if o.name == name:
                return o
        raise KeyError(f"{self.source}: no object named {name}")
