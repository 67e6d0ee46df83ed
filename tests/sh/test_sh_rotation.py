"""SH rotation matrices (thesis §3.1.2; Ivanic–Ruedenberg) in the basis convention of docs/conventions.md §1."""

from __future__ import annotations

import numpy as np
import pytest

from warpshade.sh import sh_eval
from warpshade.sh.rotation import rotate, rotation_from_axis_angle, rotation_matrix
from warpshade.sh.zonal import zh_rotate, zh_to_sh


def random_rotation(rng):
    q, r = np.linalg.qr(rng.normal(size=(3, 3)))
    q = q * np.sign(np.diag(r))
    return q if np.linalg.det(q) > 0 else -q


def random_dirs(rng, n):
    d = rng.normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=1, keepdims=True)


SPECIAL = [np.eye(3), rotation_from_axis_angle([0, 0, 1], np.pi), rotation_from_axis_angle([1, 0, 0], np.pi),
           rotation_from_axis_angle([0, 1, 0], np.pi / 2), rotation_from_axis_angle([1, 1, 0], np.pi),
           rotation_from_axis_angle([0, 0, 1], 1e-9)]


@pytest.mark.parametrize("order", [1, 2, 3, 5, 8, 12])
def test_rotated_function_pointwise(order, rng):
    # Definition: f'(s) = f(R^T s) for every direction, i.e. y(R^T s) = M^T y(s). Independent of how M is built.
    for r in SPECIAL + [random_rotation(rng) for _ in range(3)]:
        m = rotation_matrix(r, order)
        d = random_dirs(rng, 100)
        np.testing.assert_allclose(sh_eval(d @ r, order), sh_eval(d, order) @ m, atol=1e-12,
                                   err_msg=f"order {order} R={r}")


@pytest.mark.parametrize("order", [3, 8])
def test_rotate_then_project_equals_project_then_rotate(order, rng):
    # A non-band-limited function (exp of a dot product plus a clamped cubic lobe) projected by Gauss-Legendre
    # x uniform-phi quadrature on 160 x 320 nodes; the two sides differ only by quadrature error.
    a = np.array([0.3, -0.8, 0.5])
    b = np.array([0.0, 0.6, 0.8])

    def f(s):
        return np.exp(1.5 * s @ a) + np.maximum(0.0, s @ b) ** 3

    x, w = np.polynomial.legendre.leggauss(160)
    phi = (np.arange(320) + 0.5) * 2 * np.pi / 320
    st = np.sqrt(1 - x**2)
    d = np.stack([np.outer(st, np.cos(phi)), np.outer(st, np.sin(phi)), np.outer(x, np.ones(320))], -1).reshape(-1, 3)
    wq = np.repeat(w * 2 * np.pi / 320, 320)
    y = sh_eval(d, order) * wq[:, None]
    r = random_rotation(rng)
    rotated_then_projected = f(d @ r) @ y  # f'(s) = f(R^T s)
    projected_then_rotated = rotation_matrix(r, order) @ (f(d) @ y)
    # The clamped cubic lobe has a kink, so quadrature converges algebraically: measured 1e-10 at this grid
    # (9e-12 at 320 x 640); 1e-9 keeps margin and still catches any wrong sign or index (errors ~1).
    np.testing.assert_allclose(rotated_then_projected, projected_then_rotated, atol=1e-9)


def test_composition_orthogonality_and_zh(rng):
    order = 8
    r1, r2 = random_rotation(rng), random_rotation(rng)
    m1, m2 = rotation_matrix(r1, order), rotation_matrix(r2, order)
    np.testing.assert_allclose(rotation_matrix(r1 @ r2, order), m1 @ m2, atol=1e-13)
    np.testing.assert_allclose(m1 @ m1.T, np.eye(64), atol=1e-13)
    np.testing.assert_allclose(rotation_matrix(r1.T, order), m1.T, atol=1e-13)
    # Block diagonal: no band mixing.
    for l in range(order):
        lo, hi = l * l, (l + 1) ** 2
        assert np.abs(m1[lo:hi, :lo]).max(initial=0) == 0 and np.abs(m1[lo:hi, hi:]).max(initial=0) == 0
    g = rng.normal(size=order)
    np.testing.assert_allclose(m1 @ zh_to_sh(g), zh_rotate(g, r1[:, 2]), atol=1e-13)


def test_high_order_stays_orthogonal(rng):
    r = random_rotation(rng)
    m = rotation_matrix(r, 24)
    # Recurrence error grows slowly with l; measured 6e-15 at order 24.
    np.testing.assert_allclose(m @ m.T, np.eye(24 * 24), atol=1e-13)


def test_rotate_batched_and_rgb(rng):
    r = random_rotation(rng)
    m = rotation_matrix(r, 5)
    c = rng.normal(size=(7, 25))
    np.testing.assert_allclose(rotate(c, r), c @ m.T, atol=1e-13)
    rgb = rng.normal(size=(25, 3))
    np.testing.assert_allclose(rotate(rgb, r, axis=0), m @ rgb, atol=1e-13)
    with pytest.raises(ValueError, match="square number"):
        rotate(rgb, r)


def test_bad_rotations():
    with pytest.raises(ValueError, match="det"):
        rotation_matrix(np.diag([1.0, 1.0, -1.0]), 3)
    with pytest.raises(ValueError, match="orthonormal"):
        rotation_matrix(2 * np.eye(3), 3)
    with pytest.raises(ValueError, match="3x3"):
        rotation_matrix(np.eye(2), 3)
