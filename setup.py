"""Package layout (the rest of the metadata is in pyproject.toml).

Two data-only packages: ``warpshade.data`` (the planner's measured constants) and
``warpshade.usd_scenes``, which is the top-level ``usd_scenes/`` folder installed inside the package
so a wheel carries the shipped scenes; ``warpshade.usd.shipped`` finds them in a checkout and in an
install alike.
"""

from setuptools import find_packages, setup

setup(
    packages=find_packages(include=["warpshade", "warpshade.*"]) + ["warpshade.data", "warpshade.usd_scenes"],
    package_dir={"warpshade.usd_scenes": "usd_scenes"},
    package_data={"warpshade.data": ["*.json"], "warpshade.usd_scenes": ["*.usda", "*.exr"]},
)
