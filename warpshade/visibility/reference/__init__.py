"""The ray-traced reference transfer (``--method reference``): the ground truth every other method is
measured against. ``method.py`` holds :class:`ReferenceTransfer`, ``kernels.py`` its Warp kernel; the
ray helpers the methods share are in :mod:`warpshade.visibility.rays`."""

from .method import RAYS_PER_LAUNCH, ReferenceTransfer

__all__ = ["RAYS_PER_LAUNCH", "ReferenceTransfer"]
