"""The icosphere of a Sphere gprim (geometry.shapes.sphere_shape) in the per-user disk cache (warpshade._cache):
read back bit for bit as trimesh makes it, keyed on the radius and subdivisions, rebuilt from a bad entry, and a
hit imports no trimesh (the point of the cache: the command's start-up)."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest
import trimesh

from warpshade import _cache
from warpshade.geometry.shapes import SPHERE_CACHE, sphere_shape


def trimesh_sphere(radius, subdivisions):
    m = trimesh.creation.icosphere(subdivisions=subdivisions, radius=radius)
    return np.asarray(m.vertices, dtype=np.float64), np.asarray(m.faces, dtype=np.int64)


def counts():
    return {what: _cache.stats[SPHERE_CACHE, what] for what in ("hit", "miss", "write", "bad")}


@pytest.mark.parametrize("radius, subdivisions", [(1.0, 0), (0.37, 2), (2.5, 4)])
def test_miss_then_hit_give_trimesh_arrays_bit_for_bit(cache_root, radius, subdivisions):
    want = trimesh_sphere(radius, subdivisions)
    for expected in ({"hit": 0, "miss": 1, "write": 1, "bad": 0}, {"hit": 1, "miss": 1, "write": 1, "bad": 0}):
        points, faces = sphere_shape(radius, subdivisions)
        assert counts() == expected
        assert points.dtype == np.float64 and faces.dtype == np.int64
        np.testing.assert_array_equal(points, want[0])
        np.testing.assert_array_equal(faces, want[1])


def test_key_holds_radius_and_subdivisions(cache_root):
    # trimesh moves the vertices to the radius inside its subdivision loop, so a radius-r sphere is not
    # r times the unit one bit for bit: each radius is an entry of its own
    sphere_shape(1.0, 2)
    for radius, subdivisions in ((0.5, 2), (1.0, 1), (1.0, 3)):
        points, faces = sphere_shape(radius, subdivisions)
        want = trimesh_sphere(radius, subdivisions)
        np.testing.assert_array_equal(points, want[0])
        np.testing.assert_array_equal(faces, want[1])
    assert counts()["hit"] == 0 and counts()["miss"] == 4


def test_bad_entry_is_rebuilt(cache_root):
    sphere_shape(1.0, 2)
    (entry,) = (cache_root / SPHERE_CACHE).iterdir()
    good = dict(np.load(entry))
    np.savez(entry, points=good["points"][:-1], faces=good["faces"])  # one vertex short
    with pytest.warns(RuntimeWarning, match="rebuilding"):
        points, _ = sphere_shape(1.0, 2)
    np.testing.assert_array_equal(points, trimesh_sphere(1.0, 2)[0])
    assert counts()["bad"] == 1 and counts()["write"] == 2


def test_a_hit_imports_no_trimesh(cache_root):
    code = ("import sys; from warpshade.geometry.shapes import sphere_shape; p, f = sphere_shape(0.75, 3); "
            "print(len(p), len(f), 'trimesh' in sys.modules)")
    env = dict(os.environ, **{_cache.ENV: str(cache_root)})
    runs = [subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True, check=True).stdout.split()
            for _ in range(2)]
    assert runs == [["642", "1280", "True"], ["642", "1280", "False"]]
