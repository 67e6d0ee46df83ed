"""``warpshade bench``: the measured speed/accuracy frontier of every visibility method.

:func:`run_bench` sweeps each registered method's ``sweep(quick)`` knobs and SH orders over the
standard mesh set (:mod:`.meshes`) and judges transfer and radiance against a cached ray-traced
ground truth, and GEARS area-light visibility against ray-traced area-light truth (:mod:`.area`);
:mod:`.report` writes JSON, CSV, the Pareto plot and the planner's frontier file.
"""

from .area import AREA_METHODS, area_errors, bench_light, run_area
from .environments import ENV_ORDER, environments, radiance
from .meshes import BenchMesh, character, standard_meshes, two_objects, wrinkled_cloth
from .reference_cache import ground_truth, mesh_hash
from .report import frontier_from_results, markdown_table, plot_pareto, write_csv, write_json
from .records import pareto_mask
from .runner import BenchSettings, method_configs, run_bench

__all__ = ["AREA_METHODS", "area_errors", "bench_light", "run_area", "ENV_ORDER", "BenchMesh", "BenchSettings", "character", "environments", "frontier_from_results",
           "ground_truth", "markdown_table", "mesh_hash", "method_configs", "pareto_mask", "plot_pareto",
           "radiance", "run_bench", "standard_meshes", "two_objects", "wrinkled_cloth", "write_csv", "write_json"]
