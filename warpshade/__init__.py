"""warpshade: Warp (CPU) cloth and character simulation shaded with SH soft shadows, exported to USD."""

__version__ = "0.1.0"

from .geometry import MeshError, TriMesh, load_mesh
from .sh import n_coeffs, sh_eval
from .visibility import METHODS, TransferMethod, get_method
from .pipeline import Pipeline, RunReport
from .scene import LightSpec, Material, Scene, SceneError, SceneObject

__all__ = ["METHODS", "MeshError", "TransferMethod", "TriMesh", "__version__", "get_method", "load_mesh",
           "n_coeffs", "sh_eval"]
__all__ += ["LightSpec", "Material", "Pipeline", "RunReport", "Scene", "SceneError", "SceneObject"]
