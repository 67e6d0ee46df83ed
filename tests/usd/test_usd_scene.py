"""Scene input from USD: shipped scenes, lights, skins, materials, warpshade: settings, bad input."""

from __future__ import annotations

import os
import warnings

import numpy as np
import pytest

from helpers import REPO
from warpshade.scene import SceneError, SceneWarning
from warpshade.usd import read_scene

SCENES = os.path.join(REPO, "usd_scenes")


def scene(name):
    return read_scene(os.path.join(SCENES, name))


def test_default_scene_contents():
    s = scene("default.usda")
    assert s.frames == 120 and s.fps == 60 and s.up_axis == "Y" and s.lights == []  # default sky
    kinds = {o.name: o.kind for o in s.objects}
    assert kinds == {"/World/Ground": "static", "/World/Ball": "static", "/World/Cloth": "cloth"}
    cloth = s.object("/World/Cloth")
    assert cloth.params["cloth"]["density"] == pytest.approx(0.2)
    assert cloth.params["cloth"]["bendStiffness"] == pytest.approx(2e-5)
    assert cloth.params["cloth"]["selfCollision"] is True
    # 33x33 quad grid -> 32*32 quads -> 2 triangles each; rotated -90° about X and lifted to y = 1
    assert cloth.mesh.num_vertices == 33 * 33 and cloth.mesh.num_faces == 2 * 32 * 32
    assert np.allclose(cloth.mesh.points[:, 1], 1.0, atol=1e-6)
    assert np.allclose(cloth.material.albedo, (0.75, 0.2, 0.15)) and cloth.material.roughness == pytest.approx(0.9)
    assert np.all(cloth.mesh.normals[:, 1] > 0.99), "cloth quads must face up after the transform"
    ball = s.object("/World/Ball")
    assert np.allclose(ball.params["sphere"]["center"], (0, 0.35, 0))
    assert ball.params["sphere"]["radius"] == pytest.approx(0.35)
    assert np.allclose(np.linalg.norm(ball.mesh.points - (0, 0.35, 0), axis=1), 0.35, atol=1e-6)
    assert s.object("/World/Ground").params["collider"] == "ground"


def test_pins_and_wind():
    s = scene("flag_wind.usda")
    flag = s.object("/World/Flag")
    pins = flag.params["pinned"]
    assert len(pins) == 13 and np.allclose(flag.mesh.points[pins, 0], -0.8)
    assert np.allclose(s.settings["wind"], (6.0, 0.0, 1.5))


def test_lights_read_from_shipped_scenes():
    sun, sky = scene("cloth_sphere.usda").lights
    assert sun.kind == "distant" and sun.normalize and sun.intensity == 3.0
    # rotateY(30) then rotateX(-55): shines down at 55° elevation
    assert sun.direction[1] == pytest.approx(-np.sin(np.radians(55)), abs=1e-6)
    assert sky.kind == "dome" and sky.texture is None and np.allclose(sky.color, (0.5, 0.6, 0.8))
    rect = scene("rect_light.usda").lights[0]
    assert rect.kind == "rect" and (rect.width, rect.height, rect.intensity) == (1.5, 1.0, 8.0)
    assert np.allclose(rect.direction, (0, -1, 0), atol=1e-6) and np.allclose(rect.position, (0.5, 2.5, 0.5))
    dome = scene("dome_texture.usda").lights[0]
    assert dome.kind == "dome" and os.path.samefile(dome.texture, os.path.join(SCENES, "sky_small.exr"))


def test_animated_mesh_reads_time_samples_lazily():
    s = scene("dome_texture.usda")
    sheet = s.object("/World/Sheet")
    assert sheet.kind == "animated" and s.frames == 48
    p0, p5 = sheet.params["points_at"](0), sheet.params["points_at"](5)
    # the generator displaces local z by 0.15 sin(3x + 2πf/48); local z maps to world -y... plus the lift
    x = p5[:, 0]
    assert np.allclose(p5[:, 1], 1.2 + 0.15 * np.sin(3 * x + 2 * np.pi * 5 / 48), atol=1e-5)
    assert not np.allclose(p0, p5)


def test_skinned_mesh_follows_its_skeleton():
    s = scene("skinned_arm.usda")
    tube = s.object("/World/Arm/Tube")
    assert tube.kind == "skinned"
    rest = tube.mesh.points
    assert np.allclose(tube.params["points_at"](0), rest, atol=1e-6)  # frame 0: no bend
    f = 12
    a = np.radians(70.0 * np.sin(2 * np.pi * f / 48))
    top = rest[:, 1] >= 0.7 - 1e-6  # weight 1 on the elbow joint (at y = 0.7): rigid rotation about z
    c, s_ = np.cos(a), np.sin(a)
    d = rest[top] - (0, 0.7, 0)
    expect = np.stack([c * d[:, 0] - s_ * d[:, 1], s_ * d[:, 0] + c * d[:, 1], d[:, 2]], 1) + (0, 0.7, 0)
    assert np.allclose(tube.params["points_at"](f)[top], expect, atol=1e-5)


def _write(tmp_path, text, name="scene.usda"):
    path = tmp_path / name
    path.write_text("#usda 1.0\n" + text)
    return str(path)


def test_malformed_file_names_file(tmp_path):
    path = _write(tmp_path, 'def Mesh "Broken" {\n  point3f[] points = [(0, 0, 0)\n}\n')
    with pytest.raises(SceneError, match="scene.usda: cannot open USD stage"):
        read_scene(path)
    with pytest.raises(SceneError, match="no such scene file"):
        read_scene(str(tmp_path / "missing.usda"))


TRI = ('def Mesh "Tri" {\n int[] faceVertexCounts = [3]\n int[] faceVertexIndices = [0, 1, 2]\n'
       ' point3f[] points = [(0, 0, 0), (1, 0, 0), (0, 1, 0)]\n %s}\n')


def test_animated_points_not_finite_name_file_prim_time_code_and_vertex(tmp_path):
    """A NaN in an animated mesh's points at one time code (a DCC's broken cache) is named with its file,
    prim, time code (1005: not the run's frame 4) and vertex, as authored."""
    anim = ('def Mesh "Tri" {\n int[] faceVertexCounts = [3]\n int[] faceVertexIndices = [0, 1, 2]\n'
            ' point3f[] points.timeSamples = {1001: [(0, 0, 0), (1, 0, 0), (0, 1, 0)],'
            ' 1005: [(0, 0, 0), (1, 0, 0), (0, nan, 0)]}\n}\n')
    scene = read_scene(_write(tmp_path, anim))
    (tri,) = scene.objects
    assert tri.kind == "animated"
    tri.params["points_at"](1001)
    with pytest.raises(SceneError, match=r"scene.usda:/Tri: points at time code 1005: vertex 2 has a non-finite "
                                         r"position \[0.0, nan, 0.0\]"):
        tri.params["points_at"](1005)


def test_missing_texture_names_file_and_prim(tmp_path):
    path = _write(tmp_path, TRI % "" + 'def DomeLight "Sky" {\n asset inputs:texture:file = @./nope.exr@\n}\n')
    with pytest.raises(SceneError, match=r"scene.usda:/Sky: inputs:texture:file './nope.exr' not found"):
        read_scene(path)


def test_unknown_prims_warn_and_are_skipped(tmp_path):
    path = _write(tmp_path, TRI % "" + 'def BasisCurves "Hair" {\n}\ndef Camera "Cam" {\n}\ndef Cube "Box" {\n}\n')
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        s = read_scene(path)
    msgs = [str(w.message) for w in caught if issubclass(w.category, SceneWarning)]
    assert any("skipping /Hair (BasisCurves)" in m for m in msgs), msgs
    assert not any("/Box" in m for m in msgs), msgs  # a Cube gprim is read (tests/usd/test_gprims.py)
    assert not any("/Cam" in m for m in msgs), msgs  # a camera draws nothing: DCCs write one in every scene
    assert [o.name for o in s.objects] == ["/Tri", "/Box"]


def test_ngons_triangulated(tmp_path):
    pent = ('def Mesh "Pent" {\n int[] faceVertexCounts = [5]\n int[] faceVertexIndices = [0, 1, 2, 3, 4]\n'
            ' point3f[] points = [(1, 0, 0), (0.31, 0.95, 0), (-0.81, 0.59, 0), (-0.81, -0.59, 0), (0.31, -0.95, 0)]\n}\n')
    s = read_scene(_write(tmp_path, pent))
    assert s.objects[0].mesh.faces.tolist() == [[0, 1, 2], [0, 2, 3], [0, 3, 4]]


@pytest.mark.parametrize("attrs,match", [
    ('token warpshade:kind = "jelly"\n', "warpshade:kind 'jelly' is not one of"),
    ('int[] warpshade:pinned = [0, 7]\n', "warpshade:pinned vertex 7 out of range 0..2"),
    ('token warpshade:method = "magic"\n', "warpshade:method: unknown visibility method 'magic'"),
])
def test_bad_warpshade_attributes(tmp_path, attrs, match):
    with pytest.raises(SceneError, match=match):
        read_scene(_write(tmp_path, TRI % attrs))


def test_bad_values_and_empty_scene(tmp_path):
    bad_pts = TRI.replace("(1, 0, 0)", "(nan, 0, 0)") % ""
    # the authored value, not the transformed one (a matrix product spreads the NaN over x, y and z)
    with pytest.raises(SceneError, match=r"/Tri: points: vertex 1 has a non-finite position \[nan, 0.0, 0.0\]"):
        read_scene(_write(tmp_path, bad_pts))
    with pytest.raises(SceneError, match="no Mesh or gprim"):
        read_scene(_write(tmp_path, 'def Xform "World" {\n}\n', "empty.usda"))
    neg = TRI % "" + 'def SphereLight "Bulb" {\n float inputs:radius = -1\n}\n'
    with pytest.raises(SceneError, match="/Bulb: radius must be finite and >= 0"):
        read_scene(_write(tmp_path, neg, "neg.usda"))


def test_cape_walker_skinned_body_and_attachments():
    s = scene("cape_walker.usda")
    body, cape = s.object("/World/Walker/Body"), s.object("/World/Cape")
    assert body.kind == "skinned" and body.params["collider"] == "mesh"
    assert cape.kind == "cloth" and cape.params["attachTarget"] == "/World/Walker/Body"
    assert len(cape.params["attached"]) == 13 and np.allclose(cape.mesh.points[cape.params["attached"], 1], 1.43)
    # the body walks along +z (0.8 m/s at 60 fps): after 60 frames its centre moved ~0.8 m
    z0, z60 = body.params["points_at"](0)[:, 2].mean(), body.params["points_at"](60)[:, 2].mean()
    assert z60 - z0 == pytest.approx(0.8, abs=0.05)


def test_animated_transform_makes_an_animated_object(tmp_path):
    xf = ('double3 xformOp:translate.timeSamples = {0: (0, 0, 0), 10: (1, 0, 0)}\n'
          ' uniform token[] xformOpOrder = ["xformOp:translate"]\n')
    s = read_scene(_write(tmp_path, TRI % xf))
    tri = s.objects[0]
    assert tri.kind == "animated"
    assert np.allclose(tri.params["points_at"](5) - tri.mesh.points, (0.5, 0, 0))


def _cloth_stage(**attrs):
    """A 3 x 3-vertex cloth in memory with `warpshade:cloth:NAME = value` for each keyword."""
    from pxr import Gf, Sdf, Usd, UsdGeom

    st = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(st, UsdGeom.Tokens.y)
    UsdGeom.Xform.Define(st, "/World")
    st.SetDefaultPrim(st.GetPrimAtPath("/World"))
    m = UsdGeom.Mesh.Define(st, "/World/Cloth")
    m.CreatePointsAttr([Gf.Vec3f(0.1 * i, 1.0, 0.1 * j) for j in range(3) for i in range(3)])
    m.CreateFaceVertexCountsAttr([4] * 4)
    m.CreateFaceVertexIndicesAttr([v for j in range(2) for i in range(2)
                                   for v in (j * 3 + i, (j + 1) * 3 + i, (j + 1) * 3 + i + 1, j * 3 + i + 1)])
    prim = m.GetPrim()
    prim.CreateAttribute("warpshade:kind", Sdf.ValueTypeNames.Token).Set("cloth")
    types = {bool: Sdf.ValueTypeNames.Bool, int: Sdf.ValueTypeNames.Int, float: Sdf.ValueTypeNames.Float}
    for name, value in attrs.items():
        prim.CreateAttribute(f"warpshade:cloth:{name}", types[type(value)], custom=True).Set(value)
    return st


def test_cloth_solver_settings_come_from_the_first_cloth():
    """`warpshade:cloth:maxContacts`, `contactInterval`, `guard`, `selfFriction`... reach the solver
    (the defaults otherwise)."""
    from warpshade.pipeline.cloth import ClothSimulation
    from warpshade.usd.scene_io import scene_from_stage

    sim = ClothSimulation(scene_from_stage(_cloth_stage(), source="t.usda"))
    assert sim.solver.max_contacts == 128 and sim.solver.guard and sim.solver.contact_interval == 3
    assert sim.solver.stretch_limits
    assert sim.solver.knobs()["guard_relax"] == 0
    st = _cloth_stage(maxContacts=8, contactInterval=2, guard=False, selfFriction=0.1, stretchSweeps=2,
                      iterations=2, contactIterations=3, edgeContact=False, stretchLimits=False)
    k = ClothSimulation(scene_from_stage(st, source="t.usda")).solver.knobs()
    assert (k["max_contacts"], k["contact_interval"], k["guard"], k["stretch_sweeps"], k["iterations"],
            k["contact_iterations"], k["edge_contact"], k["stretch_limits"]) == (8, 2, False, 2, 2, 3, False, False)
    st = _cloth_stage(guardRelax=8)  # sweeps around the guard's reverts: with the guard on (its default)
    assert ClothSimulation(scene_from_stage(st, source="t.usda")).solver.knobs()["guard_relax"] == 8
    # the opt-in strain and hold settings (the free drape under 2 % strain: limitSliding, stretchSweeps 12,
    # limitEverySweep; heldContactInterval after a guard step), from a scene file as from Python
    st = _cloth_stage(limitSliding=True, limitEverySweep=True, stretchSweeps=12, heldContactInterval=1)
    k2 = ClothSimulation(scene_from_stage(st, source="t.usda")).solver.knobs()
    assert (k2["limit_sliding"], k2["limit_every_sweep"], k2["stretch_sweeps"], k2["held_contact_interval"]) == (
        True, True, 12, 1)
    st = _cloth_stage(limitSliding=True, coarseLevels=1, stretchChebyshev=0.8, stretchSweeps=4)
    k3 = ClothSimulation(scene_from_stage(st, source="t.usda")).solver.knobs()
    assert (k3["coarse_levels"], k3["stretch_chebyshev"], k3["stretch_sweeps"]) == (1, pytest.approx(0.8), 4)
    assert k["self_friction"] == pytest.approx(0.1)


@pytest.mark.parametrize("attrs, named", [({"maxContacts": 0}, "warpshade:cloth:maxContacts"),
                                          ({"selfFriction": -1.0}, "warpshade:cloth:selfFriction"),
                                          ({"contactInterval": 1.5}, "warpshade:cloth:contactInterval"),
                                          ({"heldContactInterval": 0}, "warpshade:cloth:heldContactInterval"),
                                          ({"coarseLevels": -1}, "warpshade:cloth:coarseLevels"),
                                          ({"stretchChebyshev": 1.5}, "warpshade:cloth:stretchChebyshev")])
def test_bad_cloth_solver_setting_names_the_attribute(attrs, named):
    from warpshade.pipeline.cloth import ClothSimulation
    from warpshade.scene import SceneError
    from warpshade.usd.scene_io import scene_from_stage

    with pytest.raises(SceneError, match=f"t.usda: /World/Cloth: {named}"):
        ClothSimulation(scene_from_stage(_cloth_stage(**attrs), source="t.usda"))
