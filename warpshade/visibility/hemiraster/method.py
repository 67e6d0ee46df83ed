"""Hemispherical rasterization (Kautz, Lehtinen, Aila 2004) as a :class:`TransferMethod`.

Per vertex, blocker triangles are projected onto the hemisphere of the vertex's tangent frame and
rasterized into a small bit mask on the unit disk (dropping z importance-samples the cosine, §3.1);
each triangle's image is the AND of three plane masks from a cube-map LUT, occluders fuse by OR
(§3.1.1). The mask is downsampled to coverage fractions and integrated against the SH basis into
the diffuse transfer of docs/conventions.md §2 (or the glossy Phong transfer of eq. 3 for a view
direction). The optimizations of §3.2 (two-level hierarchy, hierarchical cluster culling, PVS) are
each switchable. Beyond the paper, the coarse far field is refined back to the fine triangles it
stands for wherever it comes near a receiver (relative to how far it deviates from them this
frame), so surfaces in contact, folds and static ``occluders`` are rasterized exactly there. No
precomputation depends on the pose: ``update(points)`` reuses all static tables.
"""

from __future__ import annotations

import math
import time

import numpy as np
import warp as wp

from ...geometry.mesh import TriMesh, closed_orientation, vertex_neighbours
from ..base import TransferMethod
from ..knobs import Knob
from . import cache, hierarchy, integrate, tables
from .kernels import (CANDIDATES, PRECULL_BLOCKERS, Batch, Blockers, FineMesh, MaskChunk, MidLevel, PlaneLut, Refinement,
                      StaticPart, blocker_corners, follow_coarse_points, rasterize_masks, raise_deviation,
                      refit_blocker_boxes, triangle_bounds, union_boxes, union_child_boxes)


SEEN_BYTES = 64 * 1024 * 1024
"""Largest rasterized-once table (slots × ceil(F/64) uint64 words) the method allocates."""

SET_BYTES = 16 * 1024 * 1024
"""Largest pair of per-blocker bit rows over the fine triangles (``cover``, ``primary``: 2 × coarse
blockers × ceil(F/1024) chunks of 128 bytes) for which the refined blockers' fine triangles are
collected as a bit set (kernels.rasterize_fine_set; with the mid level, those of the mid triangles
replaced near a receiver, kernels.rasterize_mid_set, rows per mid triangle); above it (rows per coarse
blocker: ~130k fine triangles at 512 coarse blockers; rows per mid triangle: ~32k at 2048 mid triangles)
each refined group is walked instead (kernels.rasterize_group, kernels.rasterize_mid_fine): the same
masks, without tables and a per-receiver scan that grow with the mesh."""

STATIC_BYTES = 64 * 1024 * 1024
"""Largest table of the stored part's fine-triangle sets (``keep_static``: stored receivers × ceil(F/1024)
chunks of 128 bytes) the method allocates; above it nothing is stored."""

BATCH = 64
"""Triangles queued per slot before they are rasterized together (kernels.Batch; 4 KiB per
slot). Measured on the Table 1 cloth (interleaved runs, ratios of CPU time): 1 -> 1.28, 4 -> 1.06,
8 -> 1.03, 16 -> 1.00, 32 -> 0.94, 64 -> 0.95; without batching 1.06. Since the tiny-image test
runs in the batch (docs/benchmarks/history.md): 32 -> 64 0.965, 64 -> 128 1.02."""

RECEIVERS_PER_LAUNCH = 1024
"""Receivers of the first rasterization launch on the CPU; later launches are sized from its time to
take about :data:`LAUNCH_SECONDS` each. Python, and so Ctrl-C, runs between launches. Each receiver is
rasterized on its own, so the blocks give the same masks as one launch."""

LAUNCH_SECONDS = 0.5
"""Target duration of one CPU rasterization launch [s] (a receiver costs from ~10 us on a smooth
drape to ~470 us on a deeply crumpled 400 x 400 sheet, so a fixed block would be either many
launches or many seconds)."""


def _same_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per row: ``a`` and ``b`` (float32, same shape) equal bit for bit."""
    return (a.view(np.uint32) == b.view(np.uint32)).reshape(len(a), -1).all(axis=1)


def _rows_all(start: np.ndarray, items: np.ndarray, ok: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """For CSR lists (``start``, ``items``) of indices into ``ok``: whether every item of each row is ok, and
    each item's row and value (the lists without their padding)."""
    n = len(start) - 1
    items = items[:start[-1]]
    rows = np.repeat(np.arange(n), np.diff(start))
    good = np.ones(n, dtype=bool)
    good[rows[~ok[items]]] = False
    return good, rows, items


def scratch_slots(device, num_receivers: int) -> int:
    """Threads of the rasterization launch, each with its own scratch row (:func:`.kernels.rasterize_masks`):
    one on the CPU, where Warp runs a launch on one thread anyway and one row stays in the L1
    cache; one per receiver on a GPU."""
    return 1 if wp.get_device(device).is_cpu else max(1, int(num_receivers))


class HemirasterTransfer(TransferMethod):
    """Per-vertex SH transfer by hemispherical rasterization.

    Args:
        mesh: Receiver and blocker mesh (self-shadowing); topology is fixed for the method's lifetime.
        order: SH order N (default 5, the paper's "4th order").
        device: Warp device.
        mask: Visibility-mask resolution, 8, 16, 32 or 64 pixels across.
        lut: Cube-map resolution R of the plane LUT (6·R·R entries).
        downsample: Block size D (1, 2, 4, 8) for coverage integration.
        ring: k of the full-resolution k-ring used near each vertex when the hierarchy is on (0: none,
            the spatial refinement alone gives the near field; needs ``refine > 0``). With
            refinement, the coarse triangles standing for the k-ring are always refined.
        coarse: Target triangle count of the coarse (far-field) mesh; 0, or a count >= the mesh's,
            turns the hierarchy off and rasterizes the full mesh.
        refine: Spatial near-field refinement: a coarse triangle whose bounds (its own and those of
            the fine triangles it stands for, refitted every frame) come within ``refine`` times
            its deviation (the largest distance of those fine vertices from it, this frame) of the
            receiver is replaced by its fine triangles, so surfaces in contact or folded onto each
            other are rasterized exactly, while flat stretches stay coarse. 0 turns it off (the
            near field is then only the topological k-ring).
        occluders: Extra static meshes that cast shadows on ``mesh`` (they receive nothing), as in
            :class:`~warpshade.visibility.reference.ReferenceTransfer`; decimated to the receiver's
            coarse density (keeping their open boundary, whatever ``border``) and refined near
            receivers like the mesh itself.
        cull: Hierarchical culling of triangle clusters against the tangent plane (else a linear
            per-triangle horizon test).
        cluster: Triangles per cluster (16 clusters form a super-cluster).
        exclude: Without refinement (``refine=0``): near-field exclusion radius of coarse triangles,
            in units of the k-ring radius (rest pose). With refinement the k-ring excludes exactly
            the coarse triangles whose fine triangles it holds, and this knob is unused.
        backface: Rasterize only triangles facing away from the receiver when the mesh (and the
            coarse mesh) is closed and consistently oriented: every blocked ray leaves the solid
            through one of them, so the mask is the same with about half the triangles.
        mode: ``"diffuse"`` (docs/conventions.md §2) or ``"glossy"`` (eq. 3 with a normalised Phong lobe).
        view: Glossy mode: unit direction towards the viewer, world space (distant viewer).
        phong: Glossy mode: Phong exponent e of ``(e+2)/(2π) cos^e α``.
        lut_dir: Root of the disk cache for the plane LUT (None: the per-user cache of :mod:`warpshade._cache`,
            where the coarse far field is kept too; ``WARPSHADE_CACHE=none`` turns it off).
        pvs_frames: Optional recorded animation, shape (T, V, 3): builds a potentially-visible set
            (blocker triangles that set a bit in any frame) and rasterizes only those.
        min_image: Skip coarse far-field triangles whose projected solid angle (an upper bound from
            the Van Oosterom–Strackee formula) is below this many mask pixels: mostly triangles seen
            nearly edge-on, whose images rarely hold a pixel centre. 0 rasterizes all (exact); no
            effect without the hierarchy (``coarse=0``), nor on the k-ring. On an open mesh a sheet
            seen edge-on is a band of such triangles that each hold no pixel centre but together
            block it (a draped cloth's skirt seen from under its dome): 0 keeps it; a closed mesh's
            silhouette is also covered by the triangles behind it.
        direct_far: Rasterize the coarse far-field triangles whose image spans at most 2 x 2 pixel
            centres in the per-receiver pass over all coarse blockers, before any is queued
            (:func:`.kernels.far_field_bits`): the centres in the box of the corners' disk images
            (widened by the arcs' bulge and ``sqrt(2)/lut``, the bound on how far a LUT plane reaches
            past the exact one) that lie above the three edge planes quantised as the LUT does are
            set in the mask, and the triangle is not queued. That is the triangle's LUT image unless
            the image reaches past the box (a sliver's tip): the LUT images of a surface's triangles
            meet without gaps among themselves, where exact images beside LUT ones would leave seams.
            Off (the default) queues them all. Needs the refinement (``refine`` > 0) and the
            hierarchy with at most ``PRECULL_BLOCKERS`` coarse triangles (else no effect); not with
            a PVS; receivers whose static part is stored (``keep_static``) get none. Pays on a far
            field of many sub-pixel triangles (a draped cloth at ``min_image 0``;
            docs/benchmarks/history.md).
        fine_image: The same tiny-image cull for the fine triangles that replace refined coarse
            blockers near a receiver (0, the default, rasterizes them all: the exact near field).
            Most of them are grazing slivers along the receiver's horizon whose images hold no
            pixel centre; the cull trades a little accuracy for time on wrinkled cloth.
        rim: Skip blockers whose bounding sphere lies wholly below the elevation of the lowest pixel
            centre of the mask (their exact images hold no pixel; the LUT could only leak rim bits
            there). On by default; off only to measure it.
        fan: On a mesh that is not closed, rasterize each receiver's own triangles as seen from
            just above it, as the ray-traced reference does: where the surface folds up around the
            vertex (valleys, creases) the directions under its fan pass through the surface
            (:func:`.kernels.rasterize_fan`). On by default; off only to measure it.
        redecimate: Rebuild the coarse far field from the current pose (:meth:`rebuild`) when the
            coarse mesh's mean deviation from the fine surface, over its mean triangle radius, has
            grown by more than this since the pose it was built on (0: never, the paper's scheme:
            decimated once at rest). A flat sheet decimated flat and crumpled departs by ~0.3.
            Needs the refinement (``refine`` > 0 with the hierarchy), whose deviations it reads.
        border: Keep the vertices of the mesh's open boundary in the coarse (and mid) decimation
            (``fast_simplification``'s ``preserve_border``): decimation otherwise rounds the outline
            off, and a receiver far away sees through the missing part (under a draped cloth's hem),
            where the refinement (``hierarchy.outline_deviation``) helps only near receivers. The
            interior gets fewer vertices (a 64² cloth's 252 boundary vertices are nearly all of a
            512-triangle coarse mesh's; raise ``coarse`` with it).
        mid: Triangle target of a mid level between the coarse and the fine mesh (0, the default: off;
            used when ``coarse < mid <`` the mesh's triangles, with the refinement). A second decimation
            of the mesh, bound to and assigned over the fine triangles like the coarse one: a refined
            coarse blocker is replaced by the mid triangles it stands for, and only mid triangles
            within ``refine`` times their own deviation of the receiver (or standing for its k-ring)
            by their fine triangles. Pays on dense meshes (measured on 64² cloths and the default
            scene with ``coarse=256, mid=2048``; docs/methods/hemiraster.md), not on meshes with
            fewer than about 3× ``mid`` triangles.
        interpolate: Compute the transfer at a subset of receivers only (about every other one,
            :func:`.hierarchy.interpolation_subset`) and give each other receiver the unoccluded
            transfer of its own normal minus the mean blocked part of its computed neighbours, unless
            their blocked parts differ from that mean by more than ``interpolate`` times the
            unoccluded transfer's norm: then it is computed too (0: every receiver computed, exact).
        interp_levels: Levels of the interpolation split (with ``interpolate`` > 0; 1, the default: the
            split above). With ``n`` levels the split is repeated on the computed receivers
            (:func:`.hierarchy.interpolation_subset`): about a quarter of a smooth closed mesh's
            receivers are computed with 2, an eighth with 3; the coarsest level's targets are
            interpolated from the computed receivers, each finer level's from the level above's
            (computed or interpolated), each with the same test, where an interpolated neighbour
            adds the disagreement it was interpolated with: a receiver whose spread summed along
            its chain of interpolations exceeds ``interpolate`` is computed.
        interp_rise: With ``interpolate``: also compute a target a vertex of whose 1-ring lies more
            than this many degrees above its tangent plane (90, the default: off). Its neighbours
            may agree while it sits in a crease or pit they do not (the bear's concave voxel
            corners: neighbours unoccluded, the target 40-67 % of the mean transfer darker).
        keep_static: Store the part of each unmoved receiver's mask that unmoved blockers give and, while
            none of them moves, rasterize only the rest (:meth:`_static_mode`; the same masks). Receivers
            and blockers count as unmoved when their positions (and the receiver's normal) are bit for
            bit those of the previous frame while others moved (a pose repeated whole stores nothing);
            the part is stored on that frame and dropped when one of them moves. Not with the mid level
            or a PVS. On by default; off only to measure it.
    """

    name = "hemiraster"
    KNOBS = (
        Knob("mask", int, "visibility mask pixels across", choices=tuple(tables.MASK_SIZES), attr="mask_res"),
        Knob("lut", int, "plane LUT cube-map resolution R (6*R*R planes)", minimum=1, attr="lut_res"),
        Knob("downsample", int, "coverage block size in pixels", choices=(1, 2, 4, 8)),
        Knob("ring", int, "full-resolution k-ring (0: spatial refinement only)", choices=(0, 1, 2, 3, 4)),
        Knob("refine", float, "replace coarse triangles nearer than this many times their deviation from the fine "
                              "surface by their fine triangles (contact, folds; 0: off)", minimum=0.0),
        Knob("coarse", int, "coarse far-field mesh triangles (0: no hierarchy, full mesh)", minimum=0,
             attr="coarse_target"),
        Knob("cull", bool, "disable cluster culling"),
        Knob("cluster", int, "triangles per culling cluster", minimum=1),
        Knob("exclude", float, "coarse triangles nearer than this many k-ring radii are left to the k-ring"),
        Knob("backface", bool, "rasterize back faces too (only matters on closed meshes)"),
        Knob("mode", str, "diffuse transfer (docs/conventions.md §2) or glossy Phong transfer for --view",
             choices=("diffuse", "glossy")),
        Knob("view", "vec3", "glossy: direction towards the viewer x,y,z (world)"),
        Knob("phong", float, "glossy: Phong exponent", minimum=0.0),
        Knob("lut_dir", str, "another directory for the plane LUT's disk cache (default: $WARPSHADE_CACHE)", nullable=True),
        Knob("min_image", float, "skip far-field triangles whose image is smaller than this many mask pixels "
                                 "(0: exact; a draped cloth wants 0)", minimum=0.0),
        Knob("redecimate", float, "rebuild the coarse far field from the current pose when its deviation from the "
                                  "fine surface per triangle radius grew by more than this (0: never)", minimum=0.0),
        Knob("interpolate", float, "compute a subset of receivers, interpolate the others where their neighbours "
                                   "agree within this fraction of the unoccluded transfer (0: compute all)",
             minimum=0.0),
        Knob("interp_levels", int, "levels of the interpolation split: about 1/2, 1/4, 1/8 of a smooth mesh's "
                                   "receivers computed with 1, 2, 3 (with --interpolate)", minimum=1),
        Knob("interp_rise", float, "with --interpolate: also compute a receiver whose 1-ring rises more than this many "
                                   "degrees above its tangent plane (a crease or pit; 90: off)", minimum=0.0, maximum=90.0),
        Knob("direct_far", bool, "rasterize far-field triangles whose image spans at most 2 x 2 pixel centres in the "
                                 "per-blocker pass (their LUT images at those centres), not through the queue"),
        Knob("fine_image", float, "the same cull for the fine triangles of refined blockers near a receiver "
                                  "(0: exact near field)", minimum=0.0),
        Knob("mid", int, "mid-level triangles between the coarse and the fine mesh for the refined near field "
                         "(0: off, refined coarse triangles are replaced by fine ones)", minimum=0, attr="mid_target"),
        Knob("border", bool, "keep the open mesh's boundary vertices in the decimation of the far field (the outline of a "
                             "hem seen from afar; fewer triangles left for the interior)"),
        Knob("rim", bool, "skip blockers wholly below the lowest pixel centre", cli=False),
        Knob("fan", bool, "rasterize the receiver's own fan on open meshes", cli=False),
        Knob("keep_static", bool, "store the part of unmoved receivers' masks that unmoved blockers give", cli=False),
    )

    def __init__(self, mesh: TriMesh, order: int = 5, device: str = "cpu", mask: int = 32, lut: int = 48,
                 downsample: int = 1, ring: int = 1, coarse: int = 512, cull: bool = True, cluster: int = 16,
                 exclude: float = 0.35, backface: bool = True, mode: str = "diffuse", view=(0.0, 0.0, 1.0),
                 phong: float = 8.0, lut_dir: str | None = None, pvs_frames=None, min_image: float = 0.5,
                 refine: float = 2.0, occluders: list[TriMesh] | None = None, rim: bool = True, fine_image: float = 0.0,
                 fan: bool = True, redecimate: float = 0.0, interpolate: float = 0.0, mid: int = 0,
                 border: bool = False, keep_static: bool = True, direct_far: bool = False, interp_levels: int = 1,
                 interp_rise: float = 90.0):
        super().__init__(mesh, order, device)
        # every knob but the PVS, to rebuild the far field from another pose (:meth:`rebuild`)
        self._init_knobs = dict(mask=mask, lut=lut, downsample=downsample, ring=ring, coarse=coarse, cull=cull,
                                cluster=cluster, exclude=exclude, backface=backface, mode=mode, view=view, phong=phong,
                                lut_dir=lut_dir, min_image=min_image, refine=refine, occluders=occluders, rim=rim,
                                fine_image=fine_image, fan=fan, redecimate=redecimate,
                                interpolate=interpolate, mid=mid, border=border, keep_static=keep_static,
                                direct_far=direct_far, interp_levels=interp_levels, interp_rise=interp_rise)
        if not (float(redecimate) >= 0.0 and np.isfinite(float(redecimate))):
            raise ValueError(f"hemiraster: redecimate must be a finite number >= 0, got {redecimate}")
        if float(redecimate) > 0.0 and pvs_frames is not None:
            raise ValueError("hemiraster: redecimate needs no PVS (a PVS lists the blockers of the coarse mesh it was recorded with)")
        self.redecimate = float(redecimate)
        if not (float(interpolate) >= 0.0 and np.isfinite(float(interpolate))):
            raise ValueError(f"hemiraster: interpolate must be a finite number >= 0, got {interpolate}")
        if float(interpolate) > 0.0 and (mode != "diffuse" or pvs_frames is not None):
            raise ValueError("hemiraster: interpolate works in diffuse mode without a PVS only")
        self.interpolate = float(interpolate)
        if int(interp_levels) != interp_levels or int(interp_levels) < 1:
            raise ValueError(f"hemiraster: interp_levels must be an integer >= 1, got {interp_levels}")
        if int(interp_levels) > 1 and self.interpolate == 0.0:
            raise ValueError("hemiraster: interp_levels > 1 needs interpolate > 0")
        self.interp_levels = int(interp_levels)
        if not 0.0 <= float(interp_rise) <= 90.0:
            raise ValueError(f"hemiraster: interp_rise must be in [0, 90] degrees, got {interp_rise}")
        self.interp_rise = float(interp_rise)
        tables.check_mask(int(mask), int(downsample))
        if ring not in (0, 1, 2, 3, 4):
            raise ValueError(f"hemiraster: ring must be 0, 1, 2, 3 or 4, got {ring}")
        if not (float(refine) >= 0.0 and np.isfinite(float(refine))):
            raise ValueError(f"hemiraster: refine must be a finite number >= 0, got {refine}")
        if ring == 0 and float(refine) == 0.0:
            raise ValueError("hemiraster: ring=0 needs refine > 0 (else nothing rasterizes the near field)")
        if mode not in ("diffuse", "glossy"):
            raise ValueError(f"hemiraster: mode must be 'diffuse' or 'glossy', got {mode!r}")
        if int(coarse) < 0:
            raise ValueError(f"hemiraster: coarse must be >= 0 triangles, got {coarse}")
        if int(mid) < 0:
            raise ValueError(f"hemiraster: mid must be >= 0 triangles, got {mid}")
        self.mid_target = int(mid)
        if cluster < 1:
            raise ValueError(f"hemiraster: cluster must be >= 1 triangles, got {cluster}")
        view = np.asarray(view, dtype=np.float64)
        if view.shape != (3,) or not np.isfinite(view).all() or np.linalg.norm(view) == 0:
            raise ValueError(f"hemiraster: view must be a non-zero finite direction x,y,z, got {view.tolist()}")
        if phong < 0:
            raise ValueError(f"hemiraster: phong exponent must be >= 0, got {phong}")
        self.mask_res, self.lut_res, self.downsample = int(mask), int(lut), int(downsample)
        self.ring, self.coarse_target, self.cull = int(ring), int(coarse), bool(cull)
        self.cluster, self.exclude, self.mode = int(cluster), float(exclude), mode
        self.refine = float(refine)
        self.view = view / np.linalg.norm(view)
        self.backface = bool(backface)
        if not (float(min_image) >= 0.0):
            raise ValueError(f"hemiraster: min_image must be >= 0 pixels, got {min_image}")
        self.min_image = float(min_image)
        if not (float(fine_image) >= 0.0):
            raise ValueError(f"hemiraster: fine_image must be >= 0 pixels, got {fine_image}")
        self.fine_image = float(fine_image)
        if direct_far and pvs_frames is not None:
            raise ValueError("hemiraster: direct_far needs no PVS (a PVS lists the blockers that set a bit through the queue)")
        if direct_far and not float(refine) > 0.0:
            raise ValueError("hemiraster: direct_far needs refine > 0 (the paper scheme's near-field exclusion is applied "
                             "after the per-blocker pass)")
        self.direct_far = bool(direct_far)
        self.rim = bool(rim)
        self.fan = bool(fan)
        self.border = bool(border)
        self.keep_static = bool(keep_static)
        self.phong, self.lut_dir = float(phong), lut_dir
        t_start = time.perf_counter()
        d = device
        nv, nf = mesh.num_vertices, mesh.num_faces
        faces = mesh.faces.astype(np.int64)

        # plane LUT and integration tables (cached per (mask, R) / built per setting)
        lut_np, self._lut_seconds, self._lut_source = tables.build_lut(self.mask_res, self.lut_res, lut_dir, d)
        self._words = tables.words_per_mask(self.mask_res)
        self._lut = PlaneLut()
        half = tables.positive_half(lut_np, self.mask_res, self.lut_res)
        self._lut.rows = wp.array(tables.chunked_rows(half["rows"]), dtype=MaskChunk, device=d)
        self._lut.valid = wp.array(tables.chunked_rows(half["valid"][None, :])[0], dtype=MaskChunk, device=d)
        self._lut.chunks = self._lut.rows.shape[1]
        self._lut.res = self.lut_res
        self._lut.words = self._words
        pdirs, pvalid = tables.pixel_directions(self.mask_res)
        # strictly below the lowest pixel centre (1e-4 relative: float32 rounding of the test)
        self._lut.rim = float(pdirs[pvalid, 2].min()) * (1.0 - 1e-4) if self.rim else 0.0
        self._lut.half_mask = 0.5 * self.mask_res
        # integration (.integrate): per-pixel shares of the block integrals summed per nibble value
        # (diffuse), or the block integrals and directions (glossy); rotation to world by sampling
        self._integrate = integrate.integrate_kernels(self.order)
        vec_sh = self._integrate.vec_sh
        blocks = tables.block_tables(self.mask_res, self.downsample, self.order)
        if self.mode == "diffuse":
            pix = integrate.pixel_weights(blocks["weights"], blocks["valid"], pvalid, self.downsample)
            self._nibbles = wp.array(integrate.nibble_table(pix).astype(np.float32), dtype=vec_sh, device=d)
            self._pixel_dc = pix[:, 0]  # per-pixel shares of the DC (stop_when_dark)
        else:
            self._block_weights = wp.array(blocks["weights"].astype(np.float32), dtype=vec_sh, device=d)
            self._block_valid = wp.array(blocks["valid"], dtype=wp.int32, device=d)
            self._block_dirs = wp.array(blocks["dirs"].astype(np.float32), dtype=wp.vec3, device=d)
        self._unoccluded = vec_sh(*blocks["weights"].sum(axis=0).astype(np.float32).tolist())
        rot_dirs, rot_pinv = tables.rotation_directions(self.order)
        self._rot_dirs = wp.array(rot_dirs.astype(np.float32), dtype=wp.vec3, device=d)
        self._rot_pinv = wp.array(rot_pinv.astype(np.float32), dtype=vec_sh, device=d)
        self._basis = self._integrate.basis_constants()

        # the blocker scene: the receiver mesh, then the static occluders (they block, never receive)
        occluders = list(occluders or [])
        for k, o in enumerate(occluders):
            if not isinstance(o, TriMesh):
                raise TypeError(f"hemiraster: occluders[{k}] must be a TriMesh, got {type(o).__name__}")
        self.occluders = occluders
        parts = [(mesh.points, faces)] + [(o.points, o.faces.astype(np.int64)) for o in occluders]
        vbase = np.cumsum([0] + [len(q) for q, _ in parts])
        scene_pts = np.concatenate([q for q, _ in parts]).astype(np.float32)
        scene_faces = np.concatenate([f + b for (_, f), b in zip(parts, vbase[:-1])])
        nsf = len(scene_faces)
        if occluders:
            self._spoints = wp.array(scene_pts, dtype=wp.vec3, device=d)
            self._sfaces = wp.array(scene_faces.astype(np.int32), dtype=wp.int32, device=d)
        else:
            self._spoints, self._sfaces = self.points, self.faces

        # two-level hierarchy: coarse mesh riding the fine one, refined to the fine triangles near
        # each receiver (spatial near field) and/or the receiver's k-ring; or the full mesh alone.
        # Occluders get the receiver's coarse density (each part decimated on its own).
        targets = [self.coarse_target] + [max(1, round(self.coarse_target * len(o.faces) / max(nf, 1))) for o in occluders]
        self.hierarchy = 0 < self.coarse_target < nf
        # mid level: between the coarse and the fine mesh, for the refined near field only
        self._use_mid = self.hierarchy and self.refine > 0.0 and self.coarse_target < self.mid_target < nf
        mid_targets = ([self.mid_target] + [max(1, round(self.mid_target * len(o.faces) / max(nf, 1))) for o in occluders]
                       if self._use_mid else None)
        group_start, group_mid, group_tris = np.zeros(2, np.int32), np.zeros(1, np.int32), np.zeros(1, np.int32)
        group_owner, group_run_end = np.zeros(1, np.int32), np.zeros(1, np.int32)
        far = None
        self._mid_bind = None
        if self.hierarchy:
            # occluders keep their open outline (the edge of the shadow they cast): decimated to the receiver's
            # density without it, a 2-triangle quad became one triangle and let half its shadow through
            borders = [self.border] + [True] * len(occluders)
            far = cache.far_field([(q.astype(np.float64), f) for q, f in parts], targets, mid_targets, borders)
            cpts, block_faces = far["points"], far["faces"]
            self._near_mode = 0  # 0: none, 1: exclusion bits (paper scheme), 2: forced refinement bits
            if self.ring:
                ring_start, ring_tris, rings = hierarchy.ring_triangles(faces, nv, self.ring)
                if self.refine > 0.0:
                    # the k-ring through the coarse triangles standing for it: exact in any pose, no
                    # triangle twice, no coarse triangle cutting through it
                    excl = hierarchy.ring_groups(ring_start, ring_tris, faces, far["owner"], len(block_faces))
                    if self._use_mid:
                        # also the coarse triangles holding the mid triangles that stand for the k-ring,
                        # and those mid triangles (always replaced by their fine triangles)
                        mfar = far["mid"]
                        excl |= hierarchy.ring_groups(ring_start, ring_tris, faces, mfar["coarse_owner"][mfar["owner"]],
                                                      len(block_faces))
                        mid_ring = hierarchy.ring_lists(ring_start, ring_tris, faces, mfar["owner"])
                    ring_start, ring_tris = np.zeros(nv + 1, np.int32), np.zeros(1, np.int32)
                    self._near_mode = 2
                else:
                    excl = hierarchy.near_exclusion(mesh.points.astype(np.float64), rings, cpts, block_faces, self.exclude)
                    self._near_mode = 1
                self._excl = wp.array(excl, dtype=wp.uint32, device=d)
            else:
                ring_start, ring_tris = np.zeros(nv + 1, np.int32), np.zeros(1, np.int32)
                self._excl = wp.zeros((1, 1), dtype=wp.uint32, device=d)
            self._bind = (wp.array(far["bind_face"], dtype=wp.int32, device=d),
                          wp.array(far["bind_bary"], dtype=wp.vec3, device=d),
                          wp.array(far["bind_offset"], dtype=float, device=d))
            self._bpoints = wp.zeros(len(cpts), dtype=wp.vec3, device=d)
        else:
            ring_start, ring_tris = np.zeros(nv + 1, np.int32), np.zeros(1, np.int32)
            self._bind = None
            self._near_mode = 0
            self._bpoints = self._spoints
            block_faces = scene_faces
            self._excl = wp.zeros((1, 1), dtype=wp.uint32, device=d)
        self._use_refine = self.hierarchy and self.refine > 0.0
        self._bind_offset_abs = self._bind[2] if self.hierarchy else wp.zeros(1, dtype=float, device=d)
        self._ring_start = wp.array(ring_start, dtype=wp.int32, device=d)
        self._ring_tris = wp.array(ring_tris if len(ring_tris) else np.zeros(1, np.int32), dtype=wp.int32, device=d)
        self._ring_avg = float(ring_start[-1]) / nv
        if self._near_mode == 2:  # k-ring held by its coarse triangles: their fine triangles per vertex
            gstart = hierarchy.groups_in_order(far["owner"], far["extra"], np.arange(len(block_faces)))[0]
            gsize = np.diff(gstart)
            bits = (excl[:, :, None] >> np.arange(32, dtype=np.uint32)) & 1
            self._ring_avg = float((bits.reshape(nv, -1)[:, :len(block_faces)] * gsize).sum()) / nv
        rest_blockers = (self._bpoints_rest() if self.hierarchy else scene_pts)
        # back-face culling needs closed, consistently oriented fine and blocker meshes; the sign
        # of the enclosed volume says which side faces out
        side = closed_orientation(scene_pts, scene_faces)
        fine_closed = side != 0
        if self.hierarchy:
            cside = closed_orientation(rest_blockers, block_faces)
            side = side if side == cside else 0
        # keep the triangles facing away: every blocked ray leaves the solid through one of those,
        # also rays that enter it right at the receiver (concave spots, under a skipped incident triangle)
        self._backface_side = -float(side) if self.backface else 0.0
        self._lut.backface = self._backface_side
        # one pixel of the mask covers (2/M)² of the disk (= its projected solid angle). Coarse far
        # field only: without the hierarchy the blockers are the fine triangles, individually tiny
        # but together the whole nearby surface (bear, full mesh: 1.4 -> 11 % error)
        self._lut.min_area = self.min_image * (2.0 / self.mask_res) ** 2 if self.hierarchy else 0.0
        self._lut.fine_area = self.fine_image * (2.0 / self.mask_res) ** 2 if self.hierarchy else 0.0
        # sin of the largest angle between a plane normal and its LUT cell's centre normal is below
        # sqrt(2)/R (half a cell's diagonal on the cube face, where a cell subtends the most)
        self._lut.direct = math.sqrt(2.0) / self.lut_res if self.hierarchy and self.direct_far else -1.0
        self._lut.lut_half = 0.5 * self.lut_res
        self._lut.lut_last = float(self.lut_res - 1)
        perm, cstart, sstart = hierarchy.build_clusters(rest_blockers, block_faces, self.cluster, 16)
        if self._use_refine:
            group_start, group_mid, group_tris, group_owner, group_run_end = hierarchy.groups_in_order(far["owner"], far["extra"], perm)
        # bounds and deviation of each coarse blocker are taken over the fine triangles it stands for
        self._fit_start = wp.array(group_start, dtype=wp.int32, device=d)
        self._fit_mid = wp.array(group_mid, dtype=wp.int32, device=d)
        self._fit_tris = wp.array(group_tris, dtype=wp.int32, device=d)
        self._mids = MidLevel()
        self._sub = Refinement()
        self._sub.refine = self.refine if self._use_mid else 0.0
        if self._use_mid:
            mfar = far["mid"]
            nm = len(mfar["faces"])
            new_coarse = np.empty(len(perm), np.int64)
            new_coarse[perm] = np.arange(len(perm))
            # mid triangles in the order of their primary coarse blockers (neighbours in memory)
            mperm = np.argsort(new_coarse[mfar["coarse_owner"]], kind="stable")
            new_mid = np.empty(nm, np.int64)
            new_mid[mperm] = np.arange(nm)
            # coarse blockers list mid triangles (primaries, then the seam-cover extras) ...
            group_start, group_mid, mtris, group_owner, group_run_end = hierarchy.groups_in_order(
                mfar["coarse_owner"], mfar["coarse_extra"], perm)
            group_tris = new_mid[mtris].astype(np.int32)
            # ... and mid triangles list fine ones
            sub = hierarchy.groups_in_order(mfar["owner"], mfar["extra"], mperm)
            self._sub_arrays = [wp.array(x, dtype=wp.int32, device=d) for x in sub]
            self._sub.start, self._sub.mid, self._sub.tris, self._sub.owner, self._sub.run_end = self._sub_arrays
            self._mid_bind = (wp.array(mfar["bind_face"], dtype=wp.int32, device=d),
                              wp.array(mfar["bind_bary"], dtype=wp.vec3, device=d),
                              wp.array(mfar["bind_offset"], dtype=float, device=d))
            self._mids.on = 1
            self._mids.points = wp.zeros(len(mfar["points"]), dtype=wp.vec3, device=d)
            self._mids.faces = wp.array(mfar["faces"][mperm].astype(np.int32), dtype=wp.int32, device=d)
            self._mids.plane = wp.zeros(nm, dtype=wp.vec4, device=d)
            self._mids.sphere = wp.zeros(nm, dtype=wp.vec4, device=d)
            self._mid_nlen = wp.zeros(nm, dtype=float, device=d)
            self._mids.coarse = wp.array(new_coarse[mfar["coarse_owner"][mperm]].astype(np.int32), dtype=wp.int32, device=d)
            if self._near_mode == 2:
                mstart, mitems = mid_ring
                mitems = new_mid[mitems].astype(np.int32) if mstart[-1] else mitems
            else:
                mstart, mitems = np.zeros(nv + 1, np.int32), np.zeros(1, np.int32)
            self._mids.ring_start = wp.array(mstart, dtype=wp.int32, device=d)
            self._mids.ring_tris = wp.array(mitems, dtype=wp.int32, device=d)
            self._mid_outline = wp.array(mfar["outline"][mperm], dtype=float, device=d)
            self._mid_box = (wp.zeros(nm, dtype=wp.vec3, device=d), wp.zeros(nm, dtype=wp.vec3, device=d))
            self._mid_dev = wp.zeros(nm, dtype=float, device=d)
            self._sub.lo, self._sub.hi = self._mid_box
            self._sub.dev = self._mid_dev
            self.num_mid = nm
            if self._backface_side != 0.0 and closed_orientation(self._mid_points_rest(), mfar["faces"]) != side:
                self._backface_side = 0.0  # the mid mesh must be closed and oriented alike too
                self._lut.backface = 0.0
        else:
            self._mid_bind = None
            self._mids.on = 0
            self._mids.points = wp.zeros(1, dtype=wp.vec3, device=d)
            self._mids.faces = wp.zeros((1, 3), dtype=wp.int32, device=d)
            self._mids.plane = wp.zeros(1, dtype=wp.vec4, device=d)
            self._mids.sphere = wp.zeros(1, dtype=wp.vec4, device=d)
            self._mids.coarse = wp.zeros(1, dtype=wp.int32, device=d)
            self._mids.ring_start = wp.zeros(nv + 1, dtype=wp.int32, device=d)
            self._mids.ring_tris = wp.zeros(1, dtype=wp.int32, device=d)
            self._sub.lo, self._sub.hi = (wp.zeros(1, dtype=wp.vec3, device=d) for _ in range(2))
            self._sub.dev = wp.zeros(1, dtype=float, device=d)
            self._sub.start, self._sub.mid, self._sub.tris, self._sub.owner, self._sub.run_end = (
                wp.zeros(2, dtype=wp.int32, device=d) for _ in range(5))
            self.num_mid = 0
        self._mids.counts = wp.zeros(nv, dtype=wp.int32, device=d)
        self._group_start = wp.array(group_start, dtype=wp.int32, device=d)
        self._group_tris = wp.array(group_tris, dtype=wp.int32, device=d)
        self._group_mid = wp.array(group_mid, dtype=wp.int32, device=d)
        self._group_owner = wp.array(group_owner, dtype=wp.int32, device=d)
        self._group_run_end = wp.array(group_run_end, dtype=wp.int32, device=d)
        self._bfaces = wp.array(block_faces[perm].astype(np.int32), dtype=wp.int32, device=d)
        self._bsource = wp.array(perm.astype(np.int32), dtype=wp.int32, device=d)
        self._perm_inv = np.argsort(perm)
        self._cluster_start = wp.array(cstart, dtype=wp.int32, device=d)
        self._super_start = wp.array(sstart, dtype=wp.int32, device=d)
        nc, ns = len(cstart) - 1, len(sstart) - 1
        self.num_blockers = len(block_faces)
        self._blocker_box = (wp.zeros(self.num_blockers, dtype=wp.vec3, device=d),
                             wp.zeros(self.num_blockers, dtype=wp.vec3, device=d))
        self._blocker_dev = wp.zeros(self.num_blockers, dtype=float, device=d)
        self._cluster_box = (wp.zeros(nc, dtype=wp.vec3, device=d), wp.zeros(nc, dtype=wp.vec3, device=d))
        self._cluster_reach = wp.zeros(nc, dtype=float, device=d)
        self._super_box = (wp.zeros(ns, dtype=wp.vec3, device=d), wp.zeros(ns, dtype=wp.vec3, device=d))
        self._super_reach = wp.zeros(ns, dtype=float, device=d)
        self._fine = FineMesh()
        self._fine.points, self._fine.faces = self._spoints, self._sfaces
        self._fine.plane = wp.zeros(nsf, dtype=wp.vec4, device=d)
        self._fine.sphere = wp.zeros(nsf, dtype=wp.vec4, device=d)
        self._fine.nlen = wp.zeros(nsf, dtype=float, device=d)
        # the receiver's own fan seen from just above it (kernels.rasterize_fan): on open surfaces;
        # on a closed one every direction under the fan leaves the solid through a back face
        self._fan_on = self.fan and not fine_closed
        fan_lists = hierarchy.vertex_faces(faces, nv) if self._fan_on else []
        fan_start = np.concatenate([[0], np.cumsum([len(x) for x in fan_lists])]) if self._fan_on else np.zeros(nv + 1)
        self._fine.fan_start = wp.array(fan_start.astype(np.int32), dtype=wp.int32, device=d)
        self._fine.fan_tris = wp.array(np.concatenate(fan_lists).astype(np.int32) if self._fan_on else np.zeros(1, np.int32),
                                       dtype=wp.int32, device=d)
        self._fine.fan = 1 if self._fan_on else 0
        self._groups = Refinement()
        self._groups.refine = self.refine if self._use_refine else 0.0
        self._groups.lo, self._groups.hi = self._blocker_box
        self._groups.dev = self._blocker_dev
        self._groups.start, self._groups.mid = self._group_start, self._group_mid
        self._groups.tris, self._groups.owner = self._group_tris, self._group_owner
        self._groups.run_end = self._group_run_end
        # rasterized-once table: a seam triangle is listed by several coarse triangles; skip repeats
        # (1 bit per fine triangle and slot; off above SEEN_BYTES, where repeats are only slower)
        self._slots = scratch_slots(d, nv)
        seen_words = (nsf + 63) // 64
        use_seen = 1 if (self._use_refine and self._slots * seen_words * 8 <= SEEN_BYTES) else 0
        fine_refs = self._sub if self._use_mid else self._groups  # the level whose groups list fine triangles
        fine_refs.use_seen = use_seen
        fine_refs.seen = wp.zeros((self._slots, seen_words) if use_seen else (1, 1), dtype=wp.uint64, device=d)
        if self._use_mid:
            mid_words = (self.num_mid + 63) // 64
            self._groups.use_seen = 1 if self._slots * mid_words * 8 <= SEEN_BYTES else 0
            self._groups.seen = wp.zeros((self._slots, mid_words) if self._groups.use_seen else (1, 1), dtype=wp.uint64,
                                         device=d)
            self._mids.ring_bits = wp.zeros((self._slots, mid_words), dtype=wp.uint64, device=d)
        else:
            self._sub.use_seen = 0
            self._sub.seen = wp.zeros((1, 1), dtype=wp.uint64, device=d)
            self._mids.ring_bits = wp.zeros((1, 1), dtype=wp.uint64, device=d)
        # kernels.listed_set: each coarse blocker's listed and primary triangles (mid, or fine without
        # the mid level) as bit rows; for fine triangles only up to SET_BYTES (else the groups are walked)
        listed_count = self.num_mid if self._use_mid else nsf
        set_bytes = 2 * len(group_start) * -(-listed_count // 1024) * 128
        self._groups.use_set = 1 if self._use_mid or (self._use_refine and set_bytes <= SET_BYTES) else 0
        if self._groups.use_set:
            cover, primary = hierarchy.group_bits(group_start, group_mid, group_tris, listed_count)
            self._groups.cover = wp.array(tables.chunked_rows(cover), dtype=MaskChunk, device=d)
            self._groups.primary = wp.array(tables.chunked_rows(primary), dtype=MaskChunk, device=d)
            self._groups.listed = wp.zeros((self._slots, self._groups.cover.shape[1]), dtype=MaskChunk, device=d)
            self._groups.visited = wp.zeros((self._slots, (self.num_blockers + 63) // 64), dtype=wp.uint64, device=d)
        else:
            self._groups.cover, self._groups.primary, self._groups.listed = (wp.zeros((1, 1), dtype=MaskChunk, device=d)
                                                                             for _ in range(3))
            self._groups.visited = wp.zeros((1, 1), dtype=wp.uint64, device=d)
        # kernels.rasterize_mid_set: the fine triangles of the replaced mid triangles as a set too
        sub_bytes = 2 * self.num_mid * -(-nsf // 1024) * 128
        self._sub.use_set = 1 if (self._use_mid and sub_bytes <= SET_BYTES) else 0
        if self._sub.use_set:
            sstart, smid, stris = (a.numpy() for a in self._sub_arrays[:3])
            cover, primary = hierarchy.group_bits(sstart, smid, stris, nsf)
            self._sub.cover = wp.array(tables.chunked_rows(cover), dtype=MaskChunk, device=d)
            self._sub.primary = wp.array(tables.chunked_rows(primary), dtype=MaskChunk, device=d)
            self._sub.listed = wp.zeros((self._slots, self._sub.cover.shape[1]), dtype=MaskChunk, device=d)
        else:
            self._sub.cover, self._sub.primary, self._sub.listed = (wp.zeros((1, 1), dtype=MaskChunk, device=d)
                                                                    for _ in range(3))
        self._sub.visited = wp.zeros((1, 1), dtype=wp.uint64, device=d)
        self._bplane = wp.zeros(self.num_blockers, dtype=wp.vec4, device=d)
        self._bsphere = wp.zeros(self.num_blockers, dtype=wp.vec4, device=d)
        self._bnlen = wp.zeros(self.num_blockers, dtype=float, device=d)
        self._blockers = Blockers()
        self._blockers.points, self._blockers.faces = self._bpoints, self._bfaces
        self._blockers.plane, self._blockers.sphere, self._blockers.nlen = self._bplane, self._bsphere, self._bnlen
        self._blockers.source, self._blockers.skip_incident = self._bsource, 0 if self.hierarchy else 1
        self._blockers.order = wp.array(self._perm_inv.astype(np.int32), dtype=wp.int32, device=d)
        self._blockers.refined = wp.zeros((self._slots, (self.num_blockers + 63) // 64), dtype=wp.uint64, device=d)
        # kernels.far_field_bits: every blocker's culls and refinement bits per receiver in one pass (a
        # coarse far field; the full mesh as blockers is culled per cluster)
        bwords = (self.num_blockers + 63) // 64
        self._blockers.precull = 1 if (self.hierarchy and self.num_blockers <= PRECULL_BLOCKERS) else 0
        shape = (self._slots, bwords) if self._blockers.precull else (1, 1)
        self._blockers.cull, self._blockers.tiny = (wp.zeros(shape, dtype=wp.uint64, device=d) for _ in range(2))
        self._direct_on = bool(self._blockers.precull) and self._lut.direct >= 0.0
        self._blockers.corners = wp.zeros((9, self.num_blockers if self._direct_on else 1), dtype=float, device=d)
        if self._blockers.precull and self._near_mode == 2:
            # the k-ring's exclusion bits by reordered blocker index, as uint64 rows
            src = ((excl[:, :, None] >> np.arange(32, dtype=np.uint32)) & 1).reshape(nv, -1)[:, :self.num_blockers]
            rows = np.zeros((nv, bwords * 64), np.uint8)
            rows[:, :self.num_blockers] = src[:, perm]
            self._blockers.ring = wp.array(np.packbits(rows, axis=1, bitorder="little").view("<u8"), dtype=wp.uint64,
                                           device=d)
        else:
            self._blockers.ring = wp.zeros((1, 1), dtype=wp.uint64, device=d)

        # per-receiver results
        self._mask = wp.zeros((nv, self._words), dtype=wp.uint64, device=d)
        self._counts = wp.zeros(nv, dtype=wp.int32, device=d)
        self._refined = wp.zeros(nv, dtype=wp.int32, device=d)
        self._hits = wp.zeros((1, 1), dtype=wp.uint32, device=d)
        # per slot queue of triangles rasterized in batches (kernels.Batch; rows private to their thread)
        self._batch = Batch()
        ns, nq = self._slots, BATCH
        # contiguous rows: kernels.batch_codes reads them as flat float and int rows
        self._batch.a, self._batch.b, self._batch.c = (wp.zeros((ns, nq), dtype=wp.vec3, device=d) for _ in range(3))
        self._batch.codes = wp.zeros((ns, nq), dtype=wp.vec3i, device=d)
        self._batch.cand = wp.zeros((ns, CANDIDATES), dtype=wp.int32, device=d)
        self._batch.src = wp.zeros((ns, nq), dtype=wp.int32, device=d)
        self._batch.area = wp.zeros((ns, nq), dtype=float, device=d)
        self._batch.fine_flag = wp.zeros((ns, nq), dtype=wp.int32, device=d)
        self._batch.counts = self._counts
        self._batch.refined = self._refined
        self._batch.stop_free, self._batch.stop_dc, self._batch.near_first = -1, 0.0, 0
        self._batch.dark = wp.zeros(1, dtype=float, device=d)
        self._batch.halt = wp.zeros(ns, dtype=wp.int32, device=d)
        self._all = wp.array(np.arange(nv, dtype=np.int32), dtype=wp.int32, device=d)
        self._interp, self._redone = None, 0
        if self.interpolate > 0.0:
            sel, split = hierarchy.interpolation_subset(faces, nv, self.interp_levels)
            # (computed receivers, [(targets, nbr_start, nbrs) per level, coarsest first])
            self._interp = (wp.array(sel, dtype=wp.int32, device=d),
                            [tuple(wp.array(x, dtype=wp.int32, device=d) for x in level) for level in split])
            self._redo = wp.zeros(nv, dtype=wp.int32, device=d)
            self._interp_parts = {}
            self._blocked = wp.zeros(nv, dtype=vec_sh, device=d)
            self._doubt = wp.zeros(nv, dtype=float, device=d)
            self._ring_csr = tuple(wp.array(x, dtype=wp.int32, device=d) for x in vertex_neighbours(faces, nv))
            # the sine of the rise, 2 when off (no dot product exceeds it: the ring is not read)
            self._interp_rise = math.sin(math.radians(self.interp_rise)) if self.interp_rise < 90.0 else 2.0
            # relative to the unoccluded transfer's norm (the same for every normal: rotations keep it)
            self._interp_tolerance = self.interpolate * float(np.linalg.norm(np.array(self._unoccluded, dtype=np.float64)))
        self._pvs = None
        self._pvs_start = wp.zeros(nv + 1, dtype=wp.int32, device=d)
        self._pvs_tris = wp.zeros(1, dtype=wp.int32, device=d)
        self._pvs_frames = 0
        self._static_seconds = time.perf_counter() - t_start
        self._rebuilds, self._rebuild_seconds = 0, 0.0
        self._built_departure = self._departure() if self.redecimate > 0.0 and self._use_refine else 0.0
        # kernels.StaticPart: off (and its arrays placeholders) until a frame finds receivers unmoved (_static_mode)
        self._static = StaticPart()
        self._static.mode = 0
        self._static.blockers = wp.zeros((1, 1), dtype=wp.uint64, device=d)
        self._static.receiver = wp.zeros(1, dtype=wp.int32, device=d)
        self._static.mask = wp.zeros((1, 1), dtype=wp.uint64, device=d)
        self._static.counts, self._static.refined = (wp.zeros(1, dtype=wp.int32, device=d) for _ in range(2))
        self._static.listed = wp.zeros((1, 1), dtype=MaskChunk, device=d)
        self._static_last = None  # (points, normals) of the last frame, until a part is stored
        self._static_check = None  # (vertices, receivers, their points, their normals) the stored part depends on
        self._static_receivers, self._static_stores = 0, 0
        if pvs_frames is not None:
            self.build_pvs(pvs_frames)

    def _bpoints_rest(self) -> np.ndarray:
        self._follow()
        return self._bpoints.numpy()

    def _mid_points_rest(self) -> np.ndarray:
        self._follow()
        return self._mids.points.numpy()

    # -- command line ------------------------------------------------------------------------
    @classmethod
    def sweep(cls, quick: bool = False) -> list[dict]:
        if quick:
            return [{}, {"refine": 0.0}, {"mask": 16}]
        out = [{}, {"ring": 4, "refine": 0.0}]  # the defaults before the spatial refinement (wrong in contact)
        out += [{"min_image": x} for x in (0.0, 0.25, 1.0)]
        out += [{"fine_image": x} for x in (0.25, 0.5)]
        out += [{"mask": m} for m in (8, 16, 64)]
        out += [{"lut": r} for r in (32, 64, 128)]
        out += [{"downsample": s} for s in (2, 4)]
        out += [{"refine": x} for x in (1.0, 4.0)]
        out += [{"redecimate": 0.1}, {"interpolate": 0.02}, {"interpolate": 0.05}, {"interpolate": 0.05, "interp_levels": 2}]
        out += [{"mid": 2048}, {"coarse": 256, "mid": 2048}]
        out += [{"ring": 0}, {"ring": 2}, {"coarse": 256}, {"coarse": 1024}, {"coarse": 0}, {"cull": False}]
        return out

    def _extra_knobs(self) -> dict:
        return {"pvs_frames": self._pvs_frames, "occluders": [o.name for o in self.occluders]}

    def stats(self) -> dict:
        counts = self._counts.numpy()
        return {
            "triangles_per_vertex": float(counts.mean()),
            "triangles_per_vertex_max": int(counts.max()),
            "refined_per_vertex": float(self._refined.numpy().mean()),
            "mid_per_vertex": float(self._mids.counts.numpy().mean()),
            "mid_triangles": self.num_mid,
            "occluder_triangles": int(sum(o.num_faces for o in self.occluders)),
            "blocker_triangles": self.num_blockers,
            "hierarchy": self.hierarchy,
            "backface_culled": self._backface_side != 0.0,
            "fan": self._fan_on,
            "min_image_active": self._lut.min_area > 0.0,
            "ring_triangles_per_vertex": self._ring_avg,
            "clusters": int(self._cluster_start.shape[0] - 1),
            "lut_bytes": tables.lut_bytes(self.mask_res, self.lut_res),
            "lut_seconds": self._lut_seconds,
            "lut_source": self._lut_source,
            "static_seconds": self._static_seconds,
            "rebuilds": self._rebuilds,
            "computed_fraction": (1.0 if self._interp is None else
                                  (self._interp[0].shape[0] + self._redone) / self.mesh.num_vertices),
            "rebuild_seconds": self._rebuild_seconds,
            "static_receivers": self._static_receivers,
            "static_stores": self._static_stores,
            "pvs_triangles_per_vertex": (float(self._pvs_start.numpy()[-1]) / self.mesh.num_vertices
                                         if self._pvs_frames else None),
        }

    # -- per frame ---------------------------------------------------------------------------
    def stop_when_dark(self, dc: float, near_first: bool = False) -> int:
        """Let each receiver stop rasterizing once its transfer's DC coefficient is certainly at most ``dc``
        (absolute): once the DC shares of the pixels still free in its mask sum to at most ``dc`` less an
        allowance for float32 rounding. Blockers only ever block more pixels, so a receiver that stops has
        its full transfer's DC within ``dc`` too; the transfer written for it is the one of the mask so far
        (more light than the full mask gives, still at most ``dc``), and the triangle counts of
        :meth:`stats` count only what was rasterized. Every other receiver is computed exactly as without
        the stop. For callers that overwrite every row whose DC is at most ``dc``
        (:func:`warpshade.pipeline.shading.fill_buried`). Diffuse mode without ``interpolate`` only (that
        reads its computed neighbours' rows); otherwise, or with ``dc`` 0, nothing stops.

        ``near_first``: queue the fine triangles of the refined blockers (the near field, which is what
        buries a receiver) before the coarse far field, so that a buried receiver stops before the far
        field (the same triangles in another order: the same masks and counts where nothing stops). It
        pays where most receivers are buried (an underside lying on what it faces), and costs the
        extra pass over the clusters elsewhere (figures: docs/benchmarks/index.md).

        Returns the most free pixels a receiver can stop with (-1: none)."""
        free, limit = -1, 0.0
        if self.mode == "diffuse" and self.interpolate == 0.0 and dc > 0.0:
            # the local DC of a mask is the unoccluded DC minus the blocked pixels' shares summed in
            # float32 (one term per nibble, .integrate), then rotated to world (exact for band 0 but for
            # rounding): allow each term a rounding of the unoccluded DC's ulp, and 1e-3 relative
            terms = self._words * 16 + 1
            limit = dc - terms * float(np.finfo(np.float32).eps) * float(self._unoccluded[0]) - 1e-3 * dc
            shares = np.sort(self._pixel_dc[self._pixel_dc > 0.0])
            free = int(np.searchsorted(np.cumsum(shares), limit, side="right")) if limit > 0.0 else -1
            # the kernel sums in float32: the limit lowered by that sum's rounding too
            limit -= max(free, 0) * float(np.finfo(np.float32).eps) * float(shares[-1]) * 2
            self._batch.dark = wp.array(self._pixel_dc.astype(np.float32), dtype=float, device=self.device)
        self._batch.stop_free, self._batch.stop_dc = free, float(limit)
        self._batch.near_first = int(bool(near_first) and free >= 0)
        return free

    def _follow(self) -> None:
        if self._bind is not None:
            wp.launch(follow_coarse_points, dim=self._bpoints.shape[0], inputs=[self._spoints, self._sfaces, *self._bind],
                      outputs=[self._bpoints], device=self.device)
        if self._mid_bind is not None:
            wp.launch(follow_coarse_points, dim=self._mids.points.shape[0],
                      inputs=[self._spoints, self._sfaces, *self._mid_bind], outputs=[self._mids.points], device=self.device)

    def _refit(self) -> None:
        """Per-frame boxes and deviations of the blockers (and of the mid triangles): a coarse
        blocker's box holds it, the fine triangles it stands for and, with the mid level, its mid
        triangles and theirs; its deviation is taken over its fine triangles either way."""
        d = self.device
        wp.launch(refit_blocker_boxes, dim=self.num_blockers,
                  inputs=[self._bpoints, self._bfaces, self._spoints, self._sfaces, 1 if self._use_refine else 0,
                          self._fit_start, self._fit_mid, self._fit_tris, self._bind_offset_abs],
                  outputs=[*self._blocker_box, self._blocker_dev], device=d)
        if self._use_mid:
            wp.launch(refit_blocker_boxes, dim=self.num_mid,
                      inputs=[self._mids.points, self._mids.faces, self._spoints, self._sfaces, 1,
                              self._sub.start, self._sub.mid, self._sub.tris, self._mid_bind[2]],
                      outputs=[*self._mid_box, self._mid_dev], device=d)
            wp.launch(raise_deviation, dim=self.num_mid, inputs=[self._mid_outline], outputs=[self._mid_dev], device=d)
            wp.launch(union_child_boxes, dim=self.num_blockers,
                      inputs=[self._group_start, self._group_tris, *self._mid_box], outputs=[*self._blocker_box], device=d)

    def _launch(self, record: int, use_pvs: int, rows: wp.array | None = None, interp_rows=None,
                static_rows: np.ndarray | None = None) -> None:
        if self.occluders:
            wp.copy(self._spoints, self.points, count=self.mesh.num_vertices)
        self._follow()
        d = self.device
        if (self.cull and not use_pvs) or self._use_refine:
            self._refit()
        if (self.cull and not use_pvs) or self._use_refine:  # clusters: culling, and kernels.mark_refined
            wp.launch(union_boxes, dim=self._cluster_box[0].shape[0], inputs=[*self._blocker_box, self._blocker_dev, self._cluster_start],
                      outputs=[*self._cluster_box, self._cluster_reach], device=d)
        if self.cull and not use_pvs:
            wp.launch(union_boxes, dim=self._super_box[0].shape[0], inputs=[*self._cluster_box, self._cluster_reach, self._super_start],
                      outputs=[*self._super_box, self._super_reach], device=d)
        # planes and bounding spheres pre-cull triangles below the horizon or back-facing, and bound
        # image sizes, before any vertex is gathered
        wp.launch(triangle_bounds, dim=self.num_blockers, inputs=[self._bpoints, self._bfaces],
                  outputs=[self._bplane, self._bsphere, self._bnlen], device=d)
        if self._direct_on:
            wp.launch(blocker_corners, dim=self.num_blockers, inputs=[self._bpoints, self._bfaces],
                      outputs=[self._blockers.corners], device=d)
        if self.hierarchy:
            wp.launch(triangle_bounds, dim=self._sfaces.shape[0], inputs=[self._spoints, self._sfaces],
                      outputs=[self._fine.plane, self._fine.sphere, self._fine.nlen], device=d)
        if self._use_mid:
            wp.launch(triangle_bounds, dim=self.num_mid, inputs=[self._mids.points, self._mids.faces],
                      outputs=[self._mids.plane, self._mids.sphere, self._mid_nlen], device=d)
        self._batch.record = record
        self._batch.hits = self._hits
        if rows is not None:  # the receivers this frame computes, or those later frames may (static_rows)
            wanted = rows.numpy() if static_rows is None else static_rows
        elif interp_rows is not None:
            wanted = self._interp_rows(interp_rows)[0].numpy()
        else:
            wanted = None if self._interp is None else self._interp[0].numpy()
        self._static.mode = self._static_mode(record, use_pvs, wanted)
        if rows is not None:  # these receivers only (compute_rows)
            self._rasterize(rows, rows.shape[0], use_pvs)
            self._integrate_diffuse(rows, rows.shape[0])
            return
        if interp_rows is not None:  # these receivers only, with interpolation (compute_rows)
            self._interpolated(*self._interp_rows(interp_rows), use_pvs)
            return
        if self._interp is None:
            self._rasterize(self._all, self.mesh.num_vertices, use_pvs)
            if self.mode == "diffuse":
                self._integrate_diffuse(self._all, self.mesh.num_vertices)
            else:
                self._integrate_glossy()
            return
        self._interpolated(self._interp[0], [level[0] for level in self._interp[1]], use_pvs)

    def _blocked_parts(self, rows: wp.array) -> None:
        """The blocked parts (:attr:`_blocked`) of the computed receivers ``rows``, for the targets that read them."""
        wp.launch(self._integrate.blocked_part, dim=rows.shape[0],
                  inputs=[rows, self.normals, self._unoccluded, self._rot_dirs, self._rot_pinv, self._basis,
                          self.transfer], outputs=[self._blocked, self._doubt], device=self.device)

    def _interpolated(self, sel: wp.array, targets: list[wp.array], use_pvs: int) -> None:
        """Compute the receivers ``sel`` and, level by level (coarsest first), interpolate each level's
        ``targets`` from their neighbours where these agree within ``interpolate``, computing the others
        themselves (``_interp`` holds the whole mesh's split; :meth:`compute_rows` passes a part of it)."""
        d = self.device
        self._counts.zero_()
        self._refined.zero_()
        self._mids.counts.zero_()
        self._rasterize(sel, sel.shape[0], use_pvs)
        self._integrate_diffuse(sel, sel.shape[0])
        self._redone = 0
        busy = [k for k, t in enumerate(targets) if t.shape[0]]
        if busy:
            self._blocked_parts(sel)
        for k in busy:
            start, nbrs = self._interp[1][k][1:]
            self._redo.zero_()
            wp.launch(self._integrate.interpolate, dim=targets[k].shape[0],
                      inputs=[targets[k], start, nbrs, self.normals, self._unoccluded, self._rot_dirs, self._rot_pinv,
                              self._basis, self._blocked, self._interp_tolerance, self._doubt, self.points,
                              *self._ring_csr, self._interp_rise],
                      outputs=[self.transfer, self._redo], device=d)
            redo = np.flatnonzero(self._redo.numpy()).astype(np.int32)
            self._redone += len(redo)
            if len(redo):
                redo = wp.array(redo, dtype=wp.int32, device=d)
                self._rasterize(redo, redo.shape[0], use_pvs)
                self._integrate_diffuse(redo, redo.shape[0])
                if k != busy[-1]:  # a finer level reads them
                    self._blocked_parts(redo)

    def _interp_rows(self, rows: np.ndarray) -> tuple[wp.array, list[wp.array]]:
        """The part of the interpolation split that gives the transfer at ``rows``: the computed receivers
        among them and those their interpolated rows read (through every level), and each level's
        interpolated rows, coarsest first (cached per rows)."""
        key = rows.tobytes()
        if key not in self._interp_parts:
            need = np.zeros(self.mesh.num_vertices, dtype=bool)
            need[rows] = True
            parts = []
            for targets, start, nbrs in (tuple(a.numpy() for a in level) for level in self._interp[1][::-1]):
                t = targets[need[targets]]
                for v in t:  # the neighbours each interpolated row reads
                    need[nbrs[start[v]:start[v + 1]]] = True
                parts.append(wp.array(t, dtype=wp.int32, device=self.device))
            sel = self._interp[0].numpy()
            self._interp_parts[key] = (wp.array(sel[need[sel]], dtype=wp.int32, device=self.device), parts[::-1])
        return self._interp_parts[key]

    def _static_mode(self, record: int, use_pvs: int, wanted: np.ndarray | None) -> int:
        """The :class:`~.kernels.StaticPart` mode of this frame's rasterization (0 or 2), after storing the part
        of the unmoved receivers' masks that the unmoved blockers give when this frame finds them as the last
        one left them while others moved (``keep_static``), for the receivers ``wanted`` (None: all).

        Unmoved: bit for bit the positions of the last frame (receivers: also their normals). A receiver
        qualifies with its fan and k-ring; a blocker with the fine triangles its vertices are bound to and
        those it stands for (its box, deviation and refined set). The stored part stays in use while all of
        these stay as they were; when one moves it is dropped and this frame's points are the new
        comparison. Off with a PVS (recording one included), with the mid level, where the refined blockers'
        triangles are walked group by group (no ``use_set``) and where the stored sets of those triangles
        would exceed :data:`STATIC_BYTES`."""
        if not self.keep_static or record or use_pvs or self._use_mid or (self._use_refine and not self._groups.use_set):
            self._static_check = self._static_last = None
            return 0
        pts, nrm = self._spoints.numpy(), self.normals.numpy()
        if self._static_check is not None:
            verts, recv, p0, n0 = self._static_check
            if _same_rows(pts[verts], p0).all() and _same_rows(nrm[recv], n0).all():
                return 2
            self._static_check = None
            self._static_receivers = 0
        last, self._static_last = self._static_last, (pts.copy(), nrm.copy())
        if last is None:
            return 0
        nv = self.mesh.num_vertices
        same = _same_rows(pts, last[0])
        recv = same[:nv] & _same_rows(nrm, last[1])
        if recv.all() and same.all():
            return 0  # nothing moved: a pose repeated whole is the caller's to reuse (a timing loop, a still group)
        if wanted is not None and len(wanted) < nv:
            recv &= np.isin(np.arange(nv), wanted)
        if not recv.any():
            return 0
        sfaces = self._sfaces.numpy()
        tri_same = same[sfaces].all(axis=1)
        # the receivers' fans and k-rings, the blockers' fine triangles: (row of each item, item)
        ring = _rows_all(self._ring_start.numpy(), self._ring_tris.numpy(), tri_same)
        fan = _rows_all(self._fine.fan_start.numpy(), self._fine.fan_tris.numpy(), tri_same)
        recv &= ring[0] & fan[0]
        bfaces = self._bfaces.numpy()
        if self.hierarchy:
            bind = self._bind[0].numpy()  # fine triangle each coarse vertex rides
            blockers = tri_same[bind][bfaces].all(axis=1)
            group = _rows_all(self._group_start.numpy(), self._group_tris.numpy(), tri_same) if self._use_refine else None
            if group is not None:
                blockers &= group[0]
        else:
            blockers = same[bfaces].all(axis=1)
        recv_idx = np.flatnonzero(recv)
        chunks = self._groups.listed.shape[1] if self._use_refine else 0
        if not len(recv_idx) or len(recv_idx) * chunks * 128 > STATIC_BYTES:
            return 0
        # the vertices the stored part depends on: checked every frame while it is in use
        dep = np.zeros(len(pts), dtype=bool)
        dep[recv_idx] = True
        for _, rows, tris in (ring, fan):
            dep[sfaces[tris[recv[rows]]]] = True
        if self.hierarchy:
            dep[sfaces[bind[bfaces[blockers]]]] = True
            if group is not None:
                dep[sfaces[group[2][blockers[group[1]]]]] = True
        else:
            dep[bfaces[blockers]] = True
        verts = np.flatnonzero(dep)
        self._static_check = (verts, recv_idx, pts[verts].copy(), nrm[recv_idx].copy())
        self._static_last = None
        st, d = self._static, self.device
        if st.mask.shape[0] != nv:
            st.mask = wp.zeros((nv, self._words), dtype=wp.uint64, device=d)
            st.counts, st.refined, st.receiver = (wp.zeros(nv, dtype=wp.int32, device=d) for _ in range(3))
        bwords = (self.num_blockers + 63) // 64
        bits = np.zeros(bwords * 64, np.uint8)
        bits[:len(blockers)] = blockers
        st.blockers = wp.array(np.packbits(bits, bitorder="little").view("<u8")[None, :], dtype=wp.uint64, device=d)
        slot = np.zeros(nv, np.int32)
        slot[recv_idx] = np.arange(1, len(recv_idx) + 1)
        st.receiver.assign(slot)
        if self._use_refine:
            st.listed = wp.zeros((len(recv_idx), chunks), dtype=MaskChunk, device=d)
        # the stored part: the kernel's outputs are the StaticPart's arrays for this launch
        batch = (self._batch.counts, self._batch.refined)
        self._batch.counts, self._batch.refined = st.counts, st.refined
        st.mode = 1
        try:
            self._rasterize(wp.array(recv_idx.astype(np.int32), dtype=wp.int32, device=d), len(recv_idx), 0,
                            mask=st.mask, refined=st.refined)
        finally:
            self._batch.counts, self._batch.refined = batch
        self._static_receivers = len(recv_idx)
        self._static_stores += 1
        return 2

    def _rasterize(self, receivers: wp.array, count: int, use_pvs: int, mask: wp.array | None = None,
                   refined: wp.array | None = None) -> None:
        """Rasterize the masks of ``receivers[:count]`` (into :attr:`_mask` and :attr:`_refined`, or the arrays
        given); on the CPU in launches of about :data:`LAUNCH_SECONDS`."""
        mask = self._mask if mask is None else mask
        refined = self._refined if refined is None else refined
        cpu = wp.get_device(self.device).is_cpu
        block = RECEIVERS_PER_LAUNCH if cpu else max(1, count)
        start = 0
        while start < count:
            n = min(block, count - start)
            t0 = time.perf_counter()
            part = receivers if (start == 0 and n == receivers.shape[0]) else receivers[start:start + n]
            wp.launch(
                rasterize_masks,
                dim=min(self._slots, n),
                inputs=[self._fine, self.normals, self._ring_start, self._ring_tris,
                        self._blockers,
                        self._near_mode, self._excl,
                        self._groups, self._sub, self._mids,
                        1 if self.cull else 0, self._cluster_start, *self._cluster_box, self._cluster_reach,
                        self._super_start, *self._super_box,
                        use_pvs, self._pvs_start, self._pvs_tris,
                        self._lut, self._batch, self._static, part, n, self._slots],
                outputs=[mask, refined],
                device=self.device,
            )
            start += n
            if cpu:  # the next block sized to take about LAUNCH_SECONDS (growing at most 8x)
                rate = n / max(time.perf_counter() - t0, 1e-6)
                block = max(1, min(8 * n, int(rate * LAUNCH_SECONDS)))

    def _integrate_diffuse(self, receivers: wp.array, count: int) -> None:
        wp.launch(self._integrate.diffuse, dim=count,
                  inputs=[self._mask, self.normals, self._nibbles, self._unoccluded, self._rot_dirs, self._rot_pinv,
                          self._basis, receivers],
                  outputs=[self.transfer], device=self.device)

    def _integrate_glossy(self) -> None:
        wp.launch(self._integrate.glossy, dim=self.mesh.num_vertices,
                  inputs=[self._mask, self.normals, self._block_weights, self._block_valid, self._block_dirs,
                          self.downsample * self.downsample, wp.vec3(*self.view.astype(np.float32)), self.phong,
                          self._rot_dirs, self._rot_pinv, self._basis],
                  outputs=[self.transfer], device=self.device)

    def _compute(self) -> None:
        if self.redecimate > 0.0 and self._use_refine and self._departure() - self._built_departure > self.redecimate:
            self.rebuild()
        self._launch(record=0, use_pvs=1 if self._pvs_frames else 0)

    def compute_rows(self, rows, later=None) -> wp.array:
        """Recompute :attr:`transfer` at the receivers ``rows`` only, for the current :attr:`points` and
        :attr:`normals` (:meth:`set_points`); the other rows keep their values. A receiver's transfer is
        the same as :meth:`update` computes it (each receiver is rasterized on its own; with ``interpolate``
        the rows' computed neighbours are computed too). In glossy mode every receiver is computed.
        ``later``: the receivers later calls may compute (None: ``rows``); with ``keep_static`` the stored
        part is stored for the unmoved ones among them, so it serves later frames that compute others
        (temporal reuse) and costs nothing for receivers never computed.

        Returns:
            :attr:`transfer` (a new array after a :meth:`rebuild`).
        """
        rows = np.asarray(rows, dtype=np.int32)
        if self.mode != "diffuse":
            self._compute()
            return self.transfer
        if self.redecimate > 0.0 and self._use_refine and self._departure() - self._built_departure > self.redecimate:
            self.rebuild()
        if len(rows):
            # with ``interpolate``: the rows' part of the split, so the rows get what update() gives them
            self._launch(record=0, use_pvs=1 if self._pvs_frames else 0,
                         rows=wp.array(rows, dtype=wp.int32, device=self.device) if self._interp is None else None,
                         interp_rows=None if self._interp is None else rows,
                         static_rows=None if later is None else np.asarray(later, dtype=np.int32))
        return self.transfer

    def _departure(self) -> float:
        """How far the coarse mesh is from the fine surface this frame: mean blocker deviation over mean
        blocker radius (dimensionless; ~0.002 for a flat sheet decimated flat, ~0.3 for that coarse
        mesh riding a crumpled pose, ~0.15 for one decimated from the crumpled pose itself)."""
        self._follow()
        wp.launch(refit_blocker_boxes, dim=self.num_blockers,
                  inputs=[self._bpoints, self._bfaces, self._spoints, self._sfaces, 1,
                          self._fit_start, self._fit_mid, self._fit_tris, self._bind_offset_abs],
                  outputs=[*self._blocker_box, self._blocker_dev], device=self.device)
        wp.launch(triangle_bounds, dim=self.num_blockers, inputs=[self._bpoints, self._bfaces],
                  outputs=[self._bplane, self._bsphere, self._bnlen], device=self.device)
        radius = float(self._bsphere.numpy()[:, 3].mean())
        return float(self._blocker_dev.numpy().mean()) / radius if radius > 0.0 else 0.0

    def rebuild(self) -> None:
        """Rebuild every static structure (coarse far field, bindings, clusters) from the current pose.

        With ``redecimate`` > 0, :meth:`update` calls it when the coarse mesh has departed from the
        fine surface by more than ``redecimate`` (:meth:`_departure`, relative to the pose it was
        built on), so a crumpled or draped pose gets a coarse mesh that follows its folds instead of
        the flat sheet's; the cost (``stats()["rebuild_seconds"]``) is paid once per departure and
        amortised over the frames that follow. :attr:`points`, :attr:`normals` and :attr:`transfer`
        are new arrays afterwards (what :meth:`update` returns).
        """
        t0 = time.perf_counter()
        pts, nrm = self.points.numpy().copy(), self.normals.numpy().copy()
        done = (self._rebuilds + 1, self._rebuild_seconds)
        self.__init__(TriMesh(pts, self.mesh.faces, name=self.mesh.name), order=self.order, device=self.device,
                      **self._init_knobs)
        self.set_points(pts, nrm)
        self._rebuilds, self._rebuild_seconds = done[0], done[1] + time.perf_counter() - t0

    def build_pvs(self, frames) -> None:
        """Potentially-visible sets from a recorded animation (paper §3.2, "PVS").

        Every frame is rasterized with full culling; a blocker triangle enters a receiver's set when
        it sets at least one mask bit in some frame. Afterwards :meth:`update` rasterizes only the
        k-ring and the set (exact for the recorded frames, an approximation for other poses).

        Args:
            frames: Vertex positions per frame [m], shape (T, V, 3).
        """
        frames = np.asarray(frames, dtype=np.float32)
        nv = self.mesh.num_vertices
        if frames.ndim != 3 or frames.shape[1:] != (nv, 3) or len(frames) == 0:
            raise ValueError(f"{self.mesh.name}: pvs_frames must have shape (T, {nv}, 3), got {frames.shape}")
        if self.direct_far:
            raise ValueError("hemiraster: direct_far needs no PVS (a PVS lists the blockers that set a bit through the queue)")
        self._hits = wp.zeros((nv, (self.num_blockers + 31) // 32), dtype=wp.uint32, device=self.device)
        for f, pts in enumerate(frames):
            if not np.isfinite(pts).all():
                raise ValueError(f"{self.mesh.name}: pvs frame {f} has non-finite positions")
            self.set_points(pts)
            self._launch(record=1, use_pvs=0)
        bits = ((self._hits.numpy()[..., None] >> np.arange(32, dtype=np.uint32)) & 1).astype(bool)
        bits = bits.reshape(nv, -1)[:, :self.num_blockers]
        lists = [np.sort(self._perm_inv[np.flatnonzero(row)]) for row in bits]
        start = np.concatenate([[0], np.cumsum([len(x) for x in lists])]).astype(np.int32)
        tris = np.concatenate(lists).astype(np.int32) if start[-1] else np.zeros(1, np.int32)
        self._pvs_start = wp.array(start, dtype=wp.int32, device=self.device)
        self._pvs_tris = wp.array(tris, dtype=wp.int32, device=self.device)
        self._hits = wp.zeros((1, 1), dtype=wp.uint32, device=self.device)
        self._pvs_frames = len(frames)
        self.set_points(self.mesh.points)
