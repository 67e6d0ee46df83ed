"""``warpshade transfer``: per-vertex SH diffuse transfer of a mesh (docs/conventions.md §3)."""

from __future__ import annotations

import argparse
import sys

from .._atomic import replace_atomically

HELP = "compute per-vertex SH diffuse transfer of a mesh with a visibility method"
ACCEPTS_EXTRA = True  # method knobs, parsed once --method is known


def add_arguments(parser: argparse.ArgumentParser) -> None:
    from ..visibility import METHODS

    parser.add_argument("mesh", metavar="MESH", help=".usd/.usda/.usdc, .obj, .ply or .stl")
    parser.add_argument("--method", required=True, choices=sorted(METHODS), help="visibility method")
    parser.add_argument("--prim", default=None, help="USD prim path of the mesh (default: first Mesh)")
    parser.add_argument("--order", type=int, default=5, help="SH order N (N*N coefficients), default 5")
    parser.add_argument("--repeat", type=int, default=3, help="timed runs after one warm-up run")
    parser.add_argument("--save", required=True, metavar="OUT.npz", help="output arrays")
    parser.add_argument("--json", default=None, metavar="STATS.json", help="write timing and knobs")
    parser.add_argument("--device", default="cpu", help="Warp device (default cpu)")


def knob_class(method: str):
    """The class whose ``add_arguments`` defines ``--method``'s knobs (None for an unknown name)."""
    from ..visibility import METHODS, get_method

    return get_method(method) if method in METHODS else None


def knob_methods() -> list[str]:
    """The ``--method`` names whose knobs ``--help`` summarises."""
    from ..visibility import METHODS

    return sorted(METHODS)


def parse_knobs(args) -> dict:
    """The method's knobs from arguments parsed with them (:func:`warpshade.cli.main` adds the
    flags of ``args.knob_class``).

    Raises:
        ValueError: naming the method, the flags it does not know and the ones it has.
    """
    if args.extra:
        cls = args.knob_class
        name = cls.name if cls is not None else args.method
        flags = cls.knob_flags() if cls is not None else []
        known = (f"its knobs: {', '.join(flags)}; warpshade {args.command} --method {name} --help describes them"
                 if flags else "it has no knobs")
        raise ValueError(f"unknown option(s) for method '{name}': {' '.join(args.extra)} ({known})")
    return args.knob_class.knobs_from_args(args) if args.knob_class is not None else {}


def run(args) -> int:
    from ..bench.report import write_json
    from ..usd import load_mesh
    from ..bench.timing import time_transfer
    from ..visibility import get_method

    cls = get_method(args.method)
    knobs = parse_knobs(args)
    mesh = load_mesh(args.mesh, prim=args.prim)
    method = cls(mesh, order=args.order, device=args.device, **knobs)
    seconds = time_transfer(method, repeat=args.repeat)
    transfer = method.transfer_numpy()
    save_npz(args.save, points=method.points.numpy(), normals=method.normals.numpy(), faces=mesh.faces,
             transfer=transfer)
    stats = method_stats(method, mesh, seconds, args.repeat, order=method.order)
    if args.json:
        write_json(args.json, stats, indent=2)
    print(f"{cls.name}: {mesh.num_vertices} vertices, {mesh.num_faces} triangles, order {method.order}: "
          f"{seconds * 1e3:.2f} ms per frame (median of {args.repeat}) -> {args.save}", file=sys.stderr)
    return 0


def method_stats(method, mesh, seconds: float, repeat: int, order: int | None, **extra) -> dict:
    """The ``STATS.json`` of ``warpshade transfer`` and ``warpshade visibility`` (docs/conventions.md §3, §4):
    method name, order (None for area-light visibility), mesh size, timing, every knob as used, the
    method's counters, then ``extra`` keys."""
    return {"method": type(method).name, "order": order, "vertices": mesh.num_vertices, "triangles": mesh.num_faces,
            "seconds": seconds, "repeat": repeat, "knobs": method.knobs(), "mesh": mesh.name, **extra,
            **method.stats()}


def save_npz(path: str, **arrays) -> None:
    """Write an ``.npz`` atomically (temporary file, then rename)."""
    import numpy as np

    replace_atomically(lambda tmp: np.savez(tmp, **{k: np.asarray(v, dtype=np.int32 if k == "faces" else np.float32)
                                                     for k, v in arrays.items()}), path)
