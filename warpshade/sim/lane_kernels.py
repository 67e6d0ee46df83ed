"""CPU kernels that solve several constraints of one colour per thread, in SIMD lanes.

Constraints of one colour share no vertex, so solving ``LANES`` of them side by side gives
the same floats as solving them one after another. Each lane performs exactly the operations of
the scalar kernel it replaces, in the same order (every Warp operation its own C++ statement,
``dot``/``cross``/``length_sq`` written as the single expressions of Warp's ``vec.h``, so the
compiler contracts them alike), and the angle is Warp's own ``atan2`` called lane by lane: the
results are bit-for-bit those of the scalar kernel. The lanes are clang vector extensions, so the
module is for the CPU only (the solver uses the scalar kernels on a GPU).
"""

from __future__ import annotations

import numpy as np
import warp as wp

LANES = 8
"""Constraints a thread solves side by side (one vector register of 8 floats with AVX)."""
_LANES = wp.constant(LANES)

_PRELUDE = r"""
typedef float V __attribute__((ext_vector_type(8)));
const int L = 8;
auto dot3 = [](V ax, V ay, V az, V bx, V by, V bz) -> V { return ax * bx + ay * by + az * bz; };
(void)dot3;
"""
"""The lane type, and Warp's vec3 dot product as one expression (as ``vec.h`` writes it)."""

_EDGE_GATHER = r"""
const wp::vec_t<2, int>* es = (const wp::vec_t<2, int>*)edges.data;
const float* im = (const float*)inv_mass.data;
const float* comp = (const float*)compliance.data;
const wp::vec_t<3, float>* xs = (const wp::vec_t<3, float>*)x.data;
int ei[L], ej[L];
V wi, wj, xix, xiy, xiz, xjx, xjy, xjz, cm;
for (int k = 0; k < L; ++k) {
    int e = start + (k < count ? k : 0);
    wp::vec_t<2, int> q = es[e];
    ei[k] = q[0]; ej[k] = q[1];
    wi[k] = im[q[0]]; wj[k] = im[q[1]]; cm[k] = comp[e];
    wp::vec_t<3, float> pa = xs[q[0]], pb = xs[q[1]];
    xix[k] = pa[0]; xiy[k] = pa[1]; xiz[k] = pa[2];
    xjx[k] = pb[0]; xjy[k] = pb[1]; xjz[k] = pb[2];
}
V wsum = wi + wj;
// edge_axis
V dx = xix - xjx; V dy = xiy - xjy; V dz = xiz - xjz;
V len = __builtin_elementwise_sqrt(dx * dx + dy * dy + dz * dz);
V nx = dx / len; V ny = dy / len; V nz = dz / len;
"""
"""Gathers an edge group (ids, inverse masses, compliance, positions) and computes ``edge_axis``."""

_STRETCH_LANES = _PRELUDE + _EDGE_GATHER + r"""
const float* rl = (const float*)rest_length.data;
float* lm = (float*)lam.data;
wp::vec_t<3, float>* xo = (wp::vec_t<3, float>*)x.data;
V r0, l0;
for (int k = 0; k < L; ++k) {
    int e = start + (k < count ? k : 0);
    r0[k] = rl[e]; l0[k] = lm[e];
}
V c = len - r0;
float dt2 = dt * dt;
V alpha = cm / dt2;
float nrel = -relaxation;
V al = alpha * l0;
V cal = c + al;
V num = nrel * cal;
V den = wsum + alpha;
V dlam = num / den;
V lnew = l0 + dlam;
V fi = wi * dlam; V fj = wj * dlam;
V yix = nx * fi; V yiy = ny * fi; V yiz = nz * fi;
V yjx = nx * fj; V yjy = ny * fj; V yjz = nz * fj;
V oix = xix + yix; V oiy = xiy + yiy; V oiz = xiz + yiz;
V ojx = xjx - yjx; V ojy = xjy - yjy; V ojz = xjz - yjz;
for (int k = 0; k < count; ++k) {
    // the scalar kernel returns early for a kinematic edge and a degenerate one (length < 1e-12)
    if (wsum[k] == 0.0f || len[k] < 1.0e-12f) continue;
    lm[start + k] = lnew[k];
    xo[ei[k]] = wp::vec_t<3, float>(oix[k], oiy[k], oiz[k]);
    xo[ej[k]] = wp::vec_t<3, float>(ojx[k], ojy[k], ojz[k]);
}
"""

_DAMP_STRETCH_LANES = _PRELUDE + _EDGE_GATHER + r"""
wp::vec_t<3, float>* vs = (wp::vec_t<3, float>*)v.data;
V vix, viy, viz, vjx, vjy, vjz;
for (int k = 0; k < L; ++k) {
    int a = ei[k], b = ej[k];
    wp::vec_t<3, float> va = vs[a], vb = vs[b];
    vix[k] = va[0]; viy[k] = va[1]; viz[k] = va[2];
    vjx[k] = vb[0]; vjy[k] = vb[1]; vjz[k] = vb[2];
}
V dux = vix - vjx; V duy = viy - vjy; V duz = viz - vjz;
V u = dot3(dux, duy, duz, nx, ny, nz);
float hd = dt * damping;
V a = hd * wsum;
V ca = cm + a;
V fr = a / ca;
V frac = cm > 0.0f ? fr : (V)(1.0f);
V nu = -u;
V nf = nu * frac;
V p = nf / wsum;
V fi = wi * p; V fj = wj * p;
V yix = nx * fi; V yiy = ny * fi; V yiz = nz * fi;
V yjx = nx * fj; V yjy = ny * fj; V yjz = nz * fj;
V oix = vix + yix; V oiy = viy + yiy; V oiz = viz + yiz;
V ojx = vjx - yjx; V ojy = vjy - yjy; V ojz = vjz - yjz;
for (int k = 0; k < count; ++k) {
    // the scalar kernel returns early for a kinematic edge and a degenerate one (length < 1e-12)
    if (wsum[k] == 0.0f || len[k] < 1.0e-12f) continue;
    vs[ei[k]] = wp::vec_t<3, float>(oix[k], oiy[k], oiz[k]);
    vs[ej[k]] = wp::vec_t<3, float>(ojx[k], ojy[k], ojz[k]);
}
"""

_AERO_LANES = _PRELUDE + r"""
auto cross_x = [](V ay, V az, V by, V bz) -> V { return ay * bz - az * by; };
const wp::vec_t<3, int>* ts = (const wp::vec_t<3, int>*)tris.data;
const wp::vec_t<3, float>* xs = (const wp::vec_t<3, float>*)x.data;
const wp::vec_t<3, float>* vs = (const wp::vec_t<3, float>*)v.data;
float* dr = (float*)drag.data;
wp::vec_t<3, float>* lf = (wp::vec_t<3, float>*)lift.data;
int ids[L][3];
V xix, xiy, xiz, xjx, xjy, xjz, xkx, xky, xkz, vix, viy, viz, vjx, vjy, vjz, vkx, vky, vkz;
for (int k = 0; k < L; ++k) {
    int t = start + (k < count ? k : 0);
    wp::vec_t<3, int> q = ts[t];
    ids[k][0] = q[0]; ids[k][1] = q[1]; ids[k][2] = q[2];
    wp::vec_t<3, float> pa = xs[q[0]], pb = xs[q[1]], pc = xs[q[2]];
    wp::vec_t<3, float> va = vs[q[0]], vb = vs[q[1]], vc = vs[q[2]];
    xix[k] = pa[0]; xiy[k] = pa[1]; xiz[k] = pa[2];
    xjx[k] = pb[0]; xjy[k] = pb[1]; xjz[k] = pb[2];
    xkx[k] = pc[0]; xky[k] = pc[1]; xkz[k] = pc[2];
    vix[k] = va[0]; viy[k] = va[1]; viz[k] = va[2];
    vjx[k] = vb[0]; vjy[k] = vb[1]; vjz[k] = vb[2];
    vkx[k] = vc[0]; vky[k] = vc[1]; vkz[k] = vc[2];
}
V ax = xjx - xix; V ay = xjy - xiy; V az = xjz - xiz;
V bx = xkx - xix; V by = xky - xiy; V bz = xkz - xiz;
V nnx = cross_x(ay, az, by, bz);
V nny = cross_x(az, ax, bz, bx);
V nnz = cross_x(ax, ay, bx, by);
V ln = __builtin_elementwise_sqrt(nnx * nnx + nny * nny + nnz * nnz);
V area = 0.5f * ln;
V nx = nnx / ln; V ny = nny / ln; V nz = nnz / ln;
V sx = vix + vjx; V sy = viy + vjy; V sz = viz + vjz;
V s3x = sx + vkx; V s3y = sy + vky; V s3z = sz + vkz;
V mx = s3x / 3.0f; V my = s3y / 3.0f; V mz = s3z / 3.0f;
V ux = mx - wind[0]; V uy = my - wind[1]; V uz = mz - wind[2];
V speed = __builtin_elementwise_sqrt(ux * ux + uy * uy + uz * uz);
V uhx = ux / speed; V uhy = uy / speed; V uhz = uz / speed;
V cs = dot3(uhx, uhy, uhz, nx, ny, nz);
float hr = 0.5f * air_density;
V q0 = hr * area;
V qq = q0 * speed;
V d0 = qq * drag_coefficient;
V acs = __builtin_elementwise_abs(cs);
V d1 = d0 * acs;
V d = d1 / 3.0f;
V wx = uhx * cs; V wy = uhy * cs; V wz = uhz * cs;
V gx = nx - wx; V gy = ny - wy; V gz = nz - wz;
V hx = -gx; V hy = -gy; V hz = -gz;
V e0 = qq * speed;
V e1 = e0 * lift_coefficient;
V e2 = e1 * cs;
V e3 = e2 / 3.0f;
V flx = hx * e3; V fly = hy * e3; V flz = hz * e3;
for (int k = 0; k < count; ++k) {
    // the scalar kernel returns early for a degenerate triangle and one at rest in the air
    if (ln[k] == 0.0f || speed[k] == 0.0f) continue;
    dr[ids[k][0]] += d[k];
    dr[ids[k][1]] += d[k];
    dr[ids[k][2]] += d[k];
    for (int c = 0; c < 3; ++c) {
        wp::vec_t<3, float>& o = lf[ids[k][c]];
        o[0] += flx[k]; o[1] += fly[k]; o[2] += flz[k];
    }
}
"""

_BENDING_LANES = _PRELUDE + r"""
const float pi_f = 3.141592653589793f;
auto cross_x = [](V ay, V az, V by, V bz) -> V { return ay * bz - az * by; };
const wp::vec_t<4, int>* hs = (const wp::vec_t<4, int>*)hinges.data;
const float* rest = (const float*)rest_angle.data;
const float* comp = (const float*)compliance.data;
const float* im = (const float*)inv_mass.data;
float* lm = (float*)lam.data;
wp::vec_t<3, float>* xs = (wp::vec_t<3, float>*)x.data;
int ids[L][4];
V w1, w2, w3, w4, x1x, x1y, x1z, x2x, x2y, x2z, x3x, x3y, x3z, x4x, x4y, x4z, r0, cm, l0;
for (int k = 0; k < L; ++k) {
    int h = start + (k < count ? k : 0);
    wp::vec_t<4, int> q = hs[h];
    for (int j = 0; j < 4; ++j) ids[k][j] = q[j];
    w1[k] = im[q[0]]; w2[k] = im[q[1]]; w3[k] = im[q[2]]; w4[k] = im[q[3]];
    wp::vec_t<3, float> p1 = xs[q[0]], p2 = xs[q[1]], p3 = xs[q[2]], p4 = xs[q[3]];
    x1x[k] = p1[0]; x1y[k] = p1[1]; x1z[k] = p1[2];
    x2x[k] = p2[0]; x2y[k] = p2[1]; x2z[k] = p2[2];
    x3x[k] = p3[0]; x3y[k] = p3[1]; x3z[k] = p3[2];
    x4x[k] = p4[0]; x4y[k] = p4[1]; x4z[k] = p4[2];
    r0[k] = rest[h]; cm[k] = comp[h]; l0[k] = lm[h];
}
V ws12 = w1 + w2;
V ws123 = ws12 + w3;
V wsum = ws123 + w4;
// dihedral_gradients
V ex = x4x - x3x; V ey = x4y - x3y; V ez = x4z - x3z;
V le = __builtin_elementwise_sqrt(ex * ex + ey * ey + ez * ez);
V d13x = x1x - x3x; V d13y = x1y - x3y; V d13z = x1z - x3z;
V d14x = x1x - x4x; V d14y = x1y - x4y; V d14z = x1z - x4z;
V n1x = cross_x(d13y, d13z, d14y, d14z);
V n1y = cross_x(d13z, d13x, d14z, d14x);
V n1z = cross_x(d13x, d13y, d14x, d14y);
V d24x = x2x - x4x; V d24y = x2y - x4y; V d24z = x2z - x4z;
V d23x = x2x - x3x; V d23y = x2y - x3y; V d23z = x2z - x3z;
V n2x = cross_x(d24y, d24z, d23y, d23z);
V n2y = cross_x(d24z, d24x, d23z, d23x);
V n2z = cross_x(d24x, d24y, d23x, d23y);
V a1 = dot3(n1x, n1y, n1z, n1x, n1y, n1z);
V a2 = dot3(n2x, n2y, n2z, n2x, n2y, n2z);
V q1 = le / a1;
V u1x = (-n1x) * q1; V u1y = (-n1y) * q1; V u1z = (-n1z) * q1;
V q2 = le / a2;
V u2x = (-n2x) * q2; V u2y = (-n2y) * q2; V u2z = (-n2z) * q2;
V p1 = dot3(d14x, d14y, d14z, ex, ey, ez);
V s1 = le * a1;
V r1 = p1 / s1;
V t1x = n1x * r1; V t1y = n1y * r1; V t1z = n1z * r1;
V p2 = dot3(d24x, d24y, d24z, ex, ey, ez);
V s2 = le * a2;
V r2 = p2 / s2;
V t2x = n2x * r2; V t2y = n2y * r2; V t2z = n2z * r2;
V t12x = t1x + t2x; V t12y = t1y + t2y; V t12z = t1z + t2z;
V u3x = -t12x; V u3y = -t12y; V u3z = -t12z;
// the scalar kernel's degenerate hinge (zero gradients) never moves anything: its denominator is 0
// u4 = -(u1 + u2 + u3)
V v12x = u1x + u2x; V v12y = u1y + u2y; V v12z = u1z + u2z;
V v123x = v12x + u3x; V v123y = v12y + u3y; V v123z = v12z + u3z;
V u4x = -v123x; V u4y = -v123y; V u4z = -v123z;
// dihedral_angle
V cnx = cross_x(n1y, n1z, n2y, n2z);
V cny = cross_x(n1z, n1x, n2z, n2x);
V cnz = cross_x(n1x, n1y, n2x, n2y);
V sn = dot3(cnx, cny, cnz, ex, ey, ez);
V sl = sn / le;
V cs = dot3(n1x, n1y, n1z, n2x, n2y, n2z);
V theta;
for (int k = 0; k < L; ++k) theta[k] = wp::atan2(sl[k], cs[k]);
V c0 = theta - r0;
const float two_pi = 2.0f * pi_f;
V c1 = c0 > pi_f ? c0 - two_pi : c0;
V c = c1 < -pi_f ? c1 + two_pi : c1;
V l1 = dot3(u1x, u1y, u1z, u1x, u1y, u1z);
V m1 = w1 * l1;
V l2 = dot3(u2x, u2y, u2z, u2x, u2y, u2z);
V m2 = w2 * l2;
V m12 = m1 + m2;
V l3 = dot3(u3x, u3y, u3z, u3x, u3y, u3z);
V m3 = w3 * l3;
V m123 = m12 + m3;
V l4 = dot3(u4x, u4y, u4z, u4x, u4y, u4z);
V m4 = w4 * l4;
V denom = m123 + m4;
float dt2 = dt * dt;
V alpha = cm / dt2;
V al = alpha * l0;
V cal = c + al;
V ncal = -cal;
V da = denom + alpha;
V dlam = ncal / da;
V lnew = l0 + dlam;
V f1 = w1 * dlam; V f2 = w2 * dlam; V f3 = w3 * dlam; V f4 = w4 * dlam;
V y1x = u1x * f1; V y1y = u1y * f1; V y1z = u1z * f1;
V y2x = u2x * f2; V y2y = u2y * f2; V y2z = u2z * f2;
V y3x = u3x * f3; V y3y = u3y * f3; V y3z = u3z * f3;
V y4x = u4x * f4; V y4y = u4y * f4; V y4z = u4z * f4;
V o1x = x1x + y1x; V o1y = x1y + y1y; V o1z = x1z + y1z;
V o2x = x2x + y2x; V o2y = x2y + y2y; V o2z = x2z + y2z;
V o3x = x3x + y3x; V o3y = x3y + y3y; V o3z = x3z + y3z;
V o4x = x4x + y4x; V o4y = x4y + y4y; V o4z = x4z + y4z;
for (int k = 0; k < count; ++k) {
    // the scalar kernel returns early for an all-kinematic hinge, a degenerate one (zero
    // gradients: le < 1e-12 or a wing's |n|^2 < 1e-24) and a vanishing denominator
    if (wsum[k] == 0.0f) continue;
    if (le[k] < 1.0e-12f || a1[k] < 1.0e-24f || a2[k] < 1.0e-24f) continue;
    if (denom[k] < 1.0e-20f) continue;
    lm[start + k] = lnew[k];
    xs[ids[k][0]] = wp::vec_t<3, float>(o1x[k], o1y[k], o1z[k]);
    xs[ids[k][1]] = wp::vec_t<3, float>(o2x[k], o2y[k], o2z[k]);
    xs[ids[k][2]] = wp::vec_t<3, float>(o3x[k], o3y[k], o3z[k]);
    xs[ids[k][3]] = wp::vec_t<3, float>(o4x[k], o4y[k], o4z[k]);
}
"""


@wp.func_native(_BENDING_LANES)
def _bend_lanes(hinges: wp.array[wp.vec4i], rest_angle: wp.array[float], compliance: wp.array[float],
                inv_mass: wp.array[float], start: int, count: int, dt: float, lam: wp.array[float],
                x: wp.array[wp.vec3]): ...


@wp.kernel
def solve_bending_lanes(groups: wp.array[wp.vec2i], hinges: wp.array[wp.vec4i], rest_angle: wp.array[float],
                        compliance: wp.array[float], inv_mass: wp.array[float], dt: float, lam: wp.array[float],
                        x: wp.array[wp.vec3]):
    """:func:`~warpshade.sim.kernels.solve_bending` over the hinge groups (start, count) of one
    colour each, ``LANES`` hinges a thread (the same floats, for contiguous arrays)."""
    g = groups[wp.tid()]
    _bend_lanes(hinges, rest_angle, compliance, inv_mass, g[0], g[1], dt, lam, x)


@wp.func_native(_STRETCH_LANES)
def _stretch_lanes(edges: wp.array[wp.vec2i], rest_length: wp.array[float], compliance: wp.array[float],
                   inv_mass: wp.array[float], start: int, count: int, dt: float, relaxation: float,
                   lam: wp.array[float], x: wp.array[wp.vec3]): ...


@wp.kernel
def solve_stretch_lanes(groups: wp.array[wp.vec2i], edges: wp.array[wp.vec2i], rest_length: wp.array[float],
                        compliance: wp.array[float], inv_mass: wp.array[float], dt: float, relaxation: float,
                        lam: wp.array[float], x: wp.array[wp.vec3]):
    """:func:`~warpshade.sim.kernels.solve_stretch` over the edge groups (start, count) of one
    colour each, ``LANES`` edges a thread (the same floats, for contiguous arrays)."""
    g = groups[wp.tid()]
    _stretch_lanes(edges, rest_length, compliance, inv_mass, g[0], g[1], dt, relaxation, lam, x)


@wp.func_native(_DAMP_STRETCH_LANES)
def _damp_stretch_lanes(edges: wp.array[wp.vec2i], compliance: wp.array[float], inv_mass: wp.array[float],
                        x: wp.array[wp.vec3], start: int, count: int, dt: float, damping: float,
                        v: wp.array[wp.vec3]): ...


@wp.kernel
def damp_stretch_lanes(groups: wp.array[wp.vec2i], edges: wp.array[wp.vec2i], compliance: wp.array[float],
                       inv_mass: wp.array[float], x: wp.array[wp.vec3], dt: float, damping: float,
                       v: wp.array[wp.vec3]):
    """:func:`~warpshade.sim.kernels.damp_stretch` over the edge groups (start, count) of one
    colour each, ``LANES`` edges a thread (the same floats, for contiguous arrays)."""
    g = groups[wp.tid()]
    _damp_stretch_lanes(edges, compliance, inv_mass, x, g[0], g[1], dt, damping, v)


@wp.func_native(_AERO_LANES)
def _aero_lanes(x: wp.array[wp.vec3], v: wp.array[wp.vec3], tris: wp.array[wp.vec3i], start: int, count: int,
                wind: wp.vec3, air_density: float, drag_coefficient: float, lift_coefficient: float,
                lift: wp.array[wp.vec3], drag: wp.array[float]): ...


@wp.kernel
def accumulate_aero_forces_lanes(x: wp.array[wp.vec3], v: wp.array[wp.vec3], tris: wp.array[wp.vec3i], wind: wp.vec3,
                                 air_density: float, drag_coefficient: float, lift_coefficient: float,
                                 lift: wp.array[wp.vec3], drag: wp.array[float]):
    """:func:`~warpshade.sim.kernels.accumulate_aero_forces`, ``LANES`` consecutive triangles a
    thread, their sums added in triangle order (the same floats, for contiguous arrays)."""
    start = wp.tid() * _LANES
    _aero_lanes(x, v, tris, start, wp.min(_LANES, tris.shape[0] - start), wind, air_density, drag_coefficient,
                lift_coefficient, lift, drag)


def lane_groups(colors: list, device) -> wp.array:
    """(start, count) of runs of at most :data:`LANES` constraints within each colour (offset, count)."""
    out = [(off + s, min(LANES, cnt - s)) for off, cnt in colors for s in range(0, cnt, LANES)]
    return wp.array(np.asarray(out, dtype=np.int32).reshape(-1, 2), dtype=wp.vec2i, device=device)


__all__ = ["LANES", "accumulate_aero_forces_lanes", "damp_stretch_lanes", "lane_groups", "solve_bending_lanes", "solve_stretch_lanes"]
