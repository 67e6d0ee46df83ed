"""hemiraster's far field (:func:`.hierarchy.far_field`) kept in the per-user disk cache
(:mod:`warpshade._cache`), so a second run of the same scene and knobs reads it instead of decimating again.

The entry's key is a sha256 over everything the far field depends on: :data:`FORMAT`; the source of
``hierarchy.py`` (the decimation, binding and assignment) and of ``geometry/mesh.py`` (the stitching of
the decimated surface); the versions of numpy, scipy (KD-trees) and ``fast_simplification`` (the
decimation) and the machine architecture; and each part's point and face arrays (dtype, shape, bytes),
the coarse and mid targets and the per-part ``border`` flags. A loaded entry is the built one bit for bit; one that cannot
be read or does not fit the request's shapes is rebuilt.
"""

from __future__ import annotations

import functools
import platform

import numpy as np

from ... import _cache
from ...geometry import mesh as _mesh_module
from . import hierarchy

KIND = "hemiraster_far_field"
"""Subdirectory of the cache root holding far fields."""

FORMAT = "far_field 1"
"""Version of the entry layout (:func:`_flatten`); bumped when it changes."""

_BASE = ("points", "faces", "bind_face", "bind_bary", "bind_offset", "owner", "extra")
_MID = _BASE + ("coarse_owner", "coarse_extra", "outline")


@functools.lru_cache(maxsize=None)
def _environment() -> tuple:
    return (FORMAT, _cache.source_digest(hierarchy.__file__), _cache.source_digest(_mesh_module.__file__),
            platform.machine(), *_cache.versions("numpy", "scipy", "fast-simplification"))


def far_field_key(parts, targets, mid_targets=None, border=False) -> str:
    """The cache key of ``hierarchy.far_field(parts, targets, mid_targets, border)`` (module docstring)."""
    key = _cache.Key(*_environment(), len(parts))
    for pts, faces in parts:
        key.add(np.asarray(pts), np.asarray(faces))
    key.add(tuple(int(t) for t in targets).__repr__(),
            None if mid_targets is None else tuple(int(t) for t in mid_targets).__repr__(),
            hierarchy.part_borders(border, len(parts)).__repr__())
    return key.hexdigest()


def _flatten(far: dict) -> dict:
    out = {k: far[k] for k in _BASE}
    out.update({f"mid.{k}": v for k, v in far.get("mid", {}).items()})
    return out


def _fits(arrays: dict, num_faces: int, mid: bool) -> bool:
    """Whether ``arrays`` has the far field's layout for a scene of ``num_faces`` fine triangles."""
    want = set(_BASE) | ({f"mid.{k}" for k in _MID} if mid else set())
    if set(arrays) != want:
        return False
    for prefix in ("",) + (("mid.",) if mid else ()):
        a = {k: arrays[prefix + k] for k in _BASE}
        nv, nc = len(a["points"]), len(a["faces"])
        if not (a["points"].shape == (nv, 3) and a["faces"].shape == (nc, 3) and a["bind_bary"].shape == (nv, 3)
                and a["bind_face"].shape == (nv,) and a["bind_offset"].shape == (nv,)
                and a["owner"].shape == (num_faces,) and a["extra"].ndim == 2 and a["extra"].shape[1] == 2):
            return False
        if nc and not (0 <= a["faces"].min() and a["faces"].max() < nv):
            return False
        if not (0 <= a["owner"].min() and a["owner"].max() < nc) or not (0 <= a["bind_face"].min()
                                                                          and a["bind_face"].max() < num_faces):
            return False
    return True


def far_field(parts, targets, mid_targets=None, border=False) -> dict:
    """:func:`.hierarchy.far_field` (same arguments, same result bit for bit), read from the disk cache when an
    entry for these inputs exists, else built and stored there."""
    key = far_field_key(parts, targets, mid_targets, border)
    num_faces = sum(len(f) for _, f in parts)
    arrays = _cache.load(KIND, key, check=lambda a: _fits(a, num_faces, mid_targets is not None))
    if arrays is not None:
        far = {k: arrays[k] for k in _BASE}
        if mid_targets is not None:
            far["mid"] = {k: arrays[f"mid.{k}"] for k in _MID}
        return far
    far = hierarchy.far_field(parts, targets, mid_targets, border)
    _cache.save(KIND, key, _flatten(far))
    return far


__all__ = ["FORMAT", "KIND", "far_field", "far_field_key"]
