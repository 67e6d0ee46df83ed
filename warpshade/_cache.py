"""A per-user disk cache of derived arrays, reused across processes and runs.

An entry is one ``.npz`` file ``<root>/<kind>/<key>.npz``; ``key`` is a sha256 hex digest (:class:`Key`)
that the caller builds over everything the entry's arrays depend on (inputs, knobs, the source of the
code that computes them, library versions), so an entry is either valid for a request or never found.

* **Root**: ``$WARPSHADE_CACHE`` when set (``none`` or ``0``: the cache is off, nothing is read or
  written), else the platform's user cache directory (:func:`default_root`).
* **Writes** are atomic (:func:`warpshade._atomic.replace_atomically`: a temporary name per process, then a
  rename), so concurrent writers of one entry (two workers building the same structure) each leave a
  complete file and a reader never sees a part of one.
* **Failures are misses**: an entry that cannot be read or fails the caller's check (truncated, corrupt,
  another format) is rebuilt and rewritten; a root that cannot be written (read-only, no space) only
  costs the write, with one warning line per process and root.
* **Size**: after each write the root's least recently used entries (modification time, refreshed on
  each hit) are removed beyond :data:`MAX_BYTES`.
* **Callers with files of their own** (the benchmark's ray-traced ground truth, its simulated sequences) keep
  them in a subdirectory of the same root by default (:func:`directory`, :data:`USER`), never relative to the
  working directory; an explicit directory replaces it. Only ``.npz`` entries are pruned.
"""

from __future__ import annotations

import functools
import hashlib
import os
import sys
import time
import warnings
from collections import Counter

import numpy as np

from ._atomic import replace_atomically

ENV = "WARPSHADE_CACHE"
"""Environment variable naming the cache root (``none`` or ``0``: off)."""

OFF = ("none", "0")
"""Values of :data:`ENV` that turn the cache off (case-insensitive)."""

MAX_BYTES = 512 * 1024 * 1024
"""Size the root is pruned to after each write (least recently used entries first)."""

STALE_PARTIAL_SECONDS = 3600.0
"""Age after which a temporary file left by a killed writer is removed when pruning."""

stats: Counter = Counter()
"""Per process: ``(kind, "hit" | "miss" | "write" | "bad")`` counts (a ``bad`` entry also counts a miss)."""

_warned: set = set()


def default_root() -> str:
    """The platform's per-user cache directory for warpshade: ``%LOCALAPPDATA%\\warpshade\\Cache`` on
    Windows, ``~/Library/Caches/warpshade`` on macOS, else ``$XDG_CACHE_HOME/warpshade`` (default
    ``~/.cache/warpshade``)."""
    if sys.platform == "win32":
        base = os.environ.get("LOCALAPPDATA") or os.path.expanduser("~\\AppData\\Local")
        return os.path.join(base, "warpshade", "Cache")
    if sys.platform == "darwin":
        return os.path.expanduser("~/Library/Caches/warpshade")
    return os.path.join(os.environ.get("XDG_CACHE_HOME") or os.path.expanduser("~/.cache"), "warpshade")


def root() -> str | None:
    """The cache root this process uses (:data:`ENV`, else :func:`default_root`); None when the cache is off."""
    value = os.environ.get(ENV, "").strip()
    if value.lower() in OFF:
        return None
    return os.path.abspath(os.path.expanduser(value)) if value else default_root()


class _UserDirectory:
    def __repr__(self) -> str:
        return "<the user cache directory>"


USER = _UserDirectory()
"""A ``cache_dir`` default that stands for ``directory(kind)``, resolved when used (:func:`resolve`), so
:data:`ENV` and ``XDG_CACHE_HOME`` count as they are then, not at import."""


def directory(kind: str) -> str | None:
    """``<root>/<kind>``: where a caller with files of its own keeps them in the cache; None when the cache is off."""
    base = root()
    return None if base is None else os.path.join(base, kind)


def resolve(cache_dir, kind: str) -> str | None:
    """A ``cache_dir`` argument as a directory: :data:`USER` is :func:`directory` of ``kind``; a path is that
    path; None (no cache) is None."""
    return directory(kind) if cache_dir is USER else cache_dir


class Key:
    """A sha256 over typed, length-framed parts (strings, numbers, None, arrays with dtype and shape), so
    different sequences of parts never give the same bytes."""

    def __init__(self, *parts):
        self._h = hashlib.sha256()
        self.add(*parts)

    def add(self, *parts) -> "Key":
        for p in parts:
            if isinstance(p, np.ndarray):
                a = np.ascontiguousarray(p)
                head, body = f"a{a.dtype.str}{a.shape}", a.tobytes()
            elif isinstance(p, bytes):
                head, body = "b", p
            elif p is None or isinstance(p, (bool, int, float, str)):
                head, body = f"{type(p).__name__}", repr(p).encode()
            else:
                raise TypeError(f"cache key part of type {type(p).__name__}")
            self._h.update(f"{head}:{len(body)}:".encode())
            self._h.update(body)
        return self

    def hexdigest(self) -> str:
        return self._h.hexdigest()


@functools.lru_cache(maxsize=None)
def source_digest(path: str) -> str:
    """sha256 of a source file's bytes (a key part that changes whenever that code changes)."""
    with open(path, "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()


def versions(*dists: str) -> tuple[str, ...]:
    """``"<distribution> <version>"`` of each installed distribution (``"<name> ?"`` when it is not installed):
    key parts for entries whose arrays a library computes."""
    from importlib import metadata

    out = []
    for dist in dists:
        try:
            out.append(f"{dist} {metadata.version(dist)}")
        except metadata.PackageNotFoundError:
            out.append(f"{dist} ?")
    return tuple(out)


def has_layout(arrays: dict, layout: dict) -> bool:
    """Whether ``arrays`` holds exactly the names of ``layout`` (name -> ``(shape, dtype)``) with those shapes
    and dtypes: the usual ``check`` of :func:`load` for entries of a known shape."""
    return set(arrays) == set(layout) and all(arrays[k].shape == tuple(shape) and arrays[k].dtype == np.dtype(dtype)
                                              for k, (shape, dtype) in layout.items())


def _path(kind: str, key: str, where: str | None) -> str | None:
    base = where if where is not None else root()
    return None if base is None else os.path.join(base, kind, f"{key}.npz")


def load(kind: str, key: str, check=None, where: str | None = None) -> dict | None:
    """The arrays of entry ``key`` of ``kind`` (read whole), or None on a miss: no entry, the cache off,
    an unreadable entry or one for which ``check(arrays)`` is false. ``where``: another root (a directory the
    caller chose) instead of :func:`root`."""
    path = _path(kind, key, where)
    if path is None:
        return None
    try:
        with np.load(path, allow_pickle=False) as z:
            arrays = {name: z[name] for name in z.files}
        if check is not None and not check(arrays):
            raise ValueError("entry fails its check")
    except (FileNotFoundError, NotADirectoryError):  # no entry (or no root directory)
        stats[kind, "miss"] += 1
        return None
    except Exception as e:  # truncated, corrupt, another format: rebuilt and rewritten
        stats[kind, "miss"] += 1
        stats[kind, "bad"] += 1
        _warn_once(("bad", path), f"warpshade cache: rebuilding {path} ({type(e).__name__}: {e})")
        return None
    stats[kind, "hit"] += 1
    try:
        os.utime(path)  # recently used (pruning removes the least recently used first)
    except OSError:
        pass
    return arrays


def save(kind: str, key: str, arrays: dict, where: str | None = None) -> bool:
    """Store ``arrays`` (name -> numpy array) as entry ``key`` of ``kind``, atomically; False (and one
    warning line per process and root) when it cannot be written or the cache is off (then silently)."""
    path = _path(kind, key, where)
    if path is None:
        return False
    try:
        os.makedirs(os.path.dirname(path), exist_ok=True)
        replace_atomically(lambda tmp: np.savez(tmp, **arrays), path)
    except OSError as e:
        base = os.path.dirname(os.path.dirname(path))
        _warn_once(("write", base), f"warpshade cache: cannot write to {base} ({e.strerror or e}); "
                                    f"building without it (set {ENV}=none to turn the cache off)")
        return False
    stats[kind, "write"] += 1
    prune(os.path.dirname(os.path.dirname(path)))
    return True


def prune(base: str, max_bytes: int = MAX_BYTES) -> None:
    """Remove the least recently used entries under ``base`` until at most ``max_bytes`` remain, and
    temporary files older than :data:`STALE_PARTIAL_SECONDS` (writers killed mid-write)."""
    files, now = [], time.time()
    try:
        for kind in os.scandir(base):
            if kind.is_dir(follow_symlinks=False):
                for e in os.scandir(kind.path):
                    if e.is_file(follow_symlinks=False) and e.name.endswith(".npz"):
                        st = e.stat()
                        if ".partial" in e.name:
                            if now - st.st_mtime > STALE_PARTIAL_SECONDS:
                                files.append((0.0, st.st_size, e.path))
                        else:
                            files.append((st.st_mtime, st.st_size, e.path))
    except OSError:
        return
    total = sum(size for _, size, _ in files)
    for mtime, size, path in sorted(files):
        if total <= max_bytes and mtime > 0.0:
            break
        try:
            os.remove(path)
            total -= size
        except OSError:
            pass


def _warn_once(what, message: str) -> None:
    if what not in _warned:
        _warned.add(what)
        warnings.warn(message, RuntimeWarning, stacklevel=3)


__all__ = ["ENV", "Key", "MAX_BYTES", "OFF", "USER", "default_root", "directory", "has_layout", "load", "prune", "resolve",
           "root", "save", "source_digest", "stats", "versions"]
