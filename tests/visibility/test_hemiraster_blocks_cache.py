"""hemiraster's block tables (``tables.block_tables``) in the per-user disk cache (warpshade._cache): read back
bit for bit as ``build_block_tables`` makes them, keyed on the arguments and the code and libraries that compute
them, rebuilt from a bad entry (a worker's start-up reads them instead of integrating the SH basis over the disk)."""

from __future__ import annotations

import numpy as np
import pytest

from warpshade import _cache
from warpshade.sh import basis
from warpshade.visibility.hemiraster import tables


@pytest.fixture
def blocks_cache(cache_root):
    tables.block_tables.cache_clear()  # the in-memory copy would answer before the disk
    yield cache_root
    tables.block_tables.cache_clear()


def counts():
    return {what: _cache.stats[tables.BLOCKS_KIND, what] for what in ("hit", "miss", "write", "bad")}


def assert_same(got: dict, want: dict):
    assert set(got) == set(want)
    for k in want:
        assert got[k].dtype == want[k].dtype and got[k].shape == want[k].shape, k
        assert got[k].tobytes() == want[k].tobytes(), k  # bit for bit
        assert not got[k].flags.writeable, k


@pytest.mark.parametrize("mask, downsample, order", [(8, 1, 2), (16, 2, 4), (64, 2, 4)])
def test_miss_then_hit_give_the_built_tables_bit_for_bit(blocks_cache, mask, downsample, order):
    want = tables.build_block_tables(mask, downsample, order)
    for expected in ({"hit": 0, "miss": 1, "write": 1, "bad": 0}, {"hit": 1, "miss": 1, "write": 1, "bad": 0}):
        tables.block_tables.cache_clear()  # as a fresh worker process
        assert_same(tables.block_tables(mask, downsample, order), want)
        assert counts() == expected


def test_each_argument_is_its_own_entry(blocks_cache):
    tables.block_tables(16, 2, 4)
    for args in ((16, 4, 4), (16, 2, 3), (32, 2, 4), (16, 2, 4, 256)):
        assert_same(tables.block_tables(*args), tables.build_block_tables(*args))
    assert counts() == {"hit": 0, "miss": 5, "write": 5, "bad": 0}  # no entry read for another one


def test_the_key_holds_the_sh_code(blocks_cache, monkeypatch):
    tables.block_tables(16, 2, 4)
    tables.block_tables.cache_clear()
    real = _cache.source_digest
    monkeypatch.setattr(_cache, "source_digest", lambda path: "changed" if path == basis.__file__ else real(path))
    tables.block_tables(16, 2, 4)
    assert counts()["hit"] == 0 and counts()["miss"] == 2


def test_a_bad_entry_is_rebuilt(blocks_cache):
    want = tables.build_block_tables(16, 2, 4)
    tables.block_tables(16, 2, 4)
    (entry,) = (blocks_cache / tables.BLOCKS_KIND).iterdir()
    good = dict(np.load(entry))
    np.savez(entry, **{**good, "weights": good["weights"][:, :9]})  # an order-3 table under the order-4 key
    tables.block_tables.cache_clear()
    with pytest.warns(RuntimeWarning, match="rebuilding"):
        got = tables.block_tables(16, 2, 4)
    assert_same(got, want)
    assert counts()["bad"] == 1 and counts()["write"] == 2
