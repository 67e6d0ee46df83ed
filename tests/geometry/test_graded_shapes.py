"""Graded Cube and Plane tessellations (warpshade.geometry.shapes.Grading): closed and conforming,
rows where the rule puts them, fewer vertices. Expected spacings are worked out in the tests from the
rule's formula (GRADE_SLOPE x distance, clamped), not from the code's spacing function."""

import numpy as np
import pytest

from warpshade.geometry.shapes import (GRADE_LEVELS, GRADE_SLOPE, Grading, box_segments, box_shape, gprim_shape,
                                       gprim_vertex_count, plane_shape)

EDGE = 0.025
SCALE = np.array([3.0, 3.0, 0.05])  # a 3 x 3 m floor slab 5 cm thick, a unit Cube scaled
# a cloth's region (1.2 m square, down to the floor) and a pedestal standing on the top face, off centre
BOXES = [[[-0.4, -0.7, 0.025], [0.8, 0.5, 0.9]], [[0.1, -0.2, 0.025], [0.5, 0.2, 0.6]]]
DIAG = 4.3


def _floor(boxes=BOXES):
    return gprim_shape("cube", {"size": 1.0}, SCALE, EDGE, Grading(boxes, DIAG))


def _welded(v, f):
    key = np.round(v * 1e6).astype(np.int64)
    _, inv = np.unique(key, axis=0, return_inverse=True)
    return inv.ravel()[f]


def test_the_graded_box_is_closed_and_conforming():
    """Welded by position, every edge is in exactly two triangles, once each way (no T-junction, no crack,
    one orientation), no triangle is degenerate, and the enclosed volume is the slab's."""
    v, f = _floor()
    w = v * SCALE
    F = _welded(w, f)
    edges = np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]])
    _, counts = np.unique(np.sort(edges, axis=1), axis=0, return_counts=True)
    assert set(counts) == {2}
    _, directed = np.unique(edges, axis=0, return_counts=True)
    assert set(directed) == {1}
    area = np.linalg.norm(np.cross(w[f[:, 1]] - w[f[:, 0]], w[f[:, 2]] - w[f[:, 0]]), axis=1) / 2
    assert area.min() > 1e-5  # the smallest is a fan triangle of a 2.5 cm x 2.5 cm cell: 7.8e-5 m2
    volume = np.einsum("ij,ij->", w[f[:, 0]], np.cross(w[f[:, 1]], w[f[:, 2]])) / 6
    assert volume == pytest.approx(3 * 3 * 0.05, rel=1e-9)


def test_rims_have_the_same_vertices_on_both_faces():
    """Along each of the 12 rims the two faces meeting there have vertices at the same positions."""
    v, f = _floor()
    half = 0.5
    faces = {}  # (axis, sign) -> the vertices on that face
    for axis in range(3):
        for sign in (1, -1):
            on = np.isclose(v[:, axis], sign * half)
            faces[axis, sign] = {tuple(p) for p in np.round(v[on], 9)}
    for a in range(3):
        for b in range(a + 1, 3):
            for sa in (1, -1):
                for sb in (1, -1):
                    rim_a = {p for p in faces[a, sa] if np.isclose(p[b], sb * half)}
                    rim_b = {p for p in faces[b, sb] if np.isclose(p[a], sa * half)}
                    assert rim_a == rim_b and len(rim_a) >= 2


def _rows(points, axis):
    return np.unique(np.round(points[:, axis], 9))


def _asked(t, axis, boxes, height_of):
    """The rule's spacing at coordinates t along ``axis`` of the top face: GRADE_SLOPE x the distance to
    the nearest box in front, clamped to [EDGE, most]."""
    most = min(EDGE * 2 ** GRADE_LEVELS, DIAG / 20)
    d = np.full(len(t), np.inf)
    for lo, hi in boxes:
        along = np.maximum(np.maximum(lo[axis] - t, t - hi[axis]), 0)
        d = np.minimum(d, np.hypot(along, height_of(lo, hi)))
    return np.clip(GRADE_SLOPE * d, EDGE, most)


def test_top_face_rows_follow_the_rule_fine_near_coarse_far():
    """On the top face: each gap between rows is at most the spacing the rule asks for at some row of the
    uniform grid inside it (so never coarser than the rule), every row of the uniform grid is kept
    where the rule asks for the target edge (over the region), and gaps double away from it up to
    2**GRADE_LEVELS edges (3 m / 120 = 2.5 cm rows)."""
    v, _ = _floor()
    top = v[np.isclose(v[:, 2], 0.5)] * SCALE
    base = np.linspace(-1.5, 1.5, 121)
    for axis in (0, 1):
        rows = _rows(top, axis)  # the top face's own rows and its fan centres (none on the top face: its rims are its rows)
        assert set(np.round(rows, 6)) <= set(np.round(base, 6))
        asked = _asked(base, axis, BOXES, lambda lo, hi: max(lo[2] - 0.025, 0.0))
        for a, b in zip(rows[:-1], rows[1:]):
            inside = (base > a + 1e-9) & (base < b - 1e-9)
            assert b - a <= 0.025 + 1e-9 or (b - a) <= asked[inside].max() + 1e-9
        lo, hi = min(bx[0][axis] for bx in BOXES), max(bx[1][axis] for bx in BOXES)
        over = base[(base >= lo) & (base <= hi)]
        assert set(np.round(over, 6)) <= set(np.round(rows, 6))  # every row over the region
        gaps = np.diff(rows)
        assert gaps.max() == pytest.approx(2 ** GRADE_LEVELS * 0.025)  # far from it, the coarsest


def test_faces_facing_away_are_coarsest():
    """The bottom face (nothing below it) has the coarsest rows: 2**GRADE_LEVELS edges (the last gap of
    a side the rest), its rims only where the sides meet it."""
    v, _ = _floor()
    bottom = v[np.isclose(v[:, 2], -0.5)] * SCALE
    for axis in (0, 1):
        gaps = np.diff(_rows(bottom, axis))
        assert np.allclose(gaps[:-1], 2 ** GRADE_LEVELS * 0.025) and gaps[-1] <= 2 ** GRADE_LEVELS * 0.025 + 1e-9


def test_vertex_count_bounds():
    """Fewer than a third of the uniform slab's vertices, more than the region's footprint holds at the
    target edge (1.2 m x 1.2 m at 2.5 cm: 49 x 49 rows)."""
    n = len(_floor()[0])
    uniform = gprim_vertex_count("cube", {"size": 1.0}, SCALE, EDGE)
    assert uniform == 30734
    assert 49 * 49 < n < uniform / 3
    assert gprim_vertex_count("cube", {"size": 1.0}, SCALE, EDGE, Grading(BOXES, DIAG)) == n


def test_without_a_grading_the_shapes_are_the_uniform_ones():
    """No grading: gprim_shape is box_shape / plane_shape of box_segments, array for array."""
    v, f = gprim_shape("cube", {"size": 1.0}, SCALE, EDGE)
    v0, f0 = box_shape([1.0] * 3, box_segments(SCALE, EDGE))
    assert np.array_equal(v, v0) and np.array_equal(f, f0)
    v, f = gprim_shape("plane", {"width": 2.0, "length": 1.0}, (1, 1, 1), EDGE)
    v0, f0 = plane_shape(2.0, 1.0, (80, 40))
    assert np.array_equal(v, v0) and np.array_equal(f, f0)


def test_a_region_with_nothing_coarsens_every_face_and_stays_closed():
    v, f = _floor(boxes=np.zeros((0, 2, 3)))
    F = _welded(v * SCALE, f)
    edges = np.sort(np.concatenate([F[:, [0, 1]], F[:, [1, 2]], F[:, [2, 0]]]), axis=1)
    assert set(np.unique(edges, axis=0, return_counts=True)[1]) == {2}
    assert len(v) < 2 * 17 * 17 + 4 * 17 * 3 + 100  # 16 squares of 20 cm (and a part) across each side


def test_a_graded_plane_counts_boxes_on_both_sides():
    """A Plane is seen from both sides: a box below it makes it fine there as one above does."""
    above = gprim_shape("plane", {"width": 2.0, "length": 2.0}, (1, 1, 1), EDGE,
                        Grading([[[-0.2, -0.2, 0.1], [0.2, 0.2, 0.5]]], DIAG))[0]
    below = gprim_shape("plane", {"width": 2.0, "length": 2.0}, (1, 1, 1), EDGE,
                        Grading([[[-0.2, -0.2, -0.5], [0.2, 0.2, -0.1]]], DIAG))[0]
    assert np.array_equal(above, below)
    rows = _rows(above, 0)
    assert np.allclose(np.diff(rows[(rows > -0.2) & (rows < 0.2)]), EDGE)  # 0.1 m up: the target edge
    assert np.diff(rows).max() > 4 * EDGE
