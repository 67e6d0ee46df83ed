"""``warpshade visibility``: per-vertex visibility of a rectangular area light (docs/conventions.md §4)."""

from __future__ import annotations

import argparse
import sys

HELP = "fraction of a rectangular area light visible from each vertex (GEARS or ray-traced)"
ACCEPTS_EXTRA = True  # method knobs, parsed once --method is known


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from ..visibility.gears import AREA_METHODS

    parser.add_argument("mesh", metavar="MESH", help=".usd/.usda/.usdc, .obj, .ply or .stl")
    parser.add_argument("--rect-light", required=True, metavar="cx,cy,cz,ux,uy,uz,vx,vy,vz",
                        help="two-sided rectangle light with corners c ± u ± v")
    parser.add_argument("--method", required=True, choices=AREA_METHODS, help="visibility method")
    parser.add_argument("--prim", default=None, help="USD prim path of the mesh (default: first Mesh)")
    parser.add_argument("--repeat", type=int, default=3, help="timed runs after one warm-up run")
    parser.add_argument("--save", required=True, metavar="OUT.npz", help="output arrays")
    parser.add_argument("--json", default=None, metavar="STATS.json", help="write timing and knobs")
    parser.add_argument("--device", default="cpu", help="Warp device (default cpu)")


def knob_class(method: str):
    """The area-light visibility class whose ``add_arguments`` defines ``--method``'s knobs."""
    from ..visibility.gears import AREA_METHODS, get_area_method

    return get_area_method(method) if method in AREA_METHODS else None


def knob_methods() -> list[str]:
    """The ``--method`` names whose knobs ``--help`` summarises."""
    from ..visibility.gears import AREA_METHODS

    return list(AREA_METHODS)


def run(args) -> int:
    from ..usd import load_mesh
    from ..bench.timing import median_seconds
    from ..visibility.gears import LightRect, get_area_method
    from ..bench.report import write_json
    from .cmd_transfer import method_stats, parse_knobs, save_npz

    light = LightRect.parse(args.rect_light)
    cls = get_area_method(args.method)
    knobs = parse_knobs(args)
    mesh = load_mesh(args.mesh, prim=args.prim)
    method = cls(mesh, light, device=args.device, **knobs)
    seconds = median_seconds(method.update, repeat=args.repeat, warmup=1)
    save_npz(args.save, points=method.points.numpy(), normals=method.normals.numpy(),
             visibility=method.visibility.numpy())
    stats = method_stats(method, mesh, seconds, args.repeat, order=None,
                         light={"center": list(light.center), "u": list(light.u), "v": list(light.v)})
    if args.json:
        write_json(args.json, stats, indent=2)
    print(f"{cls.name}: {mesh.num_vertices} vertices, {mesh.num_faces} triangles, k={method.k}: "
          f"{seconds * 1e3:.2f} ms per frame (median of {args.repeat}) -> {args.save}", file=sys.stderr)
    return 0
