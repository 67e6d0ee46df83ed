"""Temporal reuse (warpshade.visibility.reuse): tolerance 0 is the method itself value for value, a
scene that does not move is never recomputed, a moved vertex's cluster is recomputed to exactly the
method's value while far clusters keep theirs; the pipeline with reuse 0 writes what it writes without."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import warpshade as ws
from warpshade.script import pipeline as make_pipeline
from warpshade.bench.meshes import grid, wrinkled_cloth
from warpshade.geometry.mesh import TriMesh
from warpshade.visibility import get_method
from warpshade.visibility.reuse import TemporalReuse, median_edge, kd_clusters

ORDER = 4


def _sequence(n: int = 20, frames: int = 5):
    bm = wrinkled_cloth(n)
    rest = bm.rest.points
    return bm.rest, [rest + (bm.frame - rest) * t for t in np.linspace(0.0, 1.0, frames)]


@pytest.mark.parametrize("method,knobs", [("hemiraster", {}), ("reference", {"rays": 16})])
def test_tolerance_zero_is_the_method_bit_for_bit(method, knobs):
    rest, frames = _sequence()
    cls = get_method(method)
    plain, reused = cls(rest, order=ORDER, **knobs), TemporalReuse(cls(rest, order=ORDER, **knobs), 0.0)
    for f in frames + [frames[-1], frames[2]]:  # a repeated frame, then a jump back
        a = plain.update(f).numpy()
        b = reused.update(f).numpy()
        assert np.array_equal(a, b)
        assert np.array_equal(plain.normals.numpy(), reused.normals.numpy())


def test_static_scene_reuses_everything():
    rest, frames = _sequence()
    m = TemporalReuse(get_method("hemiraster")(rest, order=ORDER), 0.0)
    first = m.update(frames[3]).numpy().copy()
    assert m.last_computed == rest.num_vertices  # the first frame computes every receiver
    for _ in range(3):
        again = m.update(frames[3]).numpy()
        assert m.last_computed == 0
        assert np.array_equal(again, first)
    assert m.stats()["reuse_computed_fraction"] == pytest.approx(1 / 4)


@pytest.mark.parametrize("method,knobs", [("hemiraster", {}), ("reference", {"rays": 16})])
def test_reset_starts_afresh(method, knobs):
    # a tolerance no motion reaches: without the reset frame 4 would keep frame 0's transfer
    rest, frames = _sequence()
    cls = get_method(method)
    plain, reused = cls(rest, order=ORDER, **knobs), TemporalReuse(cls(rest, order=ORDER, **knobs), 1e6)
    for f in frames[:3]:
        reused.update(f)
    assert reused.last_computed == 0
    reused.reset()
    b = reused.update(frames[4]).numpy().copy()
    assert reused.last_computed == rest.num_vertices
    a = plain.update(frames[4]).numpy().copy()  # a view of what the next update overwrites
    assert not np.array_equal(a, plain.update(frames[0]).numpy())  # the sequence changes the transfer
    assert np.array_equal(a, b)


def test_moved_vertex_is_recomputed_far_ones_reused():
    n = 20
    pts, faces = grid(n)
    pts[:, 2] = 0.05 * np.sin(7 * pts[:, 0]) * np.cos(5 * pts[:, 1])  # not flat: something to shadow
    rest = TriMesh(pts, faces, name="bumpy sheet")
    cls = get_method("hemiraster")
    # tolerance 0.1 rad: the moved vertex's own cluster sees its normals turn by ~2 * 0.01 m / h = 0.36 rad
    # (h = 1/19 m, the edge); a cluster 0.5 m away sees the moved cluster (radius <= 0.1 m) move by at most
    # 0.02 m / 0.3 m, weighted by its view share (0.15 m / 0.3 m)^2: 0.017 rad
    m = TemporalReuse(cls(rest, order=ORDER), 0.1)
    before = m.update(pts).numpy().copy()
    v = (n // 2) * n + n // 2  # a vertex in the middle
    moved = pts.copy()
    moved[v, 2] += 0.01
    after = m.update(moved).numpy()
    assert 0 < m.last_computed < len(pts)
    truth = cls(rest, order=ORDER).update(moved).numpy()
    own = np.flatnonzero(m.labels == m.labels[v])
    assert v in own
    assert np.array_equal(after[own], truth[own])  # recomputed: exactly the method's value this frame
    assert not np.array_equal(after[v], before[v])
    far = np.flatnonzero(np.linalg.norm(pts - pts[v], axis=1) > 0.5)
    assert len(far) and np.array_equal(after[far], before[far])  # reused: last frame's values


def test_rigid_translation_costs_nothing():
    rest, frames = _sequence()
    # 1e-4 rad: float32 rounding of the shifted positions (~3e-8 m) over the edge (1/19 m) is ~1e-6 rad
    m = TemporalReuse(get_method("hemiraster")(rest, order=ORDER), 1e-4)
    first = m.update(frames[2]).numpy().copy()
    m.update(frames[2] + np.float32(0.25))
    assert m.last_computed == 0
    assert np.array_equal(m.transfer.numpy(), first)


def test_bad_tolerance_is_named():
    rest, _ = _sequence(8, 2)
    with pytest.raises(ValueError, match="reuse tolerance"):
        TemporalReuse(get_method("hemiraster")(rest, order=ORDER), -0.1)


def test_helpers():
    pts, faces = grid(5, size=4.0)
    assert median_edge(pts, faces) == pytest.approx(1.0)
    order, start = kd_clusters(pts, 4)
    assert sorted(order.tolist()) == list(range(25)) and start[-1] == 25 and np.all(np.diff(start) <= 4)
    for a, b in zip(start[:-1], start[1:]):  # compact: a cluster of <= 4 grid points spans <= 2 edges per axis
        assert np.ptp(pts[order[a:b]], axis=0).max() <= 2.0 + 1e-6


def _small_scene():
    return ws.make_scene(ws.ground(size=2.0, resolution=9), ws.cloth_grid(size=0.6, resolution=8, height=0.3), ws.sky())


def test_pipeline_reuse_zero_shades_as_without():
    pipe = make_pipeline(_small_scene(), frames=4, reuse=None)
    frames = list(pipe.simulate())
    plain = pipe.shader.build()
    reused = dataclasses.replace(pipe.shader, reuse=0.0).build()
    for f, geo in frames + [frames[-1]]:
        a, b = plain(f, geo), reused(f, geo)
        keys = [k for k in a if not (isinstance(k, str) and k.startswith("_"))]
        assert keys and sorted(map(str, keys)) == sorted(map(str, (k for k in b if not str(k).startswith("_"))))
        for k in keys:
            for x, y in zip(a[k], b[k]):
                assert (x is None and y is None) or np.array_equal(x, y), (f, k)


def test_default_is_on_where_the_method_computes_rows_and_off_is_the_method_value_for_value():
    from warpshade.pipeline.config import REUSE, REUSE_CHUNK, resolve_reuse

    scene = _small_scene()
    on = make_pipeline(scene, frames=6)
    assert {g.method for g in on.groups} == {"hemiraster"}
    assert (on.reuse, on.chunk, on.shader.reuse) == (REUSE, REUSE_CHUNK, REUSE)
    off = make_pipeline(scene, frames=6, reuse=None)
    assert (off.reuse, off.chunk, off.shader.reuse) == (None, None, None)
    # off shades as reuse 0, the method itself value for value (test_pipeline_reuse_zero_shades_as_without);
    # the default does not: it keeps transfer somewhere in these frames
    plain, reused = off.shader.build(), on.shader.build()
    differs = False
    for f, geo in off.simulate():
        a, b = plain(f, geo), reused(f, geo)
        keys = [k for k in a if not (isinstance(k, str) and k.startswith("_"))]
        differs |= any(not np.array_equal(x, y) for k in keys for x, y in zip(a[k], b[k]) if x is not None)
    assert differs  # the default reuses somewhere in these frames: it is on
    # where the method recomputes every receiver whenever one is due, the default is off
    assert resolve_reuse("auto", ["hemiraster", None]) == REUSE
    assert resolve_reuse("auto", ["reference"]) is None and resolve_reuse("auto", [None]) is None
    assert resolve_reuse("auto", ["hemiraster", "reference"]) is None
    assert resolve_reuse(None, ["hemiraster"]) is None and resolve_reuse(0.5, ["reference"]) == 0.5
    assert make_pipeline(scene, frames=2, method="reference", knobs={"rays": 4}).reuse is None
    for bad in ("sometimes", -1.0, float("nan")):
        with pytest.raises(ValueError):
            resolve_reuse(bad, ["hemiraster"])
    with pytest.raises(ValueError, match="reuse_chunk"):
        make_pipeline(scene, frames=2, reuse=None, reuse_chunk=4)


def test_back_pass_computes_the_two_sided_rows_as_a_full_update():
    from warpshade.pipeline.shading import _Group

    pipe = make_pipeline(_small_scene(), frames=3)
    (f, geo), = [x for x in pipe.simulate()][-1:]
    spec = next(g for g in pipe.groups if any(g.two_sided))
    group = _Group(spec, ORDER, "cpu")
    _, (pts, _, normals) = group.update(geo)
    _, back = group.update_back()
    rows = group._two_rows
    assert 0 < len(rows) < len(pts)  # the cloth is two-sided, the ground is not
    full = type(group.back_method)(group.back_method.mesh, order=ORDER, **spec.knobs).update(pts, -normals).numpy()
    assert np.array_equal(back[rows], full[rows])
    assert not back[group._one_rows].any()  # one-sided members' back rows are not computed (unused)


def test_animation_bench_judges_every_kth_frame_and_reuse_zero_matches():
    from warpshade.bench.animation import format_animation, run_animation

    cfgs = [{"method": "hemiraster", "knobs": {}, "reuse": None}, {"method": "hemiraster", "knobs": {}, "reuse": 0.0}]
    res = run_animation("walk", frames=3, every=2, order=3, rays=64, cache_dir=None, configs=cfgs, log=lambda m: None)
    assert res["judged_frames"] == [0, 2]
    plain, reused = res["records"]
    assert [e["frame"] for e in plain["errors"]] == [0, 2]
    assert plain["errors"] == reused["errors"]  # reuse 0 is the method itself
    # a 64-ray truth is itself ~1/sqrt(64) = 12 % off: the bound says the errors are a comparison, not garbage
    assert 0.0 < plain["error_mean"] < 0.2 and reused["computed_fraction"] == 1.0  # the walker moves every frame
    assert "reuse 0" in format_animation(res)


def test_animation_bench_variant_knobs_are_parsed_checked_and_run():
    from warpshade.bench.animation import configurations, label, parse_variant, run_animation

    assert parse_variant("min_image=0, lut=96") == {"method": "hemiraster", "knobs": {"min_image": 0.0, "lut": 96},
                                                    "reuse": None}
    assert parse_variant("lut=48,reuse=2") == {"method": "hemiraster", "knobs": {}, "reuse": 2.0}  # lut 48 is the default
    for bad in ("lut96", "no_such_knob=1", "lut=many", "reuse=often"):
        with pytest.raises(ValueError):
            parse_variant(bad)
    cfgs = configurations([], peer_rays=16, variants=[parse_variant("mask=16")])
    assert [(c["method"], c["knobs"], c["reuse"]) for c in cfgs] == [
        ("hemiraster", {}, None), ("hemiraster", {"mask": 16}, None), ("reference", {"rays": 16}, None)]
    res = run_animation("walk", frames=2, every=1, order=3, rays=64, cache_dir=None, configs=cfgs[:2], log=lambda m: None)
    plain, variant = res["records"]
    assert label(variant) == "hemiraster mask=16"
    assert plain["errors"] != variant["errors"]  # a 16-pixel mask is another transfer, not the default's


def test_animation_bench_back_side_is_the_flipped_group_judged_at_its_two_sided_members(tmp_path):
    from warpshade.bench.animation import sequence

    front = sequence("default", frames=2, cache_dir=str(tmp_path))
    back = sequence("default", frames=2, cache_dir=str(tmp_path), side="back")
    assert np.array_equal(back.frames, front.frames) and np.array_equal(back.rest.faces, front.rest.faces[:, ::-1])
    assert front.judged(0) is None
    mask = back.judged(0)
    assert mask.dtype == bool and mask.sum() == 33 * 33  # the cloth (33 x 33 vertices) is the two-sided member
    assert not mask[:mask.argmax()].any()  # ground and ball come first in the group, one-sided
    with pytest.raises(ValueError, match="back side"):
        sequence("walk", frames=2, side="back")
