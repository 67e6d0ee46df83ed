"""Read a USD stage into a :class:`warpshade.scene.Scene` (the pipeline's pxr-free description).

What is read (docs/guide/quickstart.md, "Your own scene", documents every attribute):

* ``UsdGeom.Mesh`` prims, world transform applied, n-gons fan-triangulated. Kind: ``warpshade:kind``
  if authored, else ``skinned`` for meshes bound to a UsdSkel skeleton, ``animated`` for meshes
  with time-sampled points, ``static`` otherwise.
* ``UsdGeom.Sphere`` prims, tessellated for shading and kept analytic (``params["sphere"]``, or
  ``params["sphere_at"](time)`` when the transform is time-sampled) for colliders; ``Cube``,
  ``Cylinder``, ``Capsule``, ``Cone``, ``Plane`` tessellated for shading. Every gprim is
  tessellated for one target edge length (:func:`_gprim_edge`, the rule in
  :mod:`warpshade.geometry.shapes`), once the whole stage is read.
* ``UsdGeom.PointInstancer`` prims: each instance of a prototype's Mesh or gprim becomes an object of its own
  (:func:`_read_instancer`), at ``<instancer>_instances/instance_<id>/...``.
* UsdLux ``DomeLight`` (``inputs:texture:file`` -> environment map), ``DistantLight``,
  ``SphereLight``, ``RectLight`` -> :class:`warpshade.scene.LightSpec`.
* ``UsdPreviewSurface`` ``diffuseColor`` / ``roughness`` of the bound material -> ``Material``
  (without a material: a constant ``primvars:displayColor`` is the albedo).
* ``warpshade:`` attributes on meshes (cloth, pins, method, knobs) and on the default prim
  (frames, SH order, default method).

Anything else is skipped with a :class:`warpshade.scene.SceneWarning` naming the prim. Malformed
files, missing textures and invalid values raise :class:`warpshade.scene.SceneError` naming the
file and the prim.
"""

from __future__ import annotations

import os
import warnings

import numpy as np
from pxr import Sdf, Usd, UsdGeom, UsdLux, UsdPhysics, UsdShade, UsdSkel

from ..geometry.mesh import MeshError, TriMesh, check_finite, vertex_indices
from ..geometry.shapes import (AXIS_FROM_Z, GRADED_KINDS, Grading, cloth_region, fit_budget, frame_boxes, gprim_shape,
                               scene_edge, sphere_shape)
from ..scene import Material, LightSpec, OBJECT_KINDS, Scene, SceneError, SceneObject, SceneWarning, did_you_mean
from .assets import local_file
from .mesh_io import outward_faces, triangulate, usd_error_message
from .writer import BACK_SIDE_OF, RADIANCE_MATERIAL_ATTR

# Prim types that carry no geometry warpshade needs but are expected in scenes: skipped silently.
_UNRENDERED_PURPOSES = (UsdGeom.Tokens.guide, UsdGeom.Tokens.proxy)
"""Purposes whose prims are not shaded (a renderer shows only default and render purpose)."""

_CONTAINERS = {"", "Xform", "Scope", "SkelRoot", "Skeleton", "SkelAnimation", "Material", "Shader",
               "NodeGraph", "GeomSubset", "BlendShape", "Camera"}
"""Prim types read through or skipped without a word (a Camera draws nothing: Blender, Maya and Omniverse
write one into nearly every scene)."""
_LIGHTS = {"DomeLight": "dome", "DistantLight": "distant", "SphereLight": "sphere", "RectLight": "rect"}
#: Scene-wide ``warpshade:`` settings on the default prim and their Python types.
SCENE_SETTINGS = {"frames": int, "fps": float, "order": int, "method": str, "writeTransfer": bool,
                  "substeps": int, "reflections": bool, "refineEdge": float, "edgeLength": float}
SCENE_KEYS = (*SCENE_SETTINGS, "graded", "wind", "max_error")
"""Every ``warpshade:`` attribute the default prim may carry (the scene's settings; ``graded``, ``wind`` and
``max_error`` checked where they are used); another is reported (:func:`unknown_setting`)."""


OBJECT_ATTRIBUTES = ("kind", "collider", "method", "pinned", "attached", "attachTarget", "edgeLength", "graded",
                     "subdivisions", "shaded", "castsShadows", "twoSided", "albedo", "transferOrder",
                     BACK_SIDE_OF[len("warpshade:"):])
"""Every ``warpshade:`` attribute an object may carry (on its prim or a prim above it, below the default prim):
the marks read from a scene and, last, the two only a warpshade output adds (``transferOrder``, ``backSideOf``;
it also writes ``albedo`` and ``twoSided``), so reading an output back is quiet. ``cloth:*`` and ``knobs:*`` (:data:`OBJECT_NAMESPACES`)
are checked where they are read; another name is reported (:func:`_warn_unknown_object_attributes`)."""
OBJECT_NAMESPACES = ("cloth:", "knobs:")
"""``warpshade:`` namespaces of an object whose names the cloth solver's and the method's checks know."""


def _warn_unknown_object_attributes(stage: Usd.Stage, root, source: str) -> None:
    """Warn (SceneWarning), once per attribute, about each ``warpshade:`` attribute of a prim below the default
    prim (an object or a prim above objects; materials not) that is none of :data:`OBJECT_ATTRIBUTES` and
    :data:`OBJECT_NAMESPACES`, naming the file, the prim, the attribute and the closest known name. The
    default prim's own are scene settings (checked with :func:`unknown_setting`) unless it is a gprim, whose
    attributes are both."""
    seen = set()
    it = iter(Usd.PrimRange(stage.GetPseudoRoot(), _PRIMS))
    for prim in it:
        if prim.GetTypeName() in ("Material", "Shader", "NodeGraph"):
            it.PruneChildren()
            continue
        if prim.IsPseudoRoot() or (prim == root and not prim.IsA(UsdGeom.Gprim)):
            continue
        known = (*OBJECT_ATTRIBUTES, *SCENE_KEYS) if prim == root else OBJECT_ATTRIBUTES
        spec = prim.GetPrimInPrototype() if prim.IsInstanceProxy() else prim  # one word for all instances
        for prop in prim.GetAuthoredPropertiesInNamespace("warpshade"):
            name = prop.GetName()[len("warpshade:"):]
            if name in known or name.startswith(OBJECT_NAMESPACES) or (spec.GetPath(), name) in seen:
                continue
            seen.add((spec.GetPath(), name))
            scene_only = f"; warpshade:{name} is a scene setting: author it on the default prim" if name in SCENE_KEYS \
                else ""
            warnings.warn(f"{source}:{prim.GetPath()}: warpshade:{name} is not an object attribute"
                          f"{did_you_mean(name, OBJECT_ATTRIBUTES)}; ignored{scene_only} (an object's attributes are "
                          f"{', '.join(OBJECT_ATTRIBUTES[:-2])} and warpshade:cloth:*, warpshade:knobs:*)",
                          SceneWarning, stacklevel=3)


def unknown_setting(where: str, name: str) -> str:
    """The message for a ``warpshade:`` attribute of the default prim at ``where`` that is no scene setting."""
    return (f"{where}: warpshade:{name} is not a scene setting{did_you_mean(name, SCENE_KEYS)}; ignored (the scene "
            f"settings are {', '.join(SCENE_KEYS)}; an object's warpshade: attributes go on it or on a prim between "
            "it and the default prim)")


def read_scene(path: str) -> Scene:
    """Read a scene file.

    Args:
        path: ``.usda``, ``.usdc`` or ``.usd`` file.

    Returns:
        The scene, its objects in stage traversal order.

    Raises:
        SceneError: unreadable or malformed file, missing texture, invalid ``warpshade:`` value.
    """
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise SceneError(f"{path}: no such scene file")
    try:
        stage = Usd.Stage.Open(path)
    except Exception as exc:  # pxr raises Tf.ErrorException for syntax errors
        raise SceneError(f"{path}: cannot open USD stage: {usd_error_message(exc)}") from exc
    if stage is None:
        raise SceneError(f"{path}: cannot open USD stage")
    return scene_from_stage(stage, path)


_PRIMS = Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)
"""The prims a scene is read from: the default predicate's, and the meshes inside instances (instance
proxies: each instance is shaded as an object of its own, at its own path)."""


def scene_from_stage(stage: Usd.Stage, source: str = "<stage>") -> Scene:
    """Build a :class:`Scene` from an open stage (see :func:`read_scene`)."""
    scene = Scene(source=source)
    scene.up_axis = str(UsdGeom.GetStageUpAxis(stage))
    scene.meters_per_unit = float(UsdGeom.GetStageMetersPerUnit(stage))  # 0.01 when unauthored (UsdGeom)
    units_authored = bool(UsdGeom.StageHasAuthoredMetersPerUnit(stage))
    scene.fps = float(stage.GetTimeCodesPerSecond())
    if stage.HasAuthoredMetadata("startTimeCode"):
        start = stage.GetStartTimeCode()
        if start != round(start):
            warnings.warn(f"{source}: startTimeCode {start} is not a whole frame; frame 0 is time code "
                          f"{round(start)}", SceneWarning, stacklevel=2)
        scene.start_time = int(round(start))
    if stage.HasAuthoredMetadata("endTimeCode"):
        scene.frames = int(round(stage.GetEndTimeCode() - stage.GetStartTimeCode())) + 1
    root = stage.GetDefaultPrim() or stage.GetPseudoRoot()
    if not root.IsPseudoRoot() and not root.IsA(UsdGeom.Gprim):
        scene.default_prim = str(root.GetPath())
    scene.settings = _namespace(root, source, skip=())
    if not root.IsA(UsdGeom.Gprim):  # a gprim's own attributes are also its object marks
        for key in [k for k in scene.settings if k not in SCENE_KEYS]:
            warnings.warn(unknown_setting(f"{source}:{root.GetPath()}", key), SceneWarning, stacklevel=2)
            del scene.settings[key]
    _warn_unknown_object_attributes(stage, root, source)
    for key, value in list(scene.settings.items()):
        if key in SCENE_SETTINGS:
            scene.settings[key] = _cast(value, SCENE_SETTINGS[key], source, root, key)
    if "graded" in scene.settings:
        scene.settings["graded"] = _graded_flag(scene.settings["graded"], f"{source}:{root.GetPath()}")
    if "frames" in scene.settings:
        scene.frames = scene.settings["frames"]
    if "fps" in scene.settings:
        scene.fps = scene.settings["fps"]
    if scene.frames < 1:
        raise SceneError(f"{source}:{root.GetPath()}: warpshade:frames must be >= 1, got {scene.frames}")
    if not (np.isfinite(scene.fps) and scene.fps > 0):  # a frame is a step of 1 / fps seconds
        where = f"{source}:{root.GetPath()}: warpshade:fps" if "fps" in scene.settings else f"{source}: timeCodesPerSecond"
        raise SceneError(f"{where} must be a number of frames per second > 0, got {scene.fps:g}")
    scene.gravity = physics_gravity(stage, source)

    cache = UsdSkel.Cache()
    for skel_root in Usd.PrimRange(stage.GetPseudoRoot(), _PRIMS):
        if skel_root.IsA(UsdSkel.Root):
            cache.Populate(UsdSkel.Root(skel_root), _PRIMS)
    default_method = scene.settings.get("method")
    if default_method is None:
        from ..visibility import default_method as fastest

        default_method = fastest()
    unmarked = []  # meshes whose kind was not authored
    gprims = []  # gprims in traversal order, read once the stage's size is known
    deferred = []  # (index in scene.objects, make): instances of gprim prototypes, made once those are read
    it = iter(Usd.PrimRange(stage.GetPseudoRoot(), _PRIMS))
    for prim in it:
        if prim.IsPseudoRoot():
            continue
        tname = prim.GetTypeName()
        if not prim.IsActive() or (prim.IsA(UsdGeom.Imageable)
                                   and UsdGeom.Imageable(prim).ComputeVisibility() == UsdGeom.Tokens.invisible):
            it.PruneChildren()
            continue
        if tname in ("Material", "Shader", "NodeGraph"):
            it.PruneChildren()
            continue
        if prim.IsA(UsdGeom.Imageable) and UsdGeom.Imageable(prim).ComputePurpose() in _UNRENDERED_PURPOSES:
            # guide / proxy geometry (collision twins, stand-ins) is not what renders; marked as a
            # collider it still collides (read, not shaded, not written)
            for sub in Usd.PrimRange(prim, _PRIMS):
                if (sub.IsA(UsdGeom.Gprim) and sub.IsActive() and _physics_collider(sub)
                        and UsdGeom.Imageable(sub).ComputeVisibility() != UsdGeom.Tokens.invisible):
                    if sub.IsA(UsdGeom.Mesh):
                        obj = _read_mesh(sub, source, cache, None)
                        if obj.kind == "static" and obj.params.get("collider"):
                            scene.collision_only.append(obj)
                    elif sub.IsA(UsdGeom.Sphere) or sub.GetTypeName() in _GPRIMS:
                        gprims.append(_Gprim(sub, source, None, scene.collision_only, len(scene.collision_only)))
                        scene.collision_only.append(None)
            it.PruneChildren()
            continue
        if prim.HasRelationship(BACK_SIDE_OF):
            continue  # the back side of a two-sided warpshade output: the front carries warpshade:twoSided
        if prim.IsA(UsdGeom.Mesh):
            marks = _object_namespace(prim, source)
            scene.objects.append(_read_mesh(prim, source, cache, default_method, marks))
            if "kind" not in marks:
                unmarked.append(scene.objects[-1])
        elif prim.IsA(UsdGeom.Sphere) or tname in _GPRIMS:
            gprims.append(_Gprim(prim, source, default_method, scene.objects, len(scene.objects)))
            scene.objects.append(None)  # tessellated below, once the scene's size is known
        elif tname in _LIGHTS:
            scene.lights.append(_read_light(prim, _LIGHTS[tname], source, scene))
        elif prim.IsA(UsdGeom.PointInstancer):
            objects, later = _read_instancer(prim, source, cache, default_method, scene, gprims)
            deferred += [(len(scene.objects) + k, make) for k, make in later]
            scene.objects.extend(objects)  # None where an instance of a gprim prototype goes, made below
            it.PruneChildren()  # its prototypes are drawn only as its instances
        elif tname not in _CONTAINERS and prim.IsA(UsdGeom.Imageable) and not prim.IsA(UsdPhysics.Joint):
            # non-imageable prims (UsdPhysics scene, collision groups...) and joints draw nothing: not worth a word
            warnings.warn(f"{source}: skipping {prim.GetPath()} ({tname}): warpshade reads Mesh, Sphere, Cube, Cylinder, Capsule, Cone, Plane, "
                          "PointInstancer, UsdLux Dome/Distant/Sphere/Rect lights and UsdSkel", SceneWarning, stacklevel=2)
            it.PruneChildren()
    _read_gprims(scene, gprims, root)
    for index, make in deferred:
        scene.objects[index] = make()
    if not scene.objects:
        raise SceneError(f"{source}: no Mesh or gprim (Sphere, Cube, Cylinder, Capsule, Cone, Plane) to shade")
    for obj in unmarked:
        if _looks_like_cloth(obj, scene):
            warnings.warn(f"{source}:{obj.prim_path}: looks like cloth (an open, flat sheet of {obj.mesh.num_vertices} "
                          'vertices, above the lowest object, not a collider) but has no warpshade:kind, so it stays '
                          'static: add custom token warpshade:kind = "cloth" to simulate it, or "static" to keep it '
                          "still", SceneWarning, stacklevel=2)
    _warn_rigid_bodies(stage, scene)
    _warn_subdivision(stage, scene)
    if not units_authored and any(o.kind == "cloth" for o in scene.objects):
        warnings.warn(_unauthored_units_message(scene), SceneWarning, stacklevel=2)
    return scene


def _dynamic_body(prim):
    """The prim at or above ``prim`` with an enabled, non-kinematic UsdPhysics ``RigidBodyAPI`` (a body a
    physics engine drops and pushes), or None; None too under an ``ArticulationRootAPI`` (a robot's or
    character's links, taken as posed by the stage)."""
    body = None
    while prim and not prim.IsPseudoRoot():
        if prim.HasAPI(UsdPhysics.ArticulationRootAPI):
            return None
        if body is None and prim.HasAPI(UsdPhysics.RigidBodyAPI):
            api = UsdPhysics.RigidBodyAPI(prim)
            if api.GetRigidBodyEnabledAttr().Get() is False or api.GetKinematicEnabledAttr().Get():
                return None
            body = prim
        prim = prim.GetParent()
    return body


def _warn_rigid_bodies(stage: Usd.Stage, scene: Scene) -> None:
    """One SceneWarning naming the still objects that are free UsdPhysics dynamic rigid bodies
    (:func:`_dynamic_body`, linked by no joint; Omniverse and Isaac Sim mark the crates PhysX drops and pushes
    so): warpshade does not simulate them."""
    jointed = set()  # bodies a joint links (an articulation's links): posed by the stage, not free
    for prim in stage.Traverse():
        if prim.IsA(UsdPhysics.Joint):
            joint = UsdPhysics.Joint(prim)
            jointed.update(str(t) for rel in (joint.GetBody0Rel(), joint.GetBody1Rel()) for t in rel.GetTargets())
    bodies = []
    for obj in list(scene.objects) + list(scene.collision_only):
        if obj.kind != "static" or obj.prim_path is None:
            continue
        body = _dynamic_body(stage.GetPrimAtPath(obj.prim_path))
        if body is not None and str(body.GetPath()) not in bodies and str(body.GetPath()) not in jointed:
            bodies.append(str(body.GetPath()))
    if bodies:
        one = len(bodies) == 1
        it = "it" if one else "them"
        warnings.warn(f"{scene.source}: {', '.join(bodies[:3])}{', ...' if len(bodies) > 3 else ''}: "
                      f"{'a dynamic rigid body' if one else f'{len(bodies)} dynamic rigid bodies'} (UsdPhysics "
                      f"RigidBodyAPI), which warpshade does not simulate: {'it stays' if one else 'they stay'} where "
                      f"the stage puts {it} for the whole run; bake the motion into time-sampled transforms to move "
                      f"{it} (a moving collider follows its keys), or set physics:kinematicEnabled = true on {it} to "
                      "say the stage's pose is meant", SceneWarning, stacklevel=3)


def _warn_subdivision(stage: Usd.Stage, scene: Scene) -> None:
    """One SceneWarning naming the meshes that author a ``subdivisionScheme`` other than ``none`` (mayaUSD
    writes ``catmullClark`` by default): warpshade shades and writes their control mesh, which a renderer
    would have smoothed. (The schema's fallback is ``catmullClark`` too, but a mesh that does not author it
    was not asked to be smoothed by a DCC: it is not named.)"""
    smoothed = {}
    for obj in scene.objects:
        prim = stage.GetPrimAtPath(obj.prim_path) if obj.prim_path else None
        if not prim or not prim.IsA(UsdGeom.Mesh):  # (an instance of a PointInstancer has no prim)
            continue
        attr = UsdGeom.Mesh(prim).GetSubdivisionSchemeAttr()
        scheme = attr.Get() if attr.HasAuthoredValue() else UsdGeom.Tokens.none
        if scheme != UsdGeom.Tokens.none:
            smoothed.setdefault(str(scheme), []).append(obj.prim_path)
    for scheme, paths in smoothed.items():
        warnings.warn(f"{scene.source}: {', '.join(paths[:3])}{', ...' if len(paths) > 3 else ''}"
                      f"{f' ({len(paths)} meshes)' if len(paths) > 1 else ''}: subdivisionScheme {scheme}, but "
                      "warpshade shades and writes the control mesh (subdivisionScheme none), so the output shows "
                      "the cage a renderer would have smoothed: subdivide before exporting (mayaUSD: Subdivision "
                      "Method None after Smooth Mesh), or author subdivisionScheme = none to keep the cage",
                      SceneWarning, stacklevel=3)


EARTH_GRAVITY = 9.81
"""[m/s²]: the cloth's gravity without a ``PhysicsScene``, and a ``PhysicsScene``'s whose
``physics:gravityMagnitude`` is unauthored or negative (UsdPhysics: Earth gravity in the stage's units)."""


def physics_gravity(stage: Usd.Stage, source: str = "<stage>") -> np.ndarray | None:
    """The gravity of the stage's UsdPhysics ``PhysicsScene`` as a world vector [m/s²], or None when it
    has none (the cloth then falls at :data:`EARTH_GRAVITY` down the up axis).

    As the UsdPhysics schema reads it: ``physics:gravityDirection`` normalized, a zero vector (its
    fallback) meaning down the stage's up axis; ``physics:gravityMagnitude`` in stage units per s²
    (converted with ``metersPerUnit``), a negative value (its fallback, -inf) meaning Earth gravity
    whatever the units. Several active PhysicsScenes must agree (UsdPhysics lets each body choose its
    scene, cloth has none to choose): different gravities are a SceneError naming them."""
    found = []
    for prim in stage.Traverse():
        if not prim.IsA(UsdPhysics.Scene):
            continue
        where = f"{source}:{prim.GetPath()}"
        physics = UsdPhysics.Scene(prim)
        direction = physics.GetGravityDirectionAttr().Get()
        direction = np.zeros(3) if direction is None else np.asarray(direction, dtype=np.float64)
        magnitude = physics.GetGravityMagnitudeAttr().Get()
        magnitude = -np.inf if magnitude is None else float(magnitude)
        if not np.isfinite(direction).all():
            raise SceneError(f"{where}: physics:gravityDirection {direction.tolist()} is not finite")
        if np.isnan(magnitude) or magnitude == np.inf:
            raise SceneError(f"{where}: physics:gravityMagnitude {magnitude} is not a number >= 0 "
                             "(or negative for Earth gravity)")
        norm = float(np.linalg.norm(direction))
        if norm == 0.0:
            up = str(UsdGeom.GetStageUpAxis(stage))
            direction, norm = -np.eye(3)[_AXES.get(up, 1)], 1.0
        si = EARTH_GRAVITY if magnitude < 0 else magnitude * float(UsdGeom.GetStageMetersPerUnit(stage))
        found.append((str(prim.GetPath()), direction / norm * si))
    if not found:
        return None
    first = found[0][1]
    for path, g in found[1:]:
        if not np.allclose(g, first, rtol=1e-6, atol=1e-9):
            raise SceneError(f"{source}: PhysicsScenes {found[0][0]} and {path} give different gravities "
                             f"({np.round(first, 4).tolist()} and {np.round(g, 4).tolist()} m/s²); the cloth "
                             "has one: deactivate or delete all but one")
    return first


def _unauthored_units_message(scene: Scene) -> str:
    """The warning for a stage with cloth and no ``metersPerUnit``: the size its cloth is simulated at."""
    cloth = np.concatenate([o.mesh.points for o in scene.objects if o.kind == "cloth"])
    across = float(np.linalg.norm(np.ptp(cloth, axis=0)))
    return (f"{scene.source}: metersPerUnit is not authored, so the stage is in centimetres (UsdGeom's fallback "
            f"0.01, as Blender reads it) and its cloth is simulated {across * scene.meters_per_unit:.3g} m across "
            f"({across:.3g} units); if the scene is in metres, author metersPerUnit = 1 "
            "(UsdGeom.SetStageMetersPerUnit(stage, 1.0)), see docs/conventions.md §8")


CLOTH_LIKE_MIN_VERTICES = 64
"""A static, unmarked mesh needs at least this many vertices (an 8 x 8 grid) to look like cloth;
a 2-triangle ground or a quad has 4."""


def _looks_like_cloth(obj, scene) -> bool:
    """Whether a static mesh whose kind was not authored looks like a sheet meant to be simulated:
    open (it has boundary edges), flat (its thinnest extent at most 5 % of its widest), at least
    :data:`CLOTH_LIKE_MIN_VERTICES` vertices, no collider mark, and not the scene's floor (its lowest
    point above the lowest point of the other objects by 1 % of the scene's size)."""
    if obj.kind != "static" or obj.params.get("collider") or obj.mesh.num_vertices < CLOTH_LIKE_MIN_VERTICES:
        return False
    pts = obj.mesh.points
    ext = np.ptp(pts, axis=0)
    if not ext.max() > 0 or ext.min() > 0.05 * ext.max():
        return False
    others = [o.mesh.points for o in scene.objects if o is not obj]
    if not others:
        return False
    edges = np.sort(obj.mesh.faces[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2).astype(np.int64), axis=1)
    # one int64 key per undirected edge: a 1-D unique (np.unique(axis=0) took 28 s on 1M vertices)
    _, counts = np.unique(edges[:, 0] * obj.mesh.num_vertices + edges[:, 1], return_counts=True)
    if not np.any(counts == 1):
        return False
    up = {"X": 0, "Y": 1, "Z": 2}.get(scene.up_axis, 1)
    allpts = np.concatenate(others + [pts])
    size = float(np.linalg.norm(np.ptp(allpts, axis=0)))
    return float(pts[:, up].min()) > float(np.concatenate(others)[:, up].min()) + 0.01 * size


# -- meshes -------------------------------------------------------------------------------------
def _world(prim, t=Usd.TimeCode.EarliestTime()) -> np.ndarray:
    """Local-to-world of ``prim`` acting on column vectors, shape (4, 4), float64. At the earliest time
    by default: a transform a DCC wrote as time samples only (one, for a still object) has no value at
    the default time, where USD would read it as the identity."""
    return np.asarray(UsdGeom.Xformable(prim).ComputeLocalToWorldTransform(t), dtype=np.float64).T


def _apply(xf: np.ndarray, pts: np.ndarray) -> np.ndarray:
    return pts @ xf[:3, :3].T + xf[:3, 3]


def _hierarchy(prim) -> tuple:
    """:attr:`SceneObject.prim_xforms` of ``prim``: it and its ancestors, root first, each
    ``(path, type name, local matrix or None, resets the xform stack, is an instance)``, transforms at
    the earliest time (the first time sample, else the default value)."""
    chain = []
    t = Usd.TimeCode.EarliestTime()
    while prim and not prim.IsPseudoRoot():
        local, resets = None, False
        if prim.IsA(UsdGeom.Xformable):
            xf = UsdGeom.Xformable(prim)
            local = np.asarray(xf.GetLocalTransformation(t), dtype=np.float64).T
            resets = bool(xf.GetResetXformStack())
        chain.append((str(prim.GetPath()), str(prim.GetTypeName()), local, resets, bool(prim.IsInstance())))
        prim = prim.GetParent()
    return tuple(reversed(chain))


def _topology(mesh, where: str) -> tuple:
    """A mesh's ``faceVertexCounts`` and ``faceVertexIndices``: their default values, or, when either is
    time-sampled (Blender writes a mesh whose modifiers change it as empty defaults beside samples at every
    frame), the samples if they are alike at every time code; a SceneError naming the prim and the first time
    code where they change, since a mesh is simulated and shaded with one topology."""
    ca, ia = mesh.GetFaceVertexCountsAttr(), mesh.GetFaceVertexIndicesAttr()
    times = sorted(set(ca.GetTimeSamples()) | set(ia.GetTimeSamples()))
    if not times:
        return ca.Get(), ia.Get()
    counts, idx = ca.Get(times[0]), ia.Get(times[0])
    for t in times[1:]:
        c, i = ca.Get(t), ia.Get(t)
        if c != counts or i != idx:
            raise SceneError(f"{where}: its faces change over time (faceVertexCounts/faceVertexIndices are time-sampled: "
                             f"{len(counts or [])} faces of {sum(counts or [])} corners at time {times[0]:g}, {len(c or [])} of "
                             f"{sum(c or [])} at {t:g}), but warpshade "
                             "simulates and shades a mesh with the same vertices and faces in every frame: apply the "
                             "modifiers that change them (Blender: Build, Remesh, Decimate, Boolean...) or export "
                             "one frame")
    return counts, idx


def _read_mesh(prim, source: str, cache: UsdSkel.Cache, default_method, marks: dict | None = None) -> SceneObject:
    """A Mesh prim's object; ``marks``: its :func:`_object_namespace` when the caller has it."""
    where = f"{source}:{prim.GetPath()}"
    mesh = UsdGeom.Mesh(prim)
    counts, idx = _topology(mesh, where)
    pattr = mesh.GetPointsAttr()
    samples = pattr.GetTimeSamples()
    default = pattr.Get() if pattr.HasAuthoredValue() else None
    # Blender writes a mesh whose modifiers change it as empty defaults beside its time samples
    t0 = Usd.TimeCode.Default() if default is not None and (len(default) or not samples) else (
        Usd.TimeCode(samples[0]) if samples else Usd.TimeCode.Default())
    pts = pattr.Get(t0)
    if pts is None or counts is None or idx is None:
        raise SceneError(f"{where}: mesh lacks points, faceVertexCounts or faceVertexIndices")
    try:
        faces = triangulate(np.asarray(counts), np.asarray(idx), where, mesh.GetHoleIndicesAttr().Get())
    except MeshError as exc:
        raise SceneError(str(exc)) from None
    local = np.asarray(pts, dtype=np.float64).reshape(-1, 3)
    try:  # the authored value, before a transform spreads a NaN over the other coordinates
        check_finite(local, f"{where}: points{'' if t0.IsDefault() else f' at time {t0.GetValue():g}'}")
    except MeshError as exc:
        raise SceneError(str(exc)) from None
    settings = dict(marks) if marks is not None else _object_namespace(prim, source)
    skinning = UsdSkel.BindingAPI(prim) if prim.HasAPI(UsdSkel.BindingAPI) else None
    kind = settings.pop("kind", None)
    if kind is None:
        kind = "skinned" if skinning is not None else (
            "animated" if len(samples) > 1 or _xform_varies(prim) else "static")
    if kind not in OBJECT_KINDS:
        raise SceneError(f"{where}: warpshade:kind '{kind}' is not one of {', '.join(OBJECT_KINDS)}")
    params: dict = {}
    if kind == "skinned":
        params["points_at"] = _skinned_points(prim, cache, where)
        points = params["points_at"](samples[0] if samples else 0)
        world = _world(UsdSkel.BindingAPI(prim).GetInheritedSkeleton().GetPrim())  # skinned points' space
    else:
        world = _world(prim, Usd.TimeCode.EarliestTime() if t0.IsDefault() else t0)
        points = _apply(world, local)
    faces = outward_faces(faces, prim, world)
    if kind == "animated":
        params["points_at"] = _animated_points(prim, where)
    try:
        tri = TriMesh(points, faces, name=where)
    except MeshError as exc:
        raise SceneError(str(exc)) from None
    if kind == "cloth":
        params["cloth"] = {k[len("cloth:"):]: v for k, v in settings.items() if k.startswith("cloth:")}
    for k in [k for k in settings if k.startswith("cloth:")]:
        settings.pop(k)
    for key in ("pinned", "attached"):
        vs = _vertex_selection(prim, where, key, settings.pop(key, None), tri.num_vertices)
        if vs is not None:
            params[key] = vs
    return _object(prim, where, tri, kind, settings, params, default_method, _material(prim, where))


VERTEX_SELECTION_PRIMVARS = ("warpshade:{}", "warpshade_{}")
"""Names of the per-vertex primvars that select a mesh's ``pinned`` or ``attached`` vertices (``{}``): the
namespaced one, and the one DCCs write when an attribute name may not hold a colon (Blender exports a vertex
group or a point attribute named ``warpshade:pinned`` as ``primvars:warpshade_pinned``; Houdini's point
attributes have no colons either)."""

VERTEX_SELECTED = 0.5
"""A per-vertex selection primvar selects the vertices whose value is at least this: 1 or true, a full vertex
group weight; 0, false and weights below one half leave a vertex out."""


def _vertex_selection(prim, where: str, key: str, listed, n: int) -> np.ndarray | None:
    """The vertices ``warpshade:<key>`` selects (``pinned``, ``attached``), as int32 indices, or None.

    Either an index list (``int[] warpshade:<key>``, on the mesh or a prim above it: ``listed``) or a per-vertex
    primvar (:data:`VERTEX_SELECTION_PRIMVARS`, ``vertex`` or ``varying`` interpolation, one bool or number a
    point, selecting those at least :data:`VERTEX_SELECTED`), not both."""
    api = UsdGeom.PrimvarsAPI(prim)
    found = [pv for pv in (api.GetPrimvar(name.format(key)) for name in VERTEX_SELECTION_PRIMVARS)
             if pv and pv.HasAuthoredValue()]
    if listed is not None and found:
        raise SceneError(f"{where}: warpshade:{key} is authored twice, as a vertex list and as the primvar "
                         f"{found[0].GetName()}: keep one")
    if len(found) > 1:
        raise SceneError(f"{where}: warpshade:{key} is authored twice, as the primvars {found[0].GetName()} and "
                         f"{found[1].GetName()}: keep one")
    if found:
        pv = found[0]
        name = pv.GetName()
        if pv.GetInterpolation() not in (UsdGeom.Tokens.vertex, UsdGeom.Tokens.varying):
            raise SceneError(f"{where}: {name} must have vertex interpolation (one value a point), has "
                             f"'{pv.GetInterpolation()}'")
        try:
            values = np.asarray(pv.ComputeFlattened(), dtype=np.float64).reshape(-1)
        except (TypeError, ValueError):
            raise SceneError(f"{where}: {name} must hold one bool or number a point, has type "
                             f"{pv.GetTypeName()}") from None
        if len(values) != n:
            raise SceneError(f"{where}: {name} has {len(values)} values for the mesh's {n} points")
        if not np.isfinite(values).all():
            raise SceneError(f"{where}: {name} value of vertex {int(np.flatnonzero(~np.isfinite(values))[0])} is "
                             "not finite")
        return np.flatnonzero(values >= VERTEX_SELECTED).astype(np.int32)
    if listed is None:
        return None
    return vertex_indices(listed, n, f"{where}: warpshade:{key}", SceneError).astype(np.int32)


def _read_sphere(prim, source: str, default_method, edge: float, marks: dict) -> SceneObject:
    """A Sphere gprim's object, tessellated for ``edge``; ``marks``: its :func:`_object_namespace`."""
    where = f"{source}:{prim.GetPath()}"
    settings = dict(marks)
    settings.pop("edgeLength", None)  # in ``edge`` already (_gprim_edge)
    settings.pop("graded", None)  # a Sphere is not graded (GRADED_KINDS)
    radius = float(UsdGeom.Sphere(prim).GetRadiusAttr().Get())
    if not radius > 0:
        raise SceneError(f"{where}: sphere radius must be > 0, got {radius}")
    xf = _world(prim)
    if "subdivisions" in settings:
        verts, faces = sphere_shape(radius, int(settings.pop("subdivisions")))
    else:
        verts, faces = gprim_shape("sphere", {"radius": radius}, np.linalg.norm(xf[:3, :3], axis=0), edge)
    tri = TriMesh(_apply(xf, verts), outward_faces(faces, prim, xf), name=where)
    kind = _gprim_kind(prim, settings, where)
    if kind == "animated":
        params = {"points_at": _moved_points(prim, verts), "sphere_at": _moved_sphere(prim, radius)}
    else:
        scale = float(np.cbrt(abs(np.linalg.det(xf[:3, :3]))))
        params = {"sphere": {"center": xf[:3, 3].copy(), "radius": radius * scale}}
    return _object(prim, where, tri, kind, settings, params, default_method, _material(prim, where))


SPHERE_SCALE_TOL = 1.0e-6
"""Largest entry of ``M^T M / s^2 - I`` (M a transform's linear part, s its mean scale) that still
keeps a sphere a sphere (float32 round-off of an authored uniform scale and rotation is ~1e-7)."""


def _sphere_of(xf: np.ndarray, radius: float) -> dict | None:
    """``{"center", "radius"}`` of a sphere of ``radius`` under the transform ``xf``, or None when
    ``xf`` does not keep it a sphere (a non-uniform scale or a shear; a static Sphere takes the
    mean scale instead)."""
    m = xf[:3, :3]
    scale = float(np.cbrt(abs(np.linalg.det(m))))
    if not scale > 0 or np.abs(m.T @ m / scale**2 - np.eye(3)).max() > SPHERE_SCALE_TOL:
        return None
    return {"center": xf[:3, 3].copy(), "radius": radius * scale}


def _moved_sphere(prim, radius: float):
    """``sphere_at(time)``: an animated Sphere's :func:`_sphere_of` at that time code (None at a time
    its transform does not keep it a sphere)."""
    def sphere_at(time: float) -> dict | None:
        return _sphere_of(_world(prim, Usd.TimeCode(time)), radius)

    sphere_at.stage = prim.GetStage()  # keeps the stage (and so prim) alive as long as the function
    return sphere_at


def _gprim_kind(prim, settings: dict, where: str) -> str:
    """``warpshade:kind`` of a gprim: ``static``, or ``animated`` when its transform is time-sampled
    (a DCC's keyframed ball); a gprim is never simulated or skinned."""
    kind = settings.pop("kind", "animated" if _xform_varies(prim) else "static")
    if kind not in ("static", "animated"):
        raise SceneError(f"{where}: warpshade:kind '{kind}' on a {prim.GetTypeName()}: gprims are static or move "
                         "with their transform (convert it to a Mesh to simulate or skin it)")
    return kind


def _moved_points(prim, local: np.ndarray):
    """``points_at(time)``: a gprim's tessellation ``local`` under its transform at that time code."""
    def points_at(time: float) -> np.ndarray:
        return _apply(_world(prim, Usd.TimeCode(time)), local).astype(np.float32)

    points_at.stage = prim.GetStage()  # keeps the stage (and so prim) alive as long as the function
    return points_at


_GPRIMS = ("Cube", "Cylinder", "Capsule", "Cone", "Plane")
"""UsdGeom gprims other than Sphere that are read: tessellated for shading, mesh colliders when marked."""

_DIMS = {"Sphere": ("radius",), "Cube": ("size",), "Cylinder": ("radius", "height"), "Capsule": ("radius", "height"),
         "Cone": ("radius", "height"), "Plane": ("width", "length")}
"""A gprim's size attributes (UsdGeom's, with their schema fallbacks)."""


class _Gprim:
    """A gprim met in the traversal, read once the stage's size is known: where its object goes
    (``target[index]``), its shape for the tessellation rule (``kind``, ``dims``, ``scale``: world length
    of a unit along each local axis of the shape built along +Z), its own ``warpshade:edgeLength`` and its
    ``warpshade:`` marks (``marks``, :func:`_object_namespace`); for the gprim of a PointInstancer's prototype,
    how many instances are made of it (``copies``) and their bounds' corners (``placed``)."""

    def __init__(self, prim, source: str, default_method, target: list, index: int):
        self.prim, self.source, self.default_method, self.target, self.index = prim, source, default_method, target, index
        self.where = where = f"{source}:{prim.GetPath()}"
        tname = prim.GetTypeName()
        get = lambda name: float(prim.GetAttribute(name).Get())  # noqa: E731 - schema attributes with fallbacks
        self.dims = {name: get(name) for name in _DIMS[tname]}
        if tname != "Sphere":
            for name, value in self.dims.items():
                if not value > 0 and not (tname == "Capsule" and name == "height" and value == 0):
                    raise SceneError(f"{where}: {tname} {name} must be > 0, got {value}")
        self.axis = str(prim.GetAttribute("axis").Get() or "Z") if tname not in ("Cube", "Sphere") else "Z"
        if self.axis not in AXIS_FROM_Z:
            raise SceneError(f"{where}: {tname} axis must be X, Y or Z, got {self.axis!r}")
        self.kind = tname.lower()
        self.scale = np.linalg.norm(_world(prim)[:3, :3] @ AXIS_FROM_Z[self.axis], axis=0)
        self.marks = marks = _object_namespace(prim, source)
        self.edge = _edge_length(marks["edgeLength"], where) if "edgeLength" in marks else None
        self.own = self.edge is not None or "subdivisions" in marks  # not the scene's edge
        self.graded = _graded_flag(marks["graded"], where) if "graded" in marks else None
        self.grading = None  # set by _read_gprims when graded
        self.copies = 1  # objects made of it: a PointInstancer prototype's, its instances
        self.placed = None  # a prototype's: the world corners of its instances' bounds, (copies, 8, 3)

    def to_world(self, t=Usd.TimeCode.EarliestTime()) -> np.ndarray:
        """The world transform of its shape as built (along +Z) at time code ``t``."""
        xf = _world(self.prim, t)
        xf[:3, :3] = xf[:3, :3] @ AXIS_FROM_Z[self.axis]
        return xf

    def corners(self, t=Usd.TimeCode.EarliestTime()) -> np.ndarray:
        """The 8 corners of its local bounds in world space (UsdGeom's computed extent) at time code ``t``."""
        lo, hi = (np.asarray(c, dtype=np.float64) for c in
                  UsdGeom.Boundable.ComputeExtentFromPlugins(UsdGeom.Boundable(self.prim), Usd.TimeCode.EarliestTime()))
        box = np.array([[(hi if (i >> k) & 1 else lo)[k] for k in range(3)] for i in range(8)])
        return _apply(_world(self.prim, t), box)

    def read(self, edge: float) -> None:
        """Tessellate for ``edge`` (its own ``warpshade:edgeLength`` if authored) and put the object in place."""
        edge = self.edge or edge
        if self.kind == "sphere":
            obj = _read_sphere(self.prim, self.source, self.default_method, edge, self.marks)
        else:
            obj = _read_gprim(self.prim, self.source, self.default_method, self._mesh(edge), self.marks)
        self.target[self.index] = obj

    def _mesh(self, edge: float):
        verts, faces = gprim_shape(self.kind, self.dims, self.scale, edge, self.grading)
        return verts @ AXIS_FROM_Z[self.axis].T, faces


def _flag(value, where: str, key: str) -> bool:
    """A ``warpshade:<key>`` on/off value: a bool, else a SceneError naming the prim and the attribute (a string
    ``"false"`` is not taken for true)."""
    if not isinstance(value, (bool, np.bool_)):
        raise SceneError(f"{where}: warpshade:{key} must be a bool (true or false), got {value!r}")
    return bool(value)


def _graded_flag(value, where: str) -> bool:
    """A ``warpshade:graded`` value (:func:`_flag`)."""
    return _flag(value, where, "graded")


_REGION_SAMPLES = 25
"""Most frames (evenly spread over the scene's) at which a moving object's bounds are taken for the
region graded gprims are fine near (:func:`_regions`)."""


def _regions(scene: Scene, gprims: list, lowest: float) -> list:
    """The world boxes ((2, 3) lower and upper corners) of the region each shaded object can occupy,
    as ``(owner, box)``, ``owner`` the object or the :class:`_Gprim` (``gprims``: the shaded ones): a static object's bounds; a
    cloth's :func:`~warpshade.geometry.shapes.cloth_region` (down to ``lowest`` along the up axis);
    an animated or skinned object's bounds at up to :data:`_REGION_SAMPLES` frames."""
    up = _AXES.get(scene.up_axis, 1)
    codes = scene.start_time + np.unique(np.linspace(0, scene.frames - 1, min(scene.frames, _REGION_SAMPLES)).round())

    def bounds(pts):
        pts = np.asarray(pts, dtype=np.float64).reshape(-1, 3)
        return np.stack([pts.min(axis=0), pts.max(axis=0)])

    out = []
    for o in scene.objects:
        if o is None:
            continue
        box = bounds(o.mesh.points)
        if o.kind == "cloth":
            box = cloth_region(box, up, lowest)
        elif "points_at" in o.params:
            box = bounds(np.concatenate([box] + [bounds(o.params["points_at"](float(c))) for c in codes]))
        out.append((o, box))
    for g in gprims:
        moving = _xform_varies(g.prim)
        out.append((g, bounds(np.concatenate([g.corners(Usd.TimeCode(float(c))) for c in codes] if moving
                                             else [g.corners()]))))
    return out


def _gradings(scene: Scene, shaded: list, points: np.ndarray, instanced: list = ()) -> None:
    """Give each shaded Cube and Plane gprim to be graded (``warpshade:graded``, its own else the
    default prim's, true unless authored false) its :class:`~warpshade.geometry.shapes.Grading`: the
    regions of the scene's other shaded objects (:func:`_regions`) in its frame. ``shaded``: the shaded
    gprims, ``points``: :func:`_shaded_points`, ``instanced``: PointInstancer prototypes' gprims, whose
    instances' bounds are regions too. Collision-only gprims stay uniform."""
    default = scene.settings.get("graded", True)
    graded = [g for g in shaded if g.kind in GRADED_KINDS and (default if g.graded is None else g.graded)]
    if not graded:
        return
    diag = float(np.linalg.norm(np.ptp(points, axis=0)))
    regions = _regions(scene, shaded, float(points[:, _AXES.get(scene.up_axis, 1)].min()))
    regions += [(g, np.stack([c.min(axis=0), c.max(axis=0)])) for g in instanced for c in g.placed]
    for g in graded:
        boxes = [box for owner, box in regions if owner is not g]
        to_world = g.to_world()
        if not abs(np.linalg.det(to_world[:3, :3])) > 0:
            continue  # flattened to nothing by its transform: no frame to grade in, uniform
        g.grading = Grading(frame_boxes(boxes, to_world) if boxes else np.zeros((0, 2, 3)), diag)


def _edge_length(value, where: str) -> float:
    """A ``warpshade:edgeLength`` value: a finite length > 0, else a SceneError naming the prim."""
    try:
        edge = float(value)
    except (TypeError, ValueError):
        edge = float("nan")
    if not (np.isfinite(edge) and edge > 0) or isinstance(value, (bool, str)):
        raise SceneError(f"{where}: warpshade:edgeLength must be a length > 0 [scene units], got {value!r}")
    return edge


def _shaded_points(scene: Scene, shaded: list) -> np.ndarray | None:
    """The points of the shaded objects read so far and the corners of the ``shaded`` gprims (None if
    there are none)."""
    points = [o.mesh.points for o in scene.objects if o is not None] + [g.corners() for g in shaded]
    return np.concatenate(points) if points else None


def _gprim_edge(scene: Scene, shaded: list, points: np.ndarray | None, root) -> float | None:
    """The target edge of the scene's gprims [scene units]: the default prim's ``warpshade:edgeLength``
    if authored, else :func:`~warpshade.geometry.shapes.scene_edge` of the bounding box of the shaded
    objects and gprims and of the cloths' median edges; coarsened, with a :class:`SceneWarning`, until
    the gprims without an edge of their own fit :data:`~warpshade.geometry.shapes.VERTEX_BUDGET`.
    ``shaded``: the shaded gprims (a PointInstancer prototype's counted once an instance), ``points``:
    :func:`_shaded_points`."""
    chosen = scene.settings.get("edgeLength")
    if chosen is not None:
        return _edge_length(chosen, f"{scene.source}:{root.GetPath()}")
    if points is None:
        return None
    diag = float(np.linalg.norm(np.ptp(points, axis=0)))
    cloth = []
    for o in scene.objects:
        if o is not None and o.kind == "cloth":
            tri = o.mesh.points[o.mesh.faces].astype(np.float64)
            cloth.append(float(np.median(np.linalg.norm(tri - np.roll(tri, 1, axis=1), axis=2))))
    edge = scene_edge(diag, cloth)
    auto = [g for g in shaded if not g.own]
    fitted = fit_budget([(g.kind, g.dims, g.scale, g.grading) for g in auto for _ in range(g.copies)],
                        edge) if edge else edge
    if fitted != edge:
        from ..geometry.shapes import VERTEX_BUDGET

        warnings.warn(f"{scene.source}: gprims tessellated for edges of {fitted:.3g} instead of {edge:.3g} scene units "
                      f"to stay within {VERTEX_BUDGET} vertices; warpshade:edgeLength on the default prim (every gprim) "
                      "or on a gprim (that one) chooses", SceneWarning, stacklevel=3)
    return fitted


def _read_gprims(scene: Scene, gprims: list, root) -> None:
    """Tessellate the gprims met in the traversal for the scene's target edge and put their objects in
    place (collision-only ones only if they are static colliders, as meshes)."""
    if not gprims:
        return
    shaded = [g for g in gprims if g.target is scene.objects]
    instanced = [g for g in gprims if g.placed is not None and g.copies]  # PointInstancer prototypes' gprims
    points = _shaded_points(scene, shaded)  # the shaded objects and gprims: the scene's size, the grading's floor
    if instanced:
        placed = np.concatenate([g.placed.reshape(-1, 3) for g in instanced])
        points = placed if points is None else np.concatenate([points, placed])
    if points is not None:
        _gradings(scene, shaded, points, instanced)
    edge = _gprim_edge(scene, shaded + instanced, points, root)
    for g in gprims:
        g.read(edge)
    scene.collision_only[:] = [o for o in scene.collision_only
                               if o is not None and o.kind == "static" and o.params.get("collider")]


def _read_gprim(prim, source: str, default_method, mesh, marks: dict) -> SceneObject:
    """A Cube/Cylinder/Capsule/Cone/Plane gprim's object, ``mesh`` = its tessellation in its local
    frame ``(vertices (V, 3), triangles (F, 3))``, ``marks`` its :func:`_object_namespace`."""
    where = f"{source}:{prim.GetPath()}"
    settings = dict(marks)
    settings.pop("edgeLength", None)  # in ``mesh`` already
    settings.pop("graded", None)
    verts, faces = mesh
    xf = _world(prim)
    tri = TriMesh(_apply(xf, verts), outward_faces(faces, prim, xf), name=where)
    kind = _gprim_kind(prim, settings, where)
    params = {"points_at": _moved_points(prim, verts)} if kind == "animated" else {}
    return _object(prim, where, tri, kind, settings, params, default_method, _material(prim, where))


def _physics_collider(prim) -> bool:
    """Whether ``prim`` is a collider the UsdPhysics way: PhysicsCollisionAPI, collision enabled."""
    if not prim.HasAPI(UsdPhysics.CollisionAPI):
        return False
    enabled = UsdPhysics.CollisionAPI(prim).GetCollisionEnabledAttr().Get()
    return enabled is None or bool(enabled)


def _physics_collider_shape(prim, tri, where) -> tuple[str, dict]:
    """The ``warpshade:collider`` kind (and its exact shape) for a PhysicsCollisionAPI prim: the
    analytic sphere of a Sphere, the oriented box of a Cube, the analytic capsule, cylinder or cone
    of a Capsule, Cylinder or Cone (see :func:`_axial_collider`); for a Mesh, the box or sphere its
    ``physics:approximation`` asks for (:func:`_approximated_collider`), or its exact box when it is
    one (:func:`_mesh_box`); a ground plane for a flat horizontal mesh or Plane (its mean height),
    else the triangle mesh itself."""
    if prim.IsA(UsdGeom.Sphere):
        return "sphere", {}
    if prim.IsA(UsdGeom.Cube):
        shape = _box_collider(prim, where)
        if shape is not None:
            return "box", shape
        return "mesh", {}
    if prim.GetTypeName() in ("Capsule", "Cylinder", "Cone"):
        shape = _axial_collider(prim, where)
        if shape is not None:
            return shape
    if prim.IsA(UsdGeom.Mesh):
        shape = _approximated_collider(prim, where)
        if shape is not None:
            return shape
        box = _mesh_box(tri)
        if box is not None:
            return "box", box
    up = 1 if str(UsdGeom.GetStageUpAxis(prim.GetStage())) == "Y" else 2
    pts = tri.points
    size = float(np.ptp(pts, axis=0).max())
    if size > 0 and float(np.ptp(pts[:, up])) <= 1e-6 * size:
        return "ground", {}
    return "mesh", {}


def _box_collider(prim, where) -> dict | None:
    """The exact oriented box of a Cube gprim in world space (``{"box": {"center", "half_extents",
    "rotation" (x, y, z, w)}}``), or None (with a :class:`SceneWarning` naming the prim) when its
    world transform shears or is singular, so that the tessellated mesh is used instead."""
    half = 0.5 * float(UsdGeom.Cube(prim).GetSizeAttr().Get())
    return _local_box(_world(prim), np.full(3, -half), np.full(3, half), f"{where}: Cube collider",
                      "its tessellated mesh")


def _rotation_and_scale(xf: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """A world transform's linear part as a rotation (its columns' directions) and a scale along its local
    axes, or None when it shears or is singular (its columns not orthogonal to 1e-6)."""
    lin = xf[:3, :3]
    scale = np.linalg.norm(lin, axis=0)
    unit = lin / np.where(scale > 0, scale, 1.0)
    if not (scale > 0).all() or np.abs(unit.T @ unit - np.eye(3)).max() > 1e-6:
        return None
    return unit, scale


def _local_box(xf: np.ndarray, lo: np.ndarray, hi: np.ndarray, what: str, instead: str) -> dict | None:
    """The box ``lo``..``hi`` of a prim's local space under its world transform ``xf`` as an oriented box
    (as :func:`_box_collider`), or None with a :class:`SceneWarning` (``what`` ... ``instead``) when the
    transform shears or is singular."""
    from scipy.spatial.transform import Rotation

    split = _rotation_and_scale(xf)
    if split is None:
        warnings.warn(f"{what} is not exact because its world transform shears or is singular; colliding with "
                      f"{instead} instead", SceneWarning, stacklevel=6)
        return None
    unit, scale = split
    quat = Rotation.from_matrix(unit).as_quat()  # (x, y, z, w)
    return {"box": {"center": _apply(xf, 0.5 * (lo + hi)[None])[0], "half_extents": 0.5 * (hi - lo) * scale,
                    "rotation": quat}}


def _approximated_collider(prim, where) -> tuple[str, dict] | None:
    """A PhysicsCollisionAPI Mesh's ``physics:approximation`` (UsdPhysics' MeshCollisionAPI) as an analytic
    collider: ``boundingCube``, the box of its points' bounds in its local space under its world transform;
    ``boundingSphere``, the sphere about their local bounds' centre through the farthest point (under a
    uniform world scale). None for the other approximations (``none``, ``convexHull``,
    ``convexDecomposition``, ``meshSimplification``: the mesh itself collides) or when the transform does
    not keep the shape (a :class:`SceneWarning` says so)."""
    if not prim.HasAPI(UsdPhysics.MeshCollisionAPI):
        return None
    approx = str(UsdPhysics.MeshCollisionAPI(prim).GetApproximationAttr().Get() or "none")
    if approx not in ("boundingCube", "boundingSphere"):
        return None
    xf = _world(prim)
    local = UsdGeom.Mesh(prim).GetPointsAttr().Get(Usd.TimeCode.EarliestTime())
    local = np.asarray(local, dtype=np.float64).reshape(-1, 3)
    lo, hi = local.min(axis=0), local.max(axis=0)
    what, instead = f"{where}: physics:approximation {approx}", "the mesh itself"
    if approx == "boundingCube":
        shape = _local_box(xf, lo, hi, what, instead)
        return None if shape is None else ("box", shape)
    centre = 0.5 * (lo + hi)
    sphere = _sphere_of(xf, float(np.linalg.norm(local - centre, axis=1).max()))
    if sphere is None:
        warnings.warn(f"{what} is not exact because its world scale is not uniform; colliding with {instead} "
                      "instead", SceneWarning, stacklevel=5)
        return None
    return "sphere", {"sphere": {"center": _apply(xf, centre[None])[0], "radius": sphere["radius"]}}


MESH_BOX_TOL = 1.0e-5
"""Relative tolerance (of the box's largest extent, or of its area) within which a Mesh marked ``box`` is taken
as the box it looks like: float32 points written by a DCC are ~1e-7 off their box."""


def _mesh_box(tri: TriMesh) -> dict | None:
    """The oriented box a Mesh marked ``warpshade:collider = "box"`` is, in world space (as
    :func:`_box_collider`), or None when it is not one: every face's normal along one of three
    orthogonal axes, every face in a face of the box its points span along them, and the faces' area
    that box's surface area (so a subdivided cube is a box, an open crate or two boxes in an L are
    not)."""
    from scipy.spatial.transform import Rotation

    pts, faces = tri.points.astype(np.float64), tri.faces
    cross = np.cross(pts[faces[:, 1]] - pts[faces[:, 0]], pts[faces[:, 2]] - pts[faces[:, 0]])
    area2 = np.linalg.norm(cross, axis=1)
    if len(faces) < 12 or not (area2 > 0).all():
        return None
    normals = cross / area2[:, None]
    first = normals[0]
    other = normals[np.abs(normals @ first) < 0.5]
    if not len(other):
        return None
    second = other[0] - (other[0] @ first) * first
    second /= np.linalg.norm(second)
    first, second = (a if a[np.argmax(np.abs(a))] > 0 else -a for a in (first, second))  # nearest the world's axes
    axes = np.stack([first, second, np.cross(first, second)], axis=1)  # columns: a rotation
    if (1.0 - np.abs(normals @ axes).max(axis=1)).max() > MESH_BOX_TOL:
        return None
    local = pts @ axes
    lo, hi = local.min(axis=0), local.max(axis=0)
    extent = hi - lo
    tol = MESH_BOX_TOL * float(extent.max())
    if not (extent > tol).all():
        return None
    on_face = (np.abs(local - lo) <= tol) | (np.abs(local - hi) <= tol)  # (V, 3): on the box's faces across axis k
    across = np.argmax(np.abs(normals @ axes), axis=1)  # the axis each face is across
    box_area = 2.0 * (extent[0] * extent[1] + extent[1] * extent[2] + extent[0] * extent[2])
    if (not on_face[faces, across[:, None]].all()
            or abs(0.5 * float(area2.sum()) - box_area) > MESH_BOX_TOL * box_area):
        return None
    return {"box": {"center": axes @ (0.5 * (lo + hi)), "half_extents": 0.5 * extent,
                    "rotation": Rotation.from_matrix(axes).as_quat()}}


_AXES = {"X": 0, "Y": 1, "Z": 2}


def _axial_collider(prim, where) -> tuple[str, dict] | None:
    """The exact analytic collider of a Capsule, Cylinder or Cone gprim in world space, or None
    (with a :class:`SceneWarning` naming the prim and why) when its world transform does not keep
    the shape exact, so that the tessellated mesh is used instead.

    The world transform must be a rotation times a scale along the shape's own axes: a Cylinder or
    Cone keeps its shape under any scale that is the same across its two radial directions (a
    scale along the axis only stretches its height); a Capsule's hemispherical ends need the same
    scale in all three directions. Capsule ``height`` is the cylindrical part (USD), so the
    segment is +-height/2 along the axis; a Cone's apex is at +height/2.
    """
    tname = prim.GetTypeName()
    axis = str(prim.GetAttribute("axis").Get() or "Z")
    radius = float(prim.GetAttribute("radius").Get())
    height = float(prim.GetAttribute("height").Get())
    if axis not in _AXES or not radius > 0 or not (height > 0 or (tname == "Capsule" and height == 0)):
        return None  # _Gprim has already raised for these
    xf = _world(prim)
    lin = xf[:3, :3]
    scale = np.linalg.norm(lin, axis=0)
    k = _AXES[axis]
    radial = [j for j in range(3) if j != k]
    why = None
    if not (scale > 0).all() or abs(np.dot(lin[:, 0], lin[:, 1])) > 1e-6 * scale[0] * scale[1] or \
            abs(np.dot(lin[:, 0], lin[:, 2])) > 1e-6 * scale[0] * scale[2] or \
            abs(np.dot(lin[:, 1], lin[:, 2])) > 1e-6 * scale[1] * scale[2]:
        why = "its world transform shears or is singular"
    elif abs(scale[radial[0]] - scale[radial[1]]) > 1e-6 * scale[radial].max():
        why = f"its world scale differs across its radial directions ({scale[radial[0]]:g}, {scale[radial[1]]:g})"
    elif tname == "Capsule" and abs(scale[k] - scale[radial[0]]) > 1e-6 * scale.max():
        why = f"its world scale is not uniform ({', '.join(f'{v:g}' for v in scale)}) and would make its ends ellipsoids"
    if why is not None:
        warnings.warn(f"{where}: {tname} collider is not exact because {why}; colliding with its tessellated "
                      "mesh instead", SceneWarning, stacklevel=5)
        return None
    centre = xf[:3, 3].copy()
    half = lin[:, k] * (0.5 * height)  # world half-height vector (axis scale included)
    r = radius * float(scale[radial[0]])
    key = tname.lower()
    if tname == "Cone":
        return key, {key: {"base": centre - half, "apex": centre + half, "radius": r}}
    return key, {key: {"p0": centre - half, "p1": centre + half, "radius": r}}


def _object(prim, where, tri, kind, settings, params, default_method, material) -> SceneObject:
    if "collider" not in settings and kind != "cloth" and _physics_collider(prim):
        settings["collider"], shape = _physics_collider_shape(prim, tri, where)
        if kind == "static":  # a moving gprim collides as its moving tessellated mesh
            params.update(shape)
    elif kind == "static" and settings.get("collider") in ("capsule", "cylinder", "cone") and settings["collider"] == \
            prim.GetTypeName().lower():
        # warpshade:collider naming the gprim's own shape: its exact analytic solid (else the mesh)
        shape = _axial_collider(prim, where)
        if shape is not None:
            params.update(shape[1])
    elif kind == "static" and settings.get("collider") == "box" and prim.IsA(UsdGeom.Cube):
        # a Cube marked "box": its exact oriented box, as under PhysicsCollisionAPI (else the mesh)
        shape = _box_collider(prim, where)
        if shape is not None:
            params.update(shape)
    elif kind == "static" and settings.get("collider") == "box" and prim.IsA(UsdGeom.Mesh):
        # a DCC's cube is a Mesh (Blender's 8 vertices): its exact box when it is one (else the mesh)
        shape = _mesh_box(tri)
        if shape is None:
            warnings.warn(f"{where}: warpshade:collider 'box' on a Mesh that is not a box (its faces are not the six "
                          "faces of one rectangular box); colliding with the mesh itself", SceneWarning, stacklevel=3)
        else:
            params.update(shape)
    knobs = {k[len("knobs:"):]: v for k, v in settings.items() if k.startswith("knobs:")}
    for k in [k for k in knobs if k.endswith(("_dir", "_path", "_file"))]:
        # nothing read from a scene chooses where files are written
        warnings.warn(f"{where}: warpshade:knobs:{k} ignored: a scene cannot choose where files are written "
                      f"(give --{k.replace('_', '-')} on the command line or {k}= in Python)",
                      SceneWarning, stacklevel=3)
        del knobs[k]
    method = settings.pop("method", default_method)
    if method is not None:
        from ..visibility import NO_METHOD, transfer_method

        try:  # an empty token (a DCC's blank custom property) is no method too
            method = transfer_method(method or NO_METHOD)
        except ValueError as exc:
            raise SceneError(f"{where}: warpshade:method: {exc}") from None
    if knobs and method is not None:
        _check_knobs(where, method, knobs)
    params.update({k: v for k, v in settings.items()
                   if not k.startswith("knobs:") and k not in ("shaded", "castsShadows", "twoSided")})
    flags = {k: _flag(settings[k], where, k) for k in ("shaded", "castsShadows", "twoSided") if k in settings}
    try:
        return SceneObject(name=str(prim.GetPath()), mesh=tri, kind=kind, material=material, method=method,
                           knobs=knobs, casts_shadows=flags.get("castsShadows", True),
                           shaded=flags.get("shaded", True), params=params,
                           prim_path=str(prim.GetPath()), prim_xforms=_hierarchy(prim),
                           two_sided=flags.get("twoSided"))
    except ValueError as exc:
        raise SceneError(f"{where}: {exc}") from None


_PROBED: dict = {}
"""(method, knobs) -> error message or None: knob sets already probed by :func:`_check_knobs`."""


def _check_knobs(where: str, method: str, knobs: dict) -> None:
    """Refuse, when the scene is read, a ``warpshade:knobs:*`` value the method rejects, naming the
    prim and the attribute: the method is built once on a one-triangle probe mesh with the knobs
    (the method's own checks, no copy of them; once per distinct method and knobs). Errors that
    name no knob (a limit of the probe mesh) are left to the real build."""
    key = (method, tuple(sorted((k, repr(v)) for k, v in knobs.items())))
    if key not in _PROBED:
        import inspect

        from ..visibility import get_method

        cls = get_method(method)
        accepted = [n for n, p in inspect.signature(cls.__init__).parameters.items()
                    if p.kind is p.KEYWORD_ONLY or (p.kind is p.POSITIONAL_OR_KEYWORD and n not in ("self", "mesh"))]
        takes_any = any(p.kind is p.VAR_KEYWORD for p in inspect.signature(cls.__init__).parameters.values())
        _PROBED[key] = None
        unknown = [k for k in knobs if k not in accepted and not takes_any]
        if unknown:
            _PROBED[key] = (f"warpshade:knobs:{unknown[0]}: {method} has no knob '{unknown[0]}' "
                            f"(its knobs: {', '.join(n for n in accepted if n not in ('order', 'device'))})")
        else:
            probe = TriMesh(np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]), np.array([[0, 1, 2]]),
                         name="knob probe")
            try:
                cls(probe, **{k: (v.item() if isinstance(v, np.generic) else v) for k, v in knobs.items()})
            except (TypeError, ValueError) as exc:
                msg = str(exc)
                named = msg.split(" ", 1)[0]
                if named in knobs:
                    _PROBED[key] = f"warpshade:knobs:{named}: {msg[len(named):].strip()}"
    if _PROBED[key]:
        raise SceneError(f"{where}: {_PROBED[key]}")


def _xform_varies(prim) -> bool:
    """Whether the prim's or an ancestor's transform is time-sampled."""
    while prim and not prim.IsPseudoRoot():
        if prim.IsA(UsdGeom.Xformable) and UsdGeom.Xformable(prim).TransformMightBeTimeVarying():
            return True
        prim = prim.GetParent()
    return False


def _animated_points(prim, where):
    """Per-frame world positions read lazily from the stage (memory constant in frame count)."""
    attr = UsdGeom.Mesh(prim).GetPointsAttr()

    stage = prim.GetStage()  # the closure keeps the stage alive

    def points_at(time: float) -> np.ndarray:
        """World positions at time code ``time``."""
        assert stage
        t = Usd.TimeCode(time)
        pts = attr.Get(t)
        if pts is None:
            raise SceneError(f"{where}: no points at time code {time}")
        local = np.asarray(pts, dtype=np.float64).reshape(-1, 3)
        try:
            check_finite(local, f"{where}: points at time code {time:g}")
        except MeshError as exc:
            raise SceneError(str(exc)) from None
        return _apply(_world(prim, t), local).astype(np.float32)

    return points_at


def _skinned_points(prim, cache: UsdSkel.Cache, where):
    """Per-frame world positions of a UsdSkel-skinned mesh (linear blend skinning by UsdSkel)."""
    query = cache.GetSkinningQuery(prim)
    if not query:
        raise SceneError(f"{where}: bound to UsdSkel but has no valid skinning query "
                         "(is it under a SkelRoot with skel:skeleton and joint influences?)")
    binding = UsdSkel.BindingAPI(prim)
    skel = binding.GetInheritedSkeleton()
    if not skel:
        raise SceneError(f"{where}: skel:skeleton is not set")
    skel_query = cache.GetSkelQuery(skel)
    rest = UsdGeom.Mesh(prim).GetPointsAttr().Get()

    stage = prim.GetStage()  # the closure keeps the stage and the skel cache alive

    def points_at(time: float) -> np.ndarray:
        """Skinned world positions at time code ``time``."""
        assert stage and cache
        t = Usd.TimeCode(time)
        xforms = skel_query.ComputeSkinningTransforms(t)
        pts = type(rest)(rest)
        if not query.ComputeSkinnedPoints(xforms, pts, t):
            raise SceneError(f"{where}: UsdSkel skinning failed at time code {time}")
        # Skinned points are in skeleton space (UsdSkel "Skinning" docs): apply the skeleton's transform.
        return _apply(_world(skel.GetPrim(), t), np.asarray(pts, dtype=np.float64).reshape(-1, 3)).astype(np.float32)

    return points_at


def _is_radiance_material(mat, shader) -> bool:
    """Whether ``mat`` is the material warpshade binds to its shaded output meshes (emission =
    exit radiance, black diffuse): marked by RADIANCE_MATERIAL_ATTR, or, in outputs written before
    that mark, recognised by its emissiveColor read from the ``displayColor`` primvar."""
    mark = mat.GetPrim().GetAttribute(RADIANCE_MATERIAL_ATTR)
    if mark and mark.Get():
        return True
    emissive = shader.GetInput("emissiveColor")
    if not emissive or not emissive.HasConnectedSource():
        return False
    source = emissive.GetConnectedSource()[0]
    reader = UsdShade.Shader(source.GetPrim())
    varname = reader.GetInput("varname") if reader else None
    return bool(varname) and varname.Get() == "displayColor"


def _material(prim, where) -> Material:
    """The shading material of ``prim``: ``warpshade:albedo`` if authored (warpshade outputs carry
    it), else the bound UsdPreviewSurface's diffuseColor (unless it is warpshade's own radiance
    material, whose black diffuse is not an albedo), else a constant ``displayColor``."""
    out = None
    recorded = prim.GetAttribute("warpshade:albedo")
    if recorded and recorded.HasAuthoredValue():
        out = Material(albedo=np.asarray(recorded.Get(), dtype=np.float64))
    mat, _ = UsdShade.MaterialBindingAPI(prim).ComputeBoundMaterial()
    if mat:
        shader = mat.ComputeSurfaceSource()[0]
        if shader and shader.GetIdAttr().Get() == "UsdPreviewSurface":
            ours = _is_radiance_material(mat, shader)
            if out is None:
                out = Material()
                dc = shader.GetInput("diffuseColor")
                if dc and not ours:
                    if dc.HasConnectedSource():
                        warnings.warn(f"{where}: diffuseColor of {shader.GetPath()} is connected (texture?); "
                                      "using its fallback/default value", SceneWarning, stacklevel=4)
                    val = dc.Get()
                    if val is not None:
                        out.albedo = np.asarray(val, dtype=np.float64)
                        out.albedo_authored = True
            r = shader.GetInput("roughness")
            if r and r.Get() is not None:
                out.roughness = float(r.Get())
            _check_material(out, where, shader.GetPath())
            return out
        if out is None:
            omni = _omnipbr(mat, where)
            if omni is not None:
                return omni
            warnings.warn(f"{where}: bound material {mat.GetPath()} has no UsdPreviewSurface; default material used",
                          SceneWarning, stacklevel=4)
            return Material()
    if out is not None:
        _check_material(out, where, recorded.GetPath())
        return out
    subsets = _subset_albedo(prim, where)
    if subsets is not None:
        return subsets
    dc = UsdGeom.PrimvarsAPI(prim).GetPrimvar("displayColor")
    if dc and dc.HasAuthoredValue():
        v = np.asarray(dc.Get(), dtype=np.float64).reshape(-1, 3)
        if len(v) == 1:
            out = Material(albedo=v[0])
            _check_material(out, where, prim.GetPath())
            return out
        if len(v) > 1:
            out = Material(albedo=v.mean(axis=0))
            out.albedo_authored = True
            _check_material(out, where, prim.GetPath())
            warnings.warn(f"{where}: primvars:displayColor varies ({dc.GetInterpolation()}, {len(v)} values): warpshade "
                          f"shades a mesh with one albedo, their mean {np.round(out.albedo, 3).tolist()}; split the mesh "
                          "or bind a material to set it", SceneWarning, stacklevel=4)
            return out
    return Material()


OMNIPBR_ALBEDO = (0.2, 0.2, 0.2)
"""OmniPBR's ``diffuse_color_constant`` when it is not authored (its MDL default, as Omniverse's OmniPBR
page lists it)."""


def _omnipbr(mat, where) -> Material | None:
    """The material of an Omniverse ``OmniPBR`` MDL shader (``outputs:mdl:surface``, no UsdPreviewSurface, as
    Omniverse and Isaac Sim write every material they make): albedo ``diffuse_color_constant`` (else
    :data:`OMNIPBR_ALBEDO`) times ``diffuse_tint`` if authored; roughness ``reflection_roughness_constant``
    if authored. A ``diffuse_texture`` is not read (a SceneWarning says so). None for another MDL."""
    shader = mat.ComputeSurfaceSource("mdl")[0]
    if not shader:
        return None
    asset = shader.GetSourceAsset("mdl")
    sub = shader.GetSourceAssetSubIdentifier("mdl")
    name = sub or (os.path.splitext(os.path.basename(asset.path))[0] if asset else "")
    if name != "OmniPBR":
        return None

    def value(input_name):
        inp = shader.GetInput(input_name)
        return inp.Get() if inp and inp.GetAttr().HasAuthoredValue() else None

    colour = value("diffuse_color_constant")
    albedo = np.asarray(OMNIPBR_ALBEDO if colour is None else colour, dtype=np.float64)
    tint = value("diffuse_tint")
    if tint is not None:
        albedo = albedo * np.asarray(tint, dtype=np.float64)
    texture = value("diffuse_texture")
    if texture is not None and getattr(texture, "path", ""):
        warnings.warn(f"{where}: {shader.GetPath()} (OmniPBR) has a diffuse_texture, which warpshade does not read; "
                      f"using its diffuse_color_constant {np.round(albedo, 3).tolist()}", SceneWarning, stacklevel=5)
    out = Material(albedo=albedo)
    roughness = value("reflection_roughness_constant")
    if roughness is not None:
        out.roughness = float(roughness)
    _check_material(out, where, shader.GetPath())
    return out


def _subset_albedo(prim, where) -> Material | None:
    """For a mesh bound to no material itself but whose face subsets (``UsdGeomSubset``, family
    ``materialBind``) are: one material, the subsets' UsdPreviewSurface diffuseColor averaged by face count,
    with a warning (a mesh is shaded with one albedo). None when no subset binds a material."""
    if not prim.IsA(UsdGeom.Imageable):
        return None
    colours, weights = [], []
    for subset in UsdShade.MaterialBindingAPI(prim).GetMaterialBindSubsets():
        mat, _ = UsdShade.MaterialBindingAPI(subset.GetPrim()).ComputeBoundMaterial()
        shader = mat.ComputeSurfaceSource()[0] if mat else None
        if not shader or shader.GetIdAttr().Get() != "UsdPreviewSurface":
            continue
        dc = shader.GetInput("diffuseColor")
        val = dc.Get() if dc else None
        colours.append(np.asarray(val if val is not None else Material().albedo, dtype=np.float64))
        weights.append(len(subset.GetIndicesAttr().Get() or ()))
    if not colours:
        return None
    out = Material(albedo=np.average(np.stack(colours), axis=0, weights=np.maximum(weights, 1)))
    out.albedo_authored = True
    _check_material(out, where, prim.GetPath())
    if len(colours) > 1:
        warnings.warn(f"{where}: materials are bound to {len(colours)} face subsets: warpshade shades a mesh with one "
                      f"albedo, their mean by face count {np.round(out.albedo, 3).tolist()}; split the mesh by material "
                      "for an albedo each", SceneWarning, stacklevel=4)
    return out


def _check_material(m: Material, where, shader_path) -> None:
    if m.albedo.shape != (3,) or not np.all((m.albedo >= 0) & (m.albedo <= 1)):
        raise SceneError(f"{where}: {shader_path}: diffuseColor {m.albedo.tolist()} must be RGB in [0, 1]")
    if not 0 <= m.roughness <= 1:
        raise SceneError(f"{where}: {shader_path}: roughness {m.roughness} must be in [0, 1]")


# -- point instancers -------------------------------------------------------------------------
INSTANCES_SUFFIX = "_instances"
"""The output holds the instances of the PointInstancer at ``/P/Rocks`` at ``/P/Rocks_instances``, one
``instance_<id>`` Xform each (``<id>`` its ``ids`` entry, else its index), the prototype's meshes under it."""

_INSTANCE_ARRAYS = ("positions", "orientations", "orientationsf", "scales", "velocities", "accelerations",
                    "angularVelocities", "ids")
"""PointInstancer arrays that, when authored (not empty), hold one value per ``protoIndices`` entry."""

_PROTO_SHAPES = ("box", "sphere", "sphere_at", "capsule", "cylinder", "cone")
"""Exact collider shapes of a prototype's object, in the prototype's place: an instance collides as its mesh."""


def _instancer_arrays(pi, where: str, t: Usd.TimeCode, protos: int):
    """``protoIndices`` and ``ids`` (or the indices) of a PointInstancer at time code ``t``, after checking
    every per-instance array's length and every prototype index (a SceneError naming the prim, the
    attribute and the index)."""
    at = "" if t.IsDefault() else f" at time code {t.GetValue():g}"
    indices = pi.GetProtoIndicesAttr().Get(t)
    indices = np.zeros(0, dtype=np.int64) if indices is None else np.asarray(indices, dtype=np.int64)
    n = len(indices)
    for name in _INSTANCE_ARRAYS:
        attr = pi.GetPrim().GetAttribute(name)
        value = attr.Get(t) if attr and attr.HasAuthoredValue() else None
        if value is not None and len(value) and len(value) != n:
            raise SceneError(f"{where}: {name} has {len(value)} values{at} for the {n} instances of protoIndices")
    positions = pi.GetPositionsAttr().Get(t)
    if n and (positions is None or len(positions) != n):
        raise SceneError(f"{where}: positions{at} must hold one point per protoIndices entry ({n}), has "
                         f"{0 if positions is None else len(positions)}")
    bad = np.flatnonzero((indices < 0) | (indices >= protos))
    if len(bad):
        raise SceneError(f"{where}: protoIndices[{int(bad[0])}] = {int(indices[bad[0]])}{at} is out of range: "
                         f"prototypes has {protos} target{'s' if protos != 1 else ''}")
    ids = pi.GetIdsAttr().Get(t)
    ids = np.arange(n, dtype=np.int64) if ids is None or not len(ids) else np.asarray(ids, dtype=np.int64)
    if len(np.unique(ids)) != n:
        raise SceneError(f"{where}: ids{at} holds the same id twice")
    return indices, ids


def _instance_xforms(pi, where: str, t: Usd.TimeCode, n: int) -> np.ndarray:
    """The instances' transforms in the instancer's space at time code ``t`` (UsdGeom's
    ``ComputeInstanceTransformsAtTime``, each prototype root's own transform included, the mask
    ignored), acting on column vectors, shape (n, 4, 4), float64."""
    xforms = pi.ComputeInstanceTransformsAtTime(t, t, UsdGeom.PointInstancer.IncludeProtoXform,
                                                UsdGeom.PointInstancer.IgnoreMask)
    out = np.asarray(xforms, dtype=np.float64).reshape(-1, 4, 4).transpose(0, 2, 1)
    if len(out) != n:
        raise SceneError(f"{where}: UsdGeom computes {len(out)} instance transforms at time code "
                         f"{'default' if t.IsDefault() else f'{t.GetValue():g}'} for {n} protoIndices (are its "
                         "per-instance arrays time-sampled at different times?)")
    if not np.isfinite(out).all():
        raise SceneError(f"{where}: the transform of instance {int(np.flatnonzero(~np.isfinite(out).all(axis=(1, 2)))[0])} "
                         "is not finite (positions, orientations or scales hold NaN or inf)")
    return out


def _instancer_varies(pi) -> bool:
    """Whether a PointInstancer's instances move: a per-instance array or its transform time-sampled."""
    prim = pi.GetPrim()
    attrs = [prim.GetAttribute(name) for name in _INSTANCE_ARRAYS + ("protoIndices",)]
    return any(a and a.GetNumTimeSamples() > 1 for a in attrs) or _xform_varies(prim)


def _read_instancer(prim, source: str, cache: UsdSkel.Cache, default_method, scene: Scene,
                    gprims: list) -> tuple[list, list]:
    """The objects of a PointInstancer: for every instance its mask keeps (``invisibleIds``,
    ``inactiveIds``), every visible Mesh of its prototype, in world space under the instance's
    transform (UsdGeom's ``ComputeInstanceTransformsAtTime``), at the output path of
    :data:`INSTANCES_SUFFIX`; ``animated`` when the instances move (time-sampled positions...), else
    ``static``. An instance keeps its prototype mesh's material (its albedo the instancer's per-instance
    ``primvars:displayColor`` when the mesh binds no material) and ``warpshade:`` marks, and those
    of the instancer; it is a collider (as its triangle mesh) when marked ``warpshade:collider`` or
    when its mesh, a prim above it in the prototype or the instancer has PhysicsCollisionAPI. The
    output deactivates the instancer (``over`` with ``active = false``, for when it is layered over the
    input). A gprim of a prototype (``Cube``, ``Sphere``...) joins ``gprims``, to be tessellated with the
    scene's gprims (uniformly, not graded); nested instancers are skipped with a SceneWarning.

    Returns:
        The objects, None where an instance of a gprim goes, and ``[(index in the objects, make)]``:
        ``make()`` returns that instance once the gprims are read."""
    where = f"{source}:{prim.GetPath()}"
    pi = UsdGeom.PointInstancer(prim)
    stage = prim.GetStage()
    targets = pi.GetPrototypesRel().GetTargets()
    t0 = Usd.TimeCode(scene.start_time)  # a DCC's time samples hold from the first on
    indices, ids = _instancer_arrays(pi, where, t0, len(targets))
    if not len(indices):
        warnings.warn(f"{where}: PointInstancer without instances (protoIndices is empty)", SceneWarning, stacklevel=3)
        return [], []
    mask = pi.ComputeMaskAtTime(t0)
    keep = np.ones(len(indices), dtype=bool) if not len(mask) else np.asarray(mask, dtype=bool)
    xforms = _instance_xforms(pi, where, t0, len(indices))
    colours = _instance_colours(pi, where, t0, len(indices))
    world = _world(prim, t0)
    group = f"{prim.GetPath()}{INSTANCES_SUFFIX}"
    hierarchy = list(_hierarchy(prim))
    own = hierarchy.pop()
    hierarchy += [(group, "Xform", own[2], own[3], False), (str(prim.GetPath()), "PointInstancer", None, False, False)]
    outer = _object_namespace(prim, source)
    outer.update(_namespace(prim, source))
    outer_collider = _physics_collider(prim)
    moves = _instancer_varies(pi)
    protos = []  # per prototype: [(object in the prototype's place, path under the instance, world of its root)]
    for k, target in enumerate(targets):
        root = stage.GetPrimAtPath(target)
        if not root or not root.IsActive():
            raise SceneError(f"{where}: prototypes[{k}] targets {target}, which is not an active prim of the stage")
        protos.append(_prototype_objects(prim, root, source, cache, default_method, outer, outer_collider, gprims))
    shared = {}  # time code -> that time's instance transforms, shared by the instances' points_at

    def instance_world(i: int, time: float) -> np.ndarray:
        """Instance ``i``'s world transform at time code ``time``."""
        assert stage  # the closure keeps the stage alive
        if time not in shared:
            shared.clear()
            t = Usd.TimeCode(time)
            indices_t, _ = _instancer_arrays(pi, where, t, len(targets))
            if not np.array_equal(indices_t, indices):
                raise SceneError(f"{where}: protoIndices at time code {time:g} differ from those at "
                                 f"{t0.GetValue():g}: warpshade shades a fixed set of instances")
            shared[time] = _world(prim, t)[None] @ _instance_xforms(pi, where, t, len(indices))
        return shared[time][i]

    def instance(i: int, obj: SceneObject, sub: str, proto_world: np.ndarray, bound: bool) -> SceneObject:
        """Instance ``i`` of the prototype object ``obj`` (in the prototype's place)."""
        move = world @ xforms[i] @ np.linalg.inv(proto_world)  # the prototype's place -> this instance's
        path = f"{group}/instance_{ids[i]}/{sub}".replace("instance_-", "instance_m")
        faces = obj.mesh.faces if np.linalg.det(move[:3, :3]) >= 0 else obj.mesh.faces[:, [0, 2, 1]]
        try:
            tri = TriMesh(_apply(move, obj.mesh.points.astype(np.float64)), faces, name=f"{source}:{path}")
        except MeshError as exc:
            raise SceneError(f"{where}: instance {ids[i]}: {exc}") from None
        params = {k: v for k, v in obj.params.items() if k not in _PROTO_SHAPES}
        material = obj.material
        if colours is not None and not bound:
            material = Material(albedo=colours[i].copy(), roughness=obj.material.roughness)
        kind = obj.kind
        if moves:
            kind = "animated"
            params["points_at"] = _instance_points(instance_world, i, np.linalg.inv(proto_world),
                                                   obj.mesh.points.astype(np.float64))
        return SceneObject(name=path, mesh=tri, kind=kind, material=material, method=obj.method,
                           knobs=dict(obj.knobs), casts_shadows=obj.casts_shadows, shaded=obj.shaded,
                           two_sided=obj.two_sided, params=params, prim_path=path, prim_xforms=tuple(hierarchy))

    def later(i: int, g: _Gprim, sub: str, proto_world: np.ndarray, bound: bool):
        def make() -> SceneObject:
            return instance(i, _still_prototype(g.target[g.index], prim), sub, proto_world, bound)
        return make

    objects, deferred = [], []
    for i in np.flatnonzero(keep):
        for obj, sub, proto_world, bound in protos[indices[i]]:
            if isinstance(obj, _Gprim):  # its object is made when the scene's gprims are read
                obj.copies += 1
                obj.placed.append(_apply(world @ xforms[i] @ np.linalg.inv(proto_world), obj.corners()))
                deferred.append((len(objects), later(int(i), obj, sub, proto_world, bound)))
                objects.append(None)
            else:
                objects.append(instance(int(i), obj, sub, proto_world, bound))
    for g in {id(e[0]): e[0] for entries in protos for e in entries if isinstance(e[0], _Gprim)}.values():
        g.placed = np.stack(g.placed) if g.placed else None
    return objects, deferred


def _still_prototype(obj: SceneObject, instancer) -> SceneObject:
    """A prototype's object as its instances take it: static (its own animation is not instanced: its first
    pose, with a SceneWarning); a cloth or skinned prototype is a SceneError."""
    if obj.kind not in ("static", "animated"):
        raise SceneError(f"{obj.name}: a {obj.kind} mesh in the prototype of the PointInstancer "
                         f"{instancer.GetPath()}: instances are static or move with the instancer")
    if obj.kind == "animated":
        warnings.warn(f"{obj.name}: its own animation is not instanced: the instances of {instancer.GetPath()} take "
                      "its first pose", SceneWarning, stacklevel=4)
        obj.kind = "static"
        for key in ("points_at", "sphere_at"):
            obj.params.pop(key, None)
    return obj


def _instance_points(instance_world, i: int, from_proto: np.ndarray, points: np.ndarray):
    """``points_at(time)`` of a moving instance's mesh: ``points`` (in its prototype's place) under
    ``instance_world(i, time) @ from_proto``."""
    def points_at(time: float) -> np.ndarray:
        return _apply(instance_world(i, float(time)) @ from_proto, points).astype(np.float32)

    return points_at


_PROTOTYPE_PRIMS = Usd.TraverseInstanceProxies(Usd.PrimIsActive & Usd.PrimIsLoaded)
"""The prims a PointInstancer's prototype is read from: active ones, also under an ``over`` or a ``class``
(the USD way to keep prototypes out of the stage's ordinary traversal, :data:`_PRIMS`)."""


def _instance_colours(pi, where: str, t: Usd.TimeCode, n: int) -> np.ndarray | None:
    """The per-instance ``primvars:displayColor`` of a PointInstancer (a Houdini scatter's ``Cd``), one RGB an
    instance, shape (n, 3), or None when it has none (a constant one is not per instance)."""
    pv = UsdGeom.PrimvarsAPI(pi.GetPrim()).GetPrimvar("displayColor")
    if not pv or not pv.HasAuthoredValue() or pv.GetInterpolation() == UsdGeom.Tokens.constant:
        return None
    values = pv.ComputeFlattened(t)
    values = None if values is None else np.asarray(values, dtype=np.float64).reshape(-1, 3)
    if values is None or len(values) != n:
        raise SceneError(f"{where}: primvars:displayColor has {0 if values is None else len(values)} values for the "
                         f"{n} instances ({pv.GetInterpolation()} interpolation: one an instance)")
    if not (np.isfinite(values).all() and (values >= 0).all() and (values <= 1).all()):
        raise SceneError(f"{where}: primvars:displayColor must be RGB in [0, 1] for every instance")
    return values


def _prototype_objects(instancer, root, source: str, cache, default_method, outer: dict, outer_collider: bool,
                       gprims: list) -> list:
    """The visible Meshes and gprims of a PointInstancer's prototype ``root`` in the prototype's own place,
    each as ``(object, its path below the instance, world transform of root, binds a material)``, for a gprim
    its :class:`_Gprim` (joining ``gprims``, its object made when they are read) instead of the object;
    ``outer``: the instancer's ``warpshade:`` marks (its and those above it), the prim's own winning;
    ``outer_collider``: the instancer has PhysicsCollisionAPI."""
    where = f"{source}:{instancer.GetPath()}"
    out = []
    it = iter(Usd.PrimRange(root, _PROTOTYPE_PRIMS))
    for sub in it:
        if not sub.IsActive() or (sub.IsA(UsdGeom.Imageable) and UsdGeom.Imageable(sub).ComputeVisibility()
                                  == UsdGeom.Tokens.invisible):
            it.PruneChildren()
            continue
        if sub.IsA(UsdGeom.Imageable) and UsdGeom.Imageable(sub).ComputePurpose() in _UNRENDERED_PURPOSES:
            it.PruneChildren()
            continue
        gprim = sub.IsA(UsdGeom.Sphere) or sub.GetTypeName() in _GPRIMS
        if sub.IsA(UsdGeom.PointInstancer) or (sub.IsA(UsdGeom.Gprim) and not sub.IsA(UsdGeom.Mesh) and not gprim):
            warnings.warn(f"{where}: prototype {root.GetPath()}: skipping {sub.GetPath()} ({sub.GetTypeName()}): "
                          "warpshade instances a prototype's Mesh and gprim (Sphere, Cube, ...) prims only",
                          SceneWarning, stacklevel=4)
            it.PruneChildren()
            continue
        if not sub.IsA(UsdGeom.Mesh) and not gprim:
            continue
        chain = []
        p = sub
        while p and p != root.GetParent():
            chain.append(p)
            p = p.GetParent()
        marks = dict(outer)
        marks.update(_object_namespace(sub, source))
        if "collider" not in marks and not _physics_collider(sub) and (
                outer_collider or any(_physics_collider(p) for p in chain[1:])):
            marks["collider"] = "mesh"
        sub_path = "/".join(q.GetName() for q in reversed(chain))
        # a material bound to the prim decides its albedo; else the instancer's per-instance colour does
        bound = bool(UsdShade.MaterialBindingAPI(sub).ComputeBoundMaterial()[0])
        if gprim:
            g = _Gprim(sub, source, default_method, [None], 0)
            g.marks, g.graded = marks, False  # a prototype has no place of its own to be graded near
            g.copies, g.placed = 0, []  # counted by _read_instancer
            gprims.append(g)
            out.append((g, sub_path, _world(root, Usd.TimeCode.EarliestTime()), bound))
            continue
        obj = _still_prototype(_read_mesh(sub, source, cache, default_method, marks), instancer)
        out.append((obj, sub_path, _world(root, Usd.TimeCode.EarliestTime()), bound))
    if not out:
        warnings.warn(f"{where}: prototype {root.GetPath()} holds no Mesh or gprim: its instances are not shaded",
                      SceneWarning, stacklevel=4)
    return out


# -- lights -------------------------------------------------------------------------------------
def _read_light(prim, kind: str, source: str, scene: Scene) -> LightSpec:
    where = f"{source}:{prim.GetPath()}"
    lux = UsdLux.LightAPI(prim)

    def get(attr, default):
        v = attr.Get() if attr else None
        return default if v is None else v

    spec = LightSpec(kind=kind, name=str(prim.GetPath()),
                     color=np.asarray(get(lux.GetColorAttr(), (1.0, 1.0, 1.0)), dtype=np.float64),
                     intensity=float(get(lux.GetIntensityAttr(), 1.0)),
                     exposure=float(get(lux.GetExposureAttr(), 0.0)),
                     transform=_world(prim),
                     normalize=bool(get(lux.GetNormalizeAttr(), False)),
                     prim_path=str(prim.GetPath()), prim_xforms=_hierarchy(prim))
    if kind == "distant":
        spec.angle = float(get(UsdLux.DistantLight(prim).GetAngleAttr(), 0.53))
    elif kind == "sphere":
        spec.radius = float(get(UsdLux.SphereLight(prim).GetRadiusAttr(), 0.5))
        spec.treat_as_point = bool(get(UsdLux.SphereLight(prim).GetTreatAsPointAttr(), False))
    elif kind == "rect":
        spec.width = float(get(UsdLux.RectLight(prim).GetWidthAttr(), 1.0))
        spec.height = float(get(UsdLux.RectLight(prim).GetHeightAttr(), 1.0))
        if UsdLux.RectLight(prim).GetTextureFileAttr().Get():
            warnings.warn(f"{where}: RectLight textures are not supported; using its color", SceneWarning, stacklevel=3)
    elif kind == "dome":
        asset = UsdLux.DomeLight(prim).GetTextureFileAttr().Get()
        if asset is not None and asset.path:
            resolved = local_file(asset.resolvedPath)  # (a texture inside a .usdz is copied out)
            if resolved is None:
                layer_dir = os.path.dirname(os.path.abspath(source))
                raise SceneError(f"{where}: inputs:texture:file '{asset.path}' not found "
                                 f"(looked relative to {layer_dir})")
            spec.texture = resolved
            fmt = UsdLux.DomeLight(prim).GetTextureFormatAttr().Get()
            if fmt not in (None, "automatic", "latlong"):
                raise SceneError(f"{where}: texture format '{fmt}' unsupported (use latlong)")
    for name, value in (("intensity", spec.intensity), ("radius", spec.radius), ("width", spec.width),
                        ("height", spec.height)):
        if not np.isfinite(value) or value < 0:
            raise SceneError(f"{where}: {name} must be finite and >= 0, got {value}")
    if not np.all(np.isfinite(spec.color)) or np.any(spec.color < 0):
        raise SceneError(f"{where}: color must be finite and >= 0, got {spec.color.tolist()}")
    if _xform_varies(prim):
        if kind in ("distant", "dome"):
            # a light that only turns (a sun over a day, a rotating sky): its rotation at every frame's time code
            def rotation(xf):
                lin = xf[:3, :3]
                return lin / np.maximum(np.linalg.norm(lin, axis=0), 1e-300)

            first = rotation(spec.transform)
            spec.rotations = np.stack([rotation(_world(prim, Usd.TimeCode(scene.start_time + f))) @ first.T
                                       for f in range(scene.frames)])
        else:
            warnings.warn(f"{where}: its transform is animated: a {kind} light is lit where it stands at its first "
                          "time sample for the whole run (distant and dome lights follow their keys)", SceneWarning,
                          stacklevel=3)
    return spec


# -- warpshade: namespace ----------------------------------------------------------------------
def _namespace(prim, source: str, skip=()) -> dict:
    """Every authored ``warpshade:`` attribute of ``prim`` as ``{name without prefix: value}``."""
    out = {}
    for attr in prim.GetAuthoredAttributes():
        name = attr.GetName()
        if not name.startswith("warpshade:") or name in skip:
            continue
        value = attr.Get()
        if value is None:
            continue
        if hasattr(value, "__len__") and not isinstance(value, str):
            try:
                value = np.asarray(value)
            except Exception:  # noqa: BLE001 - leave exotic Vt types as they are
                pass
        elif isinstance(value, Sdf.AssetPath):
            value = value.resolvedPath or value.path
        out[name[len("warpshade:"):]] = value
    for rel in prim.GetAuthoredRelationships():  # e.g. rel warpshade:attachTarget = </World/Walker/Body>
        name = rel.GetName()
        if name.startswith("warpshade:"):
            targets = rel.GetTargets()
            if len(targets) != 1:
                raise SceneError(f"{source}:{prim.GetPath()}: {name} must have exactly one target, has {len(targets)}")
            out[name[len("warpshade:"):]] = str(targets[0])
    return out


VERTEX_LISTS = ("pinned", "attached", "attachTarget")
"""``warpshade:`` attributes that name one mesh's vertices: taken from a prim above the mesh only when the
mesh is the one gprim under it."""


def _object_namespace(prim, source: str) -> dict:
    """The ``warpshade:`` attributes of a mesh or gprim: its own and those authored on the prims above it,
    up to the default prim (whose attributes are the scene's settings) and not including it, the nearest
    winning. DCCs that split an object into a transform and its shape write the object's custom
    properties on the transform (Blender's USD export: ``Xform "Cloth"`` over ``Mesh "Grid"``, a custom
    property of the object on the Xform, one of its mesh data on the Mesh), and a mark on a group (an
    Xform holding a character's meshes marked ``warpshade:collider``) holds for every gprim under it.
    A vertex list (:data:`VERTEX_LISTS`) on a prim above more than one gprim is an error naming both."""
    above = []
    stop = prim.GetStage().GetDefaultPrim()
    parent = prim.GetParent()
    while parent and not parent.IsPseudoRoot() and parent != stop:
        above.append(parent)
        parent = parent.GetParent()
    out = {}
    for holder in reversed(above):
        found = _namespace(holder, source)
        lists = [key for key in VERTEX_LISTS if key in found]
        if lists and sum(1 for p in Usd.PrimRange(holder, _PRIMS) if p.IsA(UsdGeom.Gprim)) > 1:
            raise SceneError(f"{source}:{holder.GetPath()}: warpshade:{lists[0]} names vertices of one mesh, but "
                             f"{holder.GetPath()} holds more than one gprim ({prim.GetPath()} among them): author it "
                             "on the mesh itself")
        out.update(found)
    out.update(_namespace(prim, source))
    return out


def _cast(value, typ, source, prim, key):
    try:
        return typ(value)
    except (TypeError, ValueError):
        raise SceneError(f"{source}:{prim.GetPath()}: warpshade:{key} must be {typ.__name__}, got {value!r}") from None
