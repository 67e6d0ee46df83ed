"""Method knobs declared once (warpshade.visibility.knobs): the schema gives the command-line flags, the
knobs read back from them, validation naming the knob, what knobs() reports, and the run's group key,
for transfer and area-light methods alike (one interface, one registry)."""

from __future__ import annotations

import argparse
import inspect

import numpy as np
import pytest

from warpshade.geometry import TriMesh
from warpshade.pipeline.config import RUN_KNOBS, group_objects, resolve_knobs
from warpshade.scene import SceneObject
from warpshade.visibility import AREA_METHODS, METHODS, REGISTRY, VisibilityMethod, get_method
from warpshade.visibility.gears import AreaVisibilityMethod, LightRect, get_area_method

ALL = [(kind, name) for kind in REGISTRY for name in REGISTRY[kind]]


def quad(name="q"):
    p = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    return TriMesh(p, np.array([[0, 1, 2], [0, 2, 3]]), name=name)


def test_one_registry_for_both_families():
    assert set(METHODS) == {"reference", "hemiraster", "disks", "spheres"}
    assert set(AREA_METHODS) == {"gears", "reference"}
    for kind, name in ALL:
        cls = get_method(name, kind)
        assert issubclass(cls, VisibilityMethod) and cls.kind == kind and cls.name == name
    assert get_area_method("gears") is get_method("gears", kind="area")
    assert issubclass(get_area_method("reference"), AreaVisibilityMethod)
    with pytest.raises(ValueError, match="unknown area-light visibility method 'disks'"):
        get_method("disks", kind="area")


@pytest.mark.parametrize("kind,name", ALL)
def test_schema_defaults_are_the_constructors_and_the_cli_reads_them_back(kind, name):
    cls = get_method(name, kind)
    params = inspect.signature(cls.__init__).parameters
    for k in cls.SCHEMA:
        assert params[k.name].default == k.default, k.name
    parser = argparse.ArgumentParser()
    cls.add_arguments(parser)
    defaults = cls.knobs_from_args(parser.parse_args([]))
    assert defaults == {k.name: k.default for k in cls.SCHEMA if k.cli}
    # every sweep entry is a valid knob set
    for entry in cls.sweep(quick=True) + cls.sweep(quick=False):
        cls.normalise_knobs({k: v for k, v in entry.items() if k != "order"})


def test_cli_flags_parse_types_and_negated_booleans():
    cls = get_method("hemiraster")
    parser = argparse.ArgumentParser()
    cls.add_arguments(parser)
    kn = cls.knobs_from_args(parser.parse_args(["--mask", "16", "--no-cull", "--view", "0,1,0", "--lut-dir", "/tmp/x"]))
    assert kn["mask"] == 16 and kn["cull"] is False and kn["view"] == (0.0, 1.0, 0.0) and kn["lut_dir"] == "/tmp/x"
    assert "rim" not in kn  # not a command-line knob
    with pytest.raises(SystemExit):
        parser.parse_args(["--mask", "12"])


def test_knobs_reported_by_an_instance_cover_the_schema():
    m = get_method("reference")(quad(), order=2, rays=10)
    assert m.knobs() == {"rays": 9, "seed": 0, "offset": 1e-5}  # 10 rays rounded to 3x3 strata
    h = get_method("hemiraster")(quad(), order=2)
    assert set(h.knobs()) == {k.name for k in h.SCHEMA} | {"pvs_frames", "occluders"}
    light = LightRect([0.5, 0.5, 2.0], [0.5, 0, 0], [0, 0.5, 0])
    g = get_area_method("gears")(quad(), light, k=8)
    assert g.knobs() == {"k": 8, "offset": 1e-5, "grid": 16}


def test_validation_names_the_method_and_the_knob():
    cls = get_method("reference")
    with pytest.raises(ValueError, match=r"^reference: unknown knob 'ray' \(its knobs: rays, seed, offset\)$"):
        cls.normalise_knobs({"ray": 4})
    with pytest.raises(ValueError, match=r"^reference: rays must be an integer >= 1, got 0$"):
        cls.normalise_knobs({"rays": 0})
    with pytest.raises(ValueError, match=r"^disks: sides must be one of auto, one, two, got 'both'$"):
        get_method("disks").normalise_knobs({"sides": "both"})
    # a scene's integral float and numpy scalars are coerced to the knob's type
    assert get_method("reference").normalise_knobs({"rays": np.int32(64), "offset": 1})["rays"] == 64
    assert get_method("hemiraster").normalise_knobs({"mask": 16.0})["mask"] == 16


def test_empty_and_spelled_out_default_knobs_make_one_shading_group():
    # {} is the run's defaults (reference: RUN_KNOBS, 256 rays; hemiraster: its own); spelled out, they are the
    # same configuration and so the same shading group (they shadow each other through one method)
    hemi = get_method("hemiraster").default_knobs()
    ref = {"rays": 256, "seed": 0, "offset": 1e-5}
    assert RUN_KNOBS["reference"] == {"rays": 256}
    objs = [SceneObject("a", quad("a"), "static", method="hemiraster", knobs={}),
            SceneObject("b", quad("b"), "static", method="hemiraster", knobs=hemi),
            SceneObject("c", quad("c"), "static", method="hemiraster", knobs={"mask": 32, "refine": 2}),
            SceneObject("d", quad("d"), "static", method="reference", knobs={}),
            SceneObject("e", quad("e"), "static", method="reference", knobs=ref),
            SceneObject("f", quad("f"), "static", method="reference", knobs={"rays": 1024})]
    groups = group_objects(objs)
    assert [g.names for g in groups] == [["a", "b", "c"], ["d", "e"], ["f"]]
    assert groups[1].knobs == resolve_knobs("reference", {}) == {"rays": 256, "seed": 0, "offset": 1e-5}
    assert groups[0].label == {} and groups[1].label == {"rays": 256} and groups[2].label == {}


def test_planner_default_knobs_come_from_the_schema_not_argparse():
    from warpshade import planner

    assert planner.default_knobs("disks") == {"lod": 2.0, "passes": 0, "sides": "auto", "samples": 3,
                                              "back_weight": None}
    assert "argparse" not in inspect.getsource(planner.default_knobs)
