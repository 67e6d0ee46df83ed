"""Lights of a run: UsdLux descriptions (:class:`warpshade.scene.LightSpec`) to
:mod:`warpshade.lighting` objects, and the default sky back to UsdLux for the output file."""

from __future__ import annotations

import math

import numpy as np

from ..scene import LightSpec, SceneError


def default_lights(up: str = "Y") -> list:
    """warpshade's default lighting (the analytic sky with its sun) for a scene without lights."""
    from ..lighting import default_environment

    return [default_environment(up=up)]


def sky_light_specs(sky, image_path: str, up: str = "Y", height: int = 128) -> list[LightSpec]:
    """UsdLux description of an analytic :class:`warpshade.lighting.Sky` for the output file: a
    DomeLight whose lat-long texture (written to ``image_path``) is :meth:`Sky.to_image` (the sun's
    energy splatted into its texel), oriented so its pole is the stage's up axis."""
    from ..lighting import up_frame, write_image

    write_image(image_path, sky.to_image(height, up=up))
    frame = up_frame(up)  # map frame -> world; a DomeLight's map pole is its prim's +Y
    xf = np.eye(4)
    xf[:3, :3] = frame
    return [LightSpec("dome", "DefaultSky", texture=image_path, transform=xf)]


def light_from_spec(spec: LightSpec, up: str = "Y", fps: float | None = None):
    """A :mod:`warpshade.lighting` light from a UsdLux description (mapping documented in
    :mod:`warpshade.lighting.lights`: ``L = color · intensity · 2^exposure``; with ``normalize`` the
    power is independent of size, so radiance is divided by the emitting area, and a distant light
    gives irradiance). A light keyed to turn (``spec.rotations``) moves with them (``fps``: the run's
    frames per second, needed then)."""
    light = _light(spec, up)
    if spec.rotations is not None:
        from ..lighting.base import Keyed

        if fps is None:
            raise ValueError(f"{spec.name}: a keyed light needs the run's frames per second")
        light = light.with_motion(Keyed(np.asarray(spec.rotations, dtype=np.float64), float(fps)))
    return light


def _light(spec: LightSpec, up: str):
    from .. import lighting

    L = spec.radiance
    xf = spec.transform
    rot = xf[:3, :3] / np.maximum(np.linalg.norm(xf[:3, :3], axis=0), 1e-300)
    name = spec.name
    if spec.kind == "dome":
        if spec.texture:
            # UsdLux DomeLight (schema version 0, no poleAxis): the map's +Y pole is the dome prim's
            # +Y, so the prim's rotation alone orients it, whatever the stage's up axis.
            return lighting.EnvironmentMap.from_file(spec.texture, intensity=L, up="Y", rotation=rot, name=name)
        return lighting.ConstantEnvironment(radiance=L, name=name)
    if spec.kind == "distant":
        towards = xf[:3, 2]  # UsdLux: the light shines along its -Z
        if spec.normalize or spec.angle <= 0:
            return lighting.DirectionalLight(direction=towards, irradiance=L, angle=max(spec.angle, 0.0), name=name)
        return lighting.DirectionalLight.from_radiance(towards, L, angle=spec.angle, name=name)
    if spec.kind == "sphere":
        scale = float(np.cbrt(abs(np.linalg.det(xf[:3, :3]))))
        r = spec.radius * scale
        light = lighting.SphereLight(position=spec.position, radius=r,
                                     radiance=L / (4 * math.pi * r * r) if spec.normalize else L, name=name)
        return light.as_point() if spec.treat_as_point else light
    if spec.kind == "rect":
        u, v = xf[:3, 0] * spec.width / 2, xf[:3, 1] * spec.height / 2
        area = 4 * float(np.linalg.norm(np.cross(u, v)))
        return lighting.RectLight(center=spec.position, u=u, v=v, radiance=L / area if spec.normalize else L, name=name)
    raise SceneError(f"{spec.name}: light kind '{spec.kind}' is not supported")
