"""UsdSkel import: a skinned, animated mesh as plain arrays for :class:`warpshade.sim.LBSSkinner`.

UsdSkel uses row vectors (p' = p M). The transforms returned here are converted to the column
convention of :mod:`warpshade.sim.skinning` and already include the mesh's geomBindTransform and
the skeleton's local-to-world transform, so that skinning the returned rest points gives world-space
positions: x = sum_k w_k (M_k @ [rest, 1])[:3].
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pxr import Usd, UsdGeom, UsdSkel

from ..geometry.mesh import MeshError
from .mesh_io import open_stage, triangulate


@dataclass
class SkinnedMesh:
    """A skinned mesh read from UsdSkel.

    Attributes:
        rest_points: Mesh points as authored (mesh space) [m], shape (V, 3), float32.
        faces: Triangles, shape (F, 3), int32.
        joint_indices: Skeleton joint per influence, shape (V, K), int32.
        joint_weights: Weights, shape (V, K), float32.
        joint_names: Skeleton joint paths, length J.
        times: Time codes sampled, shape (T,).
        transforms: Per-time skinning transforms, shape (T, J, 4, 4), column-vector convention,
            geomBindTransform and skeleton-to-world included.
        name: "file:prim" for messages.
    """

    rest_points: np.ndarray
    faces: np.ndarray
    joint_indices: np.ndarray
    joint_weights: np.ndarray
    joint_names: list
    times: np.ndarray
    transforms: np.ndarray
    name: str


def _m4(m) -> np.ndarray:
    return np.array(m, dtype=np.float64).reshape(4, 4)


def read_usd_skel(path: str, prim_path: str | None = None, times=None) -> SkinnedMesh:
    """Read the first skinned mesh under a SkelRoot (or ``prim_path``) and its animation.

    Args:
        path: USD file.
        prim_path: A skinned Mesh prim; default: the first Mesh with a skinning binding.
        times: Time codes to sample; default: every integer time code of the stage's range.

    Raises:
        MeshError: no skinned mesh, missing skeleton, or invalid influences (naming file and prim).
    """
    stage = open_stage(path)
    cache = UsdSkel.Cache()
    roots = [p for p in stage.Traverse() if p.IsA(UsdSkel.Root)]
    if not roots:
        raise MeshError(f"{path}: no UsdSkel SkelRoot prim")
    for r in roots:
        cache.Populate(UsdSkel.Root(r), Usd.TraverseInstanceProxies())
    mesh_prim, skin_q = None, None
    for r in roots:
        for p in Usd.PrimRange(r):
            if not p.IsA(UsdGeom.Mesh) or (prim_path is not None and str(p.GetPath()) != prim_path):
                continue
            q = cache.GetSkinningQuery(p)
            if q and q.HasJointInfluences():
                mesh_prim, skin_q = p, q
                break
        if mesh_prim is not None:
            break
    where = f"{path}:{prim_path}" if prim_path else path
    if mesh_prim is None:
        raise MeshError(f"{where}: no skinned Mesh prim (with skel:jointIndices/jointWeights) under a SkelRoot")
    name = f"{path}:{mesh_prim.GetPath()}"
    binding_skel = None
    for r in roots:
        for b in cache.ComputeSkelBindings(UsdSkel.Root(r), Usd.TraverseInstanceProxies()):
            for q in b.GetSkinningTargets():
                if q.GetPrim() == mesh_prim:
                    binding_skel = b.GetSkeleton()
    if binding_skel is None:
        raise MeshError(f"{name}: the mesh is not bound to a Skeleton (skel:skeleton)")
    skel_q = cache.GetSkelQuery(binding_skel)

    mesh = UsdGeom.Mesh(mesh_prim)
    pts = np.asarray(mesh.GetPointsAttr().Get(Usd.TimeCode.Default()) or mesh.GetPointsAttr().Get(), dtype=np.float64)
    counts = np.asarray(mesh.GetFaceVertexCountsAttr().Get(), dtype=np.int64)
    indices = np.asarray(mesh.GetFaceVertexIndicesAttr().Get(), dtype=np.int64)
    faces = triangulate(counts, indices, name)
    ji, jw = skin_q.ComputeJointInfluences()
    k = skin_q.GetNumInfluencesPerComponent()
    ji = np.asarray(ji, dtype=np.int64).reshape(-1, k)
    jw = np.asarray(jw, dtype=np.float64).reshape(-1, k)
    if not skin_q.IsRigidlyDeformed() and len(ji) != len(pts):
        raise MeshError(f"{name}: {len(ji)} joint influences for {len(pts)} points")
    if skin_q.IsRigidlyDeformed():  # constant interpolation: one influence set for every point
        ji, jw = np.repeat(ji[:1], len(pts), 0), np.repeat(jw[:1], len(pts), 0)
    # mesh-local joint order -> skeleton order
    mapper = skin_q.GetJointMapper()
    skel_joints = list(skel_q.GetJointOrder())
    if mapper is not None and not mapper.IsNull() and not mapper.IsIdentity():
        local = list(skin_q.GetJointOrder())
        remap = np.array([skel_joints.index(j) for j in local], dtype=np.int64)
        ji = remap[ji]
    if len(ji) and (ji.min() < 0 or ji.max() >= len(skel_joints)):
        v = int(np.flatnonzero((ji < 0).any(1) | (ji >= len(skel_joints)).any(1))[0])
        raise MeshError(f"{name}: point {v} has a joint index outside 0..{len(skel_joints) - 1}: {ji[v].tolist()}")

    geom_bind = _m4(skin_q.GetGeomBindTransform())
    xf_cache = UsdGeom.XformCache()
    if times is None:
        t0, t1 = stage.GetStartTimeCode(), stage.GetEndTimeCode()
        times = np.arange(int(np.floor(t0)), int(np.floor(t1)) + 1) if t1 >= t0 else np.array([0.0])
    times = np.asarray(times, dtype=np.float64)
    out = np.zeros((len(times), len(skel_joints), 4, 4))
    for ti, t in enumerate(times):
        xf_cache.SetTime(Usd.TimeCode(float(t)))
        skel_to_world = _m4(xf_cache.GetLocalToWorldTransform(binding_skel.GetPrim()))
        skinning = skel_q.ComputeSkinningTransforms(Usd.TimeCode(float(t)))
        if skinning is None:
            raise MeshError(f"{name}: cannot compute skinning transforms at time {t}")
        for j, m in enumerate(skinning):
            out[ti, j] = (geom_bind @ _m4(m) @ skel_to_world).T  # row -> column convention
    return SkinnedMesh(pts.astype(np.float32), faces.astype(np.int32), ji.astype(np.int32), jw.astype(np.float32),
                       [str(j) for j in skel_joints], times, out, name)
