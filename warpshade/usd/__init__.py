"""USD boundary: the only package in warpshade that imports ``pxr``."""

from .frames import ShadedStage
from .mesh_io import read_usd_mesh, triangulate
from .scene_io import read_scene, scene_from_stage
from .skel import SkinnedMesh, read_usd_skel
from .writer import AnimationWriter

__all__ = ["AnimationWriter", "ShadedStage", "SkinnedMesh", "read_scene", "read_usd_mesh", "read_usd_skel",
           "scene_from_stage", "triangulate"]
