"""``warpshade preview``: ray-cast a frame (or a contact sheet of frames) of a shaded USD output to PNG."""

from __future__ import annotations

import argparse
import sys

from .._atomic import replace_atomically

HELP = "render a frame of a shaded USD animation to PNG (Warp ray caster; --contact-sheet for several)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("usd", metavar="OUT.usd", help="a file written by `warpshade run` (or any stage with meshes)")
    parser.add_argument("--frame", type=float, default=None, help="time code (default: the last frame)")
    parser.add_argument("-o", "--output", required=True, metavar="FRAME.png", help="PNG to write")
    parser.add_argument("--contact-sheet", default=None, metavar="START:END[:STEP]",
                        help="tile frames START..END (inclusive) every STEP (default: 8 frames over the range); "
                             "an empty START or END is the first or last frame, so ':' tiles the whole animation")
    parser.add_argument("--columns", type=int, default=4, help="contact-sheet columns")
    parser.add_argument("--size", default="640x480", metavar="WxH", help="image (or tile) size in pixels")
    parser.add_argument("--exposure", type=float, default=None,
                        help="radiance scale before sRGB encoding (default: 99th percentile -> 0.9, shared by all tiles)")
    parser.add_argument("--azimuth", type=float, default=35.0, help="camera azimuth [degrees]")
    parser.add_argument("--elevation", type=float, default=25.0, help="camera elevation [degrees]")


def _frames(spec: str | None, single, start: float, end: float) -> list[float]:
    if spec is None:
        return [end if single is None else single]
    parts = spec.split(":")
    try:
        a = float(parts[0]) if parts[0] else start
        b = float(parts[1]) if len(parts) > 1 and parts[1] else end
        step = float(parts[2]) if len(parts) > 2 else max((b - a) / 7.0, 1.0)
    except ValueError:
        raise ValueError(f"--contact-sheet '{spec}': expected START:END[:STEP] numbers") from None
    if step <= 0 or b < a:
        raise ValueError(f"--contact-sheet '{spec}': need END >= START and STEP > 0")
    out, f = [], a
    while f <= b + 1e-9:
        out.append(round(f, 6))
        f += step
    return out


def _with_back_sides(shot: list, backs: dict) -> list:
    """Render tuples of a frame: a back-side mesh is not drawn itself, its colours are its front's back colours
    (both are single-sided: each side shows its own mesh's colours, as in a DCC)."""
    back_colors = {backs[name]: c for name, _, _, c in shot if backs.get(name)}
    fronts = {name for name, _, _, _ in shot}
    return [(p, f, c, back_colors.get(name)) for name, p, f, c in shot if not (name in backs and backs[name] in fronts)]


def run(args) -> int:
    import imageio.v3 as iio
    import numpy as np

    from ..preview import contact_sheet, frame_camera, render, tonemap
    from ..usd.frames import ShadedStage

    try:
        w, h = (int(v) for v in args.size.lower().split("x"))
        if w < 1 or h < 1:
            raise ValueError
    except ValueError:
        raise ValueError(f"--size '{args.size}': expected WxH, two whole numbers of pixels >= 1, e.g. 640x480") from None
    stage = ShadedStage(args.usd)
    frames = _frames(args.contact_sheet, args.frame, stage.start, stage.end)
    outside = [f for f in frames if not stage.start - 1e-6 <= f <= stage.end + 1e-6]
    if outside:
        # USD would hold the first or last sample there: the picture would show a frame not asked for
        option = "--frame" if args.contact_sheet is None else "--contact-sheet"
        raise ValueError(f"{option}: time code {outside[0]:g} is outside {args.usd}'s frames, time codes "
                         f"{stage.start:g}..{stage.end:g} (frame f of a run is time code startTimeCode + f)")
    shots = [stage.frame(f) for f in frames]
    # one camera and one exposure for all tiles, so motion and lighting changes are comparable
    # frame what moves (a ground grid would otherwise set the scale), else everything
    moving = stage.moving()
    allpts = np.concatenate([m[1] for shot in shots for m in shot if not moving or m[0] in moving])
    cam = frame_camera(allpts, stage.up_axis, args.azimuth, args.elevation, aspect=w / h)
    images = [render(_with_back_sides(shot, stage.back_sides()), cam, w, h) for shot in shots]
    exposure = args.exposure
    if exposure is None:
        cols = np.concatenate([m[3] for shot in shots for m in shot])
        p = float(np.percentile(cols.max(axis=1), 99))
        exposure = 0.9 / p if p > 0 else 1.0
    tiles = [tonemap(img, exposure) for img in images]
    out = tiles[0] if args.contact_sheet is None else contact_sheet(tiles, args.columns)
    replace_atomically(lambda tmp: iio.imwrite(tmp, out), args.output)
    what = f"frame {frames[0]:g}" if len(frames) == 1 else f"{len(frames)} frames {frames[0]:g}..{frames[-1]:g}"
    print(f"preview: {what} of {args.usd} -> {args.output}", file=sys.stderr)
    return 0
