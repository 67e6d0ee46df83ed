"""``warpshade export``: a run's output as one self-contained ``.usdc`` or ``.usdz`` (warpshade.usd.package)."""

from __future__ import annotations

import argparse

HELP = "turn a run's output (top file + frame files + textures) into one .usdc/.usda or a .usdz package"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("usd", metavar="OUT.usda", help="a file written by `warpshade run` (or any USD file)")
    parser.add_argument("-o", "--output", required=True, metavar="SCENE.usdc|SCENE.usdz",
                        help="the self-contained file; .usdc/.usda get their textures in <stem>_textures/ beside them")


def run(args) -> int:
    from ..usd.package import export

    print(export(args.usd, args.output))
    return 0
