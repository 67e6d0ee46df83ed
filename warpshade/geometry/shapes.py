"""Tessellations of the UsdGeom axial gprims (Capsule, Cylinder, Cone) shared by the USD reader
and the Python scene API, so that both shade the same triangles."""

from __future__ import annotations

import numpy as np

AXIS_FROM_Z = {"Z": np.eye(3), "Y": np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]]),
               "X": np.array([[0, 0, 1.0], [0, 1, 0], [-1, 0, 0]])}
"""Rotations (acting on column vectors) taking a shape built along +Z to a gprim's ``axis``."""


def axial_shape(kind: str, radius: float, height: float) -> tuple[np.ndarray, np.ndarray]:
    """Vertices (V, 3) and triangles (F, 3) of a ``"capsule"``, ``"cylinder"`` or ``"cone"`` along
    +Z centred on the origin, as USD defines the gprim: a Capsule's ``height`` is its cylindrical
    part (hemispheres of ``radius`` beyond), a Cone's apex is at ``+height/2``. 48 sections around
    (a capsule's ends 24 rings), like the reader's other gprims fine enough for shadows."""
    import trimesh

    if kind == "cylinder":
        m = trimesh.creation.cylinder(radius=radius, height=height, sections=48)
    elif kind == "capsule":
        m = trimesh.creation.capsule(height=height, radius=radius, count=[48, 24])
    elif kind == "cone":  # trimesh puts the base at z = 0
        m = trimesh.creation.cone(radius=radius, height=height, sections=48)
        m.apply_translation([0.0, 0.0, -height / 2])
    else:
        raise ValueError(f"axial shape must be capsule, cylinder or cone, got {kind!r}")
    return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces)
