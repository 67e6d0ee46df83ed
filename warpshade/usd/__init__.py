"""USD boundary: the only package in warpshade that imports ``pxr``."""

from .frames import ShadedStage
from .mesh_io import load_mesh, read_usd_mesh, triangulate
from .package import export
from .scene_io import read_scene, scene_from_stage
from .skel import SkinnedMesh, read_usd_skel
from .writer import AnimationWriter


def usd_version() -> str:
    """Version of the OpenUSD library in use (e.g. ``0.26.11``)."""
    from pxr import Usd

    return ".".join(str(v) for v in Usd.GetVersion())


__all__ = ["AnimationWriter", "ShadedStage", "SkinnedMesh", "export", "load_mesh", "read_scene", "read_usd_mesh", "read_usd_skel",
           "scene_from_stage", "triangulate", "usd_version"]
