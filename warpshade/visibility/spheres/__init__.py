"""Sphere-set soft shadows (Ren et al. 2006) and one diffuse bounce (Guerrero's thesis ch. 4–5)."""

from .fitting import SphereTree, build_sphere_tree, cluster_receivers, halfspace_blocker, refit_np, tree_from_spheres
from .method import SpheresTransfer
from .reflections import SphereReflections

__all__ = ["SphereReflections", "SphereTree", "SpheresTransfer", "build_sphere_tree", "cluster_receivers", "halfspace_blocker",
           "refit_np", "tree_from_spheres"]
