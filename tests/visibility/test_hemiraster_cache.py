"""hemiraster's far field and plane LUT in the per-user disk cache (warpshade._cache, hemiraster/cache.py):
read back bit for bit, keyed on everything they depend on, rebuilt from bad entries, never an error."""

from __future__ import annotations

import multiprocessing
import os
import warnings

import numpy as np
import pytest

from helpers import bumpy_grid
from warpshade import _cache
from warpshade.geometry import TriMesh
from warpshade.visibility import get_method
from warpshade.visibility.hemiraster import cache as hr_cache
from warpshade.visibility.hemiraster import hierarchy, tables


def wavy_sheet(n=14, seed=0):
    """An open sheet with folds: the far field (coarse 64 / mid 200 of its 338 triangles) has extras and an outline."""
    return bumpy_grid(n, seed, name="wavy")


KNOBS = dict(coarse=64, mid=200)


def counts(kind=hr_cache.KIND):
    return {what: _cache.stats[kind, what] for what in ("hit", "miss", "write", "bad")}


def build(mesh, **knobs):
    return get_method("hemiraster")(mesh, order=3, **{**KNOBS, **knobs})


def parts_of(mesh, occluder=None):
    parts = [(mesh.points.astype(np.float64), mesh.faces.astype(np.int64))]
    if occluder is not None:
        parts.append((occluder.points.astype(np.float64), occluder.faces.astype(np.int64)))
    return parts


def assert_same_far(a, b):
    assert set(a) == set(b)
    for k in a:
        if k == "mid":
            assert_same_far(a[k], b[k])
        else:
            assert a[k].dtype == b[k].dtype and a[k].shape == b[k].shape, k
            assert a[k].tobytes() == b[k].tobytes(), k


def test_cached_far_field_is_the_built_one_bit_for_bit(cache_root):
    mesh = wavy_sheet()
    ground = TriMesh(np.array([[-1, -1, -0.4], [2, -1, -0.4], [2, 2, -0.4], [-1, 2, -0.4]], float),
                     np.array([[0, 1, 2], [0, 2, 3]]), name="ground")
    for mid in (None, [200, 2]):
        args = (parts_of(mesh, ground), [64, 2], mid, False)
        fresh = hierarchy.far_field(*args)
        first = hr_cache.far_field(*args)  # built and stored
        second = hr_cache.far_field(*args)  # read back
        assert_same_far(fresh, first)
        assert_same_far(fresh, second)
    assert counts() == {"hit": 2, "miss": 2, "write": 2, "bad": 0}


def test_method_from_the_cache_gives_the_same_transfer(cache_root, monkeypatch):
    mesh = wavy_sheet()
    monkeypatch.setenv(_cache.ENV, "none")
    fresh = build(mesh).update().numpy()
    monkeypatch.setenv(_cache.ENV, str(cache_root))
    first = build(mesh).update().numpy()
    assert counts() == {"hit": 0, "miss": 1, "write": 1, "bad": 0}

    def no_build(*a, **k):
        raise AssertionError("the far field was built although an entry exists")

    monkeypatch.setattr(hierarchy, "far_field", no_build)
    second = build(mesh).update().numpy()
    assert counts() == {"hit": 1, "miss": 1, "write": 1, "bad": 0}
    assert fresh.tobytes() == first.tobytes() == second.tobytes()


@pytest.mark.parametrize("damage", ["truncate", "flip", "garbage", "wrong layout"])
def test_a_bad_entry_is_rebuilt_with_one_warning(cache_root, damage):
    mesh = wavy_sheet()
    args = (parts_of(mesh), [64], None, False)
    built = hr_cache.far_field(*args)
    (path,) = (cache_root / hr_cache.KIND).iterdir()
    data = path.read_bytes()
    if damage == "truncate":
        path.write_bytes(data[:len(data) // 2])
    elif damage == "flip":  # a byte inside the first array's data: the zip member's CRC no longer matches
        b = bytearray(data)
        b[200] ^= 0xFF
        path.write_bytes(bytes(b))
    elif damage == "garbage":
        path.write_bytes(b"not a cache entry")
    else:  # a readable entry of another layout
        np.savez(path, points=np.zeros((3, 3)))
    with pytest.warns(RuntimeWarning, match="warpshade cache: rebuilding"):
        again = hr_cache.far_field(*args)
    assert_same_far(built, again)
    assert counts() == {"hit": 0, "miss": 2, "write": 2, "bad": 1}
    assert_same_far(built, hr_cache.far_field(*args))  # the rewritten entry reads back
    assert counts()["hit"] == 1


def test_changed_points_or_knobs_miss(cache_root):
    mesh = wavy_sheet()
    base = (parts_of(mesh), [64], None, False)
    moved = parts_of(mesh)
    moved[0][0][5, 2] = np.nextafter(moved[0][0][5, 2], np.inf)  # one coordinate, one ulp
    flipped = [(mesh.points.astype(np.float64), mesh.faces[:, ::-1].astype(np.int64))]  # a back pass's mesh
    variants = [base, (moved, [64], None, False), (flipped, [64], None, False), (parts_of(mesh), [63], None, False),
                (parts_of(mesh), [64], [200], False), (parts_of(mesh), [64], None, True),
                ([(mesh.points.astype(np.float32), mesh.faces.astype(np.int64))], [64], None, False)]
    keys = [hr_cache.far_field_key(*v) for v in variants]
    assert len(set(keys)) == len(keys)
    for v in variants:
        hr_cache.far_field(*v)
    assert counts()["miss"] == len(variants) and counts()["hit"] == 0
    # the same request again, through a new list of new arrays: a hit
    hr_cache.far_field(parts_of(mesh), [64], None, False)
    assert counts()["hit"] == 1


def test_key_covers_each_parts_border_flag(cache_root):
    # hemiraster keeps the occluders' outline whatever ``border`` says for the receiver: one flag per part
    parts = parts_of(wavy_sheet()) * 2
    keys = {flags: hr_cache.far_field_key(parts, [64, 64], None, flags)
            for flags in [(False, False), (False, True), (True, False), (True, True)]}
    assert len(set(keys.values())) == 4
    assert hr_cache.far_field_key(parts, [64, 64], None, True) == keys[(True, True)]  # one bool: every part
    with pytest.raises(ValueError, match="2 far-field parts"):
        hr_cache.far_field_key(parts, [64, 64], None, [True])


def test_key_covers_the_code_and_the_libraries(cache_root, monkeypatch):
    parts = parts_of(wavy_sheet())
    key = hr_cache.far_field_key(parts, [64])
    env = hr_cache._environment()
    assert env[1] == _cache.source_digest(hierarchy.__file__)
    assert any(e.startswith("fast-simplification ") and not e.endswith("?") for e in env)
    monkeypatch.setattr(hr_cache, "_environment", lambda: (*env[:1], "another hierarchy.py", *env[2:]))
    assert hr_cache.far_field_key(parts, [64]) != key


@pytest.mark.parametrize("value", ["none", "0", "NONE"])
def test_a_disabled_cache_writes_nothing(tmp_path, monkeypatch, value):
    monkeypatch.setenv(_cache.ENV, value)
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    monkeypatch.chdir(tmp_path)
    _cache.stats.clear()
    tables._LUT_CACHE.pop((8, 6), None)
    assert _cache.root() is None
    mesh = wavy_sheet()
    a = build(mesh, mask=8, lut=6).update().numpy()
    b = build(mesh, mask=8, lut=6).update().numpy()
    assert a.tobytes() == b.tobytes()
    # nothing in the default root, the home or the working directory (Warp may put its kernel cache under xdg/warp)
    written = sorted(str(p.relative_to(tmp_path)) for p in tmp_path.rglob("*") if p.is_file())
    assert not [w for w in written if not w.startswith("xdg/warp/")], written
    assert sum(_cache.stats.values()) == 0


def test_default_root_follows_the_platform_cache_dir(monkeypatch, tmp_path):
    monkeypatch.delenv(_cache.ENV, raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    if os.name == "posix" and not os.uname().sysname == "Darwin":
        assert _cache.root() == os.path.join(str(tmp_path), "warpshade")
    monkeypatch.setenv(_cache.ENV, "~/elsewhere")
    assert _cache.root() == os.path.expanduser("~/elsewhere")


def test_an_unwritable_root_builds_as_before(tmp_path, monkeypatch):
    blocker = tmp_path / "a file"
    blocker.write_text("not a directory")
    monkeypatch.setenv(_cache.ENV, str(blocker / "cache"))  # no directory can be made there, even as root
    _cache.stats.clear()
    _cache._warned.clear()
    mesh = wavy_sheet()
    monkeypatch.setenv(_cache.ENV, "none")
    fresh = build(mesh).update().numpy()
    monkeypatch.setenv(_cache.ENV, str(blocker / "cache"))
    with pytest.warns(RuntimeWarning, match="cannot write") as record:
        a = build(mesh).update().numpy()
        b = build(mesh).update().numpy()
    assert len([w for w in record if "cannot write" in str(w.message)]) == 1  # one warning line per process
    assert fresh.tobytes() == a.tobytes() == b.tobytes()
    assert counts() == {"hit": 0, "miss": 2, "write": 0, "bad": 0}


def test_a_failed_rename_leaves_no_partial_file(cache_root, monkeypatch):
    # what a read-only directory does to a writer that is not root (root may write there anyway)
    def refuse(src, dst):
        raise PermissionError(13, "Permission denied")

    monkeypatch.setattr(os, "replace", refuse)
    mesh = wavy_sheet()
    with pytest.warns(RuntimeWarning, match="cannot write"):
        far = hr_cache.far_field(parts_of(mesh), [64])
    assert_same_far(far, hierarchy.far_field(parts_of(mesh), [64]))
    assert list((cache_root / hr_cache.KIND).iterdir()) == []


def _writer(root, seed, rounds):
    os.environ[_cache.ENV] = root
    rng = np.random.default_rng(seed)
    big = {"a": np.arange(1 << 18, dtype=np.int64), "b": rng.random(1000)}
    big["b"][:] = 0.5  # every writer stores the same entry
    for _ in range(rounds):
        assert _cache.save("race", "k", big)


def test_concurrent_writers_leave_whole_entries(cache_root):
    ctx = multiprocessing.get_context("fork")
    procs = [ctx.Process(target=_writer, args=(str(cache_root), s, 15)) for s in range(3)]
    for p in procs:
        p.start()
    seen = 0
    while any(p.is_alive() for p in procs):
        got = _cache.load("race", "k")
        if got is not None:
            seen += 1
            assert got["a"].tobytes() == np.arange(1 << 18, dtype=np.int64).tobytes()
            assert (got["b"] == 0.5).all()
    for p in procs:
        p.join()
        assert p.exitcode == 0
    assert _cache.stats["race", "bad"] == 0
    assert _cache.load("race", "k") is not None
    assert [p.name for p in (cache_root / "race").iterdir()] == ["k.npz"]  # no temporary file left


def test_pruning_removes_the_least_recently_used(cache_root):
    arrays = {"x": np.zeros(1000, np.uint8)}
    for k in ("old", "mid", "new"):
        _cache.save("t", k, arrays)
    for age, k in enumerate(("new", "mid", "old")):
        t = 1_000_000 - age * 1000
        os.utime(cache_root / "t" / f"{k}.npz", (t, t))
    _cache.load("t", "old")  # a hit refreshes it
    size = (cache_root / "t" / "old.npz").stat().st_size
    _cache.prune(str(cache_root), max_bytes=2 * size)
    assert sorted(p.name for p in (cache_root / "t").iterdir()) == ["new.npz", "old.npz"]


def test_lut_from_the_disk_cache(cache_root):
    tables._LUT_CACHE.pop((8, 6), None)
    a, _, src = tables.build_lut(8, 6)
    assert src == "built" and len(list((cache_root / tables.LUT_KIND).iterdir())) == 1
    tables._LUT_CACHE.pop((8, 6), None)
    b, _, src = tables.build_lut(8, 6)
    assert src == "disk" and a.tobytes() == b.tobytes()
    np.testing.assert_array_equal(b, tables.build_lut_np(8, 6))
    (path,) = (cache_root / tables.LUT_KIND).iterdir()
    path.write_bytes(path.read_bytes()[:100])
    tables._LUT_CACHE.pop((8, 6), None)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        c, _, src = tables.build_lut(8, 6)
    assert src == "built" and c.tobytes() == a.tobytes()
