"""Vertices selected as DCCs write them: per-vertex primvars ``warpshade:pinned`` / ``warpshade_pinned``
(a Blender vertex group, a Houdini point attribute) beside the index lists, and ``warpshade:attachTarget``
as a string naming the mesh or the transform over it (Blender writes strings and objects as an Xform over
their mesh). Includes a scene written by Blender's own USD exporter (tests/data/blender/make_cape_on_rig.py)."""

from __future__ import annotations

import os

import numpy as np
import pytest
from pxr import Sdf, Usd, UsdGeom

from helpers import REPO
from warpshade.cli import main
from warpshade.pipeline.cloth import ClothSimulation
from warpshade.scene import SceneError
from warpshade.usd import read_scene

CAPE = os.path.join(REPO, "tests", "data", "blender", "cape_on_rig.usda")


def test_blender_vertex_group_attaches_the_capes_top_row():
    """Blender 5.0.1 writes the vertex group ``warpshade:attached`` as ``float[] primvars:warpshade_attached``
    (1 on the group's vertices): the attached vertices are the cape's top row, read from the file's points."""
    stage = Usd.Stage.Open(CAPE)
    points = np.asarray(UsdGeom.Mesh(stage.GetPrimAtPath("/root/Cape/Grid")).GetPointsAttr().Get())
    up = np.argmax(np.ptp(points, axis=0) * [0, 1, 1])  # the cape hangs in a vertical plane (the exporter's axes)
    top_row = np.flatnonzero(points[:, up] == points[:, up].max())
    cape = read_scene(CAPE).object("/root/Cape/Grid")
    assert len(top_row) == 13  # make_cape_on_rig.py: a grid of 12 x 15 faces, its top row of 13 vertices
    assert cape.params["attached"].tolist() == top_row.tolist()
    assert "pinned" not in cape.params


def test_blender_cape_follows_the_skinned_body(tmp_path):
    """End to end: every attached vertex of the run's output keeps its rest offset from the nearest vertex of
    the walking, swaying UsdSkel body (the target named by the string ``/root/Rig/Body``, the body's Xform),
    and the free cape below stays off the body (it hangs behind it, not through it)."""
    out = tmp_path / "out.usda"
    assert main(["run", CAPE, "--out", str(out), "--method", "reference", "--rays", "4", "--order", "2",
                 "--refine-receivers", "off", "--no-progress"]) == 0
    scene = read_scene(CAPE)
    body, cape = scene.object("/root/Rig/Body/Body"), scene.object("/root/Cape/Grid")
    attached = cape.params["attached"]
    rest_body = body.params["points_at"](scene.start_time).astype(np.float64)
    nearest = np.argmin(((cape.mesh.points[attached, None, :] - rest_body[None]) ** 2).sum(-1), axis=1)
    offset = cape.mesh.points[attached] - rest_body[nearest]
    stage = Usd.Stage.Open(str(out))
    grid = stage.GetPrimAtPath("/root/Cape/Grid")
    for t in (8, 16, 24):
        xf = np.array(UsdGeom.Xformable(grid).ComputeLocalToWorldTransform(t)).T
        world = np.asarray(UsdGeom.Mesh(grid).GetPointsAttr().Get(t), dtype=np.float64) @ xf[:3, :3].T + xf[:3, 3]
        posed = body.params["points_at"](t).astype(np.float64)
        # float32 points in metres of a 2 m scene: a few ulps (1.2e-7 m each), 1e-5 m leaves ample margin
        np.testing.assert_allclose(world[attached], posed[nearest] + offset, atol=1e-5)
        assert np.ptp(posed[:, 1]) > 0  # the body is there and has moved with the rig
    walked = body.params["points_at"](24)[:, 1].mean() - rest_body[:, 1].mean()
    assert walked == pytest.approx(0.6, abs=0.01)  # the rig walks 0.6 m along +Y in make_cape_on_rig.py


def _sheet_stage(tmp_path, primvars=(), listed=None, target=None, bodies=("Mesh",)):
    """/World (Y up, metres) with a cloth quad /World/Cloth/Sheet, ``primvars`` ((name, type, values,
    interpolation), ...) and ``listed`` (``int[] warpshade:pinned``) on it, animated bodies under /World/Body
    and ``warpshade:attachTarget`` = ``target`` (a string) on /World/Cloth."""
    stage = Usd.Stage.CreateNew(str(tmp_path / "sheet.usda"))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetStartTimeCode(0)
    stage.SetEndTimeCode(2)
    stage.SetDefaultPrim(UsdGeom.Xform.Define(stage, "/World").GetPrim())
    cloth = UsdGeom.Xform.Define(stage, "/World/Cloth").GetPrim()
    cloth.CreateAttribute("warpshade:kind", Sdf.ValueTypeNames.String, custom=True).Set("cloth")
    sheet = UsdGeom.Mesh.Define(stage, "/World/Cloth/Sheet")
    sheet.CreatePointsAttr([(0, 1, 0), (1, 1, 0), (1, 1, 1), (0, 1, 1)])
    sheet.CreateFaceVertexCountsAttr([4])
    sheet.CreateFaceVertexIndicesAttr([0, 3, 2, 1])
    for name, typ, values, interpolation in primvars:
        UsdGeom.PrimvarsAPI(sheet).CreatePrimvar(name, typ, interpolation).Set(values)
    if listed is not None:
        sheet.GetPrim().CreateAttribute("warpshade:pinned", Sdf.ValueTypeNames.IntArray, custom=True).Set(listed)
    UsdGeom.Xform.Define(stage, "/World/Body")
    for i, name in enumerate(bodies):
        body = UsdGeom.Mesh.Define(stage, f"/World/Body/{name}")
        body.CreateFaceVertexCountsAttr([3])
        body.CreateFaceVertexIndicesAttr([0, 1, 2])
        for t in (0, 1, 2):
            body.GetPointsAttr().Set([(0, 1.5 + i + 0.1 * t, 0), (1, 1.5 + i, 0), (0, 1.5 + i, 1)], t)
    if target is not None:
        cloth.CreateAttribute("warpshade:attachTarget", Sdf.ValueTypeNames.String, custom=True).Set(target)
        sheet.GetPrim().CreateAttribute("warpshade:attached", Sdf.ValueTypeNames.IntArray, custom=True).Set([0])
    stage.Save()
    return str(tmp_path / "sheet.usda")


@pytest.mark.parametrize("name, typ, values, selected", [
    ("warpshade:pinned", Sdf.ValueTypeNames.BoolArray, [True, False, False, True], [0, 3]),
    ("warpshade_pinned", Sdf.ValueTypeNames.FloatArray, [0.0, 0.49, 0.5, 1.0], [2, 3]),
    ("warpshade_pinned", Sdf.ValueTypeNames.IntArray, [0, 1, 0, 0], [1]),
])
def test_a_per_vertex_primvar_pins_the_vertices_it_selects(tmp_path, name, typ, values, selected):
    """One value a point, selected from 0.5 up (a full vertex-group weight, true, 1)."""
    path = _sheet_stage(tmp_path, [(name, typ, values, UsdGeom.Tokens.vertex)])
    assert read_scene(path).object("/World/Cloth/Sheet").params["pinned"].tolist() == selected


def test_an_index_list_and_a_primvar_together_are_an_error(tmp_path):
    path = _sheet_stage(tmp_path, [("warpshade:pinned", Sdf.ValueTypeNames.BoolArray, [True] * 4,
                                    UsdGeom.Tokens.vertex)], listed=[1])
    with pytest.raises(SceneError, match=r"/World/Cloth/Sheet: warpshade:pinned is authored twice.*"
                                         r"primvars:warpshade:pinned"):
        read_scene(path)


@pytest.mark.parametrize("values, interpolation, message", [
    ([1.0, 0.0, 0.0], UsdGeom.Tokens.vertex, r"primvars:warpshade_pinned has 3 values for the mesh's 4 points"),
    ([1.0], UsdGeom.Tokens.constant, r"primvars:warpshade_pinned must have vertex interpolation.*'constant'"),
    ([1.0, float("nan"), 0.0, 0.0], UsdGeom.Tokens.vertex, r"primvars:warpshade_pinned value of vertex 1 is not"),
])
def test_a_malformed_selection_primvar_is_an_error_naming_it(tmp_path, values, interpolation, message):
    path = _sheet_stage(tmp_path, [("warpshade_pinned", Sdf.ValueTypeNames.FloatArray, values, interpolation)])
    with pytest.raises(SceneError, match=r"sheet.usda:/World/Cloth/Sheet: " + message):
        read_scene(path)


@pytest.mark.parametrize("target", ["/World/Body", "/World/Body/Mesh"])
def test_an_attach_target_names_the_mesh_or_the_transform_over_it(tmp_path, target):
    sim = ClothSimulation(read_scene(_sheet_stage(tmp_path, target=target)))
    assert [name for name, _, _ in sim.attachments] == ["/World/Body/Mesh"]


def test_an_attach_target_over_several_meshes_is_an_error_naming_them(tmp_path):
    scene = read_scene(_sheet_stage(tmp_path, target="/World/Body", bodies=("Mesh", "Other")))
    with pytest.raises(SceneError, match=r"warpshade:attachTarget '/World/Body' holds 2 meshes "
                                         r"\(/World/Body/Mesh, /World/Body/Other\)"):
        ClothSimulation(scene)
    (tmp_path / "elsewhere").mkdir()
    scene = read_scene(_sheet_stage(tmp_path / "elsewhere", target="/World/Nowhere"))
    with pytest.raises(SceneError, match=r"'/World/Nowhere' is not a mesh of the scene nor a prim above one"):
        ClothSimulation(scene)


@pytest.mark.parametrize("key", ["pinned", "attached"])
def test_cloth_simulation_checks_a_scene_objects_vertex_selection(key):
    """A Scene built without the reader or the script API (objects made directly) gets the same
    vertex check in ClothSimulation (``geometry.mesh.vertex_indices``), as a SceneError naming the
    object and the attribute; a pinned index out of range was an IndexError from numpy before."""
    import dataclasses

    import warpshade as ws

    bar = ws.mesh("Bar", np.eye(3), [[0, 1, 2]], moving=True, points_at=lambda code: np.eye(3))
    cloth = ws.cloth_grid(resolution=4, attached=[0], attach_to="Bar")
    params = dict(cloth.params, **{key: np.array([0, 16], np.int32)})
    scene = ws.make_scene(bar, dataclasses.replace(cloth, params=params))
    with pytest.raises(SceneError, match=f"^Cloth: warpshade:{key} vertex 16 out of range 0..15$"):
        ClothSimulation(scene)
