"""Cloth of a scene simulated with :mod:`warpshade.sim` (pxr-free)."""

from __future__ import annotations

import numpy as np

from ..scene import Scene, SceneError


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
            from ..sim import ClothBuilder, ClothControl, ColliderSet, XPBDSolver  # noqa: F401
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
