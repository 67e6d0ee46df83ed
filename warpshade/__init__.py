"""warpshade: Warp (CPU) cloth and character simulation shaded with SH soft shadows, exported to USD."""

from ._version import __version__
from ._startup import guard_startup

guard_startup()  # Ctrl-C while the package loads, in the warpshade command: one line, exit code 130

from .geometry import MeshError, TriMesh


def load_mesh(path, prim: str | None = None) -> TriMesh:
    """Load a triangle mesh from USD, OBJ, PLY or STL: :func:`warpshade.usd.load_mesh`, imported on the first
    call so that ``import warpshade`` does not load USD."""
    from .usd import load_mesh as load

    return load(path, prim)


from .lighting import (ConstantEnvironment, DirectionalLight, EnvironmentMap, PointLight, RectLight, Sky, SphereLight,
                       default_environment)
from .radiance import exit_radiance, shade
from .sh import n_coeffs, sh_eval
from .sim import (ClothBuilder, ClothControl, ClothModel, ClothState, ColliderSet, LBSSkinner, MeshCollider,
                  SimulationError, WalkingFigure, XPBDSolver)
from .visibility import METHODS, REGISTRY, TransferMethod, VisibilityMethod, get_method
from .visibility.knobs import Knob
from .pipeline import Pipeline, RunConfig, RunReport, resolve_run
from .scene import LightSpec, Material, Scene, SceneError, SceneObject
from .visibility.gears import AreaVisibilityMethod, LightRect, get_area_method

__all__ = ["ConstantEnvironment", "DirectionalLight", "EnvironmentMap", "PointLight", "RectLight", "Sky",
           "SphereLight", "default_environment", "exit_radiance", "shade"]
__all__ += ["METHODS", "MeshError", "TransferMethod", "TriMesh", "__version__", "get_method", "load_mesh",
           "n_coeffs", "sh_eval"]
__all__ += ["LightSpec", "Material", "Pipeline", "RunReport", "Scene", "SceneError", "SceneObject"]
__all__ += ["Knob", "REGISTRY", "RunConfig", "VisibilityMethod", "resolve_run"]
__all__ += ["AreaVisibilityMethod", "LightRect", "get_area_method"]
__all__ += ["ClothBuilder", "ClothControl", "ClothModel", "ClothState", "ColliderSet", "LBSSkinner", "MeshCollider",
            "SimulationError", "WalkingFigure", "XPBDSolver"]

from .planner import Plan, apply_plan, make_plan

__all__ += ["Plan", "apply_plan", "make_plan"]

from .pipeline.area import AreaLightShading

__all__ += ["AreaLightShading"]

from . import script
from .script import box, capsule, cloth, cloth_grid, cone, cylinder, distant, dome, ground, make_scene, mesh, run, sky, sphere

__all__ += ["box", "capsule", "cloth", "cloth_grid", "cone", "cylinder", "distant", "dome", "ground", "make_scene", "mesh", "run",
            "script", "sky", "sphere"]
