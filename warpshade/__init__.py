"""warpshade: Warp (CPU) cloth and character simulation shaded with SH soft shadows, exported to USD.

The names below are loaded on first use (PEP 562 ``__getattr__``): ``import warpshade`` alone loads
neither Warp nor the kernels, so the ``warpshade`` command can start its worker processes first and a
worker imports only what shading needs.
"""

from ._version import __version__ as __version__  # noqa: PLC0414 - re-exported
from ._startup import guard_startup

guard_startup()  # Ctrl-C while the package loads, in the warpshade command: one line, exit code 130

import importlib
from typing import TYPE_CHECKING

_LAZY = {
    "geometry": ("MeshError", "TriMesh"),
    "lighting": ("ConstantEnvironment", "DirectionalLight", "EnvironmentMap", "PointLight", "RectLight", "Sky",
                 "SphereLight", "default_environment"),
    "radiance": ("exit_radiance", "shade"),
    "sh": ("n_coeffs", "sh_eval"),
    "sim": ("ClothBuilder", "ClothControl", "ClothModel", "ClothState", "ColliderSet", "LBSSkinner", "MeshCollider",
            "SimulationError", "WalkingFigure", "XPBDSolver"),
    "visibility": ("METHODS", "REGISTRY", "TransferMethod", "VisibilityMethod", "get_method"),
    "visibility.knobs": ("Knob",),
    "pipeline": ("Pipeline", "RunConfig", "RunReport", "resolve_run"),
    "scene": ("LightSpec", "Material", "Scene", "SceneError", "SceneObject"),
    "visibility.gears": ("AreaVisibilityMethod", "LightRect", "get_area_method"),
    "planner": ("Plan", "apply_plan", "make_plan"),
    "pipeline.area": ("AreaLightShading",),
    "script": ("box", "capsule", "cloth", "cloth_grid", "cone", "cylinder", "distant", "dome", "ground", "make_scene",
               "mesh", "run", "sky", "sphere"),
}
"""Submodule -> the public names it defines, each imported from there on first use."""

_SOURCE = {name: module for module, names in _LAZY.items() for name in names}

if TYPE_CHECKING:  # the same names for type checkers and the API docs (tests/test_package_names.py checks)
    from . import script  # noqa: F401
    from .geometry import MeshError, TriMesh  # noqa: F401
    from .lighting import (ConstantEnvironment, DirectionalLight, EnvironmentMap, PointLight, RectLight, Sky,  # noqa: F401
                           SphereLight, default_environment)
    from .pipeline import Pipeline, RunConfig, RunReport, resolve_run  # noqa: F401
    from .pipeline.area import AreaLightShading  # noqa: F401
    from .planner import Plan, apply_plan, make_plan  # noqa: F401
    from .radiance import exit_radiance, shade  # noqa: F401
    from .scene import LightSpec, Material, Scene, SceneError, SceneObject  # noqa: F401
    from .script import (box, capsule, cloth, cloth_grid, cone, cylinder, distant, dome, ground, make_scene, mesh, run,  # noqa: F401
                         sky, sphere)
    from .sh import n_coeffs, sh_eval  # noqa: F401
    from .sim import (ClothBuilder, ClothControl, ClothModel, ClothState, ColliderSet, LBSSkinner, MeshCollider,  # noqa: F401
                      SimulationError, WalkingFigure, XPBDSolver)
    from .visibility import METHODS, REGISTRY, TransferMethod, VisibilityMethod, get_method  # noqa: F401
    from .visibility.gears import AreaVisibilityMethod, LightRect, get_area_method  # noqa: F401
    from .visibility.knobs import Knob  # noqa: F401

__all__ = sorted([*_SOURCE, "__version__", "load_mesh", "script"])


def load_mesh(path, prim: str | None = None):
    """Load a triangle mesh from USD, OBJ, PLY or STL: :func:`warpshade.usd.load_mesh`, imported on the first
    call so that ``import warpshade`` does not load USD."""
    from .usd import load_mesh as load

    return load(path, prim)


def __getattr__(name: str):
    """A public name (from its submodule, :data:`_LAZY`) or a submodule, imported on first use."""
    module = _SOURCE.get(name)
    if module is not None:
        value = getattr(importlib.import_module(f"{__name__}.{module}"), name)
    elif not name.startswith("__"):
        try:
            value = importlib.import_module(f"{__name__}.{name}")
        except ModuleNotFoundError as exc:
            if exc.name != f"{__name__}.{name}":
                raise
            raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(__all__))
