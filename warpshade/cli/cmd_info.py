"""``warpshade info``: versions, Warp devices, the kernel cache and warpshade's own disk cache."""

from __future__ import annotations

import json
import platform

HELP = "print versions, Warp devices, the kernel cache and warpshade's disk cache location"


def add_arguments(parser) -> None:
    parser.add_argument("--json", action="store_true", help="print JSON instead of text")


def collect() -> dict:
    import numpy
    import warp as wp

    from .. import __version__, _cache
    from ..usd import usd_version

    wp.init()
    return {
        "warpshade": __version__,
        "python": platform.python_version(),
        "platform": platform.platform(),
        "warp": wp.__version__,
        "numpy": numpy.__version__,
        "usd": usd_version(),
        "devices": [str(d) for d in wp.get_devices()],
        "preferred_device": str(wp.get_preferred_device()),
        "kernel_cache": wp.config.kernel_cache_dir,
        # warpshade._cache.root(): hemiraster's far fields and plane LUTs, spheres' log tables, gprim icospheres; "off" with WARPSHADE_CACHE=none
        "cache": _cache.root() or "off",
    }


def run(args) -> int:
    info = collect()
    if args.json:
        print(json.dumps(info, indent=2))
    else:
        for k, v in info.items():
            print(f"{k:17s} {', '.join(v) if isinstance(v, list) else v}")
    return 0
