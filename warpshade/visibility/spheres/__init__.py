"""Sphere-set soft shadows (Ren et al. 2006) and one diffuse bounce (Guerrero's thesis ch. 4–5)."""

from .fitting import SphereTree, build_sphere_tree, cluster_receivers, refit_np
from .method import SpheresTransfer

__all__ = ["SphereTree", "SpheresTransfer", "build_sphere_tree", "cluster_receivers", "refit_np"]
