"""The ray-traced reference transfer: analytic unoccluded case, occlusion, convergence, CLI."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import trimesh

from conftest import warp_asset
from warpshade.cli import main as cli_main
from helpers import clamped_cosine_zh, rel_err, unoccluded_transfer
from warpshade.geometry import TriMesh
from warpshade.usd import load_mesh
from warpshade.visibility import get_method

def test_contract_zh_constants():
    np.testing.assert_allclose(clamped_cosine_zh(5), [math.sqrt(math.pi) / 2, math.sqrt(math.pi / 3),
                                                      math.sqrt(5 * math.pi) / 8, 0, -math.sqrt(math.pi) / 16],
                               atol=1e-12)


@pytest.mark.parametrize("scale", [1e-4, 1.0, 1e4])
def test_convex_mesh_equals_unoccluded(scale):
    ico = trimesh.creation.icosphere(2)
    m = TriMesh(ico.vertices * scale, ico.faces)
    ref = get_method("reference")(m, order=5, rays=4096)
    t = ref.update().numpy()
    # Pure Monte-Carlo error (no occlusion on a convex mesh); stratified 64x64 measured 0.26 %.
    assert rel_err(t, unoccluded_transfer(m.normals, 5)) < 0.005


def test_closed_shell_blocks_everything():
    # A small quad receiver inside a closed box: every ray hits the box.
    box = TriMesh(trimesh.creation.box(extents=(4, 4, 4)).vertices, trimesh.creation.box().faces)
    recv = TriMesh([[0, 0, 0], [0.1, 0, 0], [0, 0.1, 0]], [[0, 1, 2]])
    t = get_method("reference")(recv, order=3, rays=256, occluders=[box]).update().numpy()
    assert np.abs(t).max() == 0.0


def test_half_space_blocker():
    # A vertical wall x = 0.01 just beside an upward-facing receiver blocks the half x > 0 of the hemisphere, so T_0 = y_0 * π/2 (half the cosine mass).
    recv = TriMesh([[0, 0, 0], [-0.001, 0, 0], [0, -0.001, 0]], [[0, 1, 2]])
    assert recv.normals[0, 2] > 0.999
    # rectangle x = 0.01, |y| <= 1e4, -1 <= z <= 1e4: misses only directions within ~1e-6 of the wall
    wall = TriMesh([[0.01, -1e4, -1], [0.01, 1e4, -1], [0.01, 1e4, 1e4], [0.01, -1e4, 1e4]], [[0, 1, 2], [0, 2, 3]])
    t = get_method("reference")(recv, order=2, rays=4096, occluders=[wall]).update().numpy()
    y0 = 0.5 / math.sqrt(math.pi)
    np.testing.assert_allclose(t[0, 0], y0 * math.pi / 2, rtol=0.01)
    # y_3 = -c x: the open half x < 0 gives +c ∫ |x| cos = c * 2/3 (projected solid angle of x<0 half).
    c = math.sqrt(3 / (4 * math.pi))
    np.testing.assert_allclose(t[0, 3], c * 2 / 3, rtol=0.02)


def test_error_falls_at_least_like_inverse_sqrt_rays():
    bear = load_mesh(warp_asset("bear.usd"))
    R = get_method("reference")
    truth = R(bear, order=4, rays=16384, seed=99).update().numpy()
    errs = [rel_err(R(bear, order=4, rays=n, seed=1).update().numpy(), truth) for n in (64, 256, 1024)]
    # each 4x more rays must cut the error by at least 2x (1/sqrt(N)); 1.7 leaves room for noise
    # in the truth itself (measured ratios ~2.3-3).
    assert errs[0] / errs[1] > 1.7 and errs[1] / errs[2] > 1.7, errs


def test_deterministic_with_seed():
    bear = load_mesh(warp_asset("bear.usd"))
    a = get_method("reference")(bear, order=3, rays=64, seed=5).update().numpy()
    b = get_method("reference")(bear, order=3, rays=64, seed=5).update().numpy()
    assert np.array_equal(a, b)


def test_launch_in_vertex_blocks_changes_nothing(monkeypatch):
    # the transfer is cut into launches of about RAYS_PER_LAUNCH rays (so Ctrl-C is answered between them);
    # each vertex keeps its index, hence its random stream and its own faces: bit-identical to one launch
    import warpshade.visibility.reference.method as ref

    from warpshade.bench.meshes import grid

    gp, gf = grid(6, size=1.0)
    ico = trimesh.creation.icosphere(1, radius=0.2)
    m = TriMesh(np.concatenate([gp, np.asarray(ico.vertices) + (0, 0, 0.25)]),
                np.concatenate([gf, np.asarray(ico.faces) + len(gp)]))
    method = get_method("reference")(m, order=3, rays=64)
    monkeypatch.setattr(ref, "RAYS_PER_LAUNCH", 1 << 30)
    one = method.update().numpy().copy()
    launches = []
    real = ref.wp.launch
    monkeypatch.setattr(ref.wp, "launch", lambda *a, **kw: launches.append(kw["dim"]) or real(*a, **kw))
    monkeypatch.setattr(ref, "RAYS_PER_LAUNCH", 64 * 7)  # blocks of 7 vertices
    blocked = method.update().numpy()
    assert sum(launches) == m.num_vertices and max(launches) == 7 and len(launches) == -(-m.num_vertices // 7)
    assert np.array_equal(blocked, one)


def test_cli_writes_contract_files(tmp_path):
    out, stats = tmp_path / "t.npz", tmp_path / "s.json"
    rc = cli_main(["transfer", warp_asset("bear.usd"), "--method", "reference", "--rays", "64", "--order", "3",
                   "--repeat", "2", "--save", str(out), "--json", str(stats)])
    assert rc == 0
    z = np.load(out)
    assert z["points"].dtype == np.float32 and z["points"].shape == (1986, 3)
    assert z["normals"].dtype == np.float32 and z["faces"].dtype == np.int32 and z["faces"].shape == (3968, 3)
    assert z["transfer"].shape == (1986, 9) and z["transfer"].dtype == np.float32
    s = json.loads(stats.read_text())
    assert s["method"] == "reference" and s["order"] == 3 and s["vertices"] == 1986 and s["triangles"] == 3968
    assert s["seconds"] > 0 and s["knobs"]["rays"] == 64


def test_cli_bad_knob_is_an_error(tmp_path, capsys):
    rc = cli_main(["transfer", warp_asset("bear.usd"), "--method", "reference", "--bogus", "1",
                   "--save", str(tmp_path / "t.npz")])
    assert rc == 1 and "--bogus" in capsys.readouterr().err
