"""Linear blend skinning, the walking figure and UsdSkel import."""

from __future__ import annotations

import numpy as np
import pytest

from warpshade.sim import LBSSkinner, WalkingFigure
from warpshade.sim.figure import capsule_mesh
from warpshade.sim.oracle import skin_points_np


def _random_rig(rng, v=200, j=5, k=3):
    rest = rng.normal(size=(v, 3))
    idx = rng.integers(0, j, size=(v, k))
    w = rng.random((v, k))
    return rest, idx, w / w.sum(1, keepdims=True)


def _rigid(rng):
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    q *= np.sign(np.linalg.det(q))  # proper rotation
    m = np.eye(4)
    m[:3, :3] = q
    m[:3, 3] = rng.normal(size=3)
    return m


def test_identity_transforms_reproduce_rest_pose(rng):
    rest, idx, w = _random_rig(rng)
    sk = LBSSkinner(rest, idx, w, 5)
    out = sk.update(np.repeat(np.eye(4)[None], 5, axis=0)).numpy()
    # float32 storage of the rest pose is the only rounding: identical to it
    assert np.array_equal(out, rest.astype(np.float32)), np.abs(out - rest).max()


def test_rigid_motion_is_reproduced(rng):
    rest, idx, w = _random_rig(rng)
    m = _rigid(rng)
    sk = LBSSkinner(rest, idx, w, 5)
    out = sk.update(np.repeat(m[None], 5, axis=0)).numpy()
    expect = rest @ m[:3, :3].T + m[:3, 3]
    # float32 arithmetic on O(1) coordinates: a few ulps (1e-6 relative)
    np.testing.assert_allclose(out, expect, atol=2e-6, err_msg=f"transform {m}")


def test_kernel_matches_numpy_reference(rng):
    rest, idx, w = _random_rig(rng)
    mats = np.stack([_rigid(rng) for _ in range(5)])
    mats[:, :3, :3] *= rng.uniform(0.5, 2.0, size=(5, 1, 1))  # scaled joints too
    out = LBSSkinner(rest, idx, w, 5).update(mats).numpy()
    np.testing.assert_allclose(out, skin_points_np(rest, idx, w, mats), atol=1e-5)


@pytest.mark.parametrize("bad, msg", [
    ({"idx": 7}, "joint index outside"),
    ({"w": -1.0}, "negative"),
    ({"w": np.nan}, "negative or not finite"),
    ({"zero": True}, "no joint influence"),
])
def test_bad_skinning_input_names_vertex(rng, bad, msg):
    rest, idx, w = _random_rig(rng, v=10)
    if "idx" in bad:
        idx[3, 0] = bad["idx"]
    if "w" in bad:
        w[3, 1] = bad["w"]
    if "zero" in bad:
        w[3] = 0
    with pytest.raises(ValueError, match=f"vertex 3.*{msg}|vertex 3: {msg}"):
        LBSSkinner(rest, idx, w, 5)


def test_capsule_mesh_is_closed_and_outward():
    p, f, _ = capsule_mesh((0, 0, 0), (0, 1, 0), 0.2, around=32, cap_rings=8, body_rings=4)
    a, b, c = p[f[:, 0]], p[f[:, 1]], p[f[:, 2]]
    volume = np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0
    exact = np.pi * 0.2 ** 2 * 1.0 + 4.0 / 3.0 * np.pi * 0.2 ** 3
    # inscribed polygonal approximation: a little smaller than the exact volume, and positive (outward)
    assert 0.95 * exact < volume < exact
    edges = np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert (counts == 2).all()  # closed manifold


def test_walking_figure_moves_forward_and_keeps_limb_lengths():
    fig = WalkingFigure(speed=1.0)
    x0, x1 = fig.points(0.0), fig.points(0.5)
    assert x1[:, 2].mean() - x0[:, 2].mean() == pytest.approx(0.5, abs=0.05)
    for (p0, p1, r), (q0, q1, _) in zip(fig.capsules(0.0), fig.capsules(0.37)):
        assert np.linalg.norm(q1 - q0) == pytest.approx(np.linalg.norm(p1 - p0), abs=1e-9)
    assert x0[:, 1].min() > 0.0  # feet above the ground


def test_read_usd_skel_matches_usdskel_bake(tmp_path):
    """A two-joint bending bar authored with pxr; our import + LBS kernel must match UsdSkel's own
    BakeSkinning (an independent implementation) at every frame."""
    from pxr import Gf, Usd, UsdGeom, UsdSkel, Vt

    from warpshade.usd import read_usd_skel

    path = str(tmp_path / "bar.usda")
    stage = Usd.Stage.CreateNew(path)
    stage.SetStartTimeCode(0)
    stage.SetEndTimeCode(4)
    root = UsdSkel.Root.Define(stage, "/Root")
    UsdGeom.Xform(root.GetPrim()).AddTranslateOp().Set(Gf.Vec3d(0.5, 0.0, -1.0))
    skel = UsdSkel.Skeleton.Define(stage, "/Root/Skel")
    joints = ["a", "a/b"]
    skel.CreateJointsAttr(joints)
    bind = [Gf.Matrix4d(1), Gf.Matrix4d(1).SetTranslate(Gf.Vec3d(0, 1, 0))]
    skel.CreateBindTransformsAttr(bind)
    skel.CreateRestTransformsAttr([Gf.Matrix4d(1), Gf.Matrix4d(1).SetTranslate(Gf.Vec3d(0, 1, 0))])
    anim = UsdSkel.Animation.Define(stage, "/Root/Skel/Anim")
    anim.CreateJointsAttr(joints)
    anim.CreateTranslationsAttr(Vt.Vec3fArray([Gf.Vec3f(0, 0, 0), Gf.Vec3f(0, 1, 0)]))
    anim.CreateScalesAttr(Vt.Vec3hArray([Gf.Vec3h(1, 1, 1), Gf.Vec3h(1, 1, 1)]))
    rot = anim.CreateRotationsAttr()
    for t in range(5):
        ang = 0.3 * t
        q1 = Gf.Quatf(float(np.cos(ang / 2)), Gf.Vec3f(0, 0, float(np.sin(ang / 2))))
        q0 = Gf.Quatf(float(np.cos(ang / 4)), Gf.Vec3f(float(np.sin(ang / 4)), 0, 0))
        rot.Set(Vt.QuatfArray([q0, q1]), t)
    UsdSkel.BindingAPI.Apply(skel.GetPrim()).CreateAnimationSourceRel().SetTargets([anim.GetPath()])
    mesh = UsdGeom.Mesh.Define(stage, "/Root/Bar")
    ys = np.linspace(0, 2, 5)
    pts = np.array([[x, y, z] for y in ys for x, z in ((-0.1, -0.1), (0.1, -0.1), (0.1, 0.1), (-0.1, 0.1))])
    faces = []
    for r in range(4):
        for c in range(4):
            a, b = r * 4 + c, r * 4 + (c + 1) % 4
            faces.append([a, b, b + 4, a + 4])
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(pts.astype(np.float32)))
    mesh.CreateFaceVertexCountsAttr([4] * len(faces))
    mesh.CreateFaceVertexIndicesAttr(np.array(faces).ravel().tolist())
    binding = UsdSkel.BindingAPI.Apply(mesh.GetPrim())
    binding.CreateSkeletonRel().SetTargets([skel.GetPath()])
    wb = np.clip(pts[:, 1] - 0.5, 0, 1)
    binding.CreateJointIndicesPrimvar(False, 2).Set(np.stack([np.zeros(len(pts)), np.ones(len(pts))], 1).astype(int).ravel().tolist())
    binding.CreateJointWeightsPrimvar(False, 2).Set(np.stack([1 - wb, wb], 1).ravel().tolist())
    binding.CreateGeomBindTransformAttr(Gf.Matrix4d(1).SetTranslate(Gf.Vec3d(0.0, 0.05, 0.0)))
    stage.GetRootLayer().Save()

    sm = read_usd_skel(path)
    assert sm.transforms.shape == (5, 2, 4, 4) and sm.joint_indices.shape == (len(pts), 2)
    sk = LBSSkinner(sm.rest_points, sm.joint_indices, sm.joint_weights, len(sm.joint_names))
    ours = [sk.update(sm.transforms[t]).numpy().copy() for t in range(5)]

    baked = Usd.Stage.Open(path)
    assert UsdSkel.BakeSkinning(baked.Traverse())
    bm = UsdGeom.Mesh(baked.GetPrimAtPath("/Root/Bar"))
    xf = UsdGeom.XformCache()
    for t in range(5):
        xf.SetTime(t)
        world = np.array(xf.GetLocalToWorldTransform(bm.GetPrim())).reshape(4, 4)
        p = np.array(bm.GetPointsAttr().Get(t), dtype=np.float64)
        ref = p @ world[:3, :3] + world[3, :3]  # baked points are mesh-local; row-vector world matrix
        # float32 pipeline on O(1) coordinates
        np.testing.assert_allclose(ours[t], ref, atol=1e-5, err_msg=f"time {t}")
    assert np.abs(ours[4] - ours[0]).max() > 0.3  # the bar really bends
