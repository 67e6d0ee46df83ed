"""``warpshade light``: project an environment (HDR file or the analytic sky) to RGB SH, optionally
write its coefficients and a lat-long image (e.g. a DomeLight texture of the default sky)."""

from __future__ import annotations

import json

import numpy as np

HELP = "project an .exr/.hdr environment or the analytic sky to RGB SH (and export the sky as an image)"


def add_arguments(parser) -> None:
    parser.add_argument("env", nargs="?", help="lat-long .exr/.hdr file; omitted: the analytic sky (default environment)")
    parser.add_argument("--order", type=int, default=5, help="SH order (bands 0..N-1), default 5")
    parser.add_argument("--up", choices=["Y", "Z"], default="Y", help="stage up axis (pole of the map / sky), default Y")
    parser.add_argument("--intensity", type=float, default=1.0, help="radiance multiplier, default 1")
    parser.add_argument("--sun-elevation", type=float, default=45.0, help="sky: sun elevation [deg], default 45")
    parser.add_argument("--sun-azimuth", type=float, default=30.0, help="sky: sun azimuth [deg] (0 = +Z for Y-up), default 30")
    parser.add_argument("--turbidity", type=float, default=3.0, help="sky: turbidity 1.7..10, default 3")
    parser.add_argument("--save", help="write the coefficients, (N*N, 3) float64, to this .npy file")
    parser.add_argument("--image", help="write the environment as a lat-long .exr/.hdr")
    parser.add_argument("--height", type=int, default=512, help="--image height in pixels (width = 2x), default 512")
    parser.add_argument("--json", action="store_true", help="print JSON")


def run(args) -> int:
    from ..lighting import EnvironmentMap, Sky, write_image
    from ..sh import check_order

    check_order(args.order)
    if args.env:
        light = EnvironmentMap.from_file(args.env, intensity=args.intensity, up=args.up)
    else:
        light = Sky(sun_elevation=args.sun_elevation, sun_azimuth=args.sun_azimuth, turbidity=args.turbidity,
                    up=args.up, intensity=args.intensity, name="sky")
    coeffs = light.sh(args.order)
    if args.save:
        np.save(args.save, coeffs)
    if args.image:
        if isinstance(light, Sky):
            write_image(args.image, light.to_image(args.height))
        else:
            write_image(args.image, light.image * light.intensity.astype(np.float32))
    info = {"source": args.env or "sky", "order": args.order, "dc_rgb": coeffs[0].tolist(),
            "mean_radiance_rgb": (coeffs[0] / np.sqrt(4 * np.pi)).tolist(), "save": args.save, "image": args.image}
    if isinstance(light, Sky):
        info["sun_direction"] = light.sun_direction.tolist()
        info["sun_radiance_rgb"] = light.sun_radiance.tolist()
    if args.json:
        print(json.dumps(info, indent=2))
    else:
        for k, v in info.items():
            if v is not None:
                print(f"{k:18s} {v}")
    return 0
