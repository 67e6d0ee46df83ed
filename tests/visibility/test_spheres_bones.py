"""Spheres that follow skinning bones (``SphereScene.bind_bones``) against the point refit, on the UsdSkel
skinned arm and on analytic rigid motion."""

from __future__ import annotations

import os

import numpy as np
import pytest

from helpers import SHIPPED
from warpshade.geometry import TriMesh
from warpshade.bench.metrics import error_summary
from warpshade.sim import LBSSkinner
from warpshade.visibility.spheres import SpheresTransfer, build_sphere_tree
from warpshade.visibility.spheres.sets import SphereScene

ARM = os.path.join(SHIPPED, "skinned_arm.usda")


@pytest.fixture(scope="module")
def arm():
    from warpshade.usd.skel import read_usd_skel

    sm = read_usd_skel(ARM)
    tree = build_sphere_tree(sm.rest_points, sm.faces, 8, 2, seed=0)
    sk = LBSSkinner(sm.rest_points, sm.joint_indices, sm.joint_weights, len(sm.joint_names))
    return sm, tree, sk


def test_bone_refit_bounds_the_skinned_arm_like_the_point_refit(arm):
    sm, tree, sk = arm
    by_pts, by_bones = SphereScene([tree], [sm.rest_points]), SphereScene([tree], [sm.rest_points])
    by_bones.bind_bones(0, sm.joint_indices, sm.joint_weights, len(sm.joint_names))
    leaf = tree.level == 0
    ratios = []
    for t in range(0, len(sm.times), 4):
        pts = sk.update(sm.transforms[t]).numpy()
        by_pts.refit([pts])
        by_bones.refit([None], [sm.transforms[t]])
        ca, ra, cb, rb = (a.numpy() for a in (by_pts.centers, by_pts.radii, by_bones.centers, by_bones.radii))
        for s in range(tree.num_spheres):
            v = tree.vertices_of(s)
            # the radius bound of refit_spheres_bones is exact for rigid bones: every vertex stays inside
            # (float32 slack)
            out = np.linalg.norm(pts[v] - cb[s], axis=1) - rb[s]
            assert out.max() <= 1e-5 * rb[s], (t, s, out.max(), rb[s])
        # measured over the 48 frames: centres within 0.082 r of the point refit, radii 1.02x on average
        d = np.linalg.norm(ca - cb, axis=1) / ra
        assert d[leaf].max() < 0.15, (t, d[leaf].max())
        ratios.append(rb[leaf] / ra[leaf])
    assert 1.0 <= np.mean(ratios) < 1.1, np.mean(ratios)


def test_bone_refit_of_a_rigid_motion_equals_the_point_refit():
    # one joint, a rigid transform: the skinned centre is M c0, the radius r0, as Kabsch finds from the points
    rng = np.random.default_rng(3)
    import trimesh

    b = trimesh.creation.capsule(height=1.0, radius=0.3, count=[12, 12])
    rest = np.asarray(b.vertices)
    tree = build_sphere_tree(rest, np.asarray(b.faces), 6, 2, seed=0)
    q = rng.normal(size=4)
    q /= np.linalg.norm(q)
    w, x, y, z = q
    rot = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                    [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                    [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])
    m = np.eye(4)
    m[:3, :3], m[:3, 3] = rot, [0.4, -1.0, 2.0]
    pts = rest @ rot.T + m[:3, 3]
    by_pts, by_bones = SphereScene([tree], [rest]), SphereScene([tree], [rest])
    by_bones.bind_bones(0, np.zeros((len(rest), 1), int), np.ones((len(rest), 1)), 1)
    by_pts.refit([pts])
    by_bones.refit([None], [m[None]])
    np.testing.assert_allclose(by_bones.centers.numpy(), by_pts.centers.numpy(), atol=2e-5)
    np.testing.assert_allclose(by_bones.radii.numpy(), by_pts.radii.numpy(), rtol=2e-5)
    np.testing.assert_allclose(by_bones.rotations.numpy(), np.broadcast_to(rot, (tree.num_spheres, 3, 3)), atol=1e-5)
    with pytest.raises(ValueError, match="bone transforms"):
        by_bones.refit([None], [np.eye(4)[None].repeat(2, 0)])


def test_arm_shadow_on_the_ground_by_bones_matches_point_refit(arm):
    sm, tree, sk = arm
    n = 15
    g = np.linspace(-1.0, 1.0, n)
    X, Z = np.meshgrid(g, g, indexing="ij")
    gp = np.stack([X.ravel(), np.zeros(n * n), Z.ravel()], 1)
    i = np.arange(n * n).reshape(n, n)
    faces = np.concatenate([np.stack([i[:-1, :-1], i[:-1, 1:], i[1:, 1:]], -1).reshape(-1, 3),
                            np.stack([i[:-1, :-1], i[1:, 1:], i[1:, :-1]], -1).reshape(-1, 3)])
    ground = TriMesh(gp, faces)
    m = SpheresTransfer(ground, order=4, self_shadow=False, blockers=[(tree, sm.rest_points)])
    m.bind_bones(0, sm.joint_indices, sm.joint_weights, len(sm.joint_names))
    t = len(sm.times) * 3 // 4  # bent
    pts = sk.update(sm.transforms[t]).numpy()
    by_pts = m.update(blocker_points=[pts]).numpy().copy()
    by_bones = m.update(blocker_points=[pts], bone_transforms=[sm.transforms[t]]).numpy().copy()
    assert not np.array_equal(by_pts, by_bones)
    # measured: mean relative difference 0.013 at this frame (the bone-refit spheres are up to 19 % larger
    # near the elbow, where the radius bound of refit_spheres_bones is conservative)
    assert error_summary(by_bones, by_pts)["error_mean"] < 0.03
