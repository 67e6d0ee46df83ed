"""A scene built in Python, then simulated, shaded and written by the same :class:`~warpshade.Pipeline`
``warpshade run`` uses (docs/guide/script.md).

Each helper returns the object the USD reader would make from the equivalent prim: a
:class:`~warpshade.scene.SceneObject` with the same ``kind`` and ``params`` keys (``collider``,
``box``, ``sphere``, ``capsule``, ``cylinder``, ``cone``, ``pinned``, ``cloth``, ``points_at``), a :class:`~warpshade.scene.LightSpec`,
or an analytic :class:`~warpshade.lighting.Sky`. :func:`make_scene` collects them; :func:`run` runs them::

    scene = ws.make_scene(ws.ground(), ws.box(size=0.5), ws.cloth_grid(height=0.8), ws.sky())
    ws.run(scene, "out.usda", frames=60)

A script that simulates by itself (its own solver, its own loop) declares its moving meshes with
:func:`mesh` (``moving=True``) and gives :func:`run` a generator yielding ``{name: points}`` per frame.
"""

from __future__ import annotations

import dataclasses
import os

import numpy as np

from .geometry.mesh import TriMesh, vertex_indices
from .lighting import Sky
from .lighting.base import Light
from .scene import LightSpec, Material, Scene, SceneObject, did_you_mean
from .usd.scene_io import SCENE_KEYS, SCENE_SETTINGS

SETTINGS = SCENE_KEYS
"""Scene-wide settings :func:`make_scene` takes: the default prim's ``warpshade:`` attributes of a USD scene
(docs/guide/quickstart.md) and the planner's error budget ``max_error``."""


def _floats(value, n: int | None = None) -> np.ndarray | None:
    """``value`` as float64 (a number broadcast to ``n`` of them when ``n`` is given), or None when it is not
    numbers (a string, None, a bool, a ragged list)."""
    try:
        a = np.asarray(value, dtype=object if isinstance(value, str) else None)
        if a.dtype.kind not in "iuf":
            return None
        a = a.astype(np.float64)
    except (TypeError, ValueError):
        return None
    return np.broadcast_to(a, (n,)).copy() if n is not None and a.ndim == 0 else a


def _vec(value, what: str, n: int = 3) -> np.ndarray:
    a = _floats(value)
    if a is None or a.shape != (n,) or not np.isfinite(a).all():
        raise ValueError(f"{what} must be {n} finite numbers, got {value!r}")
    return a


def _vec3(value, what: str) -> np.ndarray:
    return _vec(value, what, 3)


def _number(value, what: str, low: float | None = None) -> float:
    """A finite number (>= ``low`` when given); the error names ``what``."""
    a = _floats(value)
    if a is None or a.shape != () or not np.isfinite(a) or (low is not None and a < low):
        kind = "finite number" if low is None else "non-negative number" if low == 0 else f"number >= {low}"
        raise ValueError(f"{what} must be a {kind}, got {value!r}")
    return float(a)


def _count(value, what: str, low: int) -> int:
    """An integer >= ``low`` (an int, or a float that is one); the error names ``what``."""
    a = _floats(value)
    if a is None or a.shape != () or not np.isfinite(a) or not float(a).is_integer() or a < low:
        raise ValueError(f"{what} must be an int >= {low}, got {value!r}")
    return int(a)


def _positive(value, what: str, n: int = 1) -> np.ndarray:
    a = _floats(value, n)
    if a is None or a.shape != (n,) or not (np.isfinite(a).all() and (a > 0).all()):
        raise ValueError(f"{what} must be {'a number' if n == 1 else f'a number or {n} numbers'} > 0, got {value!r}")
    return a


def _material(albedo, what: str) -> Material:
    if albedo is None:
        return Material()
    a = _floats(albedo, 3)
    if a is None or a.shape != (3,) or not ((a >= 0) & (a <= 1)).all():
        raise ValueError(f"{what}: albedo must be a number or RGB in [0, 1], got {albedo!r}")
    return Material(albedo=a)


def _name(name, helper: str) -> str:
    """An object's name: a non-empty string (the output prim's name)."""
    if not isinstance(name, str) or not name:
        raise ValueError(f"{helper}: name must be a non-empty string, got {name!r}")
    return name


def _object(name: str, tri: TriMesh, **kwargs) -> SceneObject:
    """A scene object shaded with the default visibility method (as the USD reader's objects are)."""
    from .pipeline import default_method

    return SceneObject(name, tri, method=default_method(), **kwargs)


def _mesh(name: str, points, faces, what: str | None = None) -> TriMesh:
    """The triangle mesh of ``points`` (V, 3) and ``faces`` (F, 3) integer indices; a wrong shape or type is an
    error naming ``what`` (the helper and the object) and the argument."""
    what = what or f"mesh '{name}'"
    p = _floats(points)
    if p is None or p.ndim != 2 or p.shape[1] != 3:
        raise ValueError(f"{what}: points must be numbers of shape (V, 3), got "
                         f"{'shape ' + str(p.shape) if p is not None else repr(points)[:60]}")
    f = _floats(faces)
    if f is None or f.ndim != 2 or f.shape[1] != 3 or not (f == np.round(f)).all():
        got = f"shape {f.shape}" if f is not None and (f.ndim != 2 or f.shape[1] != 3) else repr(faces)[:60]
        raise ValueError(f"{what}: faces must be integer vertex indices of shape (F, 3) (triangles), got {got}")
    return TriMesh(p, f.astype(np.int64), name=name)


def cloth_grid(name: str = "Cloth", size=1.0, resolution=32, height: float = 1.0, center=(0.0, 0.0),
               pinned=None, albedo=None, attached=None, attach_to=None, **material) -> SceneObject:
    """A horizontal square (or rectangular) cloth facing up (+Y), to be simulated.

    Args:
        name: Object name (output prim name).
        size: Width along X and depth along Z [m]: a number or two.
        resolution: Vertices along X and Z: an int >= 2 or two.
        height: Y of the cloth [m].
        center: X and Z of its centre [m].
        pinned: Indices of vertices held fixed (vertex ``(i, j)`` is ``j * nx + i``), or None.
        albedo: Diffuse reflectance, a number or RGB in [0, 1] (default 0.8 grey).
        attached: Indices of vertices that follow ``attach_to``, each keeping its rest offset from the
            target's nearest vertex (``warpshade:attached``), or None.
        attach_to: The moving object (:func:`mesh` with ``moving`` or ``points_at``) or its name that the
            ``attached`` vertices follow (``warpshade:attachTarget``).
        **material: Cloth material (``density`` [kg/m²], ``stretchStiffness``, ``bendStiffness``,
            ``damping``, ``thickness``, ``friction``, ``selfCollision``), as the ``warpshade:cloth:*``
            attributes of a USD cloth.
    """
    what = f"cloth_grid '{_name(name, 'cloth_grid')}'"
    w, d = _positive(size, f"{what}: size", 2)
    res = _floats(resolution, 2)
    if res is None or res.shape != (2,) or not all(np.isfinite(r) and float(r).is_integer() and r >= 2 for r in res):
        raise ValueError(f"{what}: resolution must be an int >= 2 or two, got {resolution!r}")
    nx, nz = int(res[0]), int(res[1])
    cx, cz = _vec(center, f"{what}: center (X and Z)", 2)
    height = _number(height, f"{what}: height")
    from .sim import ClothBuilder

    builder = ClothBuilder()  # its grid: alternating diagonals, triangles facing u x v = +Y
    builder.add_grid(nx, nz, w, d, origin=(cx - w / 2, float(height), cz + d / 2), u_axis=(1, 0, 0),
                     v_axis=(0, 0, -1), name=name)
    piece = builder._pieces[-1]
    return cloth(name, piece.points, piece.faces, pinned=pinned, albedo=albedo, attached=attached, attach_to=attach_to,
                 **material)


def cloth(name: str, points, faces, pinned=None, albedo=None, attached=None, attach_to=None,
          **material) -> SceneObject:
    """A cloth from a given mesh (points (V, 3) [m], triangles (F, 3)), to be simulated; the other
    arguments as :func:`cloth_grid`."""
    from .pipeline.cloth import check_cloth_attributes

    what = f"cloth '{_name(name, 'cloth')}'"
    tri = _mesh(name, points, faces, what)
    check_cloth_attributes(material, what)
    params: dict = {"cloth": dict(material)}
    for key, ids in (("pinned", pinned), ("attached", attached)):
        if ids is not None:
            params[key] = vertex_indices(ids, tri.num_vertices, f"cloth '{name}': {key}").astype(np.int32)
    if (attached is None) != (attach_to is None):
        raise ValueError(f"cloth '{name}': attached and attach_to go together (the vertices and the moving object "
                         "they follow)")
    if attach_to is not None:
        target = attach_to.name if isinstance(attach_to, SceneObject) else attach_to
        if not isinstance(target, str):
            raise ValueError(f"cloth '{name}': attach_to must be a moving object or its name, got {attach_to!r}")
        params["attachTarget"] = target
    return _object(name, tri, kind="cloth", material=_material(albedo, f"cloth '{name}'"), params=params)


def ground(name: str = "Ground", size: float = 4.0, height: float = 0.0, resolution: int = 49,
           albedo=None) -> SceneObject:
    """A horizontal square ground (a collider, a plane at ``height``) of ``resolution`` x
    ``resolution`` vertices, fine enough for contact shadows to fall on vertices."""
    what = f"ground '{_name(name, 'ground')}'"
    s = float(_positive(size, f"{what}: size")[0])
    resolution = _count(resolution, f"{what}: resolution", 2)
    height = _number(height, f"{what}: height")
    from .sim import ClothBuilder

    builder = ClothBuilder()
    builder.add_grid(int(resolution), int(resolution), s, s, origin=(-s / 2, float(height), s / 2),
                     u_axis=(1, 0, 0), v_axis=(0, 0, -1), name=name)
    piece = builder._pieces[-1]
    return _object(name, _mesh(name, piece.points, piece.faces), material=_material(albedo, f"ground '{name}'"),
                       params={"collider": "ground"})


def _edge(edge, longest: float, what: str) -> float:
    """A shape's target edge length: ``edge`` (> 0), or None for its longest extent /
    :data:`~warpshade.geometry.shapes.BOX_SEGMENTS`."""
    from .geometry.shapes import BOX_SEGMENTS

    return longest / BOX_SEGMENTS if edge is None else float(_positive(edge, f"{what}: edge")[0])


def box(name: str = "Box", center=None, size=1.0, collider: bool = True, albedo=None, edge=None) -> SceneObject:
    """An axis-aligned box (an exact box collider unless ``collider=False``), tessellated as the USD
    reader tessellates a Cube (:func:`warpshade.geometry.shapes.gprim_shape`: each face a grid of its own)
    with ``warpshade:graded = false``: uniform, since a shape is made here without the scene it will be
    in (the reader grades a Cube by the other objects' regions).

    Args:
        center: Centre [m]; default: standing on y = 0 at the origin.
        size: Edge lengths [m], a number or three.
        edge: Target edge length of the tessellation [m] (as ``warpshade:edgeLength`` on a Cube);
            default: the longest side / 22.
    """
    from .geometry.shapes import box_segments, box_shape

    ext = _positive(size, f"box '{_name(name, 'box')}': size", 3)
    c = np.array([0.0, ext[1] / 2, 0.0]) if center is None else _vec3(center, f"box '{name}': center")
    verts, faces = box_shape(ext, box_segments(ext, _edge(edge, float(ext.max()), f"box '{name}'")))
    params = {"collider": "box", "box": {"center": c, "half_extents": ext / 2, "rotation": np.array([0.0, 0, 0, 1])}}
    return _object(name, _mesh(name, verts + c, faces),
                       material=_material(albedo, f"box '{name}'"), params=params if collider else {})


def sphere(name: str = "Sphere", center=(0.0, 0.5, 0.0), radius: float = 0.5, collider: bool = True,
           albedo=None) -> SceneObject:
    """A sphere (an exact sphere collider unless ``collider=False``), an icosphere for shading."""
    from .geometry.shapes import sphere_shape

    r = float(_positive(radius, f"sphere '{_name(name, 'sphere')}': radius")[0])
    c = _vec3(center, f"sphere '{name}': center")
    verts, faces = sphere_shape(r, 3)
    params = {"collider": "sphere", "sphere": {"center": c, "radius": r}}
    return _object(name, _mesh(name, verts + c, faces),
                       material=_material(albedo, f"sphere '{name}'"), params=params if collider else {})


def _axis_rotation(axis, what: str) -> np.ndarray:
    """The rotation taking +Z to ``axis``: ``"X"``, ``"Y"``, ``"Z"`` as the USD reader turns a
    gprim's ``axis`` (so both give the same triangles), or a direction (3 numbers)."""
    from .geometry.shapes import AXIS_FROM_Z

    if isinstance(axis, str):
        if axis.upper() not in AXIS_FROM_Z:
            raise ValueError(f"{what} must be 'X', 'Y', 'Z' or 3 numbers, got {axis!r}")
        return AXIS_FROM_Z[axis.upper()]
    d = _vec3(axis, what)
    if not np.linalg.norm(d) > 0:
        raise ValueError(f"{what} must not be zero")
    import trimesh

    return trimesh.geometry.align_vectors([0.0, 0.0, 1.0], d / np.linalg.norm(d))[:3, :3]


def _axial(kind: str, name: str, center, radius, height, axis, collider: bool, albedo, edge, lift) -> SceneObject:
    """A capsule, cylinder or cone along ``axis`` through ``center``: tessellated as the USD reader
    tessellates the gprim for the target ``edge`` (None: its longest extent / 22), and the exact
    analytic collider the reader makes of it."""
    from .geometry.shapes import axial_shape

    what = f"{kind} '{_name(name, kind)}'"
    r = float(_positive(radius, f"{what}: radius")[0])
    h = _floats(height)
    if h is None or h.shape != () or not (np.isfinite(h) and (h > 0 or (kind == "capsule" and h == 0))):
        raise ValueError(f"{what}: height must be a number > 0{' (or 0)' if kind == 'capsule' else ''}, got {height!r}")
    rot = _axis_rotation(axis, f"{what}: axis")
    d = rot[:, 2]
    c = np.array([0.0, lift(r, h), 0.0]) if center is None else _vec3(center, f"{what}: center")
    longest = max(2 * r, h + (2 * r if kind == "capsule" else 0.0))
    verts, faces = axial_shape(kind, r, h, _edge(edge, longest, what))
    ends = (c - d * h / 2, c + d * h / 2)
    shape = {"base": ends[0], "apex": ends[1]} if kind == "cone" else {"p0": ends[0], "p1": ends[1]}
    params = {"collider": kind, kind: {**shape, "radius": r}}
    return _object(name, _mesh(name, verts @ rot.T + c, faces), material=_material(albedo, what),
                   params=params if collider else {})


def capsule(name: str = "Capsule", center=None, radius: float = 0.25, height: float = 0.5, axis="Y",
            collider: bool = True, albedo=None, edge=None) -> SceneObject:
    """A capsule (an exact capsule collider unless ``collider=False``), as a USD Capsule gprim.

    Args:
        center: Centre [m]; default: standing on y = 0 at the origin (for the default Y axis).
        radius: Radius of the cylinder and of its hemispherical ends [m].
        height: Length of the cylindrical part [m] (USD's Capsule ``height``; the whole capsule is
            ``height + 2 * radius`` long), >= 0.
        axis: ``"X"``, ``"Y"``, ``"Z"`` or a direction (3 numbers).
        edge: Target edge length of the tessellation [m] (as ``warpshade:edgeLength`` on the gprim);
            default: the longest extent / 22.
    """
    return _axial("capsule", name, center, radius, height, axis, collider, albedo, edge, lambda r, h: h / 2 + r)


def cylinder(name: str = "Cylinder", center=None, radius: float = 0.25, height: float = 0.5, axis="Y",
             collider: bool = True, albedo=None, edge=None) -> SceneObject:
    """A capped cylinder (an exact cylinder collider unless ``collider=False``), as a USD Cylinder
    gprim; the arguments as :func:`capsule`, ``height`` the whole length (> 0)."""
    return _axial("cylinder", name, center, radius, height, axis, collider, albedo, edge, lambda r, h: h / 2)


def cone(name: str = "Cone", center=None, radius: float = 0.25, height: float = 0.5, axis="Y",
         collider: bool = True, albedo=None, edge=None) -> SceneObject:
    """A cone (an exact cone collider unless ``collider=False``), as a USD Cone gprim: its base
    (``radius``) at ``center - axis * height / 2``, its apex at ``center + axis * height / 2``; the
    arguments as :func:`cylinder`."""
    return _axial("cone", name, center, radius, height, axis, collider, albedo, edge, lambda r, h: h / 2)


def mesh(name: str, points, faces, collider: bool = False, moving: bool = False, points_at=None,
         albedo=None) -> SceneObject:
    """A triangle mesh: static, or moving (animated) when ``moving`` or ``points_at`` is given.

    Args:
        points: Rest positions [m], shape (V, 3).
        faces: Triangles, shape (F, 3), int.
        collider: Cloth collides with it (a triangle-mesh collider, which follows a moving mesh).
        moving: Its points come per frame from the ``geometry`` generator given to :func:`run`.
        points_at: ``points_at(time_code) -> (V, 3)``: its points per frame (as an animated or
            skinned USD mesh provides them), instead of ``moving``.
    """
    tri = _mesh(_name(name, "mesh"), points, faces)
    params: dict = {"collider": "mesh"} if collider else {}
    if points_at is not None:
        if not callable(points_at):
            raise ValueError(f"mesh '{name}': points_at must be callable (time code -> points), got {points_at!r}")
        params["points_at"] = points_at
    moves = moving or points_at is not None
    return _object(name, tri, kind="animated" if moves else "static",
                       material=_material(albedo, f"mesh '{name}'"), params=params)


def sky(sun_elevation: float = 45.0, sun_azimuth: float = 30.0, turbidity: float = 3.0, intensity=1.0,
        up: str = "Y") -> Sky:
    """The analytic daylight (:class:`~warpshade.lighting.Sky`; its defaults are warpshade's default
    sky), written to the output as a DomeLight with its texture."""
    return Sky(sun_elevation=_number(sun_elevation, "sky: sun_elevation"),
               sun_azimuth=_number(sun_azimuth, "sky: sun_azimuth"), turbidity=_number(turbidity, "sky: turbidity"),
               intensity=_number(intensity, "sky: intensity", 0) if np.ndim(intensity) == 0 else
               _vec3(intensity, "sky: intensity (a number or RGB)"), up=up, name="sky")


def _frame_along(direction, what: str) -> np.ndarray:
    """Light-to-world matrix whose ``-Z`` is ``direction`` (UsdLux: a distant light shines along its -Z)."""
    d = _vec3(direction, what)
    n = np.linalg.norm(d)
    if n == 0:
        raise ValueError(f"{what} must not be zero")
    z = -d / n
    x = np.cross([0.0, 1.0, 0.0], z) if abs(z[1]) < 0.99 else np.cross([1.0, 0.0, 0.0], z)
    x /= np.linalg.norm(x)
    xf = np.eye(4)
    xf[:3, :3] = np.stack([x, np.cross(z, x), z], axis=1)
    return xf


def distant(direction=(-0.3, -1.0, -0.2), intensity: float = 1.0, color=(1.0, 1.0, 1.0), angle: float = 0.53,
            name: str = "Sun", normalize: bool = True) -> LightSpec:
    """A UsdLux DistantLight shining along ``direction`` with angular diameter ``angle`` [degrees].

    With ``normalize`` (the default, and what Blender writes for a Sun) ``color * intensity`` is the
    irradiance on a surface facing the light: ``intensity=3`` lights a white floor under it to an exit
    radiance of ``3 / pi``. With ``normalize=False`` it is the radiance of the sun's disc (UsdLux's
    unnormalized light, whose default intensity of 50000 makes a sun of irradiance ~3.4 at 0.53
    degrees; an intensity of a few is then all but black).
    """
    what = f"distant '{name}'"
    a = _number(angle, f"{what}: angle [degrees]", 0)
    if a >= 180:
        raise ValueError(f"{what}: angle [degrees] must be below 180, got {angle!r}")
    return LightSpec("distant", name, color=_vec3(color, f"{what}: color"),
                     intensity=_number(intensity, f"{what}: intensity"), angle=a, normalize=bool(normalize),
                     transform=_frame_along(direction, f"distant '{name}': direction"))


def dome(color=(1.0, 1.0, 1.0), intensity: float = 1.0, texture: str | None = None, name: str = "Dome") -> LightSpec:
    """A UsdLux DomeLight: uniform ``color * intensity``, or a lat-long ``texture`` file (+Y at the top row)."""
    if texture is not None and not isinstance(texture, (str, os.PathLike)):
        raise ValueError(f"dome '{name}': texture must be a file path, got {texture!r}")
    return LightSpec("dome", name, color=_vec3(color, f"dome '{name}': color"),
                     intensity=_number(intensity, f"dome '{name}': intensity"),
                     texture=None if texture is None else os.fspath(texture))


def _check_setting(key: str, value) -> None:
    """A scene-wide setting of :func:`make_scene` of the type its ``warpshade:`` attribute has; the error names it."""
    what = f"make_scene: {key}"
    typ = {**SCENE_SETTINGS, "graded": bool, "wind": "vec3", "max_error": float}[key]
    if typ is bool and not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{what} must be True or False, got {value!r}")
    if typ is int:
        _count(value, what, 1)
    elif typ is float:
        _number(value, what)
    elif typ is str and not isinstance(value, str):
        raise ValueError(f"{what} must be a string, got {value!r}")
    elif typ == "vec3":
        _vec3(value, f"{what} [m/s]")


def make_scene(*items, fps: float = 60.0, frames: int = 120, up: str = "Y", gravity=None, **settings) -> Scene:
    """A :class:`~warpshade.scene.Scene` of objects and lights (in any order).

    Args:
        *items: :class:`SceneObject` (from :func:`cloth_grid`, :func:`box`...), :class:`LightSpec`
            (:func:`distant`, :func:`dome`) or :mod:`warpshade.lighting` lights (:func:`sky`).
            Without lights the scene is lit by the default sky.
        fps: Frames per second (one simulation step of ``1/fps`` per frame).
        frames: Default number of frames of :func:`run`.
        up: Up axis, ``"Y"`` or ``"Z"``.
        gravity: The cloth's gravity, a world vector [m/s²] (as a UsdPhysics ``PhysicsScene`` gives it in a
            USD scene); None: 9.81 m/s² down the up axis. ``(0, 0, 0)``: the cloth floats.
        **settings: Scene-wide settings, as the ``warpshade:`` attributes of a USD scene's default
            prim (``order``, ``substeps``, ``wind``, ``reflections``...).
    """
    unknown = [k for k in settings if k not in SETTINGS]
    if unknown:
        raise ValueError(f"make_scene: '{unknown[0]}' is not a scene setting{did_you_mean(unknown[0], SETTINGS)}"
                         f"; the settings are {', '.join(SETTINGS)}")
    fps = _number(fps, "make_scene: fps")
    if fps <= 0:
        raise ValueError(f"make_scene: fps must be a number > 0, got {fps!r}")
    if not (isinstance(up, str) and up.upper() in ("Y", "Z")):
        raise ValueError(f"make_scene: up must be 'Y' or 'Z', got {up!r}")
    for key, value in settings.items():
        _check_setting(key, value)
    out = Scene(frames=_count(frames, "make_scene: frames", 1), fps=fps, up_axis=up.upper(), settings=dict(settings),
                source="<script>",
                gravity=None if gravity is None else _vec3(gravity, "make_scene: gravity"))
    for i, item in enumerate(items):
        if isinstance(item, SceneObject):
            out.objects.append(item)
        elif isinstance(item, (LightSpec, Light)):
            out.lights.append(item)
        else:
            raise TypeError(f"make_scene: item {i} is a {type(item).__name__}, not an object (cloth_grid, box, ...) "
                            "or a light (sky, distant, dome)")
    names = [o.name for o in out.objects]
    dup = next((n for n in names if names.count(n) > 1), None)
    if dup is not None:
        raise ValueError(f"make_scene: two objects are named '{dup}'; give each a name")
    for o in out.objects:
        target = o.params.get("attachTarget")
        if target is None:
            continue
        if target not in names:
            raise ValueError(f"make_scene: cloth '{o.name}' is attached to '{target}', which is not an object of the "
                             f"scene ({', '.join(names)})")
        if out.object(target).kind != "animated":
            raise ValueError(f"make_scene: cloth '{o.name}' is attached to '{target}', which does not move (give it "
                             "moving=True or points_at)")
    return out


class _Stream:
    """Frames of a user's generator, pulled in order by the moving objects' ``points_at``."""

    def __init__(self, frames, start: int):
        self.frames, self.start, self.index, self.current = iter(frames), start, -1, None

    def points(self, name: str, code: int) -> np.ndarray:
        f = int(code) - self.start
        while self.index < f:
            try:
                self.current = next(self.frames)
            except StopIteration:
                raise ValueError(f"geometry: the generator ended after {self.index + 1} frames; "
                                 f"the run needs frame {f}") from None
            self.index += 1
        if name not in self.current:
            raise ValueError(f"geometry: frame {f} gives no points for moving mesh '{name}' "
                             f"(it gives {', '.join(map(str, self.current)) or 'nothing'})")
        return self.current[name]


def pipeline(scene: Scene, frames: int | None = None, geometry=None, **kwargs):
    """The :class:`~warpshade.Pipeline` of a scene built here: analytic skies among its lights are
    passed as the run's lights, and the moving meshes read their points from ``geometry`` (an
    iterable of ``{name: points (V, 3)}``, one per frame). Other keyword arguments go to the Pipeline."""
    from .pipeline import Pipeline, light_from_spec, require_scene

    require_scene(scene, "ws.run (ws.script.pipeline)")
    objects = [dataclasses.replace(o, params=dict(o.params)) for o in scene.objects]
    stream = _Stream(geometry, scene.start_time) if geometry is not None else None
    for o in objects:
        if o.kind == "animated" and "points_at" not in o.params:
            if stream is None:
                raise ValueError(f"mesh '{o.name}' is moving but run() got no geometry generator to move it")
            o.params["points_at"] = lambda code, name=o.name: stream.points(name, code)
    specs = [li for li in scene.lights if isinstance(li, LightSpec)]
    objs = [li for li in scene.lights if not isinstance(li, LightSpec)]
    for li in objs:
        if isinstance(li, Sky) and li.up.upper() != scene.up_axis:
            raise ValueError(f"sky: up='{li.up}' but the scene's up axis is '{scene.up_axis}'; give sky(up=...)")
    if objs and "lights" not in kwargs:
        kwargs["lights"] = objs + [light_from_spec(s, scene.up_axis, scene.fps) for s in specs]
        specs = []
    return Pipeline(dataclasses.replace(scene, objects=objects, lights=specs), frames=frames, **kwargs)


def run(scene: Scene, out: str, frames: int | None = None, shade: bool = True, geometry=None,
        progress: bool = False, **kwargs):
    """Simulate, shade and write ``scene`` to ``out`` (.usda/.usdc/.usd), as ``warpshade run`` does.

    Args:
        scene: From :func:`make_scene` (or :func:`warpshade.usd.read_scene`).
        out: Output USD path.
        frames: Frames to produce (default: the scene's).
        shade: False writes geometry only: the same simulation, each mesh bound to its albedo.
        geometry: Per-frame points of the meshes declared ``moving`` (see :func:`pipeline`).
        progress: Show a progress bar.
        **kwargs: :class:`~warpshade.Pipeline` options (``method``, ``knobs``, ``order``, ``workers``...).

    Returns:
        The :class:`~warpshade.RunReport` (``path``, ``frames``, ``seconds``...).
    """
    from .pipeline import RunReport
    from .usd import AnimationWriter

    if not shade:
        kwargs.setdefault("refine_receivers", "off")
    pipe = pipeline(scene, frames, geometry, **kwargs)
    writer = AnimationWriter(out, fps=scene.fps, up_axis=scene.up_axis, meters_per_unit=scene.meters_per_unit)
    if shade:
        return pipe.run(writer, progress=progress)
    return _write_geometry(pipe, writer, RunReport)


def _write_geometry(pipe, writer, report_type):
    """Geometry-only output of a pipeline's simulation: points, normals, albedo as displayColor."""
    import time

    from .geometry import vertex_normals_np

    t0 = time.perf_counter()
    objs = pipe.scene.objects
    try:
        names = {o.name: writer.add_mesh(o.name, o.mesh.faces, o.mesh.points if o.kind == "static" else None,
                                         normals=o.mesh.normals if o.kind == "static" else None,
                                         albedo=o.material.albedo, roughness=o.material.roughness, shaded=False)
                 for o in objs}
        for f, geo in pipe.simulate():
            for o in objs:
                pts = geo.get(o.name, o.mesh.points)
                colors = np.broadcast_to(np.asarray(o.material.albedo, dtype=np.float32), (len(pts), 3))
                writer.write_frame(pipe.scene.start_time + f, names[o.name], pts,
                                   vertex_normals_np(np.asarray(pts, dtype=np.float64), o.mesh.faces), colors)
            if f + 1 >= pipe.frames:
                break
        path = writer.close()
    except BaseException:
        writer.abort()
        raise
    return report_type(path=path, frames=pipe.frames, seconds={"total": time.perf_counter() - t0},
                       vertices=sum(o.mesh.num_vertices for o in objs))


__all__ = ["box", "capsule", "cloth", "cloth_grid", "cone", "cylinder", "distant", "dome", "ground", "mesh", "pipeline",
           "make_scene", "run", "sky", "sphere"]
