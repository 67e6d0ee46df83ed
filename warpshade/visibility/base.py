"""The interface every visibility method shares (build once, ``update(points)`` per frame, ``transfer``).

Every method produces the diffuse transfer vector of docs/conventions.md §2 in world space:
``T_p,i = ∫ y_i(ω) V_p(ω) max(0, n_p·ω) dω`` (SH convention: :mod:`warpshade.sh.basis`), so the
pipeline, the benchmark and the planner treat all methods alike and compare them one to one.
"""

from __future__ import annotations

import argparse
from abc import ABC, abstractmethod
from typing import ClassVar

import numpy as np
import warp as wp

from ..geometry.mesh import TriMesh, first_nonfinite
from ..geometry.normals import vertex_normals
from ..sh.basis import check_order
from . import knobs as _knobs


def int_at_least(minimum: int):
    """argparse ``type=``: an integer >= ``minimum``; argparse names the flag in the error."""

    def parse(text: str) -> int:
        try:
            value = int(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"invalid int value: {text!r}") from None
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be an integer >= {minimum}, got {value}")
        return value

    parse.__name__ = f"int >= {minimum}"
    return parse


positive_int = int_at_least(1)
nonnegative_int = int_at_least(0)


class VisibilityMethod(ABC):
    """Base class of every visibility method: per-vertex transfer (:class:`TransferMethod`) and area-light
    visibility (:class:`~warpshade.visibility.gears.AreaVisibilityMethod`), registered together in
    :data:`warpshade.visibility.REGISTRY`.

    A method builds static structures in ``__init__`` from the mesh's topology and rest pose, then
    recomputes its output in :meth:`update` for new positions. Its knobs are declared once, in ``KNOBS``
    (:mod:`.knobs`): the command-line flags, the knobs picked out of parsed arguments, validation and
    normalisation, and :meth:`knobs` derive from it; defaults are the constructor's.
    """

    name: ClassVar[str] = ""
    """Method name used on the command line (``--method NAME``)."""
    kind: ClassVar[str] = ""
    """``"transfer"`` or ``"area"`` (the registry's two families)."""
    KNOBS: ClassVar[tuple] = ()
    """This class's own knobs (:class:`~.knobs.Knob`); :attr:`SCHEMA` adds the inherited ones."""
    SCHEMA: ClassVar[tuple] = ()
    """Every knob of the class, inherited first, defaults filled in from the constructor."""

    def __init_subclass__(cls, **kwargs):
        super().__init_subclass__(**kwargs)
        merged: dict = {}
        for base in reversed(cls.__mro__):
            for k in base.__dict__.get("KNOBS", ()):
                merged[k.name] = k
        cls.SCHEMA = _knobs.resolve_schema(cls, list(merged.values()))

    def _init_geometry(self, mesh: TriMesh, device: str) -> None:
        """The device arrays every method has: :attr:`faces`, :attr:`points`, :attr:`normals`."""
        self.device = device
        self.mesh = mesh
        self.faces = wp.array(mesh.faces, dtype=wp.int32, device=device)
        self.points = wp.array(mesh.points, dtype=wp.vec3, device=device)
        """Current vertex positions [m], shape (V,), dtype vec3."""
        self.normals = wp.array(mesh.normals, dtype=wp.vec3, device=device)
        """Current unit vertex normals, shape (V,), dtype vec3."""

    # -- knobs ---------------------------------------------------------------------------------
    @classmethod
    def add_arguments(cls, parser: argparse.ArgumentParser) -> None:
        """Add this method's knobs to a parser (``--name`` flags with defaults, from :attr:`SCHEMA`)."""
        _knobs.add_arguments(cls.SCHEMA, parser)

    @classmethod
    def knob_flags(cls) -> list[str]:
        """This method's command-line knob flags (``--rays``, ``--no-cull``), in schema order."""
        return _knobs.cli_flags(cls.SCHEMA)

    @classmethod
    def knob_summary(cls) -> str:
        """This method's command-line knobs with their defaults in one line (``--rays 1024, --seed 0, ...``)."""
        return _knobs.summary(cls.SCHEMA)

    @classmethod
    def knobs_from_args(cls, args: argparse.Namespace) -> dict:
        """Pick this method's knobs out of parsed arguments."""
        return _knobs.from_args(cls.SCHEMA, args)

    @classmethod
    def default_knobs(cls) -> dict:
        """Every knob's default."""
        return _knobs.defaults(cls.SCHEMA)

    @classmethod
    def normalise_knobs(cls, knobs: dict) -> dict:
        """Every knob, given ones validated and coerced, the others at their defaults (equal
        configurations give equal dicts).

        Raises:
            ValueError: an unknown knob or a bad value, naming the method and the knob.
        """
        return _knobs.normalise(cls.SCHEMA, knobs, cls.name)

    @classmethod
    def knob_changes(cls, knobs: dict) -> dict:
        """The knobs of ``knobs`` that differ from the defaults (how a configuration is shown and looked up)."""
        return _knobs.changes(cls.SCHEMA, cls.normalise_knobs(knobs))

    @classmethod
    def sweep(cls, quick: bool = False) -> list[dict]:
        """Knob settings ``warpshade bench`` measures for this method (``quick``: a few, < 2 min total).

        Every entry is a dict of constructor keyword arguments; the default settings must be one of them.
        """
        return [{}]

    # -- per frame ---------------------------------------------------------------------------
    def set_points(self, points, normals=None) -> None:
        """Copy new positions (and normals, else recompute angle-weighted ones) into the device arrays.

        Args:
            points: Positions [m], shape (V, 3) array-like or (V,) vec3 ``wp.array``.
            normals: Optional unit normals of the same shape.
        """
        n = self.mesh.num_vertices
        if isinstance(points, wp.array):
            wp.copy(self.points, points)
        else:
            pts = np.asarray(points, dtype=np.float32)
            if pts.shape != (n, 3):
                raise ValueError(f"{self.mesh.name}: expected points of shape ({n}, 3), got {pts.shape}")
            v = first_nonfinite(pts)
            if v is not None:
                raise ValueError(f"{self.mesh.name}: vertex {v} has a non-finite position {pts[v].tolist()}")
            self.points.assign(pts)
        if normals is None:
            vertex_normals(self.points, self.faces, out=self.normals)
        elif isinstance(normals, wp.array):
            wp.copy(self.normals, normals)
        else:
            self.normals.assign(np.asarray(normals, dtype=np.float32))

    @abstractmethod
    def _compute(self) -> None:
        """Fill the method's output from :attr:`points` and :attr:`normals`."""

    # -- reporting ---------------------------------------------------------------------------
    def knobs(self) -> dict:
        """Every knob's value as used (for STATS.json and benchmarks): the schema's knobs read from the
        instance (resolved values, e.g. rays rounded to a square), then :meth:`_extra_knobs`."""
        out = {}
        for k in self.SCHEMA:
            v = getattr(self, k.attr or k.name)
            out[k.name] = v.tolist() if isinstance(v, np.ndarray) else v
        return {**out, **self._extra_knobs()}

    def _extra_knobs(self) -> dict:
        """Reported settings that are no knobs (structures given to the constructor, e.g. occluder names)."""
        return {}

    def stats(self) -> dict:
        """Method-specific counters from the last :meth:`update` (e.g. triangles rasterized)."""
        return {}


class TransferMethod(VisibilityMethod):
    """Base class of visibility methods that produce per-vertex SH transfer.

    Subclasses build static structures in ``__init__`` (LUTs, rings, hierarchies) from the mesh's
    topology and rest pose, then recompute :attr:`transfer` in :meth:`update` for new positions.

    Args:
        mesh: Mesh giving topology (fixed for the method's lifetime) and the rest pose.
        order: SH order (docs/conventions.md §1), 1..8.
        device: Warp device.
        **knobs: Method-specific settings (the class's ``KNOBS``).
    """

    kind = "transfer"

    def __init__(self, mesh: TriMesh, order: int = 5, device: str = "cpu", **knobs):
        self.order = check_order(order)
        self._init_geometry(mesh, device)
        self.transfer = wp.zeros((mesh.num_vertices, self.order * self.order), dtype=float, device=device)
        """Diffuse transfer (docs/conventions.md §2), shape (V, N*N), dtype float32, world space."""

    def update(self, points=None, normals=None) -> wp.array:
        """Recompute :attr:`transfer` for new vertex positions (the rest pose if None).

        Returns:
            :attr:`transfer`.
        """
        if points is not None:
            self.set_points(points, normals)
        self._compute()
        return self.transfer

    def transfer_numpy(self) -> np.ndarray:
        """:attr:`transfer` on the host, shape (V, N*N), float32."""
        return self.transfer.numpy()
