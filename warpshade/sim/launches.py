"""Recorded kernel launches for the per-substep and per-detection loops of the cloth solver.

``wp.launch`` packs its arguments in Python on every call (about 20 us for a kernel of a dozen
arguments on this machine's CPU); a recorded launch (``wp.launch(..., record_cmd=True)``) keeps
them packed, but its ``launch()`` on the CPU still builds the ctypes structure of the arguments
from them on every call. :func:`recorded` wraps a recorded CPU launch in a
:class:`CpuLaunch`, which builds that structure once and calls the kernel's compiled entry point
with it, as ``Launch.launch`` does. :class:`RecordedLaunches` keeps one record per kernel,
dimension and arguments, so a loop that launches the same kernel on the same arrays with the same
scalars pays the packing once.
"""

from __future__ import annotations

import ctypes

import warp as wp

try:  # Warp's CPU capture (APIC): a launch made while it records goes through Launch.launch
    from warp._src.context import _get_apic_capture_for_device as _cpu_capture
except ImportError:  # a Warp without it
    def _cpu_capture(device):
        return None


class CpuLaunch:
    """A recorded CPU launch whose argument structure is built once.

    ``launch()`` calls the kernel's forward entry point with the launch bounds and that structure,
    which is what ``wp.Launch.launch`` does on the CPU after building the structure anew from the
    recorded parameters (the same kernel on the same arguments: the same results). While Warp's CPU
    capture records, it defers to ``wp.Launch.launch``.

    Args:
        cmd: A forward launch on the CPU recorded with ``wp.launch(..., record_cmd=True)``.
    """

    def __init__(self, cmd: wp.Launch):
        self.cmd = cmd
        self._names = [a.label for a in cmd.kernel.adj.args]
        fields = [(name, type(p)) for name, p in zip(self._names, cmd.params[1:])]
        self._args = type("ArgsStruct", (ctypes.Structure,), {"_fields_": fields})()
        for name, p in zip(self._names, cmd.params[1:]):
            setattr(self._args, name, p)
        self._call = (cmd.hooks.forward, ctypes.byref(cmd.params[0]), ctypes.byref(self._args))

    @staticmethod
    def applies(cmd: wp.Launch) -> bool:
        """A forward CPU launch of one thread per block with a compiled entry point (what
        ``wp.Launch.launch`` runs through the same call)."""
        return (cmd.device.is_cpu and not cmd.adjoint and cmd.block_dim <= 1 and cmd.hooks.forward is not None
                and len(cmd.params) == len(cmd.kernel.adj.args) + 1)

    def launch(self) -> None:
        if _cpu_capture(self.cmd.device) is not None:
            self.cmd.launch()
            return
        forward, bounds, args = self._call
        forward(bounds, args)

    def set_param_by_name(self, name: str, value) -> None:
        """Set one argument (``wp.Launch.set_param_by_name``) in the record and the structure."""
        self.cmd.set_param_by_name(name, value)
        setattr(self._args, name, self.cmd.params[1 + self._names.index(name)])


def recorded(cmd: wp.Launch):
    """``cmd`` as a :class:`CpuLaunch` where one applies, else ``cmd`` itself."""
    return CpuLaunch(cmd) if CpuLaunch.applies(cmd) else cmd


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
            cmd = self._records[key] = recorded(wp.launch(kernel, dim=dim, inputs=inputs, outputs=outputs,
                                                          device=self.device, record_cmd=True))
        cmd.launch()

    def __len__(self) -> int:
        return len(self._records)


__all__ = ["CpuLaunch", "RecordedLaunches", "recorded"]
