"""Writes cloth_on_box.usda with Blender's own USD exporter, as a Blender user would (run with
Blender's Python module, ``pip install bpy==5.0.1``: ``python make_cloth_on_box.py``).

The scene: a ground plane, a 1 m cube and a 2 m grid above it (Z up, metres, frames 1-12, 24 fps),
a sun and an area light. The warpshade marks are Blender custom properties, which the exporter
(``export_custom_properties``) writes where Blender keeps them: an *object's* on the Xform it writes
for the object (``Xform "Cloth"``), its *mesh data's* on the Mesh under it (``Mesh "Grid"``), as
``custom string`` (not ``token``) and a list of three integers as ``int3``."""

import os

import bpy

OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "cloth_on_box.usda")

bpy.ops.wm.read_factory_settings(use_empty=True)
scene = bpy.context.scene
scene.frame_start, scene.frame_end = 1, 12
bpy.ops.mesh.primitive_plane_add(size=6, location=(0, 0, 0))
bpy.context.object.name = "Ground"
bpy.context.object["warpshade:collider"] = "ground"  # an object property: on the Xform
bpy.ops.mesh.primitive_cube_add(size=1.0, location=(0, 0, 0.5))
bpy.context.object.name = "Box"
bpy.context.object["warpshade:collider"] = "box"
bpy.ops.mesh.primitive_grid_add(x_subdivisions=12, y_subdivisions=12, size=2.0, location=(0, 0, 1.3))
cloth = bpy.context.object
cloth.name = "Cloth"
cloth["warpshade:kind"] = "cloth"  # on the Xform
cloth.data["warpshade:pinned"] = [0, 6, 12]  # mesh data: on the Mesh (one edge of the grid)
bpy.ops.object.light_add(type="SUN", location=(2, -2, 5))
bpy.context.object.rotation_euler = (0.6, 0.2, 0.3)
bpy.ops.object.light_add(type="AREA", location=(-2, 2, 3))
bpy.context.object.data.size = 1.0
bpy.ops.wm.usd_export(filepath=OUT, export_animation=True, export_custom_properties=True, export_lights=True)
