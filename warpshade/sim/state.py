"""Per-step cloth arrays (:class:`ClothState`) and per-step inputs (:class:`ClothControl`)."""

from __future__ import annotations

import numpy as np
import warp as wp

from ..geometry.mesh import first_nonfinite


class ClothState:
    """What changes every step.

    Attributes:
        points: Vertex positions [m], shape (V,), dtype vec3.
        velocities: Vertex velocities [m/s], shape (V,), dtype vec3.
    """

    def __init__(self, model):
        self.model = model
        self.points = wp.array(model.rest_points_np, dtype=wp.vec3, device=model.device)
        self.velocities = wp.zeros(model.particle_count, dtype=wp.vec3, device=model.device)

    def assign(self, other: "ClothState") -> None:
        """Copy positions and velocities from another state of the same model."""
        wp.copy(self.points, other.points)
        wp.copy(self.velocities, other.velocities)

    def set_points(self, points: np.ndarray, velocities: np.ndarray | None = None) -> None:
        """Set positions (and optionally velocities) from host arrays, shape (V, 3).

        Raises:
            ValueError: wrong shape or a non-finite value (naming the vertex).
        """
        for name, arr in (("points", points), ("velocities", velocities)):
            if arr is None:
                continue
            a = np.asarray(arr, dtype=np.float32)
            if a.shape != (self.model.particle_count, 3):
                raise ValueError(f"ClothState.set_points: {name} must have shape ({self.model.particle_count}, 3), "
                                 f"got {a.shape}")
            bad = ~np.isfinite(a).all(axis=1)
            if bad.any():
                v = int(np.flatnonzero(bad)[0])
                raise ValueError(f"ClothState.set_points: {name} of vertex {v} is not finite: {a[v].tolist()}")
            getattr(self, name).assign(a)

    def energy(self, gravity=(0.0, -9.81, 0.0)) -> dict:
        """Kinetic, gravitational and elastic (stretch) energy [J] on the host (for diagnostics/tests).

        Elastic energy is 1/2 k (|xi - xj| - L)^2 over edges with finite stiffness; kinematic vertices
        contribute no kinetic or potential energy.
        """
        m = self.model
        x = self.points.numpy().astype(np.float64)
        v = self.velocities.numpy().astype(np.float64)
        free = m.inv_mass_np > 0
        mass = np.where(free, m.mass, 0.0)
        kinetic = 0.5 * float(np.sum(mass * np.sum(v * v, axis=1)))
        potential = -float(np.sum(mass * (x @ np.asarray(gravity, dtype=np.float64))))
        e = m.edges_np
        length = np.linalg.norm(x[e[:, 0]] - x[e[:, 1]], axis=1)
        comp = m.edge_compliance.numpy().astype(np.float64)
        rest = m.edge_rest_length.numpy().astype(np.float64)
        k = np.where(comp > 0, 1.0 / np.where(comp > 0, comp, 1.0), 0.0)
        elastic = 0.5 * float(np.sum(k * (length - rest) ** 2))
        return {"kinetic": kinetic, "potential": potential, "elastic": elastic,
                "total": kinetic + potential + elastic}


class ClothControl:
    """Inputs of a step that the caller animates.

    Attributes:
        attachment_targets: Where each attached vertex must be at the END of the step [m], shape (A,),
            dtype vec3. Within the step the vertex moves linearly from its current position.
        wind: Air velocity [m/s], (3,) tuple, uniform in space.
    """

    def __init__(self, model):
        self.model = model
        idx = model.attachment_indices.numpy()
        self.attachment_targets = wp.array(model.rest_points_np[idx].reshape(-1, 3), dtype=wp.vec3,
                                           device=model.device)
        self.wind = (0.0, 0.0, 0.0)

    def set_targets(self, targets: np.ndarray) -> None:
        """Set attachment targets from a host array, shape (A, 3).

        Raises:
            ValueError: wrong shape or a non-finite target (naming the attachment slot and vertex).
        """
        a = np.asarray(targets, dtype=np.float32)
        n = self.model.attachment_count
        if a.shape != (n, 3):
            raise ValueError(f"ClothControl.set_targets: expected shape ({n}, 3), got {a.shape}")
        k = first_nonfinite(a)
        if k is not None:
            raise ValueError(f"ClothControl.set_targets: target {k} (vertex "
                             f"{int(self.model.attachment_indices.numpy()[k])}) is not finite: {a[k].tolist()}")
        self.attachment_targets.assign(a)

    def set_wind(self, wind) -> None:
        """Set the wind velocity [m/s], (3,)."""
        w = np.asarray(wind, dtype=np.float64).reshape(-1)
        if w.shape != (3,) or not np.isfinite(w).all():
            raise ValueError(f"ClothControl.set_wind: wind must be 3 finite numbers, got {wind}")
        self.wind = tuple(float(c) for c in w)
