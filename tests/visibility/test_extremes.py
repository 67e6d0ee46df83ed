"""Stability at the extremes, for EVERY registered visibility method (parametrized over ``METHODS``, so a
newly registered method is covered without editing this file).

Covered here: SH orders 1..8 in float32; meshes scaled by 1e-4..1e4 or rounded one ulp differently (every
vertex, bumpy scene and Warp's bunny); the whole transfer against the reference; coincident and degenerate
triangles; receivers touching blockers; hypothesis properties over random meshes and directions; and, for
every area-light method (``REGISTRY["area"]``), the same per-vertex invariance under scale and rounding.
Method-specific extremes live with each method (SH exp ‖f̂‖ up to 100 in tests/sh/test_sh_exp.py, overlapping
blockers in tests/visibility/test_spheres.py and tests/visibility/test_disks.py, cloth stiffness/mass/time step
in tests/sim/test_sim_cloth.py).

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

from conftest import warp_asset
from warpshade.bench.meshes import grid
from warpshade.geometry import TriMesh
from warpshade.usd import load_mesh
from warpshade.sh import sh_eval
from warpshade.visibility import METHODS, REGISTRY, get_method

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


SCALE_TOL = 1e-4 * UNOCCLUDED_DC
"""Largest change of any transfer coefficient of any vertex allowed when the mesh is scaled or rounded
differently. Every method is a continuous function of the points away from discrete events (a ray crossing a
silhouette, a raster pixel or plane-LUT cell, a tree or sphere-fit decision), so rounding (relative 6e-8)
moves a vertex by float noise: measured <= 1.5e-6 of the DC for every method on ``bumpy_scene`` at every
scale and one-ulp change below (by 1e-3..1e-2 of the DC before the tangent frame turned continuously). One
discrete event costs far more than 1e-4: one of the reference's 256 rays is up to max|y_lm|/(256 y_0) = 1.0 %
(order 4), one 32² hemiraster pixel up to 0.3 %. Such events need a quantity within rounding of its
threshold: for the reference, flipped rays measured 1.4e4 x the relative jitter over this scene's 67 072 rays
(0.7 at 1e-4, 14 at 1e-3), i.e. ~1e-3 expected at rounding level, so the reference's bound is no ray at all."""

SCALE_KNOWN_BROKEN: dict[str, str] = {}
"""Methods whose transfer still changes with the scale of ``bumpy_scene`` (strict xfail; none)."""

JITTER_KNOWN_BROKEN = {
    "hemiraster": "the plane LUT quantizes each edge plane's normal to a cube-map cell (hemiraster/kernels.py "
                  "cube_cell, iu/iv = int(n * inv + half)); a one-ulp move of a vertex switches the cell of an edge "
                  "whose plane is within rounding of a cell boundary (~1e-5 of edges per coordinate), which "
                  "re-rasterizes the pixels of that edge: 0.4-0.65 % of the DC at 6-17 vertices",
}
"""Methods whose transfer jumps when each coordinate moves by -1, 0 or +1 ulp at random (strict xfail, reason)."""

BUNNY_KNOWN_BROKEN = {
    "hemiraster": JITTER_KNOWN_BROKEN["hemiraster"] + " (bunny: up to 2 % at 75-371 of 6102 vertices)",
    "spheres": "the sphere fit is chaotic in its input: spheres/fitting.py _Fitter.optimise_center (scipy Powell "
               "stopped by maxfev=36, so its result is the search path, whose branches rounding can flip) turns a "
               "one-ulp change into 1e-3 of the diagonal at its 18th call, and Lloyd's stopping test and teleport's "
               "argmax cascade it to other leaf spheres (centres 0.45 m apart): up to 20 % (92 % at x1e-4) of the DC "
               "at 4000-5900 of 6102 vertices (bumpy_scene's fit happens to be unaffected)",
}
"""Methods whose bunny transfer changes with one-ulp rounding or scale (strict xfail, reason)."""


def away_by_one_ulp(points: np.ndarray) -> np.ndarray:
    """Every float32 coordinate moved one ulp away from zero (exactly equal coordinates stay equal)."""
    p = np.asarray(points, np.float32)
    return np.nextafter(p, np.where(p >= 0, np.float32(np.inf), np.float32(-np.inf))).astype(np.float32)


def random_ulp_jitter(points: np.ndarray, seed: int) -> np.ndarray:
    """Every float32 coordinate moved by -1, 0 or +1 ulp at random (breaks exact ties such as a grid's)."""
    p = np.asarray(points, np.float32)
    step = np.random.default_rng(seed).integers(-1, 2, p.shape)
    up, down = np.nextafter(p, np.float32(np.inf)), np.nextafter(p, np.float32(-np.inf))
    return np.where(step > 0, up, np.where(step < 0, down, p)).astype(np.float32)


def changed(points: np.ndarray, change) -> np.ndarray:
    return away_by_one_ulp(points) if change == "ulp" else np.asarray(points, np.float32) * np.float32(change)


def assert_same_transfer(got, base, name, what):
    d = np.abs(got - base).max(axis=1)  # per vertex, the largest change of any coefficient
    bad = np.flatnonzero(d > SCALE_TOL)
    assert not len(bad), (f"{name} {what}: {len(bad)} vertices change by more than {SCALE_TOL / UNOCCLUDED_DC:.0e} "
                          f"of the DC, worst vertex {d.argmax()} by {d.max() / UNOCCLUDED_DC:.2e}")


def xfail_if(table):
    return [pytest.param(n, marks=pytest.mark.xfail(strict=True, reason=table[n])) if n in table else n for n in ALL]


@pytest.mark.parametrize("change", [1e-4, 1e-2, 1e2, 1e4, "ulp"])
@pytest.mark.parametrize("name", xfail_if(SCALE_KNOWN_BROKEN))
def test_scaled_mesh_same_transfer(name, change):
    m = bumpy_scene()
    base = make(name, m).update().numpy()
    got = make(name, TriMesh(changed(m.points, change), m.faces)).update().numpy()
    assert_same_transfer(got, base, name, f"x{change}")  # tolerance: SCALE_TOL
    check_bounds(got, name, f"change {change}")


@pytest.mark.parametrize("name", xfail_if(JITTER_KNOWN_BROKEN))
def test_random_ulp_jitter_same_transfer(name):
    m = bumpy_scene()
    base = make(name, m).update().numpy()
    got = make(name, TriMesh(random_ulp_jitter(m.points, seed=0), m.faces)).update().numpy()
    assert_same_transfer(got, base, name, "random one-ulp jitter")  # tolerance: SCALE_TOL


@pytest.fixture(scope="module")
def bunny():
    return load_mesh(warp_asset("bunny.usd"))


@pytest.mark.parametrize("change", ["ulp", 1e-4])
@pytest.mark.parametrize("name", xfail_if(BUNNY_KNOWN_BROKEN))
def test_bunny_same_transfer_rounded_or_scaled(bunny, name, change):
    # a real mesh (6102 vertices, irregular): many more near-threshold configurations than bumpy_scene
    base = make(name, bunny).update().numpy()
    got = make(name, TriMesh(changed(bunny.points, change), bunny.faces)).update().numpy()
    assert_same_transfer(got, base, name, f"bunny x{change}")  # tolerance: SCALE_TOL


AREA_TOL = 1e-5
"""Largest change of any vertex's area-light visibility allowed when mesh and light are scaled or rounded
differently. Visibility is a form-factor weighted count of k² = 256 light samples: one sample changing
side moves it by ~1/256 = 3.9e-3, float32 rounding of the weights by at most ~256 x 6e-8 = 1.5e-5 of a
sum that is <= 1 (measured: exactly 0 for gears and the ray-traced area reference on bumpy_scene and
the bunny, at x1e-4, 1e-2, 1e2, 1e4, one ulp and random ulp jitter)."""


_AREA_BASE: dict = {}
"""Unchanged visibility per (method, scene), computed once for the module."""


def area_case(mesh, change):
    """``(mesh, light)`` of the area-light invariance tests: a 0.3-sized rect light 1.3 above, tilted,
    scaled (or the mesh rounded) as ``change`` says."""
    from warpshade.visibility.gears import LightRect

    light = LightRect.over_points(mesh.points, size=0.3, height=1.3, tilt=0.2)
    if change in ("ulp", "jitter"):
        pts = away_by_one_ulp(mesh.points) if change == "ulp" else random_ulp_jitter(mesh.points, seed=0)
        return TriMesh(pts, mesh.faces), light
    f = np.float32(change)
    scaled = [tuple(np.asarray(v, np.float32) * f) for v in (light.center, light.u, light.v)]
    return TriMesh(np.asarray(mesh.points, np.float32) * f, mesh.faces), LightRect(*scaled)


@pytest.mark.parametrize("name, scene, change", [(n, "bumpy", c) for n in sorted(REGISTRY["area"])
                                                  for c in (1e-4, 1e-2, 1e2, 1e4, "ulp", "jitter")]
                         + [("gears", "bunny", "ulp")])  # the bunny: 1986 partly lit vertices, ~1.5 s per pass
def test_area_visibility_same_per_vertex_scaled_or_rounded(scenes, name, scene, change):
    from warpshade.visibility.gears import get_area_method

    cls, m = get_area_method(name), scenes[scene]
    if (name, scene) not in _AREA_BASE:
        _AREA_BASE[name, scene] = cls(*area_case(m, 1.0), k=16).update().numpy()
    base = _AREA_BASE[name, scene]
    partial = int(((base > 0) & (base < 1)).sum())
    assert partial > 0.05 * m.num_vertices, f"{name}: only {partial} partly lit vertices: nothing is tested"
    got = cls(*area_case(m, change), k=16).update().numpy()
    d = np.abs(got - base)  # per vertex
    assert d.max() <= AREA_TOL, (f"{name} {scene} x{change}: {int((d > AREA_TOL).sum())} vertices change, worst "
                                 f"vertex {d.argmax()} by {d.max():.2e}")  # tolerance: AREA_TOL


VS_REFERENCE = {
    "bumpy": {"disks": 0.28, "hemiraster": 0.015, "reference": 0.04, "spheres": 0.50},
    "bunny": {"disks": 0.055, "hemiraster": 0.017, "reference": 0.04, "spheres": 0.22},
}
"""Largest relative L2 error ``‖T - T_ref‖ / ‖T_ref‖`` of the whole transfer (all vertices, all coefficients,
order 4, knobs of :func:`make`) against the reference at high ray count. Measured: bumpy_scene (truth 16 384
rays, itself within 0.3 % of a 4096-ray trace of another seed) disks 0.245, hemiraster 0.0102, reference at
256 rays 0.0304, spheres (8 spheres, 2 levels) 0.448, where the unoccluded transfer (no shadows) scores
0.549; bunny (truth 2048 rays) disks 0.045, hemiraster 0.0126 (0.0126 against 4096 rays), reference 0.0294,
spheres 0.184. Tolerances: measured + ~15-30 %."""

TRUTH_RAYS = {"bumpy": 16384, "bunny": 2048}


@pytest.fixture(scope="module")
def scenes(bunny):
    return {"bumpy": bumpy_scene(), "bunny": bunny}


@pytest.fixture(scope="module")
def truths(scenes):
    return {k: get_method("reference")(m, order=4, rays=TRUTH_RAYS[k], seed=12345).update().numpy()
            for k, m in scenes.items()}


@pytest.mark.parametrize("scene", sorted(VS_REFERENCE))
@pytest.mark.parametrize("name", ALL)
def test_whole_transfer_matches_reference(scenes, truths, name, scene):
    tol = VS_REFERENCE[scene].get(name)
    assert tol is not None, f"{name}: no measured tolerance against the reference on {scene} (add it to VS_REFERENCE)"
    t, ref = make(name, scenes[scene]).update().numpy(), truths[scene]
    err = float(np.linalg.norm(t - ref) / np.linalg.norm(ref))
    assert err < tol, f"{name} on {scene}: relative L2 error {err:.4f} against the reference, tolerance {tol}"


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
