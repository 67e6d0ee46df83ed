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


def test_axial_shapes_have_caps_of_their_own_and_stay_closed():
    """A cylinder's caps have vertices of their own (each cap's rim 48 vertices, the side's rims 48
    each, at the same positions), every vertex's normal is its cap's or horizontal, and the surface is
    a closed solid wound outward. Counts for r = 0.5, height 1, edge 0.1: 48 sections (2 pi r / 0.1 =
    32 < the 48 minimum), 5 rings and a centre a cap, 11 rings on the side."""
    from warpshade.geometry import closed_orientation
    from warpshade.geometry.shapes import axial_shape

    v, f = axial_shape("cylinder", 0.5, 1.0, 0.1)
    assert len(v) == 2 * (5 * 48 + 1) + 11 * 48
    n = vertex_normals_np(v, f)
    rim = (np.abs(np.abs(v[:, 2]) - 0.5) < 1e-9) & (np.abs(np.linalg.norm(v[:, :2], axis=1) - 0.5) < 1e-9)
    on_cap = np.abs(n[:, 2]) > 1 - 1e-9
    side = np.abs(n[:, 2]) < 1e-9
    assert (on_cap | side).all() and (rim & on_cap).sum() == (rim & side).sum() == 96
    assert closed_orientation(v, f) == 1
    for kind in ("cone", "capsule"):
        assert closed_orientation(*axial_shape(kind, 0.5, 1.0, 0.1)) == 1, kind


def test_box_faces_are_grids_of_their_own():
    """Every vertex of a box lies in one face (its normal is that face's); each triangle spans two
    adjacent rows of vertices in both directions along its face, so values constant along rows
    (a contact shadow along a rim) interpolate as a function of the distance to the rim alone (a
    triangle spanning three rows draws a tooth at each rim vertex)."""
    from warpshade.geometry.shapes import box_shape

    v, f = box_shape([1.2, 0.8, 0.8], [22, 15, 15])
    n = vertex_normals_np(v, f)
    np.testing.assert_allclose(np.abs(n).max(axis=1), 1.0, atol=1e-12)
    for axis in range(3):
        face = f[np.abs(n[f[:, 0], axis]) > 0.5]
        for k in (k for k in range(3) if k != axis):
            row = np.searchsorted(np.unique(v[face, k]), v[face, k])  # each corner's row along k
            assert (row.max(axis=1) - row.min(axis=1) == 1).all(), (axis, k)


def test_a_box_split_at_its_rims_is_still_a_closed_solid():
    """Closedness is the surface's: vertices at one position count as one (hemiraster's back-face
    culling and the sphere sets' inside points need it); faces moved apart by 1 mm are open."""
    from warpshade.geometry import closed_orientation
    from warpshade.geometry.shapes import box_shape
    from warpshade.visibility.spheres.fitting import fit_leaf_spheres

    v, f = box_shape([1.0, 1.0, 1.0], [22, 22, 22])
    assert closed_orientation(v, f) == 1 and closed_orientation(v, f[:, ::-1]) == -1
    apart = v + 1e-3 * vertex_normals_np(v, f)  # each face moved out along its own normal
    assert closed_orientation(apart, f) == 0
    assert fit_leaf_spheres(v, f, 4, restarts=1)[3]  # closed: fitted with inside points


def test_stitching_joins_open_borders_not_parts_touching_inside():
    """Only vertices on open borders are stitched: a ball resting on a grid's inner vertex keeps its
    own vertex there (the two are different surfaces), a box's split rims are joined."""
    from warpshade.geometry.mesh import stitched_faces
    from warpshade.geometry.shapes import box_shape

    ball = trimesh.creation.icosphere(subdivisions=1, radius=0.5)
    bottom = int(np.argmin(ball.vertices[:, 2]))
    g = np.stack(np.meshgrid(np.linspace(-1, 1, 3), np.linspace(-1, 1, 3), indexing="ij"), -1).reshape(-1, 2)
    ground = np.c_[g, np.zeros(9)] + ball.vertices[bottom] * [0, 0, 1]  # its centre vertex under the ball
    ground_faces = np.array([[0, 3, 4], [0, 4, 1], [1, 4, 5], [1, 5, 2], [3, 6, 7], [3, 7, 4], [4, 7, 8], [4, 8, 5]])
    points = np.concatenate([ball.vertices, ground])
    faces = np.concatenate([ball.faces, ground_faces + len(ball.vertices)])
    assert np.array_equal(points[len(ball.vertices) + 4], points[bottom])
    np.testing.assert_array_equal(stitched_faces(points, faces), faces)
    v, f = box_shape([1.0, 1.0, 1.0], [22, 22, 22])
    assert len(np.unique(stitched_faces(v, f))) == 6 * 23 * 23 - 12 * 23 + 8  # shared rims, corners once


def test_import_warpshade_loads_no_warp_and_no_usd():
    # the warpshade command starts its workers before it loads Warp and reads the scene with USD
    import os
    import subprocess
    import sys

    from helpers import REPO

    code = ("import sys, warpshade\n"
            "assert 'warp' not in sys.modules and 'pxr' not in sys.modules, 'import warpshade loaded Warp or USD'\n"
            "sys.exit(0 if warpshade.__version__ else 1)\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=dict(os.environ, PYTHONPATH=REPO))
    assert proc.returncode == 0, proc.stderr[-2000:]
