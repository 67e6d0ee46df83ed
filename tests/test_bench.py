"""``warpshade bench``: Pareto mask, environment projection, and the CLI's outputs on a tiny sweep."""

from __future__ import annotations

import csv
import json
import math

import numpy as np

from warpshade.bench.environments import project, radiance
from warpshade.bench.runner import pareto_mask
from warpshade.cli import main as cli_main


def test_pareto_mask_hand_computed():
    # (time, error): b dominates c (faster and better); a and b trade off; d ties a in time but worse error
    s = [1.0, 2.0, 3.0, 1.0]
    e = [0.5, 0.1, 0.2, 0.6]
    assert pareto_mask(s, e).tolist() == [True, True, False, False]


def test_projection_of_constant_and_linear_functions():
    # constant c: only the DC term, c * y_0 * 4π; z: only y_2 (= 0.488603 z), ∫ z y_2 = sqrt(4π/3)
    c = project(lambda d: np.full((len(d), 3), 2.0), order=3)
    np.testing.assert_allclose(c[0], 2.0 * 0.5 / math.sqrt(math.pi) * 4 * math.pi, rtol=1e-6)
    assert np.abs(c[1:]).max() < 1e-4
    z = project(lambda d: np.repeat(d[:, 2:3], 3, axis=1), order=3)
    np.testing.assert_allclose(z[2], math.sqrt(4 * math.pi / 3), rtol=1e-4)
    assert np.abs(np.delete(z, 2, axis=0)).max() < 1e-4


def test_radiance_uses_common_coefficients():
    t = np.array([[1.0, 2.0, 3.0, 4.0]])
    light = np.ones((9, 3))
    np.testing.assert_allclose(radiance(t, light), [[10 / math.pi] * 3])


def test_cli_quick_sweep_writes_results(tmp_path):
    out = tmp_path / "b"
    rc = cli_main(["bench", "--quick", "--out", str(out), "--methods", "reference", "--meshes", "cloth",
                   "--orders", "3", "--ground-truth-rays", "1024", "--cache-dir", "none", "--repeat", "1"])
    assert rc == 0
    recs = json.loads((out / "results.json").read_text())
    # reference quick sweep (64, 256, 1024 rays) at order 5 + default knobs at order 3
    assert [(r["order"], r["knobs"]["rays"]) for r in recs] == [(5, 64), (5, 256), (5, 1024), (3, 1024)]
    for r in recs:
        assert {"method", "mesh", "knobs", "seconds", "error_mean", "error_p95", "radiance_error_sky",
                "radiance_error_studio", "array_bytes"} <= set(r)
        assert r["seconds"] > 0 and r["error_mean"] > 0 and r["error_max"] >= r["error_p95"]
    errs = [r["error_mean"] for r in recs[:3]]
    # Monte-Carlo error against an independent 1024-ray ground truth falls with the ray count
    assert errs[0] > errs[1] > errs[2], errs
    # the 1024-ray run matches ground truth of the same ray count to within twice its MC error (~1.5 % each)
    assert errs[2] < 0.04, errs
    rows = list(csv.DictReader((out / "results.csv").open()))
    assert len(rows) == 4 and rows[0]["method"] == "reference"
    assert (out / "pareto.png").stat().st_size > 10000
