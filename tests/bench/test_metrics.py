"""Error metrics on hand-computed cases."""

import numpy as np
import pytest

from warpshade.bench.metrics import error_summary, transfer_errors


def test_relative_errors_hand_computed():
    ref = np.array([[3.0, 4.0], [0.0, 0.0]])  # norms 5 and 0: mean 2.5
    t = np.array([[3.0, 5.0], [0.0, 0.5]])
    np.testing.assert_allclose(transfer_errors(t, ref), [1 / 2.5, 0.5 / 2.5])
    s = error_summary(t, ref)
    assert s["error_mean"] == pytest.approx(0.3) and s["error_max"] == pytest.approx(0.4)


def test_zero_reference_is_an_error():
    with pytest.raises(ValueError, match="zero"):
        transfer_errors(np.ones((2, 4)), np.zeros((2, 4)))


def _sheet(n, xy_to_xyz):
    """An n x n grid sheet over [0, 1]² mapped through ``xy_to_xyz``; edge length 1/(n-1) before mapping."""
    x, y = np.meshgrid(np.linspace(0, 1, n), np.linspace(0, 1, n), indexing="ij")
    idx = np.arange(n * n).reshape(n, n)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[1:, :-1].ravel(), idx[1:, 1:].ravel(), idx[:-1, 1:].ravel()
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    return xy_to_xyz(x.ravel(), y.ravel()), faces, idx


@pytest.mark.parametrize("gap_edges, contact", [(0.5, True), (3.0, False)])
def test_receiver_classes_two_layers(gap_edges, contact):
    # two flat 9 x 9 sheets (grid step h = 1/8, mean edge 1.14 h with the diagonals) stacked gap_edges * h
    # apart, as one mesh: at 0.5 h every vertex has the other layer within the classes' 1.5 mean edges
    # (1.71 h); at 3 h none does, and a flat sheet's own vertices within 1.71 h (1 and sqrt(2) h away, the
    # 1-ring) never count as contact
    from warpshade.bench.metrics import receiver_classes

    h = 1 / 8
    p0, f0, _ = _sheet(9, lambda x, y: np.stack([x, y, 0 * x], 1))
    p = np.concatenate([p0, p0 + [0.0, 0.0, gap_edges * h]])
    f = np.concatenate([f0, f0[:, ::-1] + len(p0)])
    c = receiver_classes(p, f)
    assert c["contact"].all() if contact else not c["contact"].any()
    assert not c["fold"].any()  # flat layers
    assert (c["contact"].astype(int) + c["fold"] + c["open"] == 1).all()


def test_receiver_classes_crease():
    # a 13 x 13 sheet bent along x = 0.5 by 130°: at the crease the vertex normal bisects the two
    # planes, so its triangles turn 65° from it (> the 60° threshold); six columns away the sheet is flat
    # (open). The flaps open at 50°, so no vertex more than 4 edges away along the mesh comes within
    # 1.5 edge lengths: nothing is contact.
    from warpshade.bench.metrics import receiver_classes

    t = np.radians(130.0)

    def bend(x, y):
        s = x - 0.5
        folded = np.stack([0.5 + np.cos(t) * s, y, np.sin(t) * s], 1)
        return np.where((s > 0)[:, None], folded, np.stack([x, y, 0 * x], 1))

    p, f, idx = _sheet(13, bend)
    c = receiver_classes(p, f)
    assert not c["contact"].any()
    assert c["fold"][idx[6]].all()
    assert c["open"][idx[0]].all() and c["open"][idx[12]].all()
    assert not c["fold"][np.r_[idx[:5].ravel(), idx[8:].ravel()]].any()
