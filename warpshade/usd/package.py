"""Self-contained export of a run's output: one flattened ``.usdc`` or a ``.usdz`` package.

A ``warpshade run`` output is a top file whose animation lives in value clips (per-chunk frame
files in ``OUT_frames/``) and whose dome light may point at a texture beside them. :func:`export`
flattens the composed stage (the clips' time samples are baked into one layer), and

* for ``.usdc`` / ``.usda``: copies every texture into ``<stem>_textures/`` beside the result and
  points the asset paths there, relatively;
* for ``.usdz``: packages the flattened layer and its textures with ``UsdUtils`` (the package
  holds the textures; asset paths inside it are relative).

pip's usd-core ships no ``usdcat``/``usdzip``; this is the same work through the Python API.
"""

from __future__ import annotations

import os
import shutil
import tempfile

from pxr import Sdf, Usd, UsdUtils

from .writer import OutputWriteError, replace_atomically

FORMATS = (".usdc", ".usda", ".usdz")


def _asset_attributes(layer: Sdf.Layer):
    """Every asset-valued attribute spec of ``layer`` with a non-empty default value."""
    found = []

    def visit(path):
        if path.IsPropertyPath():
            spec = layer.GetAttributeAtPath(path)
            if spec and spec.typeName == Sdf.ValueTypeNames.Asset and spec.default:
                found.append(spec)

    layer.Traverse(Sdf.Path.absoluteRootPath, visit)
    return found


def export(source: str, destination: str) -> str:
    """Write ``source`` (any USD file, e.g. a ``warpshade run`` output) as one self-contained file.

    Args:
        source: The output to export (``.usda``/``.usdc``/``.usd``).
        destination: ``.usdc`` or ``.usda`` (flattened layer + ``<stem>_textures/``) or ``.usdz``.

    Returns:
        The destination path.

    Raises:
        ValueError: for a missing source, an unsupported destination extension, a destination
            equal to the source or in a missing folder, or a texture that does not exist.
        OutputWriteError: when writing fails (nothing partial is left at ``destination``).
    """
    src, dst = os.path.abspath(source), os.path.abspath(destination)
    ext = os.path.splitext(dst)[1].lower()
    if not os.path.isfile(src):
        raise ValueError(f"{source}: no such file")
    if ext not in FORMATS:
        raise ValueError(f"{destination}: the export format is chosen by the extension: one of {', '.join(FORMATS)}")
    if src == dst:
        raise ValueError(f"{destination}: is the source itself; choose another name")
    folder = os.path.dirname(dst)
    if not os.path.isdir(folder):
        raise ValueError(f"{destination}: folder {folder} does not exist")
    stage = Usd.Stage.Open(src)
    if stage is None:
        raise ValueError(f"{source}: cannot open USD stage")
    flat = stage.Flatten()  # composes sublayers, references and value clips into time samples
    textures = {}
    for spec in _asset_attributes(flat):
        asset = spec.default
        path = asset.resolvedPath or asset.path
        if not os.path.isabs(path):
            path = os.path.join(os.path.dirname(src), path)
        if not os.path.isfile(path):
            raise ValueError(f"{source}: {spec.path}: asset {asset.path} not found")
        textures.setdefault(path, f"{len(textures):02d}_{os.path.basename(path)}")
        spec.default = Sdf.AssetPath(textures[path])  # relative to the flattened layer, for now
    stem = os.path.splitext(os.path.basename(dst))[0]
    if ext == ".usdz":
        with tempfile.TemporaryDirectory(prefix="warpshade-export-") as tmp:
            for path, name in textures.items():
                shutil.copyfile(path, os.path.join(tmp, name))
            layer_path = os.path.join(tmp, f"{stem}.usdc")
            flat.Export(layer_path)

            def write(tmp_path):
                if not UsdUtils.CreateNewUsdzPackage(Sdf.AssetPath(layer_path), tmp_path):
                    raise OSError(f"UsdUtils could not package {layer_path}")

            replace_atomically(write, dst, "usdz package")
        return dst
    tex_dir = os.path.join(folder, f"{stem}_textures")
    if textures:
        os.makedirs(tex_dir, exist_ok=True)
        for path, name in textures.items():
            shutil.copyfile(path, os.path.join(tex_dir, name))
        for spec in _asset_attributes(flat):
            spec.default = Sdf.AssetPath(f"./{stem}_textures/{spec.default.path}")

    def write(tmp_path):
        if not flat.Export(tmp_path):
            raise OSError(f"cannot export {tmp_path}")

    replace_atomically(write, dst, "exported file")
    return dst


__all__ = ["FORMATS", "OutputWriteError", "export"]
