"""Reading and writing HDR lat-long images: OpenEXR ``.exr`` and Radiance ``.hdr``.

``.exr`` goes through the ``OpenEXR`` package (the Academy Software Foundation's own bindings; half
and float channels, any compression). ``.hdr`` (RGBE) goes through OpenCV
(``opencv-python-headless``), whose Radiance codec is built in; imageio has no ``.hdr`` backend
without a FreeImage download. Images come back as linear RGB float32, shape (H, W, 3), row 0 at the top.
"""

from __future__ import annotations

import os

import numpy as np


class ImageError(ValueError):
    """An environment image is missing, unreadable or holds unusable values (message names the file)."""


HDR_EXTENSIONS = (".hdr", ".pic", ".rgbe")
EXR_EXTENSIONS = (".exr",)


def _channels_to_rgb(channels: dict, path: str) -> np.ndarray:
    # Plain channel names win over layered ones ("diffuse.R"), which are used only when unambiguous.
    names = {}
    for k in sorted(channels, key=lambda k: k.count(".")):
        names.setdefault(k.split(".")[-1], k)
    if all(c in names for c in "RGB"):
        return np.stack([channels[names[c]] for c in "RGB"], axis=-1)
    if "Y" in names:  # luminance-only image: grey
        y = channels[names["Y"]]
        return np.stack([y, y, y], axis=-1)
    raise ImageError(f"{path}: no R, G, B (or Y) channels in the EXR file (channels: {sorted(channels)})")


def _read_exr(path: str) -> np.ndarray:
    import OpenEXR

    try:
        with OpenEXR.File(path, separate_channels=True) as f:
            channels = {name: np.asarray(ch.pixels) for name, ch in f.channels().items()}
    except Exception as exc:  # OpenEXR raises RuntimeError with a generic message
        raise ImageError(f"{path}: cannot read as OpenEXR ({exc})") from exc
    return _channels_to_rgb(channels, path)


def _read_hdr(path: str) -> np.ndarray:
    import cv2

    with open(path, "rb") as fh:  # OpenCV only warns on failure; read the magic ourselves for a clear error
        head = fh.read(10)
    if not head.startswith((b"#?RADIANCE", b"#?RGBE")):
        raise ImageError(f"{path}: not a Radiance HDR file (missing '#?RADIANCE' header)")
    img = cv2.imread(path, cv2.IMREAD_UNCHANGED | cv2.IMREAD_ANYDEPTH | cv2.IMREAD_ANYCOLOR)
    if img is None:
        raise ImageError(f"{path}: cannot decode the Radiance HDR file")
    if img.ndim == 2:
        img = np.stack([img, img, img], axis=-1)
    return img[:, :, 2::-1]  # OpenCV is BGR


def read_image(path) -> np.ndarray:
    """Read an HDR image as linear RGB.

    Args:
        path: ``.exr`` or ``.hdr`` file.

    Returns:
        Radiance, shape (H, W, 3), dtype float32, row 0 at the top of the image.

    Raises:
        FileNotFoundError: if ``path`` does not exist (message names it).
        ImageError: unknown extension, undecodable file, or NaN/inf pixels (message names the file).
    """
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise FileNotFoundError(f"environment image not found: {path}")
    ext = os.path.splitext(path)[1].lower()
    if ext in EXR_EXTENSIONS:
        img = _read_exr(path)
    elif ext in HDR_EXTENSIONS:
        img = _read_hdr(path)
    else:
        raise ImageError(f"{path}: unsupported environment image type '{ext}' (use .exr or .hdr)")
    img = np.ascontiguousarray(img, dtype=np.float32)
    if img.ndim != 3 or img.shape[0] < 1 or img.shape[1] < 1:
        raise ImageError(f"{path}: empty image")
    bad = ~np.isfinite(img)
    if bad.any():
        r, c, _ = np.argwhere(bad)[0]
        raise ImageError(f"{path}: {int(bad.any(axis=2).sum())} pixels are NaN or infinite (first at row {r}, column {c})")
    return img


def write_image(path, rgb) -> None:
    """Write linear RGB to ``.exr`` (float32, ZIP) or ``.hdr`` (RGBE).

    Args:
        path: Output file; the extension picks the format.
        rgb: Radiance, shape (H, W, 3).

    Raises:
        ImageError: unknown extension or a failed write (message names the file).
    """
    path = os.fspath(path)
    img = np.ascontiguousarray(np.asarray(rgb, dtype=np.float32))
    if img.ndim != 3 or img.shape[2] != 3:
        raise ImageError(f"{path}: image to write must have shape (H, W, 3), got {img.shape}")
    ext = os.path.splitext(path)[1].lower()
    if ext in EXR_EXTENSIONS:
        import OpenEXR

        header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
        channels = {c: np.ascontiguousarray(img[:, :, i]) for i, c in enumerate("RGB")}
        try:
            with OpenEXR.File(header, channels) as f:
                f.write(path)
        except Exception as exc:
            raise ImageError(f"{path}: cannot write OpenEXR ({exc})") from exc
    elif ext in HDR_EXTENSIONS:
        import cv2

        if not cv2.imwrite(path, np.ascontiguousarray(img[:, :, ::-1])):
            raise ImageError(f"{path}: cannot write Radiance HDR")
    else:
        raise ImageError(f"{path}: unsupported environment image type '{ext}' (use .exr or .hdr)")
