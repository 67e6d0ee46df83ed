"""Visibility methods: one interface (:class:`VisibilityMethod`) and one registry (:data:`REGISTRY`).

Two families share them: ``"transfer"`` methods produce the diffuse transfer of docs/conventions.md §2
(:class:`TransferMethod`), ``"area"`` methods the visibility of a rectangular area light
(:class:`~warpshade.visibility.gears.AreaVisibilityMethod`, docs/conventions.md §4). Every method is
built through :func:`get_method` (the pipeline included), and declares its knobs once (:mod:`.knobs`).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from .base import TransferMethod, VisibilityMethod

REGISTRY = {
    "transfer": {
        "reference": "warpshade.visibility.reference:ReferenceTransfer",
        "hemiraster": "warpshade.visibility.hemiraster:HemirasterTransfer",
        "disks": "warpshade.visibility.disks:DiskTransfer",
        "spheres": "warpshade.visibility.spheres:SpheresTransfer",
    },
    "area": {
        "gears": "warpshade.visibility.gears.method:GearsVisibility",
        "reference": "warpshade.visibility.gears.reference:RayVisibility",
    },
}
"""kind -> name -> ``"module:Class"``; modules import lazily so one method's import cost is paid only when used."""

METHODS = REGISTRY["transfer"]
"""The transfer methods (``--method`` of ``warpshade run`` and ``warpshade transfer``)."""

AREA_METHODS = tuple(REGISTRY["area"])
"""The area-light visibility methods (``--method`` of ``warpshade visibility``)."""


METHOD_PREFERENCE = ("hemiraster", "reference")
"""Default visibility method: the first of these that is registered (fastest accurate first).

Only methods measured accurate on the shipped scenes belong here (``benchmarks/run_methods.py``:
radiance error against reference transfer at 4096 rays, order 4; the numbers behind this order are in
docs/benchmarks/history.md). ``disks`` and ``spheres`` (made for closed blockers) are not. A method goes
in front once it is measured close to the one it replaces."""


def __getattr__(name: str):
    """:class:`TransferMethod` and :class:`VisibilityMethod` load on first use (they import Warp), so the
    registry above is read without Warp (``warpshade run`` names its workers' method before starting Warp)."""
    if name in ("TransferMethod", "VisibilityMethod"):
        from . import base

        return getattr(base, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def default_method() -> str:
    """The method a run uses when neither the scene nor the command line names one."""
    return next(m for m in METHOD_PREFERENCE if m in METHODS)


NO_METHOD = "none"
"""The method name for no visibility method: each receiver sees the whole upper hemisphere (the unoccluded
transfer, no shadows), in ``warpshade:method``, ``warpshade run --method`` and ``Pipeline(method=)`` alike
(:func:`transfer_method`)."""


def transfer_method(name: str) -> str | None:
    """The transfer method a run is asked for by ``name`` (a scene's ``warpshade:method``, ``--method``,
    ``Pipeline(method=)``): ``name`` when it is registered (:data:`METHODS`), None (no method: unoccluded)
    for :data:`NO_METHOD`. The one place that decides what ``"none"`` means.

    Raises:
        ValueError: for another name, listing the known ones.
    """
    if name == NO_METHOD:
        return None
    if name not in METHODS:
        raise ValueError(f"unknown visibility method '{name}' (known: {', '.join(sorted(METHODS))}, {NO_METHOD})")
    return name


def get_method(name: str, kind: str = "transfer") -> type[VisibilityMethod]:
    """The method class registered as ``name`` in family ``kind`` (``"transfer"`` or ``"area"``).

    Raises:
        ValueError: for an unknown name (the message lists the known ones).
    """
    if kind not in REGISTRY:
        raise ValueError(f"unknown kind of visibility method '{kind}' (known: {', '.join(REGISTRY)})")
    family = REGISTRY[kind]
    try:
        target = family[name]
    except KeyError:
        what = "visibility method" if kind == "transfer" else "area-light visibility method"
        raise ValueError(f"unknown {what} '{name}' (known: {', '.join(sorted(family))})") from None
    mod, cls = target.split(":")
    return getattr(importlib.import_module(mod), cls)


__all__ = ["AREA_METHODS", "METHOD_PREFERENCE", "METHODS", "NO_METHOD", "default_method", "REGISTRY", "TransferMethod", "VisibilityMethod", "get_method", "transfer_method"]
