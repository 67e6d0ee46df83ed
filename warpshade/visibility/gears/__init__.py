"""Area-light visibility: GEARS bitmasks (Popescu) and the ray-traced reference (docs/conventions.md §4)."""

from __future__ import annotations

from .base import AreaVisibilityMethod, LightRect


def get_area_method(name: str) -> type[AreaVisibilityMethod]:
    """The area-light visibility class called ``name`` (``gears`` or ``reference``)."""
    if name == "gears":
        from .gears import GearsVisibility

        return GearsVisibility
    if name == "reference":
        from .reference import RayVisibility

        return RayVisibility
    raise ValueError(f"unknown area-light visibility method '{name}' (known: gears, reference)")


AREA_METHODS = ("gears", "reference")

__all__ = ["AREA_METHODS", "AreaVisibilityMethod", "LightRect", "get_area_method"]
