"""Spherical harmonics core. The convention is defined once, in :mod:`warpshade.sh.basis`."""

from .basis import MAX_ORDER, check_order, n_coeffs, normalization, sh_eval, sh_index
from .projection import project_function, project_latlong, sphere_quadrature

__all__ = ["MAX_ORDER", "check_order", "n_coeffs", "normalization", "sh_eval", "sh_index"]
__all__ += ["project_function", "project_latlong", "sphere_quadrature"]
