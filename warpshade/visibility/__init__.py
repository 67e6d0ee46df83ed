"""Visibility methods: one interface (:class:`VisibilityMethod`) and one registry (:data:`REGISTRY`).

Two families share them: ``"transfer"`` methods produce the diffuse transfer of docs/conventions.md §2
(:class:`TransferMethod`), ``"area"`` methods the visibility of a rectangular area light
(:class:`~warpshade.visibility.gears.AreaVisibilityMethod`, docs/conventions.md §4). Every method is
built through :func:`get_method` (the pipeline included), and declares its knobs once (:mod:`.knobs`).
"""

from __future__ import annotations

import importlib

from .base import TransferMethod, VisibilityMethod

REGISTRY = {
    "transfer": {
        "reference": "warpshade.visibility.reference:ReferenceTransfer",
        "hemiraster": "warpshade.visibility.hemiraster:HemirasterTransfer",
        "disks": "warpshade.visibility.disks:DiskTransfer",
        "spheres": "warpshade.visibility.spheres:SpheresTransfer",
    },
    "area": {
        "gears": "warpshade.visibility.gears.gears:GearsVisibility",
        "reference": "warpshade.visibility.gears.reference:RayVisibility",
    },
}
"""kind -> name -> ``"module:Class"``; modules import lazily so one method's import cost is paid only when used."""

METHODS = REGISTRY["transfer"]
"""The transfer methods (``--method`` of ``warpshade run`` and ``warpshade transfer``)."""

AREA_METHODS = tuple(REGISTRY["area"])
"""The area-light visibility methods (``--method`` of ``warpshade visibility``)."""


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


__all__ = ["AREA_METHODS", "METHODS", "REGISTRY", "TransferMethod", "VisibilityMethod", "get_method"]
