"""Disk-hierarchy anisotropic occlusion (Gong et al.; Bunnell's disks): ``--method disks``."""

from .disks import DiskTransfer, build_disk_tree, clamped_cosine_zh

__all__ = ["DiskTransfer", "build_disk_tree", "clamped_cosine_zh"]
