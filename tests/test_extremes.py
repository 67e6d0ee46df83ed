"""Stability at the extremes, for EVERY registered visibility method (parametrized over ``METHODS``, so a
newly registered method is covered without editing this file).

Covered here: SH orders 1..8 in float32; meshes scaled by 1e-4 and 1e4; coincident and degenerate
triangles; receivers touching blockers; hypothesis properties over random meshes and directions.
Method-specific extremes live with each method (SH exp ‖f̂‖ up to 100 in test_sh_exp.py, overlapping
blockers in test_spheres.py/test_disks.py, cloth stiffness/mass/time step in test_sim_cloth.py).

Bounds used throughout: binary visibility times a clamped cosine gives ``0 <= T_0 <= y_0 π`` (the
unoccluded DC, docs/conventions.md §2). Approximate methods may overshoot slightly; the slack is stated where
used.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from warpshade.bench.meshes import grid
from warpshade.geometry import TriMesh
from warpshade.sh import sh_eval
from warpshade.visibility import METHODS, get_method

Y0 = 0.5 / math.sqrt(math.pi)
UNOCCLUDED_DC = Y0 * math.pi
"""``T_0`` of a vertex that sees its whole hemisphere: ``y_0 ∫ max(0, n·ω) dω = y_0 π``."""

DC_SLACK = 0.02 * UNOCCLUDED_DC
"""Allowed overshoot of approximate methods past [0, y_0 π] (2 % of the unoccluded DC: the ray-traced
reference's Monte-Carlo error at 256 rays is ~4 % of the whole vector, its DC far less)."""

FAST_KNOBS = {"reference": {"rays": 256}, "spheres": {"spheres": 8, "levels": 2}}
"""Cheaper knobs where a method's default is slow for a test (other methods run their defaults)."""

settings.register_profile("warpshade", derandomize=True, deadline=None, max_examples=12, database=None,
                          suppress_health_check=[HealthCheck.too_slow])
settings.load_profile("warpshade")

ALL = sorted(METHODS)


def make(name, mesh, order=4):
    return get_method(name)(mesh, order=order, **FAST_KNOBS.get(name, {}))


def bumpy_scene(n: int = 10, subdivisions: int = 2) -> TriMesh:
    """An n×n ground grid with a small icosphere 2 cm above it: self and mutual occlusion (204 vertices by default)."""
    gp, gf = grid(n, size=1.0)
    ico = trimesh.creation.icosphere(subdivisions, radius=0.15)
    sp = np.asarray(ico.vertices) + (0.05, 0.0, 0.17)
    return TriMesh(np.concatenate([gp, sp]), np.concatenate([gf, np.asarray(ico.faces) + len(gp)]), name="bumpy")


def check_bounds(t, name, what):
    assert t.dtype == np.float32, f"{name} {what}: dtype {t.dtype}"
    assert np.isfinite(t).all(), f"{name} {what}: non-finite transfer at vertices {np.flatnonzero(~np.isfinite(t).all(1))[:10]}"
    dc = t[:, 0]
    lo, hi = dc.min(), dc.max()
    assert lo >= -DC_SLACK and hi <= UNOCCLUDED_DC + DC_SLACK, \
        f"{name} {what}: DC outside [0, y0*pi={UNOCCLUDED_DC:.4f}]: min {lo:.5f} at {dc.argmin()}, max {hi:.5f} at {dc.argmax()}"


@pytest.mark.parametrize("order", range(1, 9))
@pytest.mark.parametrize("name", ALL)
def test_orders_1_to_8_float32(name, order):
    m = bumpy_scene(6, 1)  # 78 vertices: 32 configurations, kept small
    t = make(name, m, order).update().numpy()
    assert t.shape == (m.num_vertices, order * order)
    check_bounds(t, name, f"order {order}")


SCALE_KNOWN_BROKEN: dict[str, str] = {}
"""Methods whose transfer changes with the mesh scale (strict xfail; none since the sphere fit runs in a
unit frame, see ``warpshade.visibility.spheres.fitting._unit_frame``)."""


@pytest.mark.parametrize("scale", [1e-4, 1e4])
@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.xfail(strict=True, reason=SCALE_KNOWN_BROKEN[n]))
                                  if n in SCALE_KNOWN_BROKEN else n for n in ALL])
def test_scaled_mesh_same_transfer(name, scale):
    m = bumpy_scene()
    base = make(name, m).update().numpy()
    got = make(name, TriMesh(m.points * scale, m.faces)).update().numpy()
    # float32 positions scaled by 1e±4 round to different values (relative 6e-8), which can flip a
    # grazing ray or a raster pixel; measured worst-case mean difference < 1e-3 of the DC (all methods).
    diff = np.abs(got - base).mean()
    assert diff < 2e-3 * UNOCCLUDED_DC, f"{name} scale {scale}: mean |ΔT| {diff:.2e}"
    check_bounds(got, name, f"scale {scale}")


@pytest.mark.parametrize("name", ALL)
def test_degenerate_triangles_change_nothing(name):
    m = bumpy_scene()
    v = m.num_vertices
    # zero-area triangles: a repeated index, and three collinear ground vertices (row y = -0.5)
    extra = np.array([[0, 0, 1], [5, 5, 5], [0, 1, 2]], dtype=np.int32)
    deg = TriMesh(m.points, np.concatenate([m.faces, extra]), name="with degenerate")
    base = make(name, m).update().numpy()
    got = make(name, deg).update().numpy()
    check_bounds(got, name, "degenerate triangles")
    assert got.shape == (v, base.shape[1])
    # Zero-area triangles occlude nothing and leave normals unchanged (angle weights of a zero-area
    # face are zero), so the transfer is the same up to float rounding of the structures built.
    diff = np.abs(got - base).mean()
    assert diff < 1e-3 * UNOCCLUDED_DC, f"{name}: degenerate triangles changed transfer by {diff:.2e}"


@pytest.mark.parametrize("name", ALL)
def test_coincident_triangles_stay_bounded(name):
    m = bumpy_scene()
    # every triangle of the sphere twice (same vertices): binary visibility is unchanged; methods that
    # sum occlusion must still not go negative or NaN.
    sphere_faces = m.faces[m.faces.min(axis=1) >= 100]
    dup = TriMesh(m.points, np.concatenate([m.faces, sphere_faces]), name="coincident")
    check_bounds(make(name, dup).update().numpy(), name, "coincident triangles")


@pytest.mark.parametrize("name", ALL)
def test_receivers_touching_blockers(name):
    # a cube resting exactly on the ground grid: ground vertices at the contact touch the blocker
    gp, gf = grid(11, size=1.0)
    box = trimesh.creation.box(extents=(0.4, 0.4, 0.4))
    bp = np.asarray(box.vertices) + (0.0, 0.0, 0.2)  # bottom face at z = 0, on the ground's central vertex
    m = TriMesh(np.concatenate([gp, bp]), np.concatenate([gf, np.asarray(box.faces) + len(gp)]), name="touching")
    t = make(name, m).update().numpy()
    check_bounds(t, name, "touching blockers")
    centre = 60  # grid vertex (0, 0, 0), under the cube's bottom face
    assert np.allclose(m.points[centre], 0.0)
    # Receivers near the cube's foot lose part of the sky: the ground ring around the cube must be
    # darker than a far corner (unoccluded).
    ring = [i for i in range(len(gp)) if 0.2 < np.abs(gp[i, :2]).max() <= 0.31]
    assert t[ring, 0].mean() < t[0, 0] - 0.02, (name, t[ring, 0].mean(), t[0, 0])


# ---------------------------------------------------------------- hypothesis properties
@st.composite
def random_mesh(draw):
    """An icosphere (42 vertices) with seeded radial noise up to ±40 % plus a random ground offset."""
    seed = draw(st.integers(0, 2**31 - 1))
    amp = draw(st.floats(0.0, 0.4))
    rng = np.random.default_rng(seed)
    ico = trimesh.creation.icosphere(1)
    p = np.asarray(ico.vertices) * (1 + amp * rng.uniform(-1, 1, (len(ico.vertices), 1)))
    gp, gf = grid(5, size=4.0)
    gp = gp + (0, 0, -1.5 + draw(st.floats(-0.3, 0.3)))
    return TriMesh(np.concatenate([p, gp]), np.concatenate([np.asarray(ico.faces), gf + len(p)]), name=f"random {seed}")


@pytest.mark.parametrize("name", ALL)
@settings(max_examples=4)
@given(mesh=random_mesh(), order=st.integers(1, 6))
def test_random_meshes_transfer_finite_and_bounded(name, mesh, order):
    check_bounds(make(name, mesh, order).update().numpy(), name, f"{mesh.name} order {order}")


unit_dirs = st.tuples(*[st.floats(-1, 1)] * 3).filter(lambda d: 1e-3 < np.linalg.norm(d))


@given(d=unit_dirs, order=st.integers(1, 8))
def test_sh_addition_theorem(d, order):
    # Σ_m y_lm(ω)² = (2l+1)/(4π) for every band (addition theorem), independently of ω.
    y = sh_eval(np.array(d), order)
    for l in range(order):
        band = y[l * l:(l + 1) * (l + 1)]
        assert abs((band ** 2).sum() - (2 * l + 1) / (4 * math.pi)) < 1e-10, (d, l)


@given(d=unit_dirs, e=unit_dirs, order=st.integers(1, 8))
def test_sh_band_inner_product_is_legendre(d, e, order):
    # Σ_m y_lm(ω) y_lm(ω') = (2l+1)/(4π) P_l(ω·ω'): pins the angular dependence, not just the norm.
    a, b = np.array(d) / np.linalg.norm(d), np.array(e) / np.linalg.norm(e)
    ya, yb = sh_eval(a, order), sh_eval(b, order)
    c = float(np.clip(a @ b, -1, 1))
    for l in range(order):
        got = (ya[l * l:(l + 1) ** 2] * yb[l * l:(l + 1) ** 2]).sum()
        want = (2 * l + 1) / (4 * math.pi) * np.polynomial.legendre.Legendre.basis(l)(c)
        assert abs(got - want) < 1e-10, (d, e, l)
