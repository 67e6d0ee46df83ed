"""Writes cape_on_rig.usda with Blender's own USD exporter, as a Blender user would (run with Blender's
Python module, ``pip install bpy==5.0.1``: ``python make_cape_on_rig.py``).

The scene: a ground plane, a 1.6 m body (a closed cylinder) skinned to a two-bone armature whose upper
bone sways while the rig walks 0.6 m (frames 1-24, 24 fps, Z up, metres), a cape behind it and a sun.
The marks are the Blender way of marking vertices: the cape's top row is the *vertex group*
``warpshade:attached``, which the exporter writes as the per-vertex float primvar
``primvars:warpshade_attached`` (a colon is not kept; a list of more than four integers as a custom
property is not exported at all), and the object property ``warpshade:attachTarget`` is the *string* path
of the body's Xform (``/root/Rig/Body``; Blender writes the object as an Xform over its mesh). The body,
a mesh marked ``warpshade:collider = "mesh"``, is exported as a UsdSkel-skinned mesh (``SkelRoot "Rig"``)."""

import math
import os

import bpy

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "cape_on_rig.usda")

bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
scene.frame_start, scene.frame_end = 1, 24
scene.render.fps = 24

bpy.ops.mesh.primitive_plane_add(size=8, location=(0, 0, 0))
ground = bpy.context.object
ground.name = "Ground"
ground["warpshade:collider"] = "ground"

# the body: a closed cylinder with rings to bend along (9 rings of 16 vertices, 0.25 m radius)
R, H, SIDES, RINGS = 0.25, 1.6, 16, 9
verts = [(R * math.cos(2 * math.pi * k / SIDES), R * math.sin(2 * math.pi * k / SIDES), H * r / (RINGS - 1))
         for r in range(RINGS) for k in range(SIDES)]
faces = [(r * SIDES + k, r * SIDES + (k + 1) % SIDES, (r + 1) * SIDES + (k + 1) % SIDES, (r + 1) * SIDES + k)
         for r in range(RINGS - 1) for k in range(SIDES)]
faces += [tuple(reversed(range(SIDES))), tuple((RINGS - 1) * SIDES + k for k in range(SIDES))]
body_mesh = bpy.data.meshes.new("Body")
body_mesh.from_pydata(verts, [], faces)
body_mesh.update()
body = bpy.data.objects.new("Body", body_mesh)
scene.collection.objects.link(body)
body["warpshade:collider"] = "mesh"

# the rig: a lower and an upper bone, the body skinned to them with automatic weights
bpy.ops.object.armature_add(location=(0, 0, 0))
rig = bpy.context.object
rig.name = "Rig"
bpy.ops.object.mode_set(mode="EDIT")
lower = rig.data.edit_bones[0]
lower.name, lower.head, lower.tail = "Lower", (0, 0, 0), (0, 0, 0.8)
upper = rig.data.edit_bones.new("Upper")
upper.head, upper.tail, upper.parent = (0, 0, 0.8), (0, 0, 1.6), lower
bpy.ops.object.mode_set(mode="OBJECT")
body.select_set(True)
rig.select_set(True)
bpy.context.view_layer.objects.active = rig
bpy.ops.object.parent_set(type="ARMATURE_AUTO")
bone = rig.pose.bones["Upper"]
bone.rotation_mode = "XYZ"
for frame, sway, walked in ((1, 0.0, 0.0), (8, 0.35, 0.2), (16, -0.35, 0.4), (24, 0.0, 0.6)):
    bone.rotation_euler = (sway, 0.0, 0.0)
    bone.keyframe_insert("rotation_euler", frame=frame)
    rig.location = (0, walked, 0)
    rig.keyframe_insert("location", frame=frame)

# the cape: a 0.8 m x 1 m grid 8 cm behind the body, its top row attached to it
bpy.ops.mesh.primitive_grid_add(x_subdivisions=12, y_subdivisions=15, size=1.0, location=(0, -0.33, 1.0))
cape = bpy.context.object
cape.name = "Cape"
cape.rotation_euler = (math.pi / 2, 0, 0)
cape.scale = (0.8, 1.0, 1.0)
bpy.ops.object.transform_apply(location=False, rotation=True, scale=True)
heights = [(cape.matrix_world @ v.co).z for v in cape.data.vertices]
top_row = [i for i, z in enumerate(heights) if z > max(heights) - 1e-4]
cape["warpshade:kind"] = "cloth"
cape["warpshade:attachTarget"] = "/root/Rig/Body"
cape.vertex_groups.new(name="warpshade:attached").add(top_row, 1.0, "REPLACE")

bpy.ops.object.light_add(type="SUN", location=(2, -2, 5))
sun = bpy.context.object
sun.rotation_euler = (0.6, 0.2, 0.3)
sun.data.energy = 4.0

bpy.ops.wm.usd_export(filepath=OUT, export_animation=True, export_custom_properties=True, export_lights=True,
                      export_armatures=True)
print("wrote", OUT, "with", len(top_row), "attached vertices")
