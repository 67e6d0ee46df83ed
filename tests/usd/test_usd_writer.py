"""Streaming USD export (docs/conventions.md §6): round trip, compliance, crash safety, bad input."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
from pxr import Gf, Usd, UsdGeom, UsdLux, UsdShade

from helpers import REPO, grid
from warpshade.scene import LightSpec
from warpshade.usd import AnimationWriter
from warpshade.usd.validate import validation_errors



def open_stage(path) -> Usd.Stage:
    """Open ``path``. USD's layer registry serves a layer from memory while any stage holds it, so
    tests drop their stages before a file is rewritten."""
    return Usd.Stage.Open(str(path))


def frames_data(rng, frames: int, v: int, order: int = 2):
    return [dict(points=rng.random((v, 3), dtype=np.float32), normals=rng.random((v, 3), dtype=np.float32),
                 colors=rng.random((v, 3), dtype=np.float32), transfer=rng.random((v, order * order), dtype=np.float32))
            for _ in range(frames)]


def write(path, data, faces, chunk=4, static=None, **kw):
    w = AnimationWriter(str(path), chunk=chunk, **kw)
    name = w.add_mesh("/World/Cloth", faces, albedo=(0.5, 0.4, 0.3), transfer_order=2)
    if static is not None:
        g = w.add_mesh("ground", static[1], points=static[0])
    for f, d in enumerate(data):
        w.write_frame(f, name, **d)
        if static is not None:
            w.write_frame(f, g, None, colors=np.full((len(static[0]), 3), f, dtype=np.float32))
    return w


def test_round_trip_per_frame(tmp_path, rng):
    pts, faces = grid(5)
    data = frames_data(rng, 10, len(pts))
    ground = grid(3)
    write(tmp_path / "out.usda", data, faces, chunk=4, static=ground).close()
    stage = open_stage(tmp_path / "out.usda")
    assert stage.GetStartTimeCode() == 0 and stage.GetEndTimeCode() == 9
    assert UsdGeom.GetStageUpAxis(stage) == "Y" and UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert stage.GetDefaultPrim().GetPath() == "/World"
    mesh = UsdGeom.Mesh.Get(stage, "/World/Cloth")
    assert mesh.GetSubdivisionSchemeAttr().Get() == "none"
    assert np.array_equal(np.asarray(mesh.GetFaceVertexIndicesAttr().Get()).reshape(-1, 3), faces)
    pv = UsdGeom.PrimvarsAPI(mesh)
    col, tr = pv.GetPrimvar("displayColor"), pv.GetPrimvar("warpshade:transfer")
    assert col.GetInterpolation() == "vertex" and tr.GetInterpolation() == "vertex" and tr.GetElementSize() == 4
    assert mesh.GetNormalsInterpolation() == "vertex"
    assert mesh.GetPointsAttr().GetTimeSamples() == list(map(float, range(10)))
    # what usdview's and Blender's importers look at to decide a mesh (and its colours) animate
    assert mesh.GetPointsAttr().ValueMightBeTimeVarying() and col.ValueMightBeTimeVarying()
    assert stage.GetTimeCodesPerSecond() == 60 and stage.GetFramesPerSecond() == 60
    for f, d in enumerate(data):  # float32 in, float32 out: exact
        assert np.array_equal(np.asarray(mesh.GetPointsAttr().Get(f)), d["points"]), f"points, frame {f}"
        assert np.array_equal(np.asarray(mesh.GetNormalsAttr().Get(f)), d["normals"]), f"normals, frame {f}"
        assert np.array_equal(np.asarray(col.Get(f)), d["colors"]), f"colors, frame {f}"
        assert np.array_equal(np.asarray(tr.Get(f)).reshape(-1, 4), d["transfer"]), f"transfer, frame {f}"
        ext = np.asarray(mesh.GetExtentAttr().Get(f))
        assert np.array_equal(ext, np.stack([d["points"].min(0), d["points"].max(0)])), f"extent, frame {f}"
    g = UsdGeom.Mesh.Get(stage, "/World/ground")
    assert np.array_equal(np.asarray(g.GetPointsAttr().Get(3)), ground[0])  # rest points, default time
    assert not g.GetPointsAttr().GetTimeSamples()
    assert np.asarray(UsdGeom.PrimvarsAPI(g).GetPrimvar("displayColor").Get(7))[0, 0] == 7
    # the material reads displayColor through UsdPrimvarReader_float3
    mat, _ = UsdShade.MaterialBindingAPI(mesh.GetPrim()).ComputeBoundMaterial()
    surf = mat.ComputeSurfaceSource()[0]
    src = surf.GetInput("emissiveColor").GetConnectedSources()[0][0].source
    reader = UsdShade.Shader(src.GetPrim())
    assert reader.GetIdAttr().Get() == "UsdPrimvarReader_float3"
    assert reader.GetInput("varname").Get() == "displayColor"
    # nothing a renderer's lights could add: no diffuse, and no specular (metallic workflow, F0 from ior)
    assert surf.GetInput("diffuseColor").Get() == Gf.Vec3f(0, 0, 0)
    ior = surf.GetInput("ior").Get()
    assert ((1 - ior) / (1 + ior)) ** 2 == 0.0
    assert surf.GetInput("metallic") is None or surf.GetInput("metallic").Get() in (None, 0.0)
    assert surf.GetInput("useSpecularWorkflow") is None or surf.GetInput("useSpecularWorkflow").Get() in (None, 0)


def test_validators_clean_with_lights_and_texture(tmp_path, rng):
    pts, faces = grid(4)
    tex = tmp_path / "sky.exr"
    import OpenEXR

    OpenEXR.File({"type": OpenEXR.scanlineimage}, {"RGB": np.ones((4, 8, 3), np.float32)}).write(str(tex))
    w = write(tmp_path / "out.usda", frames_data(rng, 5, len(pts)), faces, chunk=2)
    xf = np.eye(4)
    xf[:3, 3] = (0, 2, 0)
    for spec in (LightSpec("dome", "/World/Lights/Sky", texture=str(tex)), LightSpec("distant", "sun", normalize=True),
                 LightSpec("sphere", "bulb", radius=0.2, transform=xf), LightSpec("rect", "panel", width=2, height=1)):
        w.add_light(spec)
    w.close()
    assert validation_errors(str(tmp_path / "out.usda")) == []
    stage = open_stage(tmp_path / "out.usda")
    dome = UsdLux.DomeLight(stage.GetPrimAtPath("/World/Lights/Sky"))
    assert os.path.samefile(dome.GetTextureFileAttr().Get().resolvedPath, tex)
    bulb = stage.GetPrimAtPath("/World/Lights/bulb")
    assert np.allclose(np.asarray(UsdGeom.Xformable(bulb).ComputeLocalToWorldTransform(0))[3, :3], (0, 2, 0))


def test_memory_holds_one_chunk(tmp_path, rng):
    """The writer keeps no more than the open chunk: earlier chunks are files, not layers in memory."""
    pts, faces = grid(3)
    w = write(tmp_path / "out.usda", frames_data(rng, 9, len(pts)), faces, chunk=4)
    layer = w._chunk_layer
    times = layer.ListAllTimeSamples()
    assert sorted(times) == [8.0], times
    w.close()
    chunks = sorted(os.listdir(next((tmp_path / "out_frames").iterdir())))
    assert chunks == ["chunk_000000.usdc", "chunk_000004.usdc", "chunk_000008.usdc", "manifest.usda"]


def test_exception_keeps_complete_frames(tmp_path, rng):
    pts, faces = grid(4)
    data = frames_data(rng, 6, len(pts))
    path = tmp_path / "out.usda"
    with pytest.raises(RuntimeError):
        with AnimationWriter(str(path), chunk=4) as w:
            a = w.add_mesh("a", faces)
            b = w.add_mesh("b", faces)
            for f, d in enumerate(data):
                w.write_frame(f, a, d["points"], colors=d["colors"])
                if f == 5:
                    raise RuntimeError("solver blew up")  # frame 5 has 'a' but not 'b': incomplete
                w.write_frame(f, b, d["points"], colors=d["colors"])
    stage = open_stage(path)
    assert stage.GetEndTimeCode() == 4
    m = UsdGeom.Mesh.Get(stage, "/World/a")
    assert m.GetPointsAttr().GetTimeSamples() == [0.0, 1.0, 2.0, 3.0, 4.0]
    assert np.array_equal(np.asarray(m.GetPointsAttr().Get(4)), data[4]["points"])
    assert validation_errors(str(path)) == []


KILLED = textwrap.dedent("""
    import os, sys
    import numpy as np
    from warpshade.usd import AnimationWriter
    path, frames, value = sys.argv[1], int(sys.argv[2]), float(sys.argv[3])
    w = AnimationWriter(path, chunk=4)
    faces = np.array([[0, 1, 2]])
    name = w.add_mesh("tri", faces)
    for f in range(frames):
        w.write_frame(f, name, np.full((3, 3), value + f, np.float32), colors=np.ones((3, 3), np.float32))
    os._exit(3)  # hard kill: no close, no exception handling
""")


def _killed_run(path, frames, value):
    env = dict(os.environ, PYTHONPATH=REPO)
    r = subprocess.run([sys.executable, "-c", KILLED, str(path), str(frames), str(value)], env=env,
                       capture_output=True, text=True)
    assert r.returncode == 3, r.stderr


def test_hard_kill_leaves_valid_file_with_committed_frames(tmp_path):
    path = tmp_path / "out.usda"
    _killed_run(path, 10, 0.0)  # frames 0..7 are in committed chunks (chunk=4); 8, 9 were in memory
    stage = open_stage(path)
    m = UsdGeom.Mesh.Get(stage, "/World/tri")
    assert m.GetPointsAttr().GetTimeSamples() == [float(f) for f in range(8)]
    assert stage.GetEndTimeCode() == 7
    assert np.asarray(m.GetPointsAttr().Get(7))[0, 0] == 7.0
    assert validation_errors(str(path)) == []


def test_hard_kill_before_first_commit_keeps_previous_file(tmp_path):
    path = tmp_path / "out.usda"
    w = AnimationWriter(str(path), chunk=4)
    name = w.add_mesh("tri", np.array([[0, 1, 2]]))
    for f in range(3):
        w.write_frame(f, name, np.full((3, 3), 100.0 + f, np.float32))
    w.close()
    _killed_run(path, 2, 0.0)  # killed before its first chunk was committed
    stage = open_stage(path)
    m = UsdGeom.Mesh.Get(stage, "/World/tri")
    assert np.asarray(m.GetPointsAttr().Get(2))[0, 0] == 102.0, "previous output must be untouched"
    assert validation_errors(str(path)) == []
    del stage, m
    # a complete new run replaces it and removes the previous run's clip files
    _killed_run(path, 9, 50.0)
    stage = open_stage(path)
    assert np.asarray(UsdGeom.Mesh.Get(stage, "/World/tri").GetPointsAttr().Get(2))[0, 0] == 52.0
    assert len(os.listdir(tmp_path / "out_frames")) == 1


def test_bad_input_names_mesh_frame_vertex(tmp_path):
    w = AnimationWriter(str(tmp_path / "out.usda"))
    name = w.add_mesh("cloth", np.array([[0, 1, 2]]))
    bad = np.zeros((3, 3), np.float32)
    bad[1, 2] = np.nan
    with pytest.raises(ValueError, match=r"'cloth' frame 4: vertex 1 is not finite"):
        w.write_frame(4, name, bad)
    w.write_frame(5, name, np.zeros((3, 3)))
    with pytest.raises(ValueError, match="frame 4 written after frame 5"):
        w.write_frame(4, name, np.zeros((3, 3)))
    with pytest.raises(ValueError, match=r"colors must have shape \(3, 3\)"):
        w.write_frame(6, name, np.zeros((3, 3)), colors=np.zeros((2, 3)))
    with pytest.raises(ValueError, match="4 points, topology has 3"):
        w.write_frame(6, name, np.zeros((4, 3)))
    with pytest.raises(ValueError, match="output must end in"):
        AnimationWriter(str(tmp_path / "out.abc"))
    w.abort()


def test_back_side_lies_just_behind_the_front(tmp_path):
    """A back-side mesh's points are the front's moved BACK_SIDE_OFFSET of the mesh's size along the
    back's normals, animated and static: coincident triangles showed the back's colours in specks
    through the front in Blender's Cycles (docs/blender_check.py)."""
    from warpshade.usd.writer import BACK_SIDE_OFFSET

    pts, faces = grid(5)
    up = np.tile(np.float32([0.0, 1.0, 0.0]), (len(pts), 1))
    w = AnimationWriter(str(tmp_path / "o.usda"), chunk=2)
    cloth = w.add_mesh("Cloth", faces)
    back = w.add_back_side(cloth)
    ground = w.add_mesh("Ground", faces, points=pts * 3, normals=up)
    gback = w.add_back_side(ground)
    for f in range(3):
        moved = pts + np.float32([0.0, 0.1 * f, 0.0])
        w.write_frame(f, cloth, moved, up, colors=np.ones((len(pts), 3), np.float32))
        w.write_frame(f, back, moved, -up, colors=np.zeros((len(pts), 3), np.float32))
        w.write_frame(f, ground, None, colors=np.ones((len(pts), 3), np.float32))
        w.write_frame(f, gback, None, colors=np.ones((len(pts), 3), np.float32))
    w.close()
    stage = open_stage(tmp_path / "o.usda")
    size = np.sqrt(2.0)  # the unit grid's bounding-box diagonal
    for f in range(3):
        front = np.asarray(UsdGeom.Mesh(stage.GetPrimAtPath("/World/Cloth")).GetPointsAttr().Get(f))
        behind = np.asarray(UsdGeom.Mesh(stage.GetPrimAtPath("/World/Cloth_back")).GetPointsAttr().Get(f))
        # float32 points of magnitude ~1: 1e-7 absolute
        np.testing.assert_allclose(behind - front, np.tile([0.0, -BACK_SIDE_OFFSET * size, 0.0], (len(pts), 1)),
                                   atol=1e-7)
    front = np.asarray(UsdGeom.Mesh(stage.GetPrimAtPath("/World/Ground")).GetPointsAttr().Get(0))
    behind = np.asarray(UsdGeom.Mesh(stage.GetPrimAtPath("/World/Ground_back")).GetPointsAttr().Get(0))
    np.testing.assert_allclose(behind - front, np.tile([0.0, -BACK_SIDE_OFFSET * 3 * size, 0.0], (len(pts), 1)),
                               atol=1e-7)


def test_a_run_that_writes_nothing_removes_the_directories_it_made(tmp_path):
    """`--out` into missing directories creates them (mkdir -p); a run that then fails before its
    first frame (abort with nothing committed) removes the ones it made, deepest first, but not a
    directory that existed before or one that has someone else's file in it now."""
    made = tmp_path / "a" / "b" / "c"
    w = AnimationWriter(str(made / "out.usda"), chunk=4)
    assert made.is_dir()
    w.abort()
    assert not (tmp_path / "a").exists() and tmp_path.is_dir()

    (tmp_path / "a").mkdir()
    w = AnimationWriter(str(made / "out.usda"), chunk=4)
    (tmp_path / "a" / "b" / "note.txt").write_text("someone else's")
    w.abort()
    assert not made.exists() and (tmp_path / "a" / "b" / "note.txt").exists()

    w = AnimationWriter(str(made / "out.usda"), chunk=4)
    name = w.add_mesh("tri", np.array([[0, 1, 2]]))
    w.write_frame(0, name, np.zeros((3, 3), np.float32), colors=np.ones((3, 3), np.float32))
    w.close()
    assert (made / "out.usda").exists()  # a run that wrote its output keeps the directories
