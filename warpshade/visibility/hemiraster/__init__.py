"""Hemispherical rasterization (Kautz, Lehtinen, Aila 2004): per-vertex SH transfer for dynamic meshes.

``kernels.py`` holds the Warp kernels, ``method.py`` the :class:`HemirasterTransfer` that allocates and
launches, ``tables.py`` / ``hierarchy.py`` the static structures, ``oracle.py`` a plain NumPy
rasterizer the kernels are tested against.
"""

from .method import HemirasterTransfer

__all__ = ["HemirasterTransfer"]
