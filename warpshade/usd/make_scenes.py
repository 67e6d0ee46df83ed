"""Generate the shipped scenes in ``usd_scenes/`` (reproducible: ``python -m warpshade.usd.make_scenes``).

Each scene is plain ``.usda`` that a user can read and edit; this script only saves typing the
grids. The ``warpshade:`` attributes used are documented in docs/guide/quickstart.md ("Your own scene").
"""

from __future__ import annotations

import argparse
import os

import numpy as np
from pxr import Gf, Sdf, Usd, UsdGeom, UsdLux, UsdShade, UsdSkel, Vt

from .shipped import shipped_scenes_dir

SCENES_DIR = shipped_scenes_dir()

CLOTH = {"density": 0.2, "stretchStiffness": 5.0e4, "bendStiffness": 5.0e-5, "damping": 1.0e-3,
         "thickness": 0.01, "friction": 0.5, "selfCollision": True}
"""Default cloth material: area density [kg/m²], stretch stiffness [N/m], bending stiffness [N·m],
Rayleigh damping time [s], collision thickness [m], Coulomb friction, self-collision."""


def grid(nx: int, ny: int, sx: float, sy: float):
    """Quad grid in the XY plane centred at 0: points (nx*ny, 3), counts, indices (quads)."""
    x, y = np.meshgrid(np.linspace(-sx / 2, sx / 2, nx), np.linspace(-sy / 2, sy / 2, ny))
    pts = np.stack([x.ravel(), y.ravel(), np.zeros(nx * ny)], axis=1)
    i, j = np.meshgrid(np.arange(nx - 1), np.arange(ny - 1))
    v0 = (j * nx + i).ravel()
    quads = np.stack([v0, v0 + 1, v0 + nx + 1, v0 + nx], axis=1)
    return pts, np.full(len(quads), 4), quads.ravel()


def new_stage(path: str, frames: int, fps: float = 60.0, doc: str = "") -> Usd.Stage:
    if os.path.exists(path):
        os.remove(path)
    stage = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetTimeCodesPerSecond(fps)
    stage.SetFramesPerSecond(fps)
    stage.SetStartTimeCode(0)
    stage.SetEndTimeCode(frames - 1)
    world = UsdGeom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    world.GetPrim().CreateAttribute("warpshade:frames", Sdf.ValueTypeNames.Int, custom=True).Set(frames)
    if doc:
        stage.GetRootLayer().documentation = doc
    return stage


def set_attr(prim, name: str, value) -> None:
    if isinstance(value, bool):
        t = Sdf.ValueTypeNames.Bool
    elif isinstance(value, int):
        t = Sdf.ValueTypeNames.Int
    elif isinstance(value, float):
        t = Sdf.ValueTypeNames.Float
    elif isinstance(value, str):
        t = Sdf.ValueTypeNames.Token
    elif isinstance(value, tuple):
        t, value = Sdf.ValueTypeNames.Float3, Gf.Vec3f(*value)
    else:
        t, value = Sdf.ValueTypeNames.IntArray, Vt.IntArray([int(v) for v in value])
    prim.CreateAttribute(f"warpshade:{name}", t, custom=True).Set(value)


def material(stage, name: str, albedo, roughness: float = 1.0) -> UsdShade.Material:
    UsdGeom.Scope.Define(stage, "/World/Looks")
    mat = UsdShade.Material.Define(stage, f"/World/Looks/{name}")
    sh = UsdShade.Shader.Define(stage, f"/World/Looks/{name}/PreviewSurface")
    sh.CreateIdAttr("UsdPreviewSurface")
    sh.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(*albedo))
    sh.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(float(roughness))
    mat.CreateSurfaceOutput().ConnectToSource(sh.ConnectableAPI(), "surface")
    return mat


def bind(prim, mat) -> None:
    UsdShade.MaterialBindingAPI.Apply(prim).Bind(mat)


def mesh(stage, path, pts, counts, idx, translate=None, rotate_x=None) -> UsdGeom.Mesh:
    m = UsdGeom.Mesh.Define(stage, path)
    m.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(np.asarray(pts, dtype=np.float32)))
    m.CreateFaceVertexCountsAttr(Vt.IntArray([int(c) for c in counts]))
    m.CreateFaceVertexIndicesAttr(Vt.IntArray([int(i) for i in idx]))
    m.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    m.CreateExtentAttr(UsdGeom.PointBased.ComputeExtent(m.GetPointsAttr().Get()))
    if translate is not None:
        m.AddTranslateOp().Set(Gf.Vec3d(*translate))
    if rotate_x is not None:
        m.AddRotateXOp().Set(rotate_x)
    return m


def ground(stage, size: float = 4.0, n: int = 33, albedo=(0.6, 0.6, 0.58)) -> UsdGeom.Mesh:
    pts, c, i = grid(n, n, size, size)
    # XY grid -> XZ floor facing +Y (rotate by -90° about X keeps the quads counter-clockwise from above)
    g = mesh(stage, "/World/Ground", pts, c, i, rotate_x=-90.0)
    set_attr(g.GetPrim(), "collider", "ground")
    bind(g.GetPrim(), material(stage, "GroundMat", albedo))
    return g


def cloth(stage, path="/World/Cloth", n=33, size=1.6, height=1.0, pinned=None, albedo=(0.75, 0.2, 0.15),
          translate=None, rotate_x=-90.0, **overrides) -> UsdGeom.Mesh:
    """A square cloth grid, horizontal by default; ``overrides`` replace :data:`CLOTH` entries."""
    pts, c, i = grid(n, n, size, size)
    m = mesh(stage, path, pts, c, i, translate=translate or (0.0, height, 0.0), rotate_x=rotate_x)
    p = m.GetPrim()
    set_attr(p, "kind", "cloth")
    for k, v in {**CLOTH, **overrides}.items():
        set_attr(p, f"cloth:{k}", v)
    if pinned is not None:
        set_attr(p, "pinned", pinned)
    bind(p, material(stage, "ClothMat", albedo, roughness=0.9))
    return m


def sphere(stage, center=(0.0, 0.35, 0.0), radius=0.35, albedo=(0.7, 0.7, 0.75)) -> UsdGeom.Sphere:
    s = UsdGeom.Sphere.Define(stage, "/World/Ball")
    s.CreateRadiusAttr(radius)
    s.CreateExtentAttr([(-radius,) * 3, (radius,) * 3])
    s.AddTranslateOp().Set(Gf.Vec3d(*center))
    set_attr(s.GetPrim(), "collider", "sphere")
    bind(s.GetPrim(), material(stage, "BallMat", albedo))
    return s


def box(stage, path, center, size, albedo=(0.5, 0.35, 0.2), n: int = 6) -> UsdGeom.Mesh:
    """A box of ``size`` (3,) at ``center``: each face an n×n grid with its own vertices, so the
    per-vertex shading has crisp edges and enough vertices to carry shadows."""
    pts, idx = [], []
    u = np.linspace(-0.5, 0.5, n)
    a, b = np.meshgrid(u, u)
    for axis in range(3):
        for sign in (-1.0, 1.0):
            p = np.zeros((n * n, 3))
            i1, i2 = (axis + 1) % 3, (axis + 2) % 3
            p[:, axis], p[:, i1], p[:, i2] = 0.5 * sign, a.ravel(), b.ravel()
            i, j = np.meshgrid(np.arange(n - 1), np.arange(n - 1))
            v0 = (j * n + i).ravel() + len(pts) * n * n
            q = np.stack([v0, v0 + 1, v0 + n + 1, v0 + n], 1)
            idx.append(q if sign > 0 else q[:, ::-1])  # outward: (i1 x i2) = +axis
            pts.append(p)
    pts = np.concatenate(pts) * np.asarray(size)
    idx = np.concatenate(idx)
    m = mesh(stage, path, pts, [4] * len(idx), idx.ravel(), translate=center)
    set_attr(m.GetPrim(), "collider", "mesh")
    bind(m.GetPrim(), material(stage, path.split("/")[-1] + "Mat", albedo))
    return m


def sun(stage, elevation_deg=55.0, azimuth_deg=30.0, intensity=3.0):
    sun = UsdLux.DistantLight.Define(stage, "/World/Lights/Sun")
    sun.CreateIntensityAttr(intensity)
    sun.CreateColorAttr(Gf.Vec3f(1.0, 0.95, 0.85))
    sun.CreateAngleAttr(0.53)
    sun.CreateNormalizeAttr(True)  # intensity is the irradiance, independent of the disc's size
    # the light shines along its -Z: tilt down by the elevation, turn by the azimuth
    sun.AddRotateYOp().Set(azimuth_deg)
    sun.AddRotateXOp().Set(-elevation_deg)
    return sun


def dome(stage, texture: str | None = None, intensity=1.0, color=(0.5, 0.6, 0.8)):
    d = UsdLux.DomeLight.Define(stage, "/World/Lights/Sky")
    d.CreateIntensityAttr(intensity)
    if texture:
        d.CreateTextureFileAttr(Sdf.AssetPath(texture))
        d.CreateTextureFormatAttr(UsdLux.Tokens.latlong)
    else:
        d.CreateColorAttr(Gf.Vec3f(*color))
    return d


def write_sky_exr(path: str, width: int = 64, height: int = 32) -> None:
    """A small lat-long sky (+Y up in the top row): blue gradient, bright ground bounce, a sun disc."""
    import OpenEXR

    v, u = np.meshgrid((np.arange(height) + 0.5) / height, (np.arange(width) + 0.5) / width, indexing="ij")
    theta, phi = v * np.pi, u * 2 * np.pi
    up = np.cos(theta)
    sky = np.where(up[..., None] > 0, np.stack([0.35 + 0.3 * (1 - up), 0.55 + 0.2 * (1 - up), 1.0 + 0 * up], -1),
                   np.stack([0.25, 0.22, 0.2])[None, None, :] * np.ones_like(up)[..., None])
    sun_dir = np.array([np.sin(0.6) * np.cos(1.0), np.cos(0.6), np.sin(0.6) * np.sin(1.0)])
    d = np.stack([np.sin(theta) * np.cos(phi), np.cos(theta), np.sin(theta) * np.sin(phi)], -1)
    sky = sky + 40.0 * (d @ sun_dir > np.cos(0.12))[..., None]
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage},
                 {"RGB": sky.astype(np.float32)}).write(path)


def skinned_tube(stage, frames: int):
    """A UsdSkel character limb: a tube bound to two joints, the upper one bending over time."""
    root = UsdSkel.Root.Define(stage, "/World/Arm")
    skel = UsdSkel.Skeleton.Define(stage, "/World/Arm/Skel")
    joints = ["shoulder", "shoulder/elbow"]
    skel.CreateJointsAttr(joints)
    rest = [Gf.Matrix4d(1).SetTranslate(Gf.Vec3d(0, 0.2, 0)), Gf.Matrix4d(1).SetTranslate(Gf.Vec3d(0, 0.5, 0))]
    world_bind = [rest[0], rest[1] * rest[0]]
    skel.CreateBindTransformsAttr(world_bind)
    skel.CreateRestTransformsAttr(rest)
    anim = UsdSkel.Animation.Define(stage, "/World/Arm/Skel/Walk")
    anim.CreateJointsAttr(joints)
    anim.CreateTranslationsAttr(Vt.Vec3fArray([(0, 0.2, 0), (0, 0.5, 0)]))
    anim.CreateScalesAttr(Vt.Vec3hArray([(1, 1, 1), (1, 1, 1)]))
    rot = anim.CreateRotationsAttr()
    for f in range(frames):
        a = np.radians(70.0 * np.sin(2 * np.pi * f / max(frames, 2)))
        q = Gf.Quatf(float(np.cos(a / 2)), 0.0, 0.0, float(np.sin(a / 2)))
        rot.Set(Vt.QuatfArray([Gf.Quatf(1, 0, 0, 0), q]), f)
    UsdSkel.BindingAPI.Apply(skel.GetPrim()).CreateAnimationSourceRel().SetTargets([anim.GetPath()])
    # tube: rings of 12 along y in [0.2, 1.2]
    rings, seg = 11, 12
    ang = np.linspace(0, 2 * np.pi, seg, endpoint=False)
    ys = np.linspace(0.2, 1.2, rings)
    pts = np.array([[0.12 * np.cos(a), y, 0.12 * np.sin(a)] for y in ys for a in ang])
    quads = [[r * seg + s, r * seg + (s + 1) % seg, (r + 1) * seg + (s + 1) % seg, (r + 1) * seg + s][::-1]
             for r in range(rings - 1) for s in range(seg)]
    m = mesh(stage, "/World/Arm/Tube", pts, [4] * len(quads), np.ravel(quads))
    b = UsdSkel.BindingAPI.Apply(m.GetPrim())
    b.CreateSkeletonRel().SetTargets([skel.GetPath()])
    w_elbow = np.clip((pts[:, 1] - 0.55) / 0.3 + 0.5, 0, 1)
    idx = np.stack([np.zeros(len(pts)), np.ones(len(pts))], 1).astype(int)
    wts = np.stack([1 - w_elbow, w_elbow], 1)
    b.CreateJointIndicesPrimvar(False, 2).Set(Vt.IntArray([int(i) for i in idx.ravel()]))
    b.CreateJointWeightsPrimvar(False, 2).Set(Vt.FloatArray([float(w) for w in wts.ravel()]))
    b.CreateGeomBindTransformAttr(Gf.Matrix4d(1))
    bind(m.GetPrim(), material(stage, "SkinMat", (0.8, 0.6, 0.5)))
    return root


def walker(stage, frames: int, fps: float, path: str = "/World/Walker"):
    """:class:`warpshade.sim.figure.WalkingFigure` baked to UsdSkel: joints, bind pose, joint
    influences and one animation sample per frame (its skinning transforms, made local)."""
    from ..sim.figure import WalkingFigure

    fig = WalkingFigure()
    parents = fig.parents
    paths = []
    for j, name in enumerate(fig.joint_names):
        paths.append(name if parents[j] < 0 else f"{paths[parents[j]]}/{name}")
    root = UsdSkel.Root.Define(stage, path)
    skel = UsdSkel.Skeleton.Define(stage, f"{path}/Skel")
    skel.CreateJointsAttr(paths)
    ident = [Gf.Matrix4d(1)] * len(paths)
    # bind = identity: a joint's skinning transform is then its world transform, which is what
    # WalkingFigure.transforms() returns (rest -> posed, column vectors; USD wants rows: transpose)
    skel.CreateBindTransformsAttr(Vt.Matrix4dArray(ident))
    skel.CreateRestTransformsAttr(Vt.Matrix4dArray(ident))
    anim = UsdSkel.Animation.Define(stage, f"{path}/Skel/Walk")
    anim.CreateJointsAttr(paths)
    for f in range(frames):
        world = [np.asarray(m).T for m in fig.transforms(f / fps)]  # row convention
        local = [w if parents[j] < 0 else w @ np.linalg.inv(world[parents[j]]) for j, w in enumerate(world)]
        anim.SetTransforms(Vt.Matrix4dArray([Gf.Matrix4d(*m.reshape(-1).tolist()) for m in local]), f)
    UsdSkel.BindingAPI.Apply(skel.GetPrim()).CreateAnimationSourceRel().SetTargets([anim.GetPath()])
    pts, faces = fig.rest_points, fig.faces
    body = mesh(stage, f"{path}/Body", pts, [3] * len(faces), faces.ravel())
    b = UsdSkel.BindingAPI.Apply(body.GetPrim())
    b.CreateSkeletonRel().SetTargets([skel.GetPath()])
    k = fig.joint_indices.shape[1]
    b.CreateJointIndicesPrimvar(False, k).Set(Vt.IntArray([int(i) for i in fig.joint_indices.ravel()]))
    b.CreateJointWeightsPrimvar(False, k).Set(Vt.FloatArray([float(w) for w in fig.joint_weights.ravel()]))
    b.CreateGeomBindTransformAttr(Gf.Matrix4d(1))
    set_attr(body.GetPrim(), "collider", "mesh")
    bind(body.GetPrim(), material(stage, "BodyMat", (0.55, 0.55, 0.6)))
    return root, body, np.asarray(pts)


def cape_walker(out_dir: str, save) -> None:
    """A cape attached to the shoulders of the walking figure (needs :mod:`warpshade.sim`)."""
    frames = 120
    st = new_stage(os.path.join(out_dir, "cape_walker.usda"), frames,
                   doc="A cape attached to the shoulders of a walking, UsdSkel-skinned figure.")
    ground(st, size=5.0, n=41)
    _, body, pts = walker(st, frames, 60.0)
    back = pts[(pts[:, 1] > 1.2) & (pts[:, 1] < 1.45) & (np.abs(pts[:, 0]) < 0.12)][:, 2].min()
    nx, ny = 13, 21
    cp, cc, ci = grid(nx, ny, 0.5, 0.8)
    cape = mesh(st, "/World/Cape", cp, cc, ci, translate=(0.0, 1.43 - 0.4, float(back) - 0.04))
    c = cape.GetPrim()
    set_attr(c, "kind", "cloth")
    for k, v in CLOTH.items():
        set_attr(c, f"cloth:{k}", v)
    set_attr(c, "attached", [(ny - 1) * nx + i for i in range(nx)])  # the top row
    c.CreateRelationship("warpshade:attachTarget", custom=True).SetTargets([body.GetPath()])
    bind(c, material(st, "CapeMat", (0.6, 0.1, 0.12), roughness=0.9))
    sun(st), dome(st, intensity=0.6)
    save(st, "cape_walker.usda")


def make_all(out_dir: str = SCENES_DIR) -> list[str]:
    os.makedirs(out_dir, exist_ok=True)
    made = []

    def save(stage, name):
        stage.GetRootLayer().Save()
        made.append(os.path.join(out_dir, name))

    # default: cloth draping over a ball onto the ground under the default sky (no lights authored)
    st = new_stage(os.path.join(out_dir, "default.usda"), 120,
                   doc="Default scene: a cloth drapes over a ball onto the ground under warpshade's default sky.")
    ground(st), sphere(st), cloth(st, bendStiffness=2e-5)  # as sims/drape_sphere.py, coarser
    save(st, "default.usda")

    # sims/cloth_over_sphere: the same under an explicit sun and sky
    st = new_stage(os.path.join(out_dir, "cloth_sphere.usda"), 120, doc="Cloth over a ball, sun and blue sky.")
    ground(st), sphere(st), cloth(st, bendStiffness=2e-5), sun(st), dome(st, intensity=0.6)
    save(st, "cloth_sphere.usda")

    # sims/flag_wind: a flag pinned to a pole in wind
    st = new_stage(os.path.join(out_dir, "flag_wind.usda"), 180, doc="A flag pinned to a pole, in wind.")
    ground(st)
    box(st, "/World/Pole", (-0.85, 1.0, 0.0), (0.05, 2.0, 0.05), albedo=(0.4, 0.4, 0.4))
    n = 25
    flag = cloth(st, "/World/Flag", n=n, size=1.6, rotate_x=0.0, translate=(0.0, 1.4, 0.0), albedo=(0.1, 0.3, 0.8),
                 pinned=[j * n for j in range(n // 2, n)])
    flag.GetPrim()  # pinned: left edge (x = -0.8), upper half
    set_attr(st.GetPrimAtPath("/World"), "wind", (6.0, 0.0, 1.5))
    set_attr(st.GetPrimAtPath("/World"), "substeps", 12)  # the wind load needs them (sims/flag.py)
    sun(st), dome(st, intensity=0.6)
    save(st, "flag_wind.usda")

    # sims/table_fold: a cloth falls half on a table, half over its edge onto the floor, and folds there
    st = new_stage(os.path.join(out_dir, "cloth_table.usda"), 180,
                   doc="A cloth falls half on a table; the overhanging half drops to the floor and folds onto itself.")
    ground(st, size=5.0, n=41)
    box(st, "/World/Table", (0.0, 0.375, 0.0), (0.8, 0.75, 0.8))
    cloth(st, n=31, size=1.4, translate=(0.65, 1.0, 0.0), albedo=(0.85, 0.8, 0.3), bendStiffness=2e-5)
    sun(st), dome(st, intensity=0.6)
    save(st, "cloth_table.usda")

    # RectLight: cloth over a ball lit by an area light
    st = new_stage(os.path.join(out_dir, "rect_light.usda"), 120, doc="Cloth over a ball under a rectangular area light.")
    ground(st), sphere(st), cloth(st, bendStiffness=2e-5)
    rect = UsdLux.RectLight.Define(st, "/World/Lights/Panel")
    rect.CreateWidthAttr(1.5), rect.CreateHeightAttr(1.0), rect.CreateIntensityAttr(8.0)
    rect.AddTranslateOp().Set(Gf.Vec3d(0.5, 2.5, 0.5))
    rect.AddRotateXOp().Set(-90.0)  # emit downwards (-Z of the light -> -Y of the world)
    dome(st, intensity=0.3)
    save(st, "rect_light.usda")

    # DomeLight texture: a time-sampled waving sheet over a ball (no simulation needed)
    write_sky_exr(os.path.join(out_dir, "sky_small.exr"))
    frames = 48
    st = new_stage(os.path.join(out_dir, "dome_texture.usda"), frames,
                   doc="A waving sheet (time-sampled points) and a ball under an HDR sky from sky_small.exr.")
    ground(st), sphere(st)
    pts, c, i = grid(17, 17, 1.6, 1.6)
    m = mesh(st, "/World/Sheet", pts, c, i, translate=(0.0, 1.2, 0.0), rotate_x=-90.0)
    pa = m.GetPointsAttr()
    pa.Clear()
    for f in range(frames):
        p = pts.copy()
        p[:, 2] = 0.15 * np.sin(3.0 * p[:, 0] + 2 * np.pi * f / frames)
        pa.Set(Vt.Vec3fArray.FromNumpy(p.astype(np.float32)), f)
    bind(m.GetPrim(), material(st, "SheetMat", (0.3, 0.7, 0.35)))
    dome(st, texture="./sky_small.exr", intensity=1.0)
    save(st, "dome_texture.usda")

    # sims/cape_walker: a cape hanging from the shoulders of the walking figure (UsdSkel body)
    try:
        import warpshade.sim.figure  # noqa: F401
    except ImportError:
        print("cape_walker.usda not regenerated: warpshade.sim.figure is not installed")
    else:
        cape_walker(out_dir, save)

    # UsdSkel: a skinned limb bending over time, on the ground, under the sun
    st = new_stage(os.path.join(out_dir, "skinned_arm.usda"), 48, doc="A UsdSkel-skinned limb bending.")
    ground(st), skinned_tube(st, 48), sun(st), dome(st, intensity=0.6)
    save(st, "skinned_arm.usda")
    return made


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("out_dir", nargs="?", default=SCENES_DIR)
    args = p.parse_args(argv)
    for path in make_all(args.out_dir):
        print(path)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
