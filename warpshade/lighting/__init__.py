"""Lighting: environment maps (.exr/.hdr), analytic sky (the default), directional, point, sphere and
rect lights, all as RGB SH radiance in world space (see :mod:`warpshade.lighting.base`)."""

from .base import Light, Spin, lights_sh, spin
from .environment import ConstantEnvironment, EnvironmentMap, up_frame
from .images import ImageError, read_image, write_image
from .lights import DirectionalLight, PointLight, RectLight, SphereLight
from .sky import Sky, default_environment, sun_direction

__all__ = ["ConstantEnvironment", "DirectionalLight", "EnvironmentMap", "ImageError", "Light", "PointLight",
           "RectLight", "Sky", "SphereLight", "Spin", "default_environment", "lights_sh",
           "read_image", "spin", "sun_direction", "up_frame", "write_image"]
