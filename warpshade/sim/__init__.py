"""Cloth and character simulation in Warp kernels (Model / State / Solver split).

Build a :class:`ClothModel` with :class:`ClothBuilder`, make states with ``model.state()``, advance
them with :meth:`XPBDSolver.step`. Colliders live in a :class:`ColliderSet`; characters come from
:class:`LBSSkinner` (linear blend skinning) and :class:`WalkingFigure`. :func:`count_intersections`
counts the triangle pairs of a frame that pass through each other.
"""

from .colliders import ColliderSet, MeshCollider
from .figure import WalkingFigure
from .intersections import IntersectionCounter, count_intersections
from .model import ClothBuilder, ClothModel, SimulationError
from .solver_xpbd import XPBDSolver
from .skinning import LBSSkinner
from .state import ClothControl, ClothState

__all__ = ["ClothBuilder", "ClothControl", "ClothModel", "ClothState", "ColliderSet", "IntersectionCounter", "LBSSkinner",
           "MeshCollider", "SimulationError", "WalkingFigure", "XPBDSolver", "count_intersections"]
