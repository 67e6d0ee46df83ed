"""USD boundary: the only package in warpshade that imports ``pxr``."""

from .mesh_io import read_usd_mesh, triangulate
from .writer import AnimationWriter

__all__ = ["AnimationWriter", "read_usd_mesh", "triangulate"]
