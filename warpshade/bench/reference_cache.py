"""Ground-truth transfer for the benchmark: :class:`ReferenceTransfer` at many rays, cached on disk.

The ground truth uses a different seed (:data:`GROUND_TRUTH_SEED`) from the ``reference`` method's
default, so the ``reference`` entries of the sweep are judged against independent samples rather
than against themselves.

Cache files are ``<cache_dir>/<content hash>-<TRUTH_VERSION>-o<order>-r<rays>-s<seed>.npy`` where the hash
covers the points and faces (float32/int32 bytes; with occluders, one hash per mesh joined by ``+``); the reference's other knobs stay at their defaults. A cached result of a higher order
serves lower orders (SH coefficients nest: order N is the first N*N of any higher order).
"""

from __future__ import annotations

import glob
import hashlib
import os
import re

import numpy as np

from .. import _cache
from .._atomic import replace_atomically
from ..geometry.mesh import TriMesh

GROUND_TRUTH_SEED = 982451653
"""Seed of the ground-truth rays (independent of the ``reference`` method's default seed 0)."""

TRUTH_VERSION = "t4"
"""Version of the reference's ray tracing in the cache file names: bumped when it changes what it computes
(t2: rays leave the vertex itself, ``trace_surface_ray``; files without it came from origins pushed along the
normal, wrong for vertices resting on another surface; t4: the vertex's own triangles block the cone of their edges
and ``-n``, seen from the vertex lifted along its normal, where t3 tested each from its own side), so stale files are
not reused."""

CACHE_KIND = "reference"
"""Subdirectory of the per-user cache root (:func:`warpshade._cache.directory`) holding the ground truth by default."""

DEFAULT_CACHE_DIR = _cache.USER
"""``cache_dir`` default: ``<user cache root>/reference`` (``$WARPSHADE_CACHE``, else the platform's user cache
directory; none when ``WARPSHADE_CACHE=none``), wherever the process runs from."""


def mesh_hash(mesh: TriMesh) -> str:
    """Hex digest (16 characters) of a mesh's positions and faces."""
    h = hashlib.sha256()
    h.update(np.ascontiguousarray(mesh.points, dtype=np.float32).tobytes())
    h.update(np.ascontiguousarray(mesh.faces, dtype=np.int32).tobytes())
    return h.hexdigest()[:16]


def ground_truth(mesh: TriMesh, order: int, rays: int = 4096, cache_dir: str | None = DEFAULT_CACHE_DIR,
                 device: str = "cpu", log=None, occluders: tuple[TriMesh, ...] | list[TriMesh] = ()) -> np.ndarray:
    """Reference transfer of ``mesh`` (it shadows itself, and ``occluders`` shadow it), shape (V, order*order), float32.

    Args:
        mesh: Mesh in the judged pose.
        occluders: Other meshes that cast shadows on ``mesh`` (their hashes join the cache key).
        order: SH order needed.
        rays: Rays per vertex (rounded to a square by :class:`ReferenceTransfer`).
        cache_dir: Directory of cached results (default: :data:`DEFAULT_CACHE_DIR`); None disables caching.
        device: Warp device.
        log: Optional ``print``-like callable told about cache misses and their cost.
    """
    import time

    from ..visibility.reference import ReferenceTransfer

    cache_dir = _cache.resolve(cache_dir, CACHE_KIND)
    key = "+".join(mesh_hash(m) for m in (mesh, *occluders)) + f"-{TRUTH_VERSION}"
    if cache_dir:
        for path in glob.glob(os.path.join(cache_dir, f"{key}-o*-r{rays}-s{GROUND_TRUTH_SEED}.npy")):
            m = re.search(r"-o(\d+)-r", os.path.basename(path))
            if m and int(m.group(1)) >= order:
                t = np.load(path)
                if t.shape == (mesh.num_vertices, int(m.group(1)) ** 2):
                    return t[:, : order * order]
    t0 = time.perf_counter()
    ref = ReferenceTransfer(mesh, order=order, device=device, rays=rays, seed=GROUND_TRUTH_SEED,
                            occluders=list(occluders) or None)
    t = ref.update().numpy()
    if log:
        log(f"  ground truth {mesh.name}: {mesh.num_vertices} vertices x {rays} rays, order {order}: "
            f"{time.perf_counter() - t0:.1f} s" + (f" (cached in {cache_dir})" if cache_dir else ""))
    if cache_dir:
        os.makedirs(cache_dir, exist_ok=True)
        path = os.path.join(cache_dir, f"{key}-o{order}-r{rays}-s{GROUND_TRUTH_SEED}.npy")
        replace_atomically(lambda tmp: np.save(tmp, t), path)
    return t
