"""``"none"`` (no visibility method: unoccluded transfer) means the same in a scene's ``warpshade:method``, in
``Pipeline(method=)`` and in ``warpshade run --method``: one decision, ``visibility.transfer_method``."""

import numpy as np
import pytest
from helpers import usd_grid
from pxr import Sdf, Usd, UsdGeom, UsdLux

from warpshade.pipeline import Pipeline
from warpshade.scene import SceneError
from warpshade.usd import read_scene


def _scene(tmp_path, method=None):
    """A floor under a smaller roof, under a dome; ``warpshade:method = method`` on both if given."""
    path = tmp_path / f"scene_{method}.usda"
    stage = Usd.Stage.CreateNew(str(path))
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    stage.SetDefaultPrim(stage.DefinePrim("/World", "Xform"))
    for prim in (usd_grid(stage, "/World/Floor", 9, 0.0, 4.0).GetPrim(),
                 usd_grid(stage, "/World/Roof", 5, 0.5, 1.0).GetPrim()):
        if method is not None:
            prim.CreateAttribute("warpshade:method", Sdf.ValueTypeNames.Token, custom=True).Set(method)
    UsdLux.DomeLight.Define(stage, "/World/Sky")
    stage.GetRootLayer().Save()
    return read_scene(str(path))


def _shade(scene, **kwargs):
    pipe = Pipeline(scene, frames=1, order=3, write_transfer=True, between=None, two_sided="off",
                    refine_receivers="off", reuse=None, **kwargs)
    return pipe, pipe.shader.build()(0, {})


def test_none_in_usd_and_in_the_pipeline_shade_alike(tmp_path):
    # Pipeline(method="none") was rejected ("unknown visibility method 'none'") while the scene's was accepted
    usd_pipe, usd_out = _shade(_scene(tmp_path, "none"))
    py_pipe, py_out = _shade(_scene(tmp_path), method="none")
    for pipe in (usd_pipe, py_pipe):
        assert [(g.method, sorted(g.names)) for g in pipe.groups] == [(None, ["/World/Floor", "/World/Roof"])]
    for name in ("/World/Floor", "/World/Roof"):
        for a, b in zip(usd_out[name], py_out[name]):
            np.testing.assert_array_equal(np.asarray(a), np.asarray(b))  # bit for bit: the same decision
    # and "none" is unoccluded: the default method darkens the floor under the roof, "none" does not
    _, shadowed = _shade(_scene(tmp_path))
    floor_none, floor_shadowed = np.asarray(py_out["/World/Floor"][3]), np.asarray(shadowed["/World/Floor"][3])
    assert floor_shadowed[:, 0].min() < 0.9 * floor_none[:, 0].min()
    assert np.ptp(floor_none[:, 0]) < 1e-6 * floor_none[:, 0].max()  # a flat floor's unoccluded T0: one value


def test_an_unknown_method_and_knobs_with_none_are_named_alike(tmp_path):
    with pytest.raises(ValueError, match=r"unknown visibility method 'nonee' \(known: .*, none\)"):
        Pipeline(_scene(tmp_path), frames=1, method="nonee")
    with pytest.raises(SceneError, match=r"/World/Floor: warpshade:method: unknown visibility method 'nonee' "
                                         r"\(known: .*, none\)"):
        _scene(tmp_path, "nonee")
    with pytest.raises(ValueError, match="knobs rays given with method 'none'"):
        Pipeline(_scene(tmp_path), frames=1, method="none", knobs={"rays": 8})
