"""``python -m warpshade ...`` is the same as the ``warpshade`` console script."""

import sys

from .cli import main

sys.exit(main())
