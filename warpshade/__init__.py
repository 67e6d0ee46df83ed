"""warpshade: Warp (CPU) cloth and character simulation shaded with SH soft shadows, exported to USD."""

__version__ = "0.1.0"

from .geometry import MeshError, TriMesh, load_mesh
from .sh import n_coeffs, sh_eval
from .sim import (ClothBuilder, ClothControl, ClothModel, ClothState, ColliderSet, LBSSkinner, MeshCollider,
                  SimulationError, WalkingFigure, XPBDSolver)
from .visibility import METHODS, TransferMethod, get_method

__all__ = ["METHODS", "ClothBuilder", "ClothControl", "ClothModel", "ClothState", "ColliderSet", "LBSSkinner",
           "MeshCollider", "MeshError", "SimulationError", "TransferMethod", "TriMesh", "WalkingFigure", "XPBDSolver",
           "__version__", "get_method", "load_mesh", "n_coeffs", "sh_eval"]
