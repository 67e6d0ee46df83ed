"""Spherical harmonics core. The convention is defined once, in :mod:`warpshade.sh.basis`."""

from .basis import MAX_ORDER, check_order, n_coeffs, normalization, sh_eval, sh_index
from .exp import OLTable, fit_ol_table, hybrid_exp_parts, ol_table, sh_exp, sh_log, unit_vector, zh_log
from .projection import project_function, project_latlong, sphere_quadrature
from .products import GauntTensor, gaunt_tensor, product_matrix, sh_product, sh_square, symmetric_product_table
from .rotation import rotate, rotation_blocks, rotation_from_axis_angle, rotation_matrix
from .zonal import (cap_zh, clamped_cosine_zh, phong_zh, sh_to_zh, sphere_visibility_zh, unoccluded_transfer,
                    zh_band_factors, zh_rotate, zh_to_sh)

__all__ = ["GauntTensor", "MAX_ORDER", "OLTable", "cap_zh", "check_order", "clamped_cosine_zh",
           "fit_ol_table", "gaunt_tensor", "hybrid_exp_parts", "n_coeffs", "normalization", "ol_table",
           "phong_zh", "product_matrix", "rotate", "rotation_blocks", "rotation_from_axis_angle",
           "rotation_matrix", "sh_eval", "sh_exp", "sh_index", "sh_log", "sh_product", "sh_square",
           "sh_to_zh", "sphere_visibility_zh", "symmetric_product_table", "unit_vector", "unoccluded_transfer", "zh_band_factors",
           "zh_log", "zh_rotate", "zh_to_sh"]
__all__ += ["project_function", "project_latlong", "sphere_quadrature"]
