"""Files inside USD packages (``.usdz``): a texture that a scene in a package refers to has no path of
its own on disk, so it is copied out to a temporary directory of this process for the readers that need
a file (the environment map), and the writer copies it beside its output rather than referring to it."""

from __future__ import annotations

import atexit
import os
import shutil
import tempfile

from pxr import Ar

_EXTRACTED: dict[str, str] = {}
"""Package-relative resolved path -> the file it was copied to."""

_DIR: list[str] = []


def _directory() -> str:
    if not _DIR:
        _DIR.append(tempfile.mkdtemp(prefix="warpshade-package-"))
        atexit.register(shutil.rmtree, _DIR[0], True)
    return _DIR[0]


def local_file(resolved: str) -> str | None:
    """A file on disk holding the asset at ``resolved`` (a resolved asset path): itself when it is a
    file, a copy in this process's temporary directory when it lies inside a package, else None (missing)."""
    if not Ar.IsPackageRelativePath(resolved):
        return resolved if resolved and os.path.isfile(resolved) else None
    if resolved in _EXTRACTED:
        return _EXTRACTED[resolved]
    asset = Ar.GetResolver().OpenAsset(Ar.ResolvedPath(resolved))
    if asset is None:
        return None
    inner = Ar.SplitPackageRelativePathInner(resolved)[1]
    folder = os.path.join(_directory(), str(len(_EXTRACTED)))
    os.makedirs(folder)
    path = os.path.join(folder, os.path.basename(inner))
    with open(path, "wb") as f:
        f.write(bytes(asset.GetBuffer()))
    _EXTRACTED[resolved] = path
    return path


def extracted(path: str) -> bool:
    """Whether ``path`` is a copy :func:`local_file` made of an asset inside a package (temporary: a
    file that refers to it must carry its own copy)."""
    return bool(_DIR) and os.path.abspath(path).startswith(os.path.abspath(_DIR[0]) + os.sep)
