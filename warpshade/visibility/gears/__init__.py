"""Area-light visibility: GEARS bitmasks (Popescu) and the ray-traced reference (docs/conventions.md §4).

Both are the ``"area"`` family of :data:`warpshade.visibility.REGISTRY`. ``base.py`` holds the rect light
and the interface area-light methods share, ``method.py`` :class:`GearsVisibility`, ``kernels.py`` the Warp
kernels, ``oracle.py`` the NumPy version they are tested against, ``reference.py`` the ray-traced truth.
"""

from __future__ import annotations

from .. import AREA_METHODS, get_method
from .base import AreaVisibilityMethod, LightRect


def get_area_method(name: str) -> type[AreaVisibilityMethod]:
    """The area-light visibility class called ``name`` (``gears`` or ``reference``):
    ``get_method(name, kind="area")``."""
    return get_method(name, kind="area")


__all__ = ["AREA_METHODS", "AreaVisibilityMethod", "LightRect", "get_area_method"]
