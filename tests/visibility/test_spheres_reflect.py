"""Second pass of the sphere-set reflections (kernel ``reflect``) against its NumPy reference, and the
thesis' rule for intersecting spheres in eq. 4.32."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
import warp as wp
from helpers import post_on_floor

from warpshade.geometry import TriMesh
from warpshade.visibility.spheres import SpheresTransfer, SphereReflections, tree_from_spheres
from warpshade.visibility.spheres.bounce_reference import reflected_irradiance_reference
from warpshade.visibility.spheres.oracle import reflect_np

ORDER = 4


def _ball(c, r):
    b = trimesh.creation.icosphere(2, radius=r)
    return TriMesh(b.vertices + np.asarray(c), b.faces)


def _setup(objects, exclude, seed=0):
    """``objects``: list of (centres, radii) per object. Receivers: a row of points at z = 0 facing +z.
    The radiance vectors are random (this tests the second pass alone)."""
    rx = np.linspace(-1.0, 1.0, 5)
    recv_pts = np.stack([rx, 0.3 * rx, np.zeros_like(rx)], 1)
    quad = TriMesh(np.array([[-3, -3, 0], [3, -3, 0], [3, 3, 0], [-3, 3, 0.0]]), np.array([[0, 1, 2], [0, 2, 3]]))
    blockers, meshes = [], []
    for c, r in objects:
        blockers.append(tree_from_spheres(c, r))
        meshes.append(_ball(np.mean(c, axis=0), max(r)))
    m = SpheresTransfer(quad, order=ORDER, self_shadow=False, blockers=blockers)
    m.update()
    refl = SphereReflections(m, meshes, exclude_intersecting=exclude)
    rad = np.zeros(refl.radiance.shape)
    for row, sid in enumerate(refl.rows):  # random per sphere, seeded by its position (same alone or not)
        c = m.scene.centers.numpy()[sid]
        rng = np.random.default_rng([seed, *np.round(1000 * np.abs(c)).astype(int)])
        rad[row] = rng.normal(size=rad.shape[1:]) * 0.3
        rad[row, :, 0] = 1.0 + rng.random(3)  # bright DC: mostly positive radiance
    refl.radiance.assign(rad.astype(np.float32))
    pts = wp.array(recv_pts.astype(np.float32), dtype=wp.vec3)
    nrm = wp.array(np.tile([0.0, 0.0, 1.0], (len(rx), 1)).astype(np.float32), dtype=wp.vec3)
    e = refl.gather(pts, nrm).numpy()
    sc = m.scene
    obj = np.concatenate([[o] * len(r) for o, (_c, r) in enumerate(objects)])
    ref = np.array([reflect_np(p, [0, 0, 1], sc.centers.numpy(), sc.radii.numpy(), sc.rotations.numpy(),
                               rad[refl._row_of[np.arange(sc.num_spheres)]], obj, ORDER, "ol",
                               exclude_intersecting=exclude) for p in recv_pts])
    return e, ref


# two objects; object 0 has a chain of intersecting spheres above the receivers, object 1 one sphere
CHAIN = ([[0.0, 0.0, 1.0], [0.2, 0.0, 1.6], [0.5, 0.1, 2.2]], [0.45, 0.5, 0.5])
OTHER = ([[-0.8, 0.5, 1.4]], [0.35])


@pytest.mark.parametrize("exclude", [False, True])
def test_reflect_kernel_matches_numpy_reference(exclude):
    e, ref = _setup([CHAIN, OTHER], exclude)
    # float32 kernel vs float64 reference: same tables and interpolation; measured max rel diff ~1e-5
    np.testing.assert_allclose(e, ref, rtol=2e-4, atol=1e-6 * np.abs(ref).max())
    assert ref.max() > 0.05


def test_intersecting_spheres_of_one_object_do_not_occlude_each_other():
    # Thesis, below eq. 4.33: spheres that intersect sphere i in the same object are left out of its
    # visibility. Two intersecting spheres stacked above the receivers then reflect exactly what each
    # reflects alone; without the rule the near one occludes the far one.
    near, far = ([0.0, 0.0, 1.0], 0.45), ([0.1, 0.0, 1.7], 0.5)
    both_on, _ = _setup([([near[0], far[0]], [near[1], far[1]])], True)
    both_off, _ = _setup([([near[0], far[0]], [near[1], far[1]])], False)
    alone_near, _ = _setup([([near[0]], [near[1]])], True)
    alone_far, _ = _setup([([far[0]], [far[1]])], True)
    np.testing.assert_allclose(both_on, alone_near + alone_far, rtol=1e-5)
    assert (both_on >= both_off - 1e-6).all() and (both_on - both_off).max() > 0.05 * both_on.max(), (both_on, both_off)
    # spheres of different objects intersecting: the rule does not apply
    split_on, _ = _setup([([near[0]], [near[1]]), ([far[0]], [far[1]])], True)
    split_off, _ = _setup([([near[0]], [near[1]]), ([far[0]], [far[1]])], False)
    np.testing.assert_array_equal(split_on, split_off)
    # non-intersecting spheres of one object: the rule changes nothing
    apart = ([[0.0, 0.0, 1.0], [0.0, 0.0, 2.6]], [0.4, 0.4])
    np.testing.assert_array_equal(_setup([apart], True)[0], _setup([apart], False)[0])


@pytest.mark.parametrize("shift", [1e3, 1e4])
def test_bounce_reference_far_from_the_origin_matches_the_origin(shift):
    """The ray-traced one-bounce reference (``reflected_irradiance_reference``) of a ball resting on a floor
    (:func:`helpers.post_on_floor`'s floor, exit radiance 1; the ball 0.5), receivers the floor's and ball's
    vertices, everything moved by ``shift``, agrees with the scene at the origin: rays are traced about
    ``rays.local_origin``. Measured (256 rays, same seed): floor exact, ball max 0.012 at 1e3 and 0.037 at
    1e4 (the float32 rounding of the shifted ball, ulp 1e-3 on a 0.5 radius, moves its normals and so its
    rays), mean 2e-3; E about 1.1. Bound: max 0.06, mean 5e-3. Before (world coordinates) at 1e4: mean
    error 1.09 (everything blocked)."""
    ico = trimesh.creation.icosphere(3, radius=0.5)
    fl, _ = post_on_floor()
    out = []
    for s in (0.0, shift):
        ball = TriMesh((ico.vertices + [0.0, 0.0, 0.5] + s).astype(np.float32), ico.faces)
        floor = TriMesh((fl.points[:81].astype(np.float64) + s).astype(np.float32), fl.faces[:128])
        rad = [np.ones((floor.num_vertices, 3), np.float32), np.full((ball.num_vertices, 3), 0.5, np.float32)]
        pts, nrm = np.concatenate([floor.points, ball.points]), np.concatenate([floor.normals, ball.normals])
        out.append(reflected_irradiance_reference(pts, nrm, [floor, ball], rad, rays=256)[:, 0])
    d = np.abs(out[1] - out[0])
    assert d.max() <= 0.06 and d.mean() <= 5e-3, (d.max(), d.mean())
