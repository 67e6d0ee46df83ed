"""Render warpshade outputs in Blender and check that every shaded mesh shows its baked colours.

Run it with Blender's Python module (``pip install bpy`` in a venv of its own; not a warpshade
dependency), one or more outputs of ``warpshade run`` or a ``sims/`` script::

    python docs/blender_check.py OUT.usda [MORE.usda ...] --frame 10 --out-dir renders/

For each file it imports the stage with ``bpy.ops.wm.usd_import`` (default options: the materials
as Blender's importer builds them from the output's ``UsdPreviewSurface``), applies step 4 of
docs/guide/dcc.md for Cycles (a back face is transparent, so ``<mesh>`` and ``<mesh>_back`` each
show their own side), sets a black world (the colours are emission) and renders with Cycles on the
CPU: ``<name>.png`` of the whole scene from a camera above, then each shaded mesh alone from that
camera and, for two-sided meshes, the front, the back and the pair from above and from below. Each
mesh alone is rendered twice from the same camera: through the imported material, and through a
control material that emits the ``displayColor`` attribute itself (what the mesh's baked colours
look like from there: the faces the camera sees, each at its share of the picture). It prints, per
mesh, the rendered pixels' mean linear RGB beside the control's and the mean ``displayColor`` of its
vertices, and the share of its pixels that are black beyond the control's, and exits non-zero if a
mesh renders black (mean luminance below 1/4 of the control's or 5 % more black pixels than the
control), brighter than its brightest vertex (99th percentile of its pixels' luminance above 1.25
times it: the scene's lights lit it again), or if fewer than 90 % of a two-sided pair's pixels show
what the front alone or the back alone shows there (both sides drawn at once, or specks of one
through the other). (The vertices' mean is no yardstick for the picture: a crate under a cloth
shows its black top and two sides, not its black bottom and the other two.)
``--no-recipe`` keeps the imported materials unchanged.
"""

from __future__ import annotations

import argparse
import math
import os
import sys

import bpy
import numpy as np
from mathutils import Vector

LUM = np.array([0.2126, 0.7152, 0.0722])


def _reset():
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    scene.cycles.device = "CPU"
    scene.cycles.samples = 4
    scene.cycles.use_denoising = False
    scene.render.resolution_x, scene.render.resolution_y = 320, 240
    scene.view_settings.view_transform = "Standard"
    world = bpy.data.worlds.new("black")
    world.use_nodes = True
    world.node_tree.nodes["Background"].inputs["Color"].default_value = (0, 0, 0, 1)
    scene.world = world
    return scene


def _backface_transparent(mat):
    """docs/guide/dcc.md step 4 for Cycles: Mix Shader (surface, Transparent) by Geometry ▸ Backfacing."""
    nt = mat.node_tree
    out = next(n for n in nt.nodes if n.bl_idname == "ShaderNodeOutputMaterial")
    link = next(link for link in nt.links if link.to_node == out and link.to_socket.name == "Surface")
    surf = link.from_socket
    nt.links.remove(link)
    mix = nt.nodes.new("ShaderNodeMixShader")
    geo = nt.nodes.new("ShaderNodeNewGeometry")
    transparent = nt.nodes.new("ShaderNodeBsdfTransparent")
    nt.links.new(geo.outputs["Backfacing"], mix.inputs[0])
    nt.links.new(surf, mix.inputs[1])
    nt.links.new(transparent.outputs[0], mix.inputs[2])
    nt.links.new(mix.outputs[0], out.inputs["Surface"])


def _bounds(objs):
    dg = bpy.context.evaluated_depsgraph_get()  # animated meshes: the frame's points (Mesh Sequence Cache)
    pts = np.array([tuple(o.matrix_world @ v.co) for o in objs for v in o.evaluated_get(dg).data.vertices])
    return pts.min(axis=0), pts.max(axis=0)


def _camera(scene, lo, hi, from_below=False):
    centre, radius = (lo + hi) / 2, max(float(np.linalg.norm(hi - lo)) / 2, 1e-3)
    # Blender is Z up; "below" is the opposite direction, so a plane of any orientation is seen from both sides
    direction = np.array([0.55, -0.75, 0.9]) * (-1.0 if from_below else 1.0)
    direction /= np.linalg.norm(direction)
    cam = bpy.data.objects.get("check_camera")
    if cam is None:
        cam = bpy.data.objects.new("check_camera", bpy.data.cameras.new("check_camera"))
        scene.collection.objects.link(cam)
    cam.data.lens = 35
    cam.data.clip_end = 100 * radius
    cam.location = Vector(centre + direction * radius * 2.6)
    cam.rotation_euler = (Vector(centre) - cam.location).to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam


def _render(scene, path):
    scene.render.filepath = path
    scene.render.image_settings.file_format = "OPEN_EXR" if path.endswith(".exr") else "PNG"
    if path.endswith(".exr"):
        scene.render.image_settings.color_depth = "32"
    bpy.ops.render.render(write_still=True)
    if not path.endswith(".exr"):
        return None
    img = bpy.data.images.load(path)
    px = np.array(img.pixels[:], dtype=np.float64).reshape(img.size[1], img.size[0], 4)
    bpy.data.images.remove(img)
    return px


def _colours(obj, scene):
    dg = bpy.context.evaluated_depsgraph_get()
    me = obj.evaluated_get(dg).data
    attr = me.attributes.get("displayColor")
    if attr is None:
        return None
    return np.array([tuple(d.color)[:3] for d in attr.data], dtype=np.float64)


def _alone(scene, meshes, show, path):
    for o in meshes:
        o.hide_render = o not in show
    px = _render(scene, path)
    for o in meshes:
        o.hide_render = False
    mask = px[..., 3] > 0.5
    rgb = px[..., :3][mask]
    return px, int(mask.sum()), (rgb.mean(axis=0) if len(rgb) else np.zeros(3))


def _black_share(px) -> float:
    """Share of a mesh's pixels that are black."""
    rgb = px[..., :3][px[..., 3] > 0.5]
    return float(np.mean(rgb @ LUM < 1e-3)) if len(rgb) else 0.0


def _control(scene, meshes, o, path, recipe):
    """``o`` alone rendered with a material emitting its ``displayColor`` attribute (back faces
    transparent with the recipe, as the check's render): the picture its baked colours make."""
    mat = bpy.data.materials.get("check_control")
    if mat is None:
        mat = bpy.data.materials.new("check_control")
        mat.use_nodes = True
        nt = mat.node_tree
        nt.nodes.clear()
        attr, emit = nt.nodes.new("ShaderNodeAttribute"), nt.nodes.new("ShaderNodeEmission")
        attr.attribute_name = "displayColor"
        nt.links.new(attr.outputs["Color"], emit.inputs["Color"])
        nt.links.new(emit.outputs[0], nt.nodes.new("ShaderNodeOutputMaterial").inputs["Surface"])
        if recipe:
            _backface_transparent(mat)
    own = list(o.data.materials)
    o.data.materials.clear()
    o.data.materials.append(mat)
    try:
        return _alone(scene, meshes, [o], path)
    finally:
        o.data.materials.clear()
        for m in own:
            o.data.materials.append(m)


def _bright(px) -> float:
    """99th percentile of a mesh's pixel luminance: emission interpolated between its vertices can be no
    brighter than its brightest vertex, so more means a renderer lit it again."""
    rgb = px[..., :3][px[..., 3] > 0.5]
    return float(np.percentile(rgb @ LUM, 99)) if len(rgb) else 0.0


def check(usd, frame, out_dir, recipe=True) -> list[str]:
    scene = _reset()
    bpy.ops.wm.usd_import(filepath=os.path.abspath(usd))
    scene.frame_set(frame)
    scene.render.film_transparent = True
    meshes = [o for o in scene.objects if o.type == "MESH"]
    for mat in {m for o in meshes for m in o.data.materials if m is not None and m.node_tree} if recipe else ():
        _backface_transparent(mat)
    lo, hi = _bounds(meshes)
    stem = os.path.join(out_dir, os.path.splitext(os.path.basename(usd))[0])
    _camera(scene, lo, hi)
    scene.render.film_transparent = False
    _render(scene, f"{stem}.png")
    scene.render.film_transparent = True
    failures = []
    by_name = {o.name: o for o in meshes}
    print(f"{usd} frame {frame}:")
    for o in meshes:
        cols = _colours(o, scene)
        if cols is None:
            failures.append(f"{o.name}: no displayColor attribute after import")
            continue
        for below in (False, True):  # a single-sided mesh (a side of cloth) may face down: try from below
            _camera(scene, *_bounds([o]), from_below=below)
            px, n, mean = _alone(scene, meshes, [o], f"{stem}_{o.name}.exr")
            if n > 100:
                break
        pc, _, want = _control(scene, meshes, o, f"{stem}_{o.name}_control.exr", recipe)
        black = _black_share(px) - _black_share(pc)
        print(f"  {o.name:24s} {n:6d} px  rendered {np.round(mean, 3)}  control {np.round(want, 3)}  "
              f"displayColor {np.round(cols.mean(axis=0), 3)}  extra black {100 * black:.1f} %")
        if not n:
            failures.append(f"{o.name}: not in the picture (no pixel)")
        elif want @ LUM > 1e-3 and (mean @ LUM < 0.25 * (want @ LUM) or black > 0.05):
            failures.append(f"{o.name}: renders black (mean {mean.round(3).tolist()}, {100 * black:.0f} % more black "
                            f"pixels than its displayColor emitted; that control's mean is {want.round(3).tolist()})")
        bright, brightest = _bright(px), float((cols @ LUM).max())
        if n and bright > 1.25 * brightest + 0.01:
            failures.append(f"{o.name}: renders brighter than its colours (99th percentile luminance {bright:.3f}, "
                            f"brightest vertex {brightest:.3f}): the scene's lights light it again")
        back = by_name.get(o.name + "_back")
        if back is None:
            continue
        for below in (False, True):
            # each pixel of the pair shows the side facing the camera: what that side's mesh alone shows
            _camera(scene, *_bounds([o]), from_below=below)
            side = "below" if below else "above"
            pf, nf, mf = _alone(scene, meshes, [o], f"{stem}_{o.name}_front_{side}.exr")
            pb, nb, mb = _alone(scene, meshes, [back], f"{stem}_{o.name}_back_{side}.exr")
            pp, npair, mp = _alone(scene, meshes, [o, back], f"{stem}_{o.name}_both_{side}.exr")
            cover = pp[..., 3] > 0.99
            close = lambda a: np.abs(pp[..., :3] - a[..., :3]).max(axis=-1) < 0.02 + 0.1 * np.abs(pp[..., :3]).max(axis=-1)
            from_front = (close(pf) & cover).sum() / max(cover.sum(), 1)
            from_back = (close(pb) & ~close(pf) & cover).sum() / max(cover.sum(), 1)
            print(f"    from {side}: pair {npair} px {np.round(mp, 3)}: {100 * from_front:.1f} % as the front alone "
                  f"{np.round(mf, 3)}, {100 * from_back:.1f} % as the back alone {np.round(mb, 3)}")
            if from_front + from_back < 0.9:
                failures.append(f"{o.name}: from {side}, only {100 * (from_front + from_back):.0f} % of the pair's "
                                "pixels show the front's or the back's own colour")
    return failures


def main(argv=None) -> int:
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else (argv or sys.argv[1:])
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("usd", nargs="+")
    ap.add_argument("--frame", type=int, default=0)
    ap.add_argument("--out-dir", default=".")
    ap.add_argument("--no-recipe", action="store_true", help="keep the imported materials as they are "
                    "(no transparent back faces)")
    args = ap.parse_args(argv)
    os.makedirs(args.out_dir, exist_ok=True)
    bad = {}
    for usd in args.usd:
        f = check(usd, args.frame, args.out_dir, recipe=not args.no_recipe)
        if f:
            bad[usd] = f
    for usd in args.usd:
        print(f"{'FAIL' if usd in bad else 'ok  '} {usd}" + "".join(f"\n     {m}" for m in bad.get(usd, [])))
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
