"""Rectangular area lights and the interface area-light visibility methods share.

Mirrors :class:`~warpshade.visibility.base.TransferMethod`: build once in ``__init__(mesh, light,
k, device, **knobs)``, ``update(points, normals=None)`` per frame, then read :attr:`visibility`
(fraction of the light's area visible, docs/conventions.md §4) and :attr:`form_factor` (the same with
the light's cosine terms, for radiance).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import warp as wp

from ...geometry.mesh import TriMesh
from ...lighting import RectLight
from ..base import VisibilityMethod
from ..knobs import Knob
from ..rays import local_origin


@dataclass
class LightRect(RectLight):
    """The rect light of area-light visibility: a :class:`warpshade.lighting.RectLight` that emits on both
    sides (docs/conventions.md §4) and whose half-axes must be orthogonal (the GEARS kernels recover light
    coordinates with dual axes ``u/|u|²``, ``v/|v|²``). Positional ``LightRect(center, u, v)`` as before.

    Attributes:
        center: Centre [m], shape (3,).
        u: First half-axis [m], shape (3,) (half the width, along the width).
        v: Second half-axis [m], shape (3,), orthogonal to ``u``.
    """

    two_sided: bool = True

    def __post_init__(self):
        for name in ("center", "u", "v"):
            x = np.asarray(getattr(self, name), dtype=np.float64)
            if x.shape != (3,) or not np.isfinite(x).all():
                raise ValueError(f"rect light {name} must be 3 finite numbers, got {x.tolist()}")
        u, v = np.asarray(self.u, np.float64), np.asarray(self.v, np.float64)
        lu, lv = np.linalg.norm(u), np.linalg.norm(v)
        if lu == 0.0 or lv == 0.0:
            raise ValueError(f"rect light half-axes must be non-zero, got u={u.tolist()} v={v.tolist()}")
        if abs(np.dot(u, v)) > 1e-4 * lu * lv:
            raise ValueError(f"rect light half-axes must be orthogonal, got u={u.tolist()} v={v.tolist()} "
                             f"(cos = {np.dot(u, v) / (lu * lv):.3g})")
        super().__post_init__()

    @classmethod
    def from_light(cls, light) -> LightRect:
        """The area-light view of any light with ``center``, ``u``, ``v`` (e.g. a :class:`RectLight`)."""
        if isinstance(light, cls):
            return light
        if not all(hasattr(light, a) for a in ("center", "u", "v")):
            raise TypeError(f"expected a LightRect or a light with center, u, v; got {type(light).__name__}")
        kw = {"radiance": light.radiance, "name": light.name} if isinstance(light, RectLight) else {}
        return cls(*(np.asarray(getattr(light, a), float).reshape(3) for a in ("center", "u", "v")), **kw)


class AreaVisibilityMethod(VisibilityMethod):
    """Base class of per-vertex area-light visibility methods (the ``"area"`` family of
    :data:`warpshade.visibility.REGISTRY`).

    Args:
        mesh: Receiver mesh; it also blocks the light (self-shadowing). Topology fixed.
        light: The area light (changeable per frame with :meth:`set_light`).
        k: Light sampling resolution: k×k samples (4..32).
        device: Warp device.
        offset: Receiver offset along its normal, as a fraction of the mesh's bounding-box diagonal
            at construction (keeps a vertex's own triangles from shadowing it, like the ray
            reference's origin offset).
    """

    kind = "area"
    KNOBS = (
        Knob("k", int, "k×k light samples per vertex", minimum=1, maximum=32),
        Knob("offset", float, "receiver offset along its normal, fraction of the mesh's bbox diagonal", minimum=0.0,
             attr="offset_rel"),
    )

    def __init__(self, mesh: TriMesh, light: LightRect, k: int = 16, device: str = "cpu", offset: float = 1e-5):
        if int(k) != k or not 1 <= k <= 32:
            raise ValueError(f"k (light samples per side) must be an integer in 1..32, got {k!r}")
        if not offset >= 0.0:
            raise ValueError(f"offset must be >= 0, got {offset}")
        self.k = int(k)
        self.offset_rel = float(offset)
        self._init_geometry(mesh, device)
        n = mesh.num_vertices
        self.masks = wp.zeros((n, self.k), dtype=wp.uint32, device=device)
        """Blocked-sample bitmasks, shape (V, k), dtype uint32: bit i of row j = sample (s_i, t_j) blocked."""
        self.visibility = wp.zeros(n, dtype=float, device=device)
        """Fraction of the light's area visible from each vertex, shape (V,), dtype float32."""
        self.form_factor = wp.zeros(n, dtype=float, device=device)
        """Unoccluded-part form factor ``(1/π) ∫ V max(0, n·ω) |n_L·ω| / r² dA``, shape (V,), dtype float32.

        A Lambertian vertex of albedo ρ under a light of radiance L_e has exit radiance ``ρ L_e F``.
        """
        self._clear = None  # all-clear masks for weighted_visibility, allocated on first use
        self._local_points = wp.empty_like(self.points)
        self._origin = np.zeros(3)
        self.set_light(light)

    def set_light(self, light) -> None:
        """Use another light from the next :meth:`update` on.

        Args:
            light: A :class:`LightRect`, or anything with ``center``, ``u``, ``v`` (e.g.
                :class:`warpshade.lighting.RectLight`); visibility is geometric, so emission
                (radiance, sidedness) is ignored and :attr:`form_factor` treats the light as two-sided.
        """
        self.light = LightRect.from_light(light)

    # -- command line ------------------------------------------------------------------------
    @classmethod
    def sweep(cls, quick: bool = False) -> list[dict]:
        """Constructor keyword arguments ``warpshade bench`` measures (``quick``: a few); includes the defaults."""
        return [{"k": 16}]

    # -- per frame ---------------------------------------------------------------------------
    def update(self, points=None, normals=None) -> wp.array:
        """Recompute :attr:`visibility` (and :attr:`masks`, :attr:`form_factor`) for new positions.

        Args:
            points: New vertex positions, shape (V, 3) (the current ones if None).
            normals: Optional unit normals; recomputed (angle-weighted) when None.

        Returns:
            :attr:`visibility`.
        """
        if points is not None:
            self.set_points(points, normals)
        self._localize()
        self._compute()
        return self.visibility

    def radiance(self, emitted: float = 1.0, albedo=1.0) -> np.ndarray:
        """Lambertian exit radiance ``ρ L_e F`` per vertex (needs a prior :meth:`update`).

        Args:
            emitted: Light radiance L_e [W/(m² sr)], scalar or RGB shape (3,).
            albedo: Albedo ρ, scalar, (3,) or per vertex (V, 3).

        Returns:
            Radiance, shape (V,) for scalar inputs else (V, 3), float32.
        """
        f = self.form_factor.numpy()
        e = np.asarray(emitted, dtype=np.float32)
        a = np.asarray(albedo, dtype=np.float32)
        if e.ndim == 0 and a.ndim == 0:
            return (f * e * a).astype(np.float32)
        return (f[:, None] * e * a).astype(np.float32)

    def weighted_visibility(self, out: wp.array | None = None) -> wp.array:
        """Cosine-weighted visible fraction per vertex (needs a prior :meth:`update`): the share of the
        unshadowed form factor that the visible mask samples carry, ``F_visible / F_all`` over the k×k
        samples (kernel :func:`~warpshade.visibility.gears.kernels.weight_visibility`).

        Multiplied by the exact unshadowed irradiance it estimates the shadowed irradiance; unlike
        :attr:`visibility` (every sample counts alike, the paper's ``v_p``) it weights samples by the
        cosines and distance that make their irradiance, and it is exactly 1 for an unblocked vertex
        and 0 for a fully blocked one.

        Args:
            out: Optional output, shape (V,), dtype float32.

        Returns:
            Shape (V,), dtype float32, in [0, 1].
        """
        from .kernels import weight_visibility

        n = self.mesh.num_vertices
        if self._clear is None:
            self._clear = wp.zeros((n, self.k), dtype=wp.uint32, device=self.device)
        if out is None:
            out = wp.empty(n, dtype=float, device=self.device)
        c, u, v, nl = self.light_args()
        wp.launch(weight_visibility, dim=n, inputs=[self._local_points, self.normals, c, u, v, nl, self.k, self._clear,
                                                    self.visibility, self.form_factor],
                  outputs=[out], device=self.device)
        return out

    # -- reporting ---------------------------------------------------------------------------
    def _offset_abs(self) -> float:
        return self.offset_rel * (self.mesh.bbox_diagonal() or 1.0)

    def _localize(self) -> None:
        """Set :attr:`_local_points` (positions relative to :attr:`_origin`, ``rays.local_origin`` of them), the
        coordinates every kernel works in: float32 resolves a scene far from the world origin there as at the
        origin (0 for a scene about the world origin, where they are the positions themselves)."""
        world = self.points.numpy()
        self._origin = local_origin(world)
        self._local_points.assign((world.astype(np.float64) - self._origin).astype(np.float32))

    @property
    def origin(self) -> np.ndarray:
        """World position (float64, shape (3,)) the kernels' coordinates are relative to, as of the last :meth:`update`."""
        return self._origin

    @property
    def local_points(self) -> wp.array:
        """Vertex positions relative to :attr:`origin` as of the last :meth:`update`, shape (V,), vec3."""
        return self._local_points

    def light_center(self) -> np.ndarray:
        """The light's centre relative to :attr:`_origin`, float64 shape (3,)."""
        return np.asarray(self.light.center, np.float64) - self._origin

    def light_args(self) -> list:
        """(c, u, v, unit normal) as Warp vectors for kernel launches, ``c`` relative to :attr:`_origin`."""
        lt = self.light
        return [wp.vec3(*self.light_center()), wp.vec3(*lt.u), wp.vec3(*lt.v), wp.vec3(*lt.normal)]

