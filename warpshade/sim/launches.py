"""Recorded kernel launches for the per-substep and per-detection loops of the cloth solver.

``wp.launch`` packs its arguments in Python on every call (about 20 us for a kernel of a dozen
arguments on this machine's CPU); a recorded launch (``wp.launch(..., record_cmd=True)``) keeps
them packed and its ``launch()`` skips that work. :class:`RecordedLaunches` keeps one record per
kernel, dimension and arguments, so a loop that launches the same kernel on the same arrays with
the same scalars pays the packing once.
"""

from __future__ import annotations

import warp as wp


class RecordedLaunches:
    """One recorded launch per (kernel, dim, arguments); arrays are told apart by identity (the
    record keeps them alive, so an identity is never reused while its record is kept), every other
    argument by value.

    Args:
        device: Warp device of the launches.
    """

    MAX_RECORDED = 256
    """Most records kept; beyond, the cache starts afresh (arguments that change every call, such as
    a time that grows, would otherwise grow it without bound)."""

    def __init__(self, device):
        self.device = device
        self._records: dict = {}

    def launch(self, kernel, dim: int, inputs: list, outputs: list) -> None:
        """``wp.launch(kernel, dim=dim, inputs=inputs, outputs=outputs)`` through its record."""
        key = (kernel, dim, *(id(a) if isinstance(a, wp.array) else a for a in (*inputs, *outputs)))
        cmd = self._records.get(key)
        if cmd is None:
            if len(self._records) >= self.MAX_RECORDED:
                self._records.clear()
            cmd = self._records[key] = wp.launch(kernel, dim=dim, inputs=inputs, outputs=outputs, device=self.device,
                                                 record_cmd=True)
        cmd.launch()

    def __len__(self) -> int:
        return len(self._records)


__all__ = ["RecordedLaunches"]
