"""Disk-hierarchy anisotropic occlusion (Gong et al.; Bunnell's disks): ``--method disks``.

``method.py`` holds :class:`DiskTransfer`, ``kernels.py`` its Warp kernels, ``oracle.py`` the NumPy
version the kernels are tested against.
"""

from .method import DiskTransfer, build_disk_tree

__all__ = ["DiskTransfer", "build_disk_tree"]
