"""Visibility methods. Each produces the diffuse transfer of docs/conventions.md §2 through :class:`TransferMethod`."""

from __future__ import annotations

import importlib

from .base import TransferMethod

# name -> "module:Class"; modules import lazily so one method's import cost is paid only when used.
METHODS = {
    "reference": "warpshade.visibility.reference:ReferenceTransfer",
    "hemiraster": "warpshade.visibility.hemiraster:HemirasterTransfer",
    "disks": "warpshade.visibility.disks:DiskTransfer",
    "spheres": "warpshade.visibility.spheres:SpheresTransfer",
}


def get_method(name: str) -> type[TransferMethod]:
    """The :class:`TransferMethod` subclass registered as ``name``.

    Raises:
        ValueError: for an unknown name (the message lists the known ones).
    """
    try:
        target = METHODS[name]
    except KeyError:
        raise ValueError(f"unknown visibility method '{name}' (known: {', '.join(sorted(METHODS))})") from None
    mod, cls = target.split(":")
    return getattr(importlib.import_module(mod), cls)


__all__ = ["METHODS", "TransferMethod", "get_method"]
