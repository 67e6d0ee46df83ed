"""Mesh input: formats, triangulation, validation errors that name the culprit, normals."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh
import warp as wp

from conftest import warp_asset
from warpshade.geometry import MeshError, TriMesh, vertex_normals, vertex_normals_np
from warpshade.usd import load_mesh
from warpshade.usd import triangulate


def test_load_warp_assets_and_ngons():
    bunny = load_mesh(warp_asset("bunny.usd"))
    assert bunny.num_vertices == 6102 and bunny.num_faces == 12200
    rocks = load_mesh(warp_asset("rocks.usd"))  # up to 17-gons, fan-triangulated
    assert rocks.faces.max() < rocks.num_vertices
    assert np.allclose(np.linalg.norm(rocks.normals, axis=1), 1, atol=1e-5)


def test_triangulate_mixed_polygons():
    counts = np.array([3, 4, 5])
    idx = np.arange(12)
    tri = triangulate(counts, idx, "t")
    assert tri.tolist() == [[0, 1, 2], [3, 4, 5], [3, 5, 6], [7, 8, 9], [7, 9, 10], [7, 10, 11]]
    with pytest.raises(MeshError, match="sum to"):
        triangulate(np.array([3, 3]), np.arange(5), "t")


@pytest.mark.parametrize("ext", [".obj", ".ply", ".stl"])
def test_trimesh_formats_round_trip(tmp_path, ext):
    box = trimesh.creation.box()
    path = tmp_path / f"box{ext}"
    box.export(path)
    m = load_mesh(path)
    assert m.num_faces == 12 and m.num_vertices == 8


def test_errors_name_the_culprit(tmp_path):
    pts = np.zeros((4, 3))
    pts[2] = np.nan
    with pytest.raises(MeshError, match="vertex 2"):
        TriMesh(pts, [[0, 1, 3]], name="m")
    with pytest.raises(MeshError, match="face 1"):
        TriMesh(np.eye(3), [[0, 1, 2], [0, 1, 3]], name="m")
    with pytest.raises(MeshError, match="empty"):
        TriMesh(np.zeros((0, 3)), np.zeros((0, 3)), name="m")
    with pytest.raises(MeshError, match="nosuch.obj"):
        load_mesh(tmp_path / "nosuch.obj")
    bad = tmp_path / "bad.usda"
    bad.write_text("#usda 1.0\ndef Mesh garbage {")
    with pytest.raises(MeshError, match="bad.usda"):
        load_mesh(bad)
    with pytest.raises(MeshError, match="/nope"):
        load_mesh(warp_asset("bunny.usd"), prim="/nope")


def test_degenerate_triangles_tolerated():
    pts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]], float)
    m = TriMesh(pts, [[0, 1, 2], [0, 1, 3], [1, 1, 2]])  # collinear and repeated-index faces
    np.testing.assert_allclose(m.normals[:3], [[0, 0, 1]] * 3, atol=1e-6)
    assert np.isfinite(m.normals).all()


def test_normals_kernel_matches_numpy():
    m = load_mesh(warp_asset("bear.usd"))
    got = vertex_normals(wp.array(m.points, dtype=wp.vec3), wp.array(m.faces, dtype=wp.int32)).numpy()
    np.testing.assert_allclose(got, vertex_normals_np(m.points, m.faces), atol=1e-5)


def test_angle_weighting_is_tessellation_independent():
    # A vertex at a cube corner: three faces meet at right angles whatever their triangulation.
    box = trimesh.creation.box()
    n = vertex_normals_np(box.vertices, box.faces)
    np.testing.assert_allclose(np.abs(n), 1 / np.sqrt(3), atol=1e-12)
