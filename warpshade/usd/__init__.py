"""USD boundary: the only package in warpshade that imports ``pxr``."""

from .mesh_io import read_usd_mesh, triangulate
from .skel import SkinnedMesh, read_usd_skel
from .writer import AnimationWriter

__all__ = ["AnimationWriter", "SkinnedMesh", "read_usd_mesh", "read_usd_skel", "triangulate"]
