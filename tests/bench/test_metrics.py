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
