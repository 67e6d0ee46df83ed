"""Disk-hierarchy anisotropic occlusion (Gong et al.; Bunnell's disks): ``--method disks``."""

from .disks import DiskTransfer, build_disk_tree

__all__ = ["DiskTransfer", "build_disk_tree"]
