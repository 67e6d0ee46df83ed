"""A user's scene from issue 19: a sheet pinned at two corners (or along an edge) falls 10 cm onto
a Cylinder post and drapes over its rim (the stage: ``post_scene`` of benchmarks/post_drape.py).
Nothing moves but the cloth, and the sheet can slide over the post unstretched. Before the
cylinder's rim was kept out of the cloth triangles in the substeps (``ColliderSet.collide_edges``'
face pass), the rim cut the triangles lying over it at the end of almost every step, the
intersection guard held those vertices at their start positions for 30 steps in a row while the
rest fell, and the edges between stretched to 3x their rest length (``ClothSimulation`` warned).
A fine sheet (3 cm edges) over a thin post (4 cm radius) still hooked on the rim at 8 substeps a
frame (edges past 3x, guard holds of 9-14 steps), which a scene with a cylinder or cone now gets 16
of (``pipeline.cloth.RIM_SUBSTEPS``).

Each case asserts 0 intersecting pairs (cloth-cloth and cloth-collider, exact count) at the end
of every frame, no strain warning, guard holds of at most :data:`HOLD` steps, and the p99 and
worst edge strain over all frames under :data:`P99` and :data:`WORST`, and that the sheet lay on the
post's cap (so a sheet that missed the post cannot pass). Measured on the branch that brought the
16 substeps (the four cases): holds of 0 steps, p99 4-10 %, worst 19-97 %; at 8 substeps: holds of
0-6 steps, p99 12-36 %, worst 30-332 % (the fine sheet)."""

from __future__ import annotations

import importlib.util
import os
import warnings

import numpy as np
import pytest
from helpers import REPO

from warpshade.pipeline.cloth import ClothSimulation
from warpshade.scene import SceneWarning
from warpshade.sim import IntersectionCounter
from warpshade.usd.scene_io import read_scene

HOLD = 3
"""Longest guard hold allowed [steps] (measured 0; at 8 substeps 0-6, before the face pass 30-31)."""
P99 = 0.2
"""p99 edge strain allowed over all frames (measured 0.04-0.10; at 8 substeps 0.12-0.36)."""
WORST_FINE = 1.5
"""Worst edge strain allowed on the 41 x 41 sheet over the 4 cm post (measured 0.97 over its 35 frames; the
matrix's other pinnings and stage conventions of it 0.87-1.59, benchmarks/post_drape.py; 8 substeps 3.10-3.42)."""
CAP_FRAMES = 5
"""Frames the sheet must lie on the cap."""
WORST = 0.6
"""Worst edge strain allowed but on the 41 x 41 sheet (measured 0.19-0.36; at 8 substeps 0.30-0.69, before the
face pass 0.98-2.22)."""


_BENCH = importlib.util.spec_from_file_location("post_drape", os.path.join(REPO, "benchmarks", "post_drape.py"))
post_drape = importlib.util.module_from_spec(_BENCH)
_BENCH.loader.exec_module(post_drape)


@pytest.mark.parametrize("case", [{}, {"n": 17, "pins": "edge", "yup": True}, {"n": 17, "jitter": 1},
                                  {"n": 41, "radius": 4.0, "frames": 20}],
                         ids=["z_up_cm_25", "edge_pinned_y_up_m_17", "jittered_17", "fine_41_thin_post_4cm"])
def test_sheet_drapes_over_a_post_unheld_and_unstretched(tmp_path, case):
    case = dict(case)
    frames = case.pop("frames", None)  # (the fine sheet: the first 20 frames, where it hooked on the rim)
    sim = ClothSimulation(read_scene(post_drape.post_scene(tmp_path / "post.usda", diagonal="test", **case)))
    solver, model = sim.solver, sim.model
    counter = IntersectionCounter(model.faces)
    edges = model.edges_np
    rest = model.edge_rest_length.numpy().astype(np.float64)
    radius = case.get("radius", 8.0)
    pairs, strain, on_cap = [], [], []
    with warnings.catch_warnings():
        warnings.simplefilter("error", SceneWarning)
        for f in range(1, sim.frames if frames is None else frames + 1):
            sim.advance(f, {})
            x = sim.state.points
            pairs.append(counter.self_pairs(x)[0] + counter.collider_pairs(x, solver.colliders)[0])
            p = x.numpy().astype(np.float64)
            strain.append(np.linalg.norm(p[edges[:, 0]] - p[edges[:, 1]], axis=1) / rest - 1.0)
            # vertices on the post's cap (within 2 cm above its 70 cm) [cm]
            up, across = (100 * p[:, 1], 100 * np.stack([p[:, 0], -p[:, 2]], 1)) if case.get("yup") else \
                (100 * p[:, 2], 100 * p[:, :2])
            on_cap.append(int(((np.linalg.norm(across - (0.0, 10.0), axis=1) < radius) & (up > 70.0)
                               & (up < 72.0)).sum()))
    strain = np.concatenate(strain)
    stats = solver.stats()
    assert not any(pairs), f"intersecting pairs at frames {[f + 1 for f, n in enumerate(pairs) if n]}: {stats}"
    assert stats["guard_longest_hold"] <= HOLD, stats
    worst = WORST_FINE if case.get("n") == 41 else WORST
    assert np.percentile(strain, 99) < P99 and strain.max() < worst, (np.percentile(strain, 99), strain.max(), stats)
    # the sheet fell onto the post: some of it lay on the cap for CAP_FRAMES frames or more, and most of it
    # ends below the cap
    assert sum(n > 0 for n in on_cap) >= CAP_FRAMES and np.median(up) < 70.0, (on_cap, np.median(up))
