"""The planner's cost model and the measured frontier it reads: per-pass constants
(``warpshade/data/pass_costs.json``), the method cost fit ``t = a V + b V log2 F + c V F``
(:func:`fit_cost`, :func:`estimate_seconds`) and the frontier lookups (:func:`load_frontier`,
:func:`find_config`). See :mod:`warpshade.planner` for how the plan uses them."""

from __future__ import annotations

import json
import os
from importlib import resources
from typing import TYPE_CHECKING

if TYPE_CHECKING:
    import numpy as np

REDOT_SECONDS_PER_COEFF = 2.5e-9
"""Re-dot cost per vertex per SH coefficient per RGB channel [s] (NumPy matmul, measured on this machine:
6102×25 @ 25×3 in ~1.1 ms)."""

_PASS_COSTS: dict | None = None


def load_pass_costs() -> dict:
    """The measured per-pass constants (``warpshade/data/pass_costs.json``, written by
    ``benchmarks/planner_costs.py --write-data``): ``{"constants": {...}, "order", "note"}``."""
    global _PASS_COSTS
    if _PASS_COSTS is None:
        with resources.files("warpshade").joinpath("data/pass_costs.json").open() as f:
            _PASS_COSTS = json.load(f)
    return _PASS_COSTS


def cost_features(vertices, triangles) -> "np.ndarray":
    """Features of the method cost model, ``[V, V log2 F, V F]``, shape (n, 3) float64."""
    import numpy as np

    v = np.atleast_1d(np.asarray(vertices, dtype=np.float64))
    f = np.maximum(np.atleast_1d(np.asarray(triangles, dtype=np.float64)), 2.0)
    return np.stack([v, v * np.log2(f), v * f], axis=1)


def fit_cost(features, seconds) -> "np.ndarray":
    """Non-negative least squares ``seconds ≈ features @ coef`` with relative residuals (each row weighted
    by 1/seconds, so small and large meshes count alike); shape (k,) float64.

    Solved exactly by trying every support: the optimum of this convex problem is the unconstrained
    least-squares fit on its support (the features whose coefficient is > 0), so the best of the
    non-negative fits over the 2^k supports is it (k = 3 here: 7 tiny solves). This keeps
    ``scipy.optimize`` (0.2-0.4 s to import) off ``warpshade run``'s path before its workers get their
    spec; :func:`scipy.optimize.nnls` gives the same coefficients (tested).
    """
    import itertools

    import numpy as np

    x = np.asarray(features, dtype=np.float64)
    y = np.asarray(seconds, dtype=np.float64)
    w = 1.0 / np.maximum(y, 1e-12)
    scale = np.maximum(np.abs(x).max(axis=0), 1e-300)  # conditioning: V·F is ~1e7 where V is ~1e3
    a, b = x * w[:, None] / scale, y * w
    k = a.shape[1]
    best, best_res = np.zeros(k), float(b @ b)  # the empty support: every coefficient 0
    for size in range(1, k + 1):
        for support in itertools.combinations(range(k), size):
            cols = list(support)
            c, *_ = np.linalg.lstsq(a[:, cols], b, rcond=None)
            if (c < 0.0).any():
                continue
            r = b - a[:, cols] @ c
            res = float(r @ r)
            if res < best_res * (1.0 - 1e-12):
                best, best_res = np.zeros(k), res
                best[cols] = c
    return best / scale


REFLECTION_SECONDS_PER_VERTEX_SPHERE = 7.7e-8
"""One-bounce reflection cost per receiver vertex per reflecting leaf sphere at SH order 4 [s] (both passes,
the pipeline's default cuts; CPU time of ``python benchmarks/spheres.py --reflections-only``: 106 ms for
30 588 receivers and 45 leaf spheres); scaled by (order/4)² for other orders."""

REFLECTION_SPHERES_PER_OBJECT = 15
"""Leaf spheres per object of ``warpshade run --reflections`` (``--reflection-spheres``)."""


def load_frontier(path: str | None = None) -> dict:
    """The measured frontier: ``path`` (a frontier file, as ``warpshade bench --frontier`` writes), else the one
    shipped in ``warpshade/data/frontier.json``."""
    if path is None:
        with resources.files("warpshade").joinpath("data/frontier.json").open() as f:
            return json.load(f)
    if not os.path.isfile(path):
        raise ValueError(f"{path}: no such frontier file")
    with open(path) as f:
        data = json.load(f)
    if isinstance(data, list):
        raise ValueError(f"{path}: a warpshade bench results.json, not a frontier: convert it with "
                         "warpshade.bench.report.frontier_from_results (warpshade plan --frontier does)")
    if "configs" not in data:
        raise ValueError(f"{path}: not a frontier (no 'configs')")
    return data


def estimate_seconds(config: dict, vertices: int, key: str = "seconds", triangles: int | None = None) -> float:
    """Time of a frontier configuration on a mesh of ``vertices`` vertices and ``triangles`` triangles.

    With ``triangles`` and at least three distinct measured meshes: :func:`fit_cost` over the timings
    (the fastest timing per mesh, since repeats on a loaded machine only add noise). Otherwise the time of
    the measured mesh nearest in vertex count, scaled linearly by vertex count.
    """
    import math

    best: dict = {}
    for t in config["timings"]:
        k = (t["vertices"], t.get("triangles"))
        if k not in best or t.get(key, 0.0) < best[k].get(key, 0.0):
            best[k] = t
    rows = [t for t in best.values() if t.get("triangles")]
    if triangles is not None and len(rows) >= 3:
        coef = fit_cost(cost_features([t["vertices"] for t in rows], [t["triangles"] for t in rows]),
                        [t.get(key, 0.0) for t in rows])
        return float(cost_features(vertices, triangles)[0] @ coef)
    t = min(config["timings"], key=lambda t: abs(math.log(max(1, t["vertices"]) / max(1, vertices))))
    return float(t.get(key, 0.0)) * vertices / max(1, t["vertices"])


def _matches(config: dict, method: str, order: int, knobs: dict) -> bool:
    if config["method"] != method or config["order"] != order:
        return False
    return all(config["knobs"].get(k) == v for k, v in knobs.items())


def default_knobs(method: str) -> dict:
    """A method's default knobs (its knob schema, :attr:`warpshade.visibility.VisibilityMethod.SCHEMA`)."""
    from ..visibility import get_method

    return get_method(method).default_knobs()


def find_config(frontier: dict, method: str, order: int, knobs: dict) -> tuple[dict | None, str]:
    """The frontier configuration of ``method`` with ``knobs`` at ``order`` (else at the nearest measured order).

    Among matches, the one agreeing with most command-line defaults (defaults may be sentinels such as
    "auto" that ``knobs()`` reports resolved, so agreement is scored).

    Returns:
        ``(config or None, source)``: source says which order it was measured at when not ``order``.
    """
    defaults = default_knobs(method)
    orders = sorted({c["order"] for c in frontier["configs"] if c["method"] == method}, key=lambda o: (abs(o - order), -o))
    for o in orders:
        match = [c for c in frontier["configs"] if _matches(c, method, o, knobs)]
        if match:
            cfg = max(match, key=lambda c: sum(c["knobs"].get(k) == v for k, v in defaults.items()))
            if "kwargs" in cfg:
                # the same constructor call may report different knobs per mesh (e.g. disks' sides=auto
                # resolving to one or two sides): its timings on every mesh belong to one cost fit
                same = [c for c in frontier["configs"] if c["method"] == method and c["order"] == o
                        and c.get("kwargs") == cfg["kwargs"]]
                cfg = {**cfg, "timings": [t for c in same for t in c["timings"]]}
            return cfg, ("" if o == order else f"cost measured at order {o}")
    return None, ""
