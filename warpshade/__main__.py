"""``python -m warpshade ...`` is the same as the ``warpshade`` console script."""

from .cli import entry

entry()
