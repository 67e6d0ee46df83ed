"""Benchmark records shared by the transfer and area-light sweeps: their knob text and Pareto frontier."""

from __future__ import annotations

import numpy as np


def knobs_text(knobs: dict) -> str:
    """A record's knobs as ``k=v`` words for the progress log (the seed left out)."""
    return " ".join(f"{k}={v}" for k, v in knobs.items() if k not in ("seed",))


def pareto_mask(seconds, errors) -> np.ndarray:
    """True where no other point is at least as fast and as accurate and strictly better in one."""
    s = np.asarray(seconds, dtype=float)
    e = np.asarray(errors, dtype=float)
    out = np.ones(len(s), dtype=bool)
    for i in range(len(s)):
        dominated = (s <= s[i]) & (e <= e[i]) & ((s < s[i]) | (e < e[i]))
        out[i] = not dominated.any()
    return out
