"""Where the shipped scenes are: the one place that knows the folder of ``usd_scenes/*.usda``.

The scenes live in the repository's top-level ``usd_scenes/``. A wheel ships that folder as
package data inside the package, at ``warpshade/usd_scenes/`` (``setup.py`` maps the package
``warpshade.usd_scenes`` onto it), so the same scenes are found in a source checkout, an editable
install and a wheel install alike.
"""

from __future__ import annotations

import os

_PACKAGE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))  # .../warpshade
_CANDIDATES = (
    os.path.join(_PACKAGE, "usd_scenes"),  # installed wheel: package data inside the package
    os.path.join(os.path.dirname(_PACKAGE), "usd_scenes"),  # source checkout or editable install
)


def shipped_scenes_dir() -> str:
    """Folder holding the shipped scenes (``default.usda`` and the others).

    Returns:
        Absolute path of the folder.

    Raises:
        FileNotFoundError: no candidate folder holds ``default.usda`` (a broken install).
    """
    for folder in _CANDIDATES:
        if os.path.isfile(os.path.join(folder, "default.usda")):
            return folder
    raise FileNotFoundError("shipped scenes not found: no default.usda in " + " or ".join(_CANDIDATES)
                            + " (reinstall warpshade)")


def shipped_scene(name: str = "default.usda") -> str:
    """Path of one shipped scene, e.g. ``shipped_scene("rect_light.usda")``.

    Raises:
        FileNotFoundError: the shipped scenes hold no file of that name (the message lists those there are).
    """
    folder = shipped_scenes_dir()
    path = os.path.join(folder, name)
    if not os.path.isfile(path):
        have = ", ".join(sorted(f for f in os.listdir(folder) if f.endswith(".usda")))
        raise FileNotFoundError(f"no shipped scene {name!r} in {folder} (shipped: {have})")
    return path
