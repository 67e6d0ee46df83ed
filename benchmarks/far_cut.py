"""A distance-dependent cut of hemiraster's far field, emulated in NumPy (issue 18, target 1; idea (b)).

What it measures: per sampled receiver, the order-5 transfer error (against the 4096-ray truth,
:func:`warpshade.bench.metrics.transfer_errors`, normalised over the whole mesh) and the triangles
considered and rasterized when the far field is a *cut* through a hierarchy of decimations chosen per
receiver: a coarse level ``C`` (e.g. 256 or 384 triangles) wherever it is far, and a near level (the
1536-triangle decimation, or the fine mesh) where the receiver is near a coarse triangle. A coarse
triangle is replaced by what it stands for when the method's own refinement test replaces it (its box,
with its fine triangles, within ``refine`` times its deviation of the receiver, or it stands for the
receiver's 1-ring), or when the cut rule says so: ``dist``, the receiver closer to it than ``K`` times
its size (largest corner distance from its centroid); ``omega``, its area over the squared distance
above ``K`` mask pixels of projected solid angle; or ``dev``, the method's own test with ``K`` for
``refine`` (its box within ``K`` times its deviation: the angle its deviation subtends above ~1/K).
With the 1536 level in between, a near-level triangle is in turn replaced by its fine triangles by the
refinement test at its own level (its deviation, the outline's, or its 1-ring), as the method's mid
level does. Every triangle is rasterized through the
plane LUT (``lut``, as the method does) and, separately, with exact edge planes, so the decimation error
and the seams between levels (a coarse triangle next to finer ones does not share their edges) can be
told apart. The receiver's own triangles are rasterized as its fan (nadir, b, c), as the method does.

It is an emulation, not the method: it builds the levels with :func:`.hierarchy.decimate`
(:func:`.cache.far_field`, at the frame's pose as ``redecimate`` does), assigns triangles as
:func:`.hierarchy.assign_to_coarse` does, takes the sets the kernels take (a refined triangle's primaries
and seam-cover extras), and rasterizes with the NumPy oracle's conventions
(:mod:`warpshade.visibility.hemiraster.oracle`: coplanar lift, horizon cull, the kernels' rim cull by
bounding sphere). No timing: the triangle counts stand for the cost (per receiver the method's work
is about a third per coarse blocker tested, a third per queued triangle and a third the visit;
docs/benchmarks/history.md, branch ``drapefine``). First it checks itself against the method's own
masks and transfers at ``coarse 1536`` on the same receivers (the method built twice per mesh, with and
without ``direct_far``: seconds to 2 minutes each with the caches and the load; then 4-160 s per row).

How to run::

    OPENBLAS_NUM_THREADS=1 python benchmarks/far_cut.py [--meshes draped,cloth] [--receivers 150]
        [--rows A:B] [--json benchmarks/results/far_cut.json]

``--rows`` takes a slice of :data:`CONFIGS` (one process per slice runs them side by side; the JSON is
rewritten after every row).
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.dirname(HERE))

import warp as wp

from warpshade.bench.meshes import draped_cloth, wrinkled_cloth
from warpshade.bench.metrics import RECEIVER_CLASSES, receiver_classes
from warpshade.bench.reference_cache import ground_truth
from warpshade.geometry import TriMesh
from warpshade.sh.rotation import rotation_matrix
from warpshade.visibility import get_method
from warpshade.visibility.hemiraster import cache, hierarchy, tables
from warpshade.visibility.hemiraster.oracle import tangent_frame_np

ORDER, MASK, LUT, REFINE = 5, 32, 96, 2.0
METHOD = {"redecimate": 0.1, "min_image": 0.0, "border": True, "coarse": 1536, "lut": LUT}
"""The method's setting the emulation is checked against (``direct_far`` off: every image through the LUT)."""
EXTRA_CLASS = 40
"""Receivers added per class (contact, fold) beyond the random ones, so the small classes are measured."""


# ------------------------------------------------------------------------------------------------
# levels
def _cover(owner: np.ndarray, extra: np.ndarray, n_parent: int):
    """CSR over parents of the children each stands for (primaries and extras), and primaries only."""
    child = np.concatenate([np.arange(len(owner)), extra[:, 0]])
    parent = np.concatenate([owner, extra[:, 1]])
    order = np.lexsort((child, parent))
    start = np.searchsorted(parent[order], np.arange(n_parent + 1))
    return start, child[order]


def _follow(points, faces, bind_face, bind_bary, bind_offset):
    """Coarse points riding the fine surface (:func:`.kernels.follow_coarse_points`)."""
    f = faces[bind_face]
    a, b, c = (points[f[:, k]] for k in range(3))
    n = np.cross(b - a, c - a)
    ln = np.linalg.norm(n, axis=1, keepdims=True)
    n = np.where(ln > 0, n / np.where(ln > 0, ln, 1.0), 0.0)
    bb = bind_bary.astype(np.float64)
    return bb[:, :1] * a + bb[:, 1:2] * b + bb[:, 2:] * c + bind_offset.astype(np.float64)[:, None] * n


def _level_fit(lpts, lfaces, points, faces, start, items, nprim, bind_offset, kids_box=None):
    """Per triangle of a level: box of it and the (fine) triangles it covers, and its deviation
    (:func:`.kernels.refit_blocker_boxes`): corners' binding offsets, primary fine vertices off its plane,
    at least 1/1000 of its size (its size when it stands for nothing)."""
    a, b, c = (lpts[lfaces[:, k]] for k in range(3))
    cen = (a + b + c) / 3.0
    size = np.maximum(np.maximum(np.linalg.norm(a - cen, axis=1), np.linalg.norm(b - cen, axis=1)),
                      np.linalg.norm(c - cen, axis=1))
    lo = np.minimum(np.minimum(a, b), c)
    hi = np.maximum(np.maximum(a, b), c)
    nrm = np.cross(b - a, c - a)
    ln = np.linalg.norm(nrm, axis=1)
    dev = np.abs(bind_offset[lfaces]).max(axis=1).astype(np.float64)
    fp = points[faces]  # (F, 3, 3)
    flo, fhi = fp.min(axis=1), fp.max(axis=1)
    n = len(lfaces)
    row = np.repeat(np.arange(n), np.diff(start))
    np.minimum.at(lo, row, flo[items])
    np.maximum.at(hi, row, fhi[items])
    prim = nprim[row]  # entry is a primary
    if kids_box is not None:
        klo, khi, kstart, kitems = kids_box
        krow = np.repeat(np.arange(n), np.diff(kstart))
        np.minimum.at(lo, krow, klo[kitems])
        np.maximum.at(hi, krow, khi[kitems])
    r, f = row[prim], items[prim]
    unit = np.where(ln[r, None] > 0, nrm[r] / np.where(ln[r] > 0, ln[r], 1.0)[:, None], 0.0)
    d = np.abs(np.einsum("ij,ikj->ik", unit, fp[f] - a[r][:, None, :])).max(axis=1)
    d = np.where(ln[r] > 0, d, np.linalg.norm(fp[f] - a[r][:, None, :], axis=2).max(axis=1))
    np.maximum.at(dev, r, d)
    has = np.zeros(n, bool)
    has[r] = True
    dev = np.where(has, dev, np.maximum(dev, size))
    dev = np.maximum(dev, 1e-3 * size)
    return {"lo": lo, "hi": hi, "dev": dev, "size": size, "cen": cen, "a": a, "b": b, "c": c,
            "area": 0.5 * ln}


def build_levels(points, faces, coarse: int, mid: int | None, border: bool = True):
    """Coarse level ``coarse`` (and the near level ``mid``, None: the fine mesh) at this pose, with their
    assignments, boxes and deviations, as the method builds them (:func:`.cache.far_field`, its open
    boundary kept). ``border`` False: the coarse level decimated without keeping the boundary (a 64²
    cloth's 252 boundary vertices are nearly all of a 256-triangle mesh's), the near level as before and
    assigned to it as :func:`.hierarchy.far_field` assigns a mid level."""
    far = cache.far_field([(points.astype(np.float64), faces)], [coarse], [mid] if mid else None, True)
    if not border:
        loose = dict(cache.far_field([(points.astype(np.float64), faces)], [coarse], None, False))
        if mid:
            m = dict(far["mid"])
            m["coarse_owner"], m["coarse_extra"] = hierarchy.assign_to_coarse(m["points"], m["faces"], loose["points"],
                                                                             loose["faces"], fans=False)
            loose["mid"] = m
        far = loose
    pts = points.astype(np.float64)
    nf = len(faces)
    cf = far["faces"]
    cpts = _follow(pts, faces, far["bind_face"], far["bind_bary"], far["bind_offset"])
    cstart, citems = _cover(far["owner"], far["extra"], len(cf))
    cprim = far["owner"][citems] == np.repeat(np.arange(len(cf)), np.diff(cstart))
    lev = {"far": far, "coarse_faces": cf, "cstart": cstart, "citems": citems, "cprim": cprim}
    ring_start, ring_tris, _ = hierarchy.ring_triangles(faces, len(points), 1)
    lev["ring_start"], lev["ring_tris"] = ring_start, ring_tris
    if mid:
        m = far["mid"]
        mf = m["faces"]
        mpts = _follow(pts, faces, m["bind_face"], m["bind_bary"], m["bind_offset"])
        mstart, mitems = _cover(m["owner"], m["extra"], len(mf))
        mprim = m["owner"][mitems] == np.repeat(np.arange(len(mf)), np.diff(mstart))
        mfit = _level_fit(mpts, mf, pts, faces, mstart, mitems, mprim, m["bind_offset"])
        mfit["dev"] = np.maximum(mfit["dev"], m["outline"])
        # coarse -> mid cover
        kstart, kitems = _cover(m["coarse_owner"], m["coarse_extra"], len(cf))
        lev["cfit"] = _level_fit(cpts, cf, pts, faces, cstart, citems, cprim, far["bind_offset"],
                                 (mfit["lo"], mfit["hi"], kstart, kitems))
        lev.update(mfit=mfit, mstart=mstart, mitems=mitems, kstart=kstart, kitems=kitems, mid_faces=mf)
        # the k-ring: mid triangles owning a ring (or incident) fine triangle, and their coarse owners
        lev["mring_start"], lev["mring"] = hierarchy.ring_lists(ring_start, ring_tris, faces, m["owner"])
        owner_c = m["coarse_owner"][m["owner"]]
    else:
        lev["cfit"] = _level_fit(cpts, cf, pts, faces, cstart, citems, cprim, far["bind_offset"])
        owner_c = far["owner"]
    lev["cring_start"], lev["cring"] = hierarchy.ring_lists(ring_start, ring_tris, faces, owner_c)
    lev["n_fine"] = nf
    return lev


def _box_dist(p, lo, hi):
    d = np.maximum(np.maximum(lo - p, p - hi), 0.0)
    return np.sqrt((d * d).sum(-1))


def _tri_dist(p, fit):
    cp, _ = hierarchy.closest_points_on_triangles(p[None], fit["a"], fit["b"], fit["c"])
    return np.linalg.norm(cp - p, axis=1)


def _sphere_culled(p, n, fit, rim):
    """:func:`.kernels.skip_early` on the triangles' own bounding spheres: wholly at or below the horizon or
    the lowest pixel centre (such a refined triangle is not visited: its primaries are left out)."""
    q = fit["cen"] - p
    h = q @ n + fit["size"]
    hr = h + rim * fit["size"]
    return (h <= 0) | (hr * hr <= rim * rim * (q * q).sum(1))


def cut_sets(lev, v, p, n, rim, rule: str | None, k: float):
    """Per receiver: the coarse triangles kept, the near-level triangles kept and the fine triangles
    kept (indices), by the method's refinement test plus the cut rule (``rule`` None: the method's alone).
    A refined triangle stands for its primaries and its extras whose primary triangle is not refined;
    the primaries of a refined triangle culled by its own sphere are left out, as the kernels' set
    (``listed_set``) does."""
    cfit = lev["cfit"]
    nc = len(cfit["dev"])
    ref = _box_dist(p, cfit["lo"], cfit["hi"]) < REFINE * cfit["dev"]
    ref[lev["cring"][lev["cring_start"][v]:lev["cring_start"][v + 1]]] = True
    if rule is not None:
        d = _tri_dist(p, cfit)
        if rule == "dist":
            ref |= d < k * cfit["size"]
        elif rule == "dev":
            ref |= _box_dist(p, cfit["lo"], cfit["hi"]) < k * cfit["dev"]
        elif rule == "omega":
            ref |= cfit["area"] > k * (2.0 / MASK) ** 2 * np.maximum(d, 1e-12) ** 2
        else:
            raise ValueError(rule)
    keep_c = np.flatnonzero(~ref)
    visited = ref & ~_sphere_culled(p, n, cfit, rim)
    if "mfit" not in lev:
        fine = _listed(lev["cstart"], lev["citems"], lev["far"]["owner"], ref, visited, lev["n_fine"])
        return keep_c, np.zeros(0, np.int64), fine, nc, 0
    nm = len(lev["mfit"]["dev"])
    m = lev["far"]["mid"]
    mids = _listed(lev["kstart"], lev["kitems"], m["coarse_owner"], ref, visited, nm)
    mfit = lev["mfit"]
    mref = np.zeros(nm, bool)
    mref[mids] = _box_dist(p, mfit["lo"][mids], mfit["hi"][mids]) < REFINE * mfit["dev"][mids]
    ring = np.zeros(nm, bool)
    ring[lev["mring"][lev["mring_start"][v]:lev["mring_start"][v + 1]]] = True
    mref[mids] |= ring[mids]
    mvis = mref & ~_sphere_culled(p, n, mfit, rim)
    fine = _listed(lev["mstart"], lev["mitems"], m["owner"], mref, mvis, lev["n_fine"])
    return keep_c, mids[~mref[mids]], fine, nc, len(mids)


def _listed(start, items, owner, ref, visited, n):
    """The children listed by the visited refined parents (cover rows: primaries and extras), less the
    primaries of refined parents not visited, and less extras whose primary parent is refined (they are
    that one's primaries, or left out with it)."""
    sel = np.zeros(n, bool)
    sel[_members(start, items, np.flatnonzero(visited), n)] = True
    sel &= ~(ref[owner] & ~visited[owner])
    return np.flatnonzero(sel)


def _members(start, items, parents, n):
    """Union of the children listed by ``parents`` (sorted unique)."""
    if len(parents) == 0:
        return np.zeros(0, np.int64)
    sel = np.zeros(n, bool)
    lens = start[parents + 1] - start[parents]
    idx = np.repeat(start[parents], lens) + (np.arange(lens.sum()) - np.repeat(np.cumsum(lens) - lens, lens))
    sel[items[idx]] = True
    return np.flatnonzero(sel)


# ------------------------------------------------------------------------------------------------
# rasterization (vectorized oracle)
class Raster:
    """The oracle's rasterization and integration, vectorized over a receiver's triangles."""

    def __init__(self, mask: int = MASK, lut: int = LUT, order: int = ORDER):
        self.mask, self.lut_res, self.order = mask, lut, order
        self.table = tables.build_lut(mask, lut)[0]
        self.dirs, self.valid = tables.pixel_directions(mask)
        self.nw = tables.words_per_mask(mask)
        self.blocks = tables.block_tables(mask, 1, order)
        pdirs = self.dirs[self.valid]
        self.rim = float(pdirs[:, 2].min()) * (1.0 - 1e-4)

    def cull(self, loc):
        """Corners (T, 3, 3) in the tangent frame: coplanar lift applied, and the keep flag (exact horizon
        cull, rim cull by bounding sphere as :func:`.kernels.skip_early`)."""
        a, b, c = loc[:, 0], loc[:, 1], loc[:, 2]
        g = np.cross(b - a, c - a)
        gl = np.linalg.norm(g, axis=1)
        size = np.sqrt(gl)
        with np.errstate(invalid="ignore", divide="ignore"):
            near = np.abs((g * a).sum(1)) <= tables.COPLANAR_NEAR * gl * size
            inside = np.minimum(np.minimum((g * np.cross(a, b)).sum(1), (g * np.cross(b, c)).sum(1)),
                                (g * np.cross(c, a)).sum(1)) >= -tables.COPLANAR * gl * gl
            lift = np.where((near & inside & (gl > 0))[:, None],
                            g * (tables.COPLANAR * size / np.where(gl > 0, gl, 1.0))[:, None], 0.0)
        loc = loc - lift[:, None, :]
        above = (loc[:, :, 2] > 0).any(axis=1)
        cen = loc.mean(axis=1)
        r = np.linalg.norm(loc - cen[:, None, :], axis=2).max(axis=1)
        h = cen[:, 2] + r
        hr = h + self.rim * r
        rim_skip = (h <= 0) | (hr * hr <= self.rim ** 2 * (cen * cen).sum(1))
        return loc, above & ~rim_skip

    def bits(self, loc, exact: bool) -> np.ndarray:
        """Blocked pixels (M*M,) bool of the triangles ``loc`` (already culled)."""
        if len(loc) == 0:
            return np.zeros(self.mask * self.mask, bool)
        a, b, c = loc[:, 0], loc[:, 1], loc[:, 2]
        planes = np.stack([np.cross(a, b), np.cross(b, c), np.cross(c, a)], axis=1)
        det = (a * planes[:, 1]).sum(1)
        ok = det != 0
        planes = planes[ok] * np.sign(det[ok])[:, None, None]
        if exact:
            vd = self.dirs[self.valid]
            hit = np.zeros(len(vd), bool)
            for s in range(0, len(planes), 512):
                dots = (planes[s:s + 512].reshape(-1, 3) @ vd.T).reshape(-1, 3, len(vd))
                hit |= (dots > 0).all(axis=1).any(axis=0)
            out = np.zeros(self.mask * self.mask, bool)
            out[self.valid] = hit
            return out
        rows = tables.cube_cell_np(planes.astype(np.float32), self.lut_res)
        words = self.table[rows[:, 0], :self.nw] & self.table[rows[:, 1], :self.nw] & self.table[rows[:, 2], :self.nw]
        return tables.unpack_bits(np.bitwise_or.reduce(words, axis=0), self.mask * self.mask)

    def transfer(self, blocked, frame):
        frac = np.where(self.blocks["valid"] > 0, blocked.astype(float) / np.maximum(self.blocks["valid"], 1), 0.0)
        return rotation_matrix(frame, self.order) @ ((1.0 - frac)[:, None] * self.blocks["weights"]).sum(axis=0)


def fan_local(points, faces, v, frame):
    """The receiver's own triangles as (nadir, b, c) in its tangent frame (:func:`.kernels.rasterize_fan`)."""
    own = faces[(faces == v).any(axis=1)]
    first = np.argmax(own == v, axis=1)
    rolled = np.stack([np.roll(f, -k) for f, k in zip(own, first)])
    virt = (points[rolled] - points[v]) @ frame
    virt[:, 0] = (0.0, 0.0, -1.0)
    return virt


# ------------------------------------------------------------------------------------------------
def emulate(lev, points, faces, normals, receivers, ras: Raster, rule, k, exact_too=True):
    """Per receiver: blocked pixels (LUT, exact) and the counts of one cut."""
    out = {"lut": [], "exact": [], "coarse": [], "mid": [], "fine": [], "mid_considered": [], "raster": [],
           "raster_coarse": [], "raster_mid": []}
    none = np.zeros(0, np.int64)
    cpts_a = cpts_b = cpts_c = np.zeros((0, 3))
    mfit = None
    if lev is not None:
        cpts_a, cpts_b, cpts_c = lev["cfit"]["a"], lev["cfit"]["b"], lev["cfit"]["c"]
        mfit = lev.get("mfit")
    for v in receivers:
        p = points[v]
        frame = tangent_frame_np(normals[v])
        if lev is None:  # no hierarchy: the whole fine mesh
            keep_c, keep_m, fine, _nc, nmc = none, none, np.arange(len(faces)), 0, 0
        else:
            keep_c, keep_m, fine, _nc, nmc = cut_sets(lev, v, p, normals[v], ras.rim, rule, k)
        fine = fine[(faces[fine] != v).all(axis=1)]
        parts = [np.stack([cpts_a[keep_c], cpts_b[keep_c], cpts_c[keep_c]], 1)]
        if mfit is not None:
            parts.append(np.stack([mfit["a"][keep_m], mfit["b"][keep_m], mfit["c"][keep_m]], 1))
        parts.append(points[faces[fine]])
        loc = (np.concatenate(parts) - p) @ frame
        loc, keep = ras.cull(loc)
        fan = fan_local(points, faces, v, frame)
        tri = np.concatenate([loc[keep], fan])
        out["lut"].append(ras.transfer(ras.bits(tri, False), frame))
        if exact_too:
            out["exact"].append(ras.transfer(ras.bits(tri, True), frame))
        out["coarse"].append(len(keep_c))
        out["mid"].append(len(keep_m))
        out["fine"].append(len(fine))
        out["mid_considered"].append(nmc)
        out["raster"].append(int(keep.sum()) + len(fan))
        out["raster_coarse"].append(int(keep[:len(keep_c)].sum()))
        out["raster_mid"].append(int(keep[len(keep_c):len(keep_c) + len(keep_m)].sum()))
    return out


def sample(nv: int, classes: dict, n: int, seed: int = 0):
    """``n`` random receivers (fixed seed) and up to :data:`EXTRA_CLASS` more of each small class."""
    rng = np.random.default_rng(seed)
    rand = np.sort(rng.choice(nv, n, replace=False))
    extra = []
    for c in ("contact", "fold"):
        pool = np.setdiff1d(np.flatnonzero(classes[c]), rand)
        if len(pool):
            extra.append(np.sort(rng.choice(pool, min(EXTRA_CLASS, len(pool)), replace=False)))
    return rand, np.concatenate([rand, *extra]) if extra else rand


def summarize(tr, truth, scale, rand_n, classes_sub):
    e = np.linalg.norm(np.asarray(tr) - truth, axis=1) / scale
    res = {"all": float(e[:rand_n].mean())}
    for c in RECEIVER_CLASSES:
        m = classes_sub[c]
        res[c] = float(e[m].mean()) if m.any() else None
    return res


def method_runs(mesh, frame) -> dict:
    """The method at :data:`METHOD` (and with ``direct_far``) on ``frame``: its transfers and triangles per
    receiver, and (without ``direct_far``) its points, normals and masks."""
    hm = get_method("hemiraster")
    out = {"transfers": {}}
    for label, knobs in (("method", METHOD), ("method, direct_far", {**METHOD, "direct_far": True})):
        m = hm(mesh, order=ORDER, **knobs)
        m.update(frame)
        m.update(frame)
        out["transfers"][label] = (m.transfer_numpy().astype(np.float64), m.stats().get("triangles_per_vertex"))
        if label == "method":
            out["points"] = m.points.numpy().astype(np.float64)
            out["normals"] = m.normals.numpy().astype(np.float64)
            out["mask"] = m._mask.numpy()
        del m
    return out


def run_mesh(name: str, nrec: int, configs, log=print, partial=None) -> dict:
    bm = {"draped": lambda: draped_cloth(64), "cloth": lambda: wrinkled_cloth(64)}[name]()
    mesh, frame = bm.rest, bm.frame
    faces = mesh.faces.astype(np.int64)
    truth_all = ground_truth(TriMesh(frame, mesh.faces, name=f"{name}-frame"), ORDER, log=log).astype(np.float64)
    scale = np.linalg.norm(truth_all, axis=1).mean()
    cls = receiver_classes(frame, mesh.faces)
    rand, recv = sample(mesh.num_vertices, cls, nrec)
    truth = truth_all[recv]
    classes_sub = {c: cls[c][recv] for c in RECEIVER_CLASSES}
    out = {"vertices": mesh.num_vertices, "receivers": len(recv), "random": len(rand),
           "class_counts": {c: int(classes_sub[c].sum()) for c in RECEIVER_CLASSES}, "rows": []}

    # the method itself at coarse 1536, on the same receivers (and its whole-mesh error)
    ras = Raster()
    runs = method_runs(mesh, frame)
    meth = {}
    for label, (tr, count) in runs["transfers"].items():
        full = float((np.linalg.norm(tr - truth_all, axis=1) / scale).mean())
        meth[label] = {"errors": summarize(tr[recv], truth, scale, len(rand), classes_sub), "error_all_vertices": full,
                       "triangles_per_vertex": count}
        log(f"{name}: {label}: {meth[label]}")
    out["method"] = meth
    pts, nrm, mask = runs["points"], runs["normals"], runs["mask"][recv]
    t0 = time.time()
    base = build_levels(pts, faces, 1536, None)
    em = emulate(base, pts, faces, nrm, recv, ras, None, 0.0)
    have = tables.unpack_bits(mask, MASK * MASK)
    # pixel agreement of the emulation's LUT masks with the method's masks
    emb = []
    for i, v in enumerate(recv):
        frame_v = tangent_frame_np(nrm[v])
        keep_c, _, fine, _, _ = cut_sets(base, v, pts[v], nrm[v], ras.rim, None, 0.0)
        fine = fine[(faces[fine] != v).all(axis=1)]
        cfit = base["cfit"]
        loc = (np.concatenate([np.stack([cfit["a"][keep_c], cfit["b"][keep_c], cfit["c"][keep_c]], 1),
                               pts[faces[fine]]]) - pts[v]) @ frame_v
        loc, keep = ras.cull(loc)
        emb.append(ras.bits(np.concatenate([loc[keep], fan_local(pts, faces, v, frame_v)]), False))
    emb = np.array(emb)
    diff = np.linalg.norm(np.asarray(em["lut"]) - runs["transfers"]["method"][0][recv], axis=1) / scale
    out["check"] = {"transfer_difference_mean": float(diff.mean()), "transfer_difference_max": float(diff.max()),
                    "pixels_method_only": float((have & ~emb).sum(1).mean()),
                    "pixels_emulation_only": float((emb & ~have).sum(1).mean()),
                    "pixels_blocked_method": float(have.sum(1).mean()),
                    "emulation_lut": summarize(em["lut"], truth, scale, len(rand), classes_sub),
                    "emulation_exact": summarize(em["exact"], truth, scale, len(rand), classes_sub),
                    "emulation_rasterized": float(np.mean(em["raster"][:len(rand)])),
                    "seconds": time.time() - t0}
    log(f"{name}: check {out['check']}")

    for coarse, mid, rule, k, border in configs:
        t0 = time.time()
        lev = build_levels(pts, faces, coarse, mid, border) if coarse else None
        em = emulate(lev, pts, faces, nrm, recv, ras, rule, k)
        r = len(rand)
        row = {"coarse": coarse or "none (the fine mesh)", "coarse_border": border, "near": mid or "fine",
               "rule": rule or "method", "k": k,
               "lut": summarize(em["lut"], truth, scale, r, classes_sub),
               "exact": summarize(em["exact"], truth, scale, r, classes_sub),
               "coarse_tested": len(lev["coarse_faces"]) if lev else 0,
               "coarse_kept": float(np.mean(em["coarse"][:r])), "mid_considered": float(np.mean(em["mid_considered"][:r])),
               "mid_kept": float(np.mean(em["mid"][:r])), "fine": float(np.mean(em["fine"][:r])),
               "rasterized": float(np.mean(em["raster"][:r])), "rasterized_coarse": float(np.mean(em["raster_coarse"][:r])),
               "rasterized_mid": float(np.mean(em["raster_mid"][:r])),
               "seconds": time.time() - t0}
        row["considered"] = row["coarse_tested"] + row["mid_considered"] + row["fine"]
        out["rows"].append(row)
        if partial is not None:
            partial(out)
        log(f"{name}: C {coarse}{'' if border else ' (no border)'} near {mid or 'fine'} {rule} {k}: LUT {row['lut']['all'] * 100:.2f} % exact "
            f"{row['exact']['all'] * 100:.2f} % considered {row['considered']:.0f} rasterized {row['rasterized']:.0f} "
            f"({row['seconds']:.0f} s)")
    return out


CONFIGS = [(c, m, r, k, True) for c, m, r, k in
           [(0, None, None, 0.0)] + [(c, None, None, 0.0) for c in (1536, 1024, 512, 384, 256)]
           + [(c, None, "dist", k) for c in (256, 384, 512) for k in (1.0, 2.0, 3.0, 4.0, 6.0)]
           + [(c, 1536, "dist", k) for c in (256, 384, 512) for k in (1.0, 2.0, 3.0, 4.0, 6.0)]
           + [(c, 1536, "omega", k) for c in (256, 384) for k in (1.0, 4.0, 16.0)]
           + [(256, 1536, None, 0.0)]]
CONFIGS += [(c, m, r, k, False) for c, m, r, k in
            [(c, None, None, 0.0) for c in (512, 384, 256)]
            + [(c, None, "dist", k) for c in (256, 384) for k in (2.0, 4.0)]
            + [(c, 1536, None, 0.0) for c in (256, 384, 512)]
            + [(c, 1536, "dist", k) for c in (256, 384, 512) for k in (2.0, 4.0, 8.0)]
            + [(c, 1536, "omega", k) for c in (256, 384) for k in (1.0, 4.0)]]
CONFIGS += [(c, m, "dev", k, True) for c, m, k in
            [(c, 1536, k) for c in (256, 384, 512) for k in (4.0, 8.0, 16.0)] + [(512, None, 4.0), (512, None, 8.0)]]
"""Rows: (coarse triangles (0: none, the fine mesh), near level (None: the fine mesh), cut rule (None: the
method's refinement alone), K, the coarse level keeps the open boundary)."""


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--meshes", default="draped,cloth")
    ap.add_argument("--receivers", type=int, default=150)
    ap.add_argument("--rows", default=":", metavar="A:B", help="a slice of CONFIGS (default: all)")
    ap.add_argument("--json", default=None, metavar="PATH")
    args = ap.parse_args(argv)
    wp.config.log_level = wp.LOG_WARNING
    lo, hi = (int(x) if x else None for x in args.rows.split(":"))
    configs = CONFIGS[lo:hi]
    out = {"order": ORDER, "mask": MASK, "lut": LUT, "refine": REFINE, "method_setting": METHOD, "meshes": {}}
    def save(res=None, name=None):
        if res is not None:
            out["meshes"][name] = res
        if args.json:
            with open(args.json, "w") as f:
                json.dump(out, f, indent=1, default=float)

    for name in args.meshes.split(","):
        run_mesh(name, args.receivers, configs, partial=lambda res, name=name: save(res, name))
        save()
    return 0


if __name__ == "__main__":
    sys.exit(main())
