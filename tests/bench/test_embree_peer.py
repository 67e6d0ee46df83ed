"""benchmarks/embree_peer.py's embree caster: the two-thread casting answers every ray as one thread does."""

from __future__ import annotations

import importlib.util
import os

import embreex  # noqa: F401  (the test extra installs it: the embree peer's casting is under test)
import numpy as np
import pytest

from helpers import REPO


@pytest.fixture(scope="module")
def peer():
    spec = importlib.util.spec_from_file_location("embree_peer", os.path.join(REPO, "benchmarks", "embree_peer.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def test_split_casting_answers_each_ray_in_order(peer):
    # a square lid z = 1 over [0,1]²; rays from z = 0 at random (x, y) in [-1,2]², straight up or down,
    # some stopped at t = 0.5: blocked exactly when up, inside the square and reaching past t = 1.
    # 10007 rays (prime): the parts are uneven and no part boundary falls on a pattern.
    lid = np.array([[0, 0, 1], [1, 0, 1], [1, 1, 1], [0, 1, 1]], float)
    caster = peer.EmbreeCaster(lid, np.array([[0, 1, 2], [0, 2, 3]]))
    rng = np.random.default_rng(7)
    xy = rng.uniform(-1, 2, (10007, 2))
    # keep 1e-3 off the square's edges and its diagonal (the shared edge of the two triangles)
    xy = xy[(np.abs(xy - 0).min(1) > 1e-3) & (np.abs(xy - 1).min(1) > 1e-3) & (np.abs(xy[:, 0] - xy[:, 1]) > 1e-3)]
    n = len(xy)
    org = np.column_stack([xy, np.zeros(n)]).astype(np.float32)
    up = rng.random(n) < 0.7
    dirs = np.zeros((n, 3), np.float32)
    dirs[:, 2] = np.where(up, 1, -1)
    dists = np.where(rng.random(n) < 0.2, 0.5, 10.0).astype(np.float32)
    inside = ((xy > 0) & (xy < 1)).all(1)
    expected = np.where(up & inside & (dists > 1), 0, -1)
    assert 0.05 * n < (expected == 0).sum() < 0.5 * n  # both answers well represented
    try:
        for threads in (1, 2, 3):
            np.testing.assert_array_equal(caster.occluded(org, dirs, dists, threads=threads), expected,
                                          err_msg=f"{threads} threads")
        np.testing.assert_array_equal(caster.occluded(org, dirs, threads=2), np.where(up & inside, 0, -1))
    finally:
        caster.close()


def test_two_threads_equal_one_thread_on_the_bunny(peer):
    # the benchmark's own rays (stratified cosine-weighted, 16 per vertex) on Warp's bunny
    from warpshade.bench.meshes import warp_mesh
    from warpshade.geometry.normals import vertex_normals_np

    mesh = warp_mesh("bunny").rest
    points = mesh.points.astype(np.float64)
    org, dirs32, _ = peer.cosine_rays(points, vertex_normals_np(points, mesh.faces), 4, seed=1)
    caster = peer.EmbreeCaster(points, mesh.faces)
    try:
        one = caster.occluded(org, dirs32, threads=1)
        two = caster.occluded(org, dirs32, threads=2)
    finally:
        caster.close()
    assert 0.05 * len(one) < (one == 0).sum() < 0.95 * len(one)  # a mix of blocked and free rays
    np.testing.assert_array_equal(two, one)
