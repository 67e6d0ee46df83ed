"""Error metrics shared by tests, benchmarks and the planner (one definition everywhere).

Relative L2 transfer error: per vertex ``e_v = ||T_v - R_v||_2`` over the SH coefficients, divided by
the mean reference magnitude ``mean_v ||R_v||_2``. Normalising by the mean rather than per vertex
keeps fully occluded vertices (``R_v ≈ 0``) from dividing by zero while still weighting every
vertex equally.
"""

from __future__ import annotations

import numpy as np


def transfer_errors(transfer: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Per-vertex relative L2 errors, shape (V,).

    Args:
        transfer: Transfer to judge, shape (V, N*N).
        reference: Ground truth, shape (V, M*M); compared on the first ``min(N*N, M*M)`` coefficients.
    """
    t = np.asarray(transfer, dtype=np.float64)
    r = np.asarray(reference, dtype=np.float64)
    n = min(t.shape[1], r.shape[1])
    scale = np.linalg.norm(r[:, :n], axis=1).mean()
    if scale == 0.0:
        raise ValueError("reference transfer is zero everywhere; relative error undefined")
    return np.linalg.norm(t[:, :n] - r[:, :n], axis=1) / scale


def error_summary(transfer: np.ndarray, reference: np.ndarray) -> dict:
    """``{"error_mean", "error_p95", "error_max"}`` of :func:`transfer_errors`."""
    e = transfer_errors(transfer, reference)
    return {"error_mean": float(e.mean()), "error_p95": float(np.percentile(e, 95)), "error_max": float(e.max())}


def radiance_error(radiance: np.ndarray, reference: np.ndarray) -> float:
    """Mean relative radiance error: ``mean_v ||L_v - L*_v|| / mean_v ||L*_v||`` over RGB, shape (V, 3) inputs."""
    a = np.asarray(radiance, dtype=np.float64)
    b = np.asarray(reference, dtype=np.float64)
    scale = np.linalg.norm(b, axis=1).mean()
    if scale == 0.0:
        raise ValueError("reference radiance is zero everywhere; relative error undefined")
    return float(np.linalg.norm(a - b, axis=1).mean() / scale)
