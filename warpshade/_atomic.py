"""Atomic file replacement: a file is written under a temporary name beside its final name, then
renamed onto it, so a reader sees either the old file or the complete new one, never a part."""

from __future__ import annotations

import os


def partial_path(path: str) -> str:
    """The temporary name beside ``path`` that :func:`replace_atomically` writes to:
    ``ROOT.partialPID.EXT`` for ``ROOT.EXT`` (the extension kept, since writers such as ``np.save``,
    ``np.savez`` and image writers pick the format from it or append their own)."""
    root, ext = os.path.splitext(path)
    return f"{root}.partial{os.getpid()}{ext}"


def replace_atomically(write, path: str) -> None:
    """Call ``write(tmp)`` with the temporary path :func:`partial_path` of ``path``, then rename it onto
    ``path`` (``os.replace``: atomic within one file system). If ``write`` or the rename raises (an
    interrupt included), the temporary file is removed and the exception propagates; ``path`` is
    then as it was before."""
    tmp = partial_path(path)
    try:
        write(tmp)
        os.replace(tmp, path)
    except BaseException:
        try:
            os.remove(tmp)
        except OSError:
            pass
        raise


__all__ = ["partial_path", "replace_atomically"]
