"""Streaming export of shaded, animated meshes to USD (docs/conventions.md §6).

Layout of an output ``OUT.usda``::

    OUT.usda                        stage metadata, topology, material, lights, value-clip metadata
    OUT_frames/<run>/manifest.usda  the animated attributes, declared once (clip manifest)
    OUT_frames/<run>/chunk_000000.usdc, chunk_000032.usdc, ...   time samples, ``chunk`` frames each

Why value clips: a single layer keeps every time sample in memory until it is saved (memory grows
with the frame count) and, in ``.usdc``, writing many time samples to one attribute slows down
sharply (OpenUSD issue #3249; ``benchmarks/usd_write.py`` measures both). With clips the writer
holds at most ``chunk`` frames, each chunk is a small crate file written once, and the stage
composes them with the standard value-clip machinery that usdview, Blender, Houdini and Omniverse
all resolve. ``usdcat --flatten OUT.usda -o single.usdc`` makes one self-contained file.

Crash safety: every file is written under a temporary name and renamed into place. After each
chunk the top-level file is rewritten (temp + rename) to list the chunks done so far, so at any
moment ``OUT.usda`` is either the previous output (untouched until the first chunk of this run is
committed; this run's chunks go to a fresh ``<run>`` directory) or a valid stage holding every
committed frame.
"""

from __future__ import annotations

import contextlib
import errno
import fcntl
import os
import re
import shutil
import signal
import socket
import threading
import time
import uuid

import numpy as np
from pxr import Gf, Sdf, Tf, Usd, UsdGeom, UsdLux, UsdShade, Vt

from .._atomic import replace_atomically as _replace_atomically
from .._version import __version__
from .assets import extracted
from ..geometry.mesh import first_nonfinite
from ..scene import DEFAULT_ALBEDO

#: Animated attributes: name -> (value type, USD interpolation or None).
RADIANCE_MATERIAL_ATTR = "warpshade:radianceMaterial"
"""Bool on the material prims this writer binds to shaded meshes (emission = exit radiance)."""

BACK_SIDE_OF = "warpshade:backSideOf"
"""Relationship on a back-side mesh (:meth:`AnimationWriter.add_back_side`) targeting its front mesh."""

BACK_SIDE_SUFFIX = "_back"
BACK_SIDE_OFFSET = 1e-4
"""How far a back-side mesh's points lie behind the front's, along the back's normals, as a fraction
of the mesh's bounding-box diagonal (its first written frame). Coincident front and back triangles
are drawn at random by ray tracers (Blender's Cycles shows the back's colours in specks through the
front, even with back faces transparent) and fight in rasterisers without culling; 1e-4 of the
size (0.2 mm on a 2 m cloth) is far above float32 point precision and a 24-bit depth buffer's
step at a few metres, and far below anything visible.
"""
"""Appended to a front mesh's prim path to name its back-side sibling (:func:`back_side_path`)."""

_ANIMATED = {
    "points": Sdf.ValueTypeNames.Point3fArray,
    "normals": Sdf.ValueTypeNames.Normal3fArray,
    "extent": Sdf.ValueTypeNames.Float3Array,
    "primvars:displayColor": Sdf.ValueTypeNames.Color3fArray,
    "primvars:warpshade:transfer": Sdf.ValueTypeNames.FloatArray,
}


def prim_name(name: str) -> str:
    """A valid USD prim name from any string (non-identifier characters become ``_``)."""
    n = re.sub(r"[^A-Za-z0-9_]", "_", str(name).strip("/").split("/")[-1] if "/" in str(name) else str(name))
    return n if n and not n[0].isdigit() else "_" + n


_prim_name = prim_name  # older name, kept for callers


def back_side_path(front_path: str) -> str:
    """Prim path of the back-side mesh of the mesh at ``front_path``: a sibling, so it shares its parent's
    transform (``/World/Drape`` -> ``/World/Drape_back``)."""
    return str(front_path).rstrip("/") + BACK_SIDE_SUFFIX


class OutputWriteError(OSError):
    """Writing a file of the output failed (disk full, permissions...); the message names the file
    and the cause (``errno`` is set when known). Frames committed before the failure stay in the output."""

    def __init__(self, code: int | None, message: str):
        super().__init__(message)
        self.errno = code

    def __str__(self):
        return self.args[0]


class OutputLockedError(OutputWriteError):
    """Another live run is writing the same output."""


def _write_cause(exc: BaseException) -> tuple[int | None, str]:
    """(errno, words) of a failed write: from an OSError, or from the text of a pxr error."""
    if isinstance(exc, OSError) and exc.errno:
        return exc.errno, exc.strerror or str(exc)
    text = str(exc)
    for code in (errno.ENOSPC, errno.EDQUOT, errno.EACCES, errno.EROFS, errno.EIO, errno.EFBIG):
        if os.strerror(code) in text:
            return code, os.strerror(code)
    quoted = re.findall(r"'([^'\n]+)'\s*$", text, flags=re.M)
    return None, (quoted[-1] if quoted else text.strip().splitlines()[-1] if text.strip() else type(exc).__name__)


def _write_file(write, path: str, what: str, final: str | None = None) -> None:
    """Run ``write(path)`` (a pxr Save/Export or any writer); on failure remove whatever it left at
    ``path`` and raise :class:`OutputWriteError` naming the file (``final``, the name ``path`` is
    renamed to, if given) and the cause."""
    try:
        ok = write(path)
    except (OSError, Tf.ErrorException) as exc:
        ok, cause = False, exc
    else:
        cause = None
    if ok is False:
        try:
            os.remove(path)
        except OSError:
            pass
        code, words = _write_cause(cause) if cause is not None else (None, "the USD library reported a failed save")
        hint = " (free some space; --resume then completes the output)" if code in (errno.ENOSPC, errno.EDQUOT) else ""
        raise OutputWriteError(code, f"cannot write {what} {final or path}: {words}{hint}") from cause


_STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


@contextlib.contextmanager
def _signals_held():
    """Hold Ctrl-C, SIGTERM and SIGHUP while a commit runs: their Python handlers are swapped for one
    that notes the signal, and the first one noted is handed to its own handler on leaving the block,
    so a commit, once begun, ends with its files renamed into place rather than half-way. (A signal
    mask would not do: pxr's threads would take the signal and Python would still run the handler.)
    Signals left to the operating system (no Python handler) are not touched."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    pending: list[int] = []
    previous = {}
    for sig in _STOP_SIGNALS:
        handler = signal.getsignal(sig)
        if callable(handler):
            previous[sig] = signal.signal(sig, lambda signum, frame: pending.append(signum))
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        if pending:
            previous[pending[0]](pending[0], None)


def replace_atomically(write, path: str, what: str = "output file") -> None:
    """Call ``write(tmp_path)`` then rename the temporary file onto ``path``; on failure (or any
    exception, an interrupt included) nothing is left behind, and a write failure raises
    :class:`OutputWriteError` naming ``path`` and the cause."""
    try:
        _replace_atomically(lambda tmp: _write_file(write, tmp, what, path), path)
    except OSError as exc:
        if not isinstance(exc, OutputWriteError):
            raise OutputWriteError(exc.errno, f"cannot write {what} {path}: {exc.strerror}") from exc
        raise


def frames_dir_name(path: str) -> str:
    """Name of the folder beside output ``path`` that holds its clip files: ``OUT_frames`` for
    ``OUT.usda``, ``OUT_usdc_frames`` / ``OUT_usd_frames`` for the other formats, so outputs that
    differ only in format never share files."""
    stem, ext = os.path.splitext(os.path.basename(path))
    ext = ext.lower()
    return f"{stem}_frames" if ext == ".usda" else f"{stem}_{ext[1:]}_frames"


def _outputs_of_frames_dir(folder: str) -> list[str]:
    """Every output file name whose :func:`frames_dir_name` is ``folder``."""
    names = [f"{folder[:-len('_frames')]}.usda"] if folder.endswith("_frames") else []
    for ext in ("usdc", "usd"):
        if folder.endswith(f"_{ext}_frames"):
            names.append(f"{folder[:-len(f'_{ext}_frames')]}.{ext}")
    return names


class OutputLock:
    """Exclusive ownership of an output by one run: ``OUT_frames.lock`` beside it (named after the
    clip folder, the thing runs must not share), held with ``flock`` and holding the owner's pid and
    host. A lock left by a dead process is taken over (the kernel drops ``flock`` locks when their
    process dies); a live owner makes :class:`OutputLockedError`."""

    def __init__(self, path: str, frames_dir: str):
        self.path = f"{frames_dir}.lock"
        while True:
            fd = os.open(self.path, os.O_RDWR | os.O_CREAT, 0o644)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except BlockingIOError:
                owner = os.read(fd, 200).decode(errors="replace").strip() or "another process"
                os.close(fd)
                raise OutputLockedError(errno.EBUSY, f"{path} is being written by another run ({owner}); "
                                        f"wait for it to finish or choose another --out "
                                        f"(lock file {self.path})") from None
            try:  # the file may have been removed by the previous owner between open and flock
                same = os.path.samestat(os.fstat(fd), os.stat(self.path))
            except FileNotFoundError:
                same = False
            if same:
                break
            os.close(fd)
        os.ftruncate(fd, 0)
        os.write(fd, f"pid {os.getpid()} on {socket.gethostname()}\n".encode())
        self._fd = fd

    def release(self) -> None:
        """Remove the lock file and give up the lock (idempotent)."""
        if self._fd is None:
            return
        try:
            os.remove(self.path)
        except OSError:
            pass
        os.close(self._fd)
        self._fd = None

    def __del__(self):
        fd = getattr(self, "_fd", None)
        if fd is not None:
            os.close(fd)


class AnimationWriter:
    """Write animated triangle meshes, their shading and the lights to USD, one frame at a time.

    Usage: :meth:`add_mesh` for every mesh, then :meth:`add_light` for the lights, then :meth:`write_frame` per
    mesh per frame with non-decreasing frame numbers, then :meth:`close`. Memory stays constant in
    the number of frames (at most ``chunk`` frames are held).

    Args:
        path: Output file (``.usda``, ``.usdc`` or ``.usd``); clip files go to ``<stem>_frames/``
            beside it.
        fps: Frames per second; frame ``k`` is written at time code ``k``.
        up_axis: ``"Y"`` or ``"Z"``.
        meters_per_unit: Stage units.
        chunk: Frames per clip file (also the commit interval: a hard kill loses at most this many
            frames).
        metadata: Extra strings recorded in the root layer's ``customLayerData`` (scene, method...).
        resume: Continue an output that an interrupted run left at ``path``: its committed frames are
            kept, new chunks are added to the same run directory, and :attr:`resume_frame` says
            which frame to produce next. The same meshes must be declared again (checked against
            the existing manifest). Without an existing output this is an ordinary new run.
    """

    def __init__(self, path: str, fps: float = 60.0, up_axis: str = "Y", meters_per_unit: float = 1.0,
                 chunk: int = 64, metadata: dict | None = None, resume: bool = False):
        if chunk < 1:
            raise ValueError(f"{path}: chunk must be >= 1 frame, got {chunk}")
        self.path = os.path.abspath(os.fspath(path))
        self.chunk = int(chunk)
        ext = os.path.splitext(self.path)[1].lower()
        if ext not in (".usda", ".usdc", ".usd"):
            raise ValueError(f"{path}: output must end in .usda, .usdc or .usd")
        frames = frames_dir_name(self.path)
        self._frames_dir = os.path.join(os.path.dirname(self.path), frames)
        self._run = f"run-{time.strftime('%Y%m%d-%H%M%S')}-{uuid.uuid4().hex[:6]}"
        self._run_dir = os.path.join(self._frames_dir, self._run)
        self._rel_run = f"./{frames}/{self._run}"
        self._make_parent_dir()
        self._check_owner()
        self._lock = OutputLock(self.path, self._frames_dir)

        # The top-level stage lives in memory; it is exported (temp + rename) at every commit.
        self.stage = Usd.Stage.CreateInMemory()
        UsdGeom.SetStageUpAxis(self.stage, UsdGeom.Tokens.y if up_axis.upper() == "Y" else UsdGeom.Tokens.z)
        UsdGeom.SetStageMetersPerUnit(self.stage, meters_per_unit)
        self.stage.SetTimeCodesPerSecond(fps)
        self.stage.SetFramesPerSecond(fps)
        world = UsdGeom.Xform.Define(self.stage, "/World")
        self.stage.SetDefaultPrim(world.GetPrim())
        self._root = "/World"                    # default prim: holds Looks and Lights
        self._parents: set[str] = set()          # prims written from an input hierarchy
        data = {"generator": f"warpshade {__version__}", "warpshade:layout": "value clips"}
        data.update({f"warpshade:{k}": str(v) for k, v in (metadata or {}).items()})
        self.stage.GetRootLayer().customLayerData = data
        self.stage.GetRootLayer().documentation = "Shaded animation written by warpshade (docs/conventions.md §6)"

        self._meshes: dict[str, dict] = {}      # prim name -> info (path, vertex count, transfer size)
        self._lights: list[str] = []
        self._chunk_layer: Sdf.Layer | None = None
        self._chunk_start: int | None = None
        self._chunk_tmp: str | None = None
        self._clips: list[tuple[int, str]] = []  # (first frame, relative asset path) of committed chunks
        self._first: int | None = None           # first frame written
        self._last_committed: int | None = None
        self._frame: int | None = None           # frame being written
        self._frame_meshes: set[str] = set()     # meshes written for ``_frame``
        self._animated_meshes: set[str] = set()  # meshes written in some earlier frame
        self._attrs: set[tuple[str, str]] = set()  # (mesh, attribute) pairs that were written
        self._closed = False
        self._resumed_attrs: dict[str, set[str]] = {}  # prim path -> attributes of the manifest resumed
        self.resume_frame = 0
        """First frame this writer still needs (> 0 when resuming an interrupted output)."""
        if resume and os.path.isfile(self.path):
            try:
                self._load_existing(metadata or {})
            except BaseException:
                self._lock.release()
                raise

    def _make_parent_dir(self) -> None:
        """Create the output's directory and its missing parents (like ``mkdir -p``; a run that
        writes nothing removes them again if they are still empty); if that fails,
        :class:`OutputWriteError` names the directory and the cause."""
        parent = os.path.dirname(self.path)
        self._made_dirs = []  # the directories this writer created, deepest first
        d = parent
        while d and not os.path.exists(d):
            self._made_dirs.append(d)
            d = os.path.dirname(d)
        try:
            os.makedirs(parent, exist_ok=True)
        except OSError as exc:
            raise OutputWriteError(exc.errno, f"cannot create the output directory {parent} for {self.path}: "
                                   f"{exc.strerror or exc}") from exc

    def _check_owner(self) -> None:
        """Refuse a frame folder that another existing output (another name) also maps to, e.g.
        ``X.usdc`` and ``X_usdc.usda``: never share or delete its files."""
        folder = os.path.basename(self._frames_dir)
        here = os.path.dirname(self.path)
        for other in _outputs_of_frames_dir(folder):
            other = os.path.join(here, other)
            if other != self.path and os.path.exists(other):
                raise ValueError(f"{self.path}: its clip folder {self._frames_dir} would be shared with the "
                                 f"existing output {other}; choose another --out")

    def _make_run_dir(self) -> None:
        try:
            os.makedirs(self._run_dir, exist_ok=True)
        except OSError as exc:
            raise OutputWriteError(exc.errno, f"cannot create {self._run_dir}: {exc.strerror}") from exc

    def _load_existing(self, metadata: dict) -> None:
        """Pick up the committed clips of an interrupted output (see ``resume``)."""
        try:
            layer = Sdf.Layer.FindOrOpen(self.path)
        except Exception as exc:  # pxr raises Tf.ErrorException
            raise ValueError(f"{self.path}: cannot resume: not a readable USD layer ({exc})") from exc
        anchors = [p for p in (layer.rootPrims if layer else []) if p.HasInfo("clips")]
        clips = anchors[0].GetInfo("clips").get("default") if anchors else None
        if not clips:
            return  # a static output or one with no committed frame: start over
        old = layer.customLayerData or {}
        for k, v in metadata.items():
            key = f"warpshade:{k}"
            if key in old and old[key] != str(v):
                raise ValueError(f"{self.path}: cannot resume: it was written with {k} = {old[key]}, "
                                 f"this run has {k} = {v}")
        manifest = clips["manifestAssetPath"].path
        rel_run = os.path.dirname(manifest)
        run_dir = os.path.normpath(os.path.join(os.path.dirname(self.path), rel_run))
        assets = [a.path for a in clips["assetPaths"]]
        # whatever the file says, a resumed run writes and deletes only in one run folder of its own
        # frame folder
        for a in [manifest] + assets:
            where = os.path.dirname(os.path.normpath(os.path.join(os.path.dirname(self.path), a)))
            if (where != run_dir or os.path.dirname(where) != self._frames_dir
                    or not os.path.basename(where).startswith("run-") or os.path.islink(where)):
                raise ValueError(f"{self.path}: cannot resume: clip file {a} is not in a run folder of "
                                 f"{self._frames_dir} (the output was moved, renamed or edited); "
                                 f"run without --resume to start over")
        starts = [int(t[0]) for t in clips["active"]]
        missing = [a for a in assets if not os.path.isfile(os.path.join(os.path.dirname(self.path), a))]
        if missing:
            raise ValueError(f"{self.path}: cannot resume: clip file {missing[0]} is missing")
        self._run = os.path.basename(run_dir)
        self._run_dir = run_dir
        self._rel_run = rel_run
        self._clips = list(zip(starts, assets))
        times = clips["times"]
        self._first = int(times[0][0])
        self._last_committed = int(times[-1][0])
        self.resume_frame = self._last_committed + 1
        man = Sdf.Layer.FindOrOpen(os.path.join(run_dir, "manifest.usda"))
        todo = list(man.rootPrims)
        while todo:
            spec = todo.pop()
            todo.extend(spec.nameChildren)
            if spec.attributes:
                self._resumed_attrs[str(spec.path)] = {a.name for a in spec.attributes}
        for entry in os.listdir(run_dir):  # a chunk that was being written when the run died
            if ".partial" in entry:
                os.remove(os.path.join(run_dir, entry))


    # -- declarations -----------------------------------------------------------------------
    def set_default_prim(self, path: str) -> None:
        """Make the root prim ``path`` (an Xform) the output's default prim, which holds ``Looks``
        and ``Lights`` (``/World`` unless set); call it before :meth:`add_mesh` and :meth:`add_light`."""
        if self._meshes or self._lights:
            raise ValueError(f"{self.path}: set_default_prim('{path}') after meshes or lights were added")
        sdf = Sdf.Path(path) if Sdf.Path.IsValidPathString(path) else None
        if sdf is None or not sdf.IsRootPrimPath():
            raise ValueError(f"{self.path}: default prim '{path}' is not a root prim path such as /World")
        if path == self._root:
            return
        self.stage.RemovePrim(self._root)
        self.stage.SetDefaultPrim(UsdGeom.Xform.Define(self.stage, path).GetPrim())
        self._root = path

    @staticmethod
    def mesh_path(pname: str, prim_path: str | None) -> str:
        """Where the output holds a mesh: at its input prim path if it has one (the input's
        hierarchy is kept, so the output can be layered over the source asset), else at
        ``/World/<pname>``."""
        return prim_path or f"/World/{pname}"

    def _define_parents(self, path: str, prim_xforms: tuple) -> np.ndarray:
        """Write the ancestors of the mesh at ``path`` (from ``prim_xforms``, see
        :attr:`warpshade.scene.SceneObject.prim_xforms`; missing ones as plain Xforms) and return
        the parent's local-to-world matrix in the output (column vectors, shape (4, 4))."""
        world = np.eye(4)
        for p, tname, *_ in prim_xforms:
            if tname == "PointInstancer" and p not in self._parents:
                # the instancer a mesh was expanded from: deactivated, so that the output layered over the
                # input shows its shaded instances and not the instancer's own (scene_io.INSTANCES_SUFFIX)
                self._parents.add(p)
                self.stage.OverridePrim(p).SetActive(False)
        given = {p: (t, local, resets) for p, t, local, resets, *_ in prim_xforms}
        instances = {p for p, _t, _local, _resets, *instance in prim_xforms if instance and instance[0]}
        for prefix in Sdf.Path(path).GetPrefixes()[:-1]:
            p = str(prefix)
            tname, local, resets = given.get(p, ("Xform", None, False))
            if local is not None:
                world = local if resets else world @ local
            if p in self._parents or any(i["path"] == p for i in self._meshes.values()):
                continue
            self._parents.add(p)
            if p in given and local is None:  # a Scope or typeless prim carries no transform
                self.stage.DefinePrim(p, "Scope" if tname == "Scope" else "")
                continue
            prim = UsdGeom.Xform.Define(self.stage, p)
            if local is not None:
                _set_transform(prim, local, resets)
            if p in instances:
                # an instance in the input: layered over it, this output's meshes inside it are only
                # seen if it is no longer instanced (USD ignores opinions on instance proxies)
                prim.GetPrim().SetInstanceable(False)
        return world

    def add_mesh(self, name: str, faces: np.ndarray, points: np.ndarray | None = None, *,
                 normals: np.ndarray | None = None, albedo=None, roughness: float = 1.0, transfer_order: int | None = None,
                 shaded: bool = True, prim_path: str | None = None, prim_xforms: tuple = ()) -> str:
        """Declare a mesh; its topology (and ``points`` if given) is written at the default time.

        Points and normals are given in world space; a mesh with an input hierarchy is written in
        its parent's space under the input's ancestor transforms, its own transform baked into its
        points (see :meth:`mesh_path`).

        Args:
            name: Object name; the returned handle is it sanitised to a valid identifier (its leaf
                for a path), suffixed ``_1``, ``_2``... when taken.
            faces: Triangle indices, shape (F, 3), int.
            points: Rest positions, shape (V, 3). Give them for meshes that never move (they are
                then written at the default time and :meth:`write_frame` may pass ``points=None``);
                animated meshes get their points per frame.
            normals: Unit vertex normals of a static mesh, shape (V, 3), written at the default time.
            albedo: Diffuse reflectance, linear RGB, shape (3,), recorded as ``warpshade:albedo``.
            roughness: UsdPreviewSurface roughness of the output material.
            transfer_order: SH order N if :meth:`write_frame` will get ``transfer`` (V, N*N).
            shaded: ``True`` if :meth:`write_frame` will get ``colors`` (exit radiance): the mesh is
                bound to the radiance material (emission from ``displayColor``, black diffuse).
                ``False`` for geometry only: a plain UsdPreviewSurface whose diffuse colour is the
                albedo (:data:`DEFAULT_ALBEDO` without one), so no renderer shows it black.
            prim_path: The input prim path to write the mesh at, or None for ``/World/<handle>``.
            prim_xforms: The input hierarchy of ``prim_path``
                (:attr:`warpshade.scene.SceneObject.prim_xforms`): its ancestors are written with
                their types and transforms (as one ``xformOp:transform``), the mesh with an identity
                ``xformOp:transform``.

        Returns:
            The handle for :meth:`write_frame`.
        """
        if self._frame is not None:
            raise ValueError(f"{self.path}: add_mesh('{name}') after frames were written; declare every mesh first")
        if self._lights:  # a mesh's ancestors may move the parents of lights already placed
            raise ValueError(f"{self.path}: add_mesh('{name}') after add_light; declare every mesh first")
        pname = base = prim_name(name)
        k = 1
        while pname in self._meshes:  # two prims with the same leaf name (/A/Mesh, /B/Mesh)
            pname, k = f"{base}_{k}", k + 1
        path = self.mesh_path(pname, prim_path)
        if any(info["path"] == path for info in self._meshes.values()):
            raise ValueError(f"{self.path}: two meshes at {path} ('{name}' and an earlier one)")
        to_world = self._define_parents(path, prim_xforms)
        mesh = UsdGeom.Mesh.Define(self.stage, path)
        own = [x for x in prim_xforms if x[0] == path]
        if own:
            # the mesh's own transform is baked into its points (exact world points under identity
            # parents); the identity op still overrides the source's ops when layered over it
            resets = own[0][3]
            _set_transform(mesh, np.eye(4), resets)
            if resets:
                to_world = np.eye(4)
        to_local = None if np.allclose(to_world, np.eye(4)) else _LocalFrame(to_world, path)
        faces = np.asarray(faces, dtype=np.int32).reshape(-1, 3)
        if np.linalg.det(to_world[:3, :3]) < 0.0:
            # the faces are wound outward in world space; under a mirroring parent a renderer flips the
            # winding of what it draws, so the local winding is the reverse
            faces = faces[:, [0, 2, 1]]
        mesh.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(len(faces), 3, dtype=np.int32)))
        mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(np.ascontiguousarray(faces.reshape(-1))))
        mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
        mesh.CreateOrientationAttr(UsdGeom.Tokens.rightHanded)
        mesh.CreateDoubleSidedAttr(True)
        mesh.SetNormalsInterpolation(UsdGeom.Tokens.vertex)
        nverts = int(faces.max()) + 1 if len(faces) else 0
        if points is not None:
            pts = np.ascontiguousarray(points, dtype=np.float32).reshape(-1, 3)
            nverts = len(pts)
            if to_local is not None:
                pts = to_local.points(pts)
            mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(pts))
            mesh.CreateExtentAttr(Vt.Vec3fArray.FromNumpy(_extent(pts)))
            if normals is not None:
                nrm = _check(normals, pts.shape, pname, "default", "normals")
                mesh.CreateNormalsAttr(Vt.Vec3fArray.FromNumpy(nrm if to_local is None else to_local.normals(nrm)))
        pv = UsdGeom.PrimvarsAPI(mesh)
        pv.CreatePrimvar("displayColor", Sdf.ValueTypeNames.Color3fArray, UsdGeom.Tokens.vertex)
        if transfer_order is not None:
            n2 = int(transfer_order) ** 2
            pv.CreatePrimvar("warpshade:transfer", Sdf.ValueTypeNames.FloatArray, UsdGeom.Tokens.vertex, n2)
            mesh.GetPrim().CreateAttribute("warpshade:transferOrder", Sdf.ValueTypeNames.Int,
                                           custom=True).Set(int(transfer_order))
        if albedo is not None:
            mesh.GetPrim().CreateAttribute("warpshade:albedo", Sdf.ValueTypeNames.Color3f, custom=True).Set(
                Gf.Vec3f(*[float(a) for a in np.asarray(albedo).reshape(3)]))
        if shaded:
            self._bind_radiance_material(mesh, pname, roughness)
        else:
            self._bind_albedo_material(mesh, pname, DEFAULT_ALBEDO if albedo is None else albedo, roughness)
        self._meshes[pname] = {"path": path, "vertices": nverts, "static": points is not None, "to_local": to_local,
                               "transfer": None if transfer_order is None else int(transfer_order) ** 2}
        if self._resumed_attrs:
            if path not in self._resumed_attrs:
                raise ValueError(f"{self.path}: cannot resume: mesh {path} is not in the interrupted output "
                                 f"(it has {', '.join(sorted(self._resumed_attrs))})")
            self._attrs |= {(pname, a) for a in self._resumed_attrs[path]}
        return pname

    def add_back_side(self, name: str) -> str:
        """Declare the back side of mesh ``name`` (from :meth:`add_mesh`), for surfaces shaded on both sides.

        The back is a sibling mesh at :func:`back_side_path`: the front's points moved
        :data:`BACK_SIDE_OFFSET` of the mesh's size along the back's normals (given to
        :meth:`write_frame`: the front's negated), reversed winding (so its geometric normal is the
        front's flipped), the same material, its own ``displayColor``. Both meshes become ``doubleSided = false``, so a
        renderer shows each side's own colour and culls the other. The back carries the relationship
        :data:`BACK_SIDE_OF` to the front and the front ``warpshade:twoSided = true``
        (docs/conventions.md §6).

        Returns:
            The name to pass to :meth:`write_frame` for the back side.
        """
        if self._frame is not None:
            raise ValueError(f"{self.path}: add_back_side('{name}') after frames were written; declare every mesh first")
        if name not in self._meshes:
            raise KeyError(f"{self.path}: no mesh '{name}' (declared: {', '.join(self._meshes)})")
        info = self._meshes[name]
        path = back_side_path(info["path"])
        key = name + BACK_SIDE_SUFFIX
        if key in self._meshes or self.stage.GetPrimAtPath(path):
            raise ValueError(f"{self.path}: back side of '{name}': prim {path} already exists")
        layer = self.stage.GetRootLayer()
        Sdf.CopySpec(layer, info["path"], layer, path)
        front = UsdGeom.Mesh(self.stage.GetPrimAtPath(info["path"]))
        back = UsdGeom.Mesh(self.stage.GetPrimAtPath(path))
        faces = np.asarray(front.GetFaceVertexIndicesAttr().Get(), dtype=np.int32).reshape(-1, 3)
        back.GetFaceVertexIndicesAttr().Set(Vt.IntArray.FromNumpy(np.ascontiguousarray(faces[:, ::-1].reshape(-1))))
        normals = back.GetNormalsAttr().Get()
        if normals is not None:  # static mesh: normals at the default time
            back.GetNormalsAttr().Set(Vt.Vec3fArray.FromNumpy(-np.asarray(normals, dtype=np.float32)))
        pts = back.GetPointsAttr().Get()
        if pts is not None and normals is not None:  # static mesh: points at the default time
            pts = np.asarray(pts, dtype=np.float64)
            offset = BACK_SIDE_OFFSET * float(np.linalg.norm(np.ptp(pts, axis=0)) if len(pts) else 0.0)
            back.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(
                (pts - offset * np.asarray(normals, dtype=np.float64)).astype(np.float32)))
        for m in (front, back):
            m.GetDoubleSidedAttr().Set(False)
        front.GetPrim().CreateAttribute("warpshade:twoSided", Sdf.ValueTypeNames.Bool, custom=True).Set(True)
        back.GetPrim().CreateRelationship(BACK_SIDE_OF, custom=True).SetTargets([Sdf.Path(info["path"])])
        self._meshes[key] = dict(info, path=path, back_offset=None)
        if self._resumed_attrs:
            if path not in self._resumed_attrs:
                raise ValueError(f"{self.path}: cannot resume: mesh {path} is not in the interrupted output "
                                 f"(it has {', '.join(sorted(self._resumed_attrs))})")
            self._attrs |= {(key, a) for a in self._resumed_attrs[path]}
        return key

    def _bind_albedo_material(self, mesh: UsdGeom.Mesh, pname: str, albedo, roughness: float) -> None:
        looks = UsdGeom.Scope.Define(self.stage, f"{self._root}/Looks")
        mat = UsdShade.Material.Define(self.stage, f"{looks.GetPath()}/{pname}_albedo")
        surf = UsdShade.Shader.Define(self.stage, f"{mat.GetPath()}/PreviewSurface")
        surf.CreateIdAttr("UsdPreviewSurface")
        rgb = Gf.Vec3f(*[float(a) for a in np.asarray(albedo, dtype=np.float64).reshape(3)])
        surf.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(rgb)
        surf.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(float(roughness))
        mat.CreateSurfaceOutput().ConnectToSource(surf.ConnectableAPI(), "surface")
        UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(mat)

    def _bind_radiance_material(self, mesh: UsdGeom.Mesh, pname: str, roughness: float) -> None:
        # displayColor holds exit radiance (shading already done), so the material shows it as
        # emission with a black diffuse and no specular (ior 1: UsdPreviewSurface's Fresnel F0 =
        # ((1 - ior) / (1 + ior))^2 = 0): a renderer that re-lights the scene adds nothing to it,
        # whatever it makes of the lights' units (Blender's importer makes a 5 cm sphere light of a
        # stage in centimetres 5 m wide, whose specular alone outshone the colours 40x).
        # RADIANCE_MATERIAL_ATTR marks it, so a reader of this output does not take the black
        # diffuse for the albedo (that is warpshade:albedo on the mesh).
        looks = UsdGeom.Scope.Define(self.stage, f"{self._root}/Looks")
        mat = UsdShade.Material.Define(self.stage, f"{looks.GetPath()}/{pname}_radiance")
        mat.GetPrim().CreateAttribute(RADIANCE_MATERIAL_ATTR, Sdf.ValueTypeNames.Bool, custom=True).Set(True)
        surf = UsdShade.Shader.Define(self.stage, f"{mat.GetPath()}/PreviewSurface")
        surf.CreateIdAttr("UsdPreviewSurface")
        reader = UsdShade.Shader.Define(self.stage, f"{mat.GetPath()}/displayColorReader")
        reader.CreateIdAttr("UsdPrimvarReader_float3")
        reader.CreateInput("varname", Sdf.ValueTypeNames.String).Set("displayColor")
        reader.CreateInput("fallback", Sdf.ValueTypeNames.Float3).Set(Gf.Vec3f(0.0, 0.0, 0.0))
        out = reader.CreateOutput("result", Sdf.ValueTypeNames.Float3)
        surf.CreateInput("emissiveColor", Sdf.ValueTypeNames.Color3f).ConnectToSource(out)
        surf.CreateInput("diffuseColor", Sdf.ValueTypeNames.Color3f).Set(Gf.Vec3f(0.0, 0.0, 0.0))
        surf.CreateInput("ior", Sdf.ValueTypeNames.Float).Set(1.0)
        surf.CreateInput("roughness", Sdf.ValueTypeNames.Float).Set(float(roughness))
        mat.CreateSurfaceOutput().ConnectToSource(surf.ConnectableAPI(), "surface")
        UsdShade.MaterialBindingAPI.Apply(mesh.GetPrim()).Bind(mat)

    def add_light(self, light) -> str:
        """Write a light (a :class:`warpshade.scene.LightSpec`): at its input prim path under its
        input ancestors if it has one (``light.prim_path``, as :meth:`add_mesh` does for meshes, so
        the output can be layered over the source), else under ``Lights`` of the default prim
        (``/World/Lights`` unless :meth:`set_default_prim` chose another).

        Returns:
            The light's prim path.
        """
        prim_path = getattr(light, "prim_path", None)
        resets = False
        if prim_path:
            path = prim_path
            if self.stage.GetPrimAtPath(path):
                raise ValueError(f"{self.path}: light {path}: a prim already exists at that path")
            prim_xforms = tuple(getattr(light, "prim_xforms", ()))
            self._define_parents(path, prim_xforms)
            own = [x for x in prim_xforms if x[0] == path]
            resets = bool(own and own[0][3])
        else:
            UsdGeom.Scope.Define(self.stage, f"{self._root}/Lights")
            pname = prim_name(light.name)
            path = f"{self._root}/Lights/{pname}"
            if self.stage.GetPrimAtPath(path):
                path = f"{path}_{len(self._lights)}"
        cls = {"dome": UsdLux.DomeLight, "distant": UsdLux.DistantLight, "sphere": UsdLux.SphereLight,
               "rect": UsdLux.RectLight}[light.kind]
        lux = cls.Define(self.stage, path)
        lux.CreateColorAttr(Gf.Vec3f(*[float(c) for c in light.color]))
        lux.CreateIntensityAttr(float(light.intensity))
        lux.CreateExposureAttr(float(light.exposure))
        if light.normalize:
            lux.CreateNormalizeAttr(True)
        if light.kind == "distant":
            lux.CreateAngleAttr(float(light.angle))
        elif light.kind == "sphere":
            lux.CreateRadiusAttr(float(light.radius))
            if light.treat_as_point:
                lux.CreateTreatAsPointAttr(True)
        elif light.kind == "rect":
            lux.CreateWidthAttr(float(light.width))
            lux.CreateHeightAttr(float(light.height))
        elif light.kind == "dome" and light.texture:
            texture = light.texture
            if extracted(texture):  # copied out of an input package for this process: the output keeps its own
                texture = os.path.join(self.asset_dir(), os.path.basename(texture))
                shutil.copyfile(light.texture, texture)
            lux.CreateTextureFileAttr(Sdf.AssetPath(self._asset_path(texture)))
            lux.CreateTextureFormatAttr(UsdLux.Tokens.latlong)
        xf = np.asarray(light.transform, dtype=np.float64)
        # the light's world transform in its output parent's space (the default prim may be moved)
        parent = self.stage.GetPrimAtPath(path).GetParent()
        parent_world = np.eye(4) if resets or parent.IsPseudoRoot() else np.asarray(
            UsdGeom.XformCache(Usd.TimeCode.Default()).GetLocalToWorldTransform(parent), dtype=np.float64).T
        if abs(np.linalg.det(parent_world[:3, :3])) < 1e-300:
            raise ValueError(f"{self.path}: light {path}: its parent's transform is singular (a zero scale?); "
                             "it cannot be written in its parent's space")
        local = np.linalg.inv(parent_world) @ xf
        if prim_path or not np.allclose(local, np.eye(4)):
            # authored even when it is the identity for an input light: layered over the source,
            # this one op overrides the source's ops
            _set_transform(lux, local, resets)
        self._lights.append(path)
        return path

    def asset_dir(self) -> str:
        """A directory for files the output refers to (e.g. an environment image), kept with this
        run's clip files (and removed with them if the run commits nothing)."""
        self._make_run_dir()
        return self._run_dir

    def _asset_path(self, file: str) -> str:
        rel = os.path.relpath(os.path.abspath(file), os.path.dirname(self.path))
        return rel if rel.startswith("..") else f"./{rel}"

    # -- frames -----------------------------------------------------------------------------
    def write_frame(self, frame: int, name: str, points: np.ndarray, normals: np.ndarray | None = None,
                    colors: np.ndarray | None = None, transfer: np.ndarray | None = None) -> None:
        """Write one frame of one mesh.

        Args:
            frame: Frame number (time code); non-decreasing across calls.
            name: A name returned by :meth:`add_mesh`.
            points: Positions, shape (V, 3), or None for a mesh declared with rest points (static).
            normals: Unit vertex normals, shape (V, 3), or None.
            colors: Linear RGB exit radiance per vertex, shape (V, 3), or None.
            transfer: SH transfer per vertex, shape (V, N*N) (N from ``transfer_order``), or None.
        """
        if self._closed:
            raise ValueError(f"{self.path}: write_frame after close")
        if name not in self._meshes:
            raise KeyError(f"{self.path}: no mesh '{name}' (declared: {', '.join(self._meshes)})")
        frame = int(frame)
        if self._frame is not None and frame < self._frame:
            raise ValueError(f"{self.path}: frame {frame} written after frame {self._frame}; frames must not go back")
        info = self._meshes[name]
        values = {}
        if points is None:
            if not info["static"]:
                raise ValueError(f"{self.path}: mesh '{name}' frame {frame}: points=None needs rest points in add_mesh")
            v = info["vertices"]
        else:
            pts = np.ascontiguousarray(points, dtype=np.float32).reshape(-1, 3)
            v = len(pts)
            if info["vertices"] and v != info["vertices"]:
                raise ValueError(f"{self.path}: mesh '{name}' frame {frame}: {v} points, topology has {info['vertices']}")
            info["vertices"] = v
            bad = first_nonfinite(pts)
            if bad is not None:
                raise ValueError(f"{self.path}: mesh '{name}' frame {frame}: vertex {bad} is not finite {pts[bad].tolist()}")
            if "back_offset" in info and normals is not None:  # a back side: behind the front (BACK_SIDE_OFFSET)
                if info["back_offset"] is None:
                    info["back_offset"] = BACK_SIDE_OFFSET * float(np.linalg.norm(np.ptp(pts, axis=0)) if v else 0.0)
                nrm = _check(normals, (v, 3), name, frame, "normals")
                pts = (pts + info["back_offset"] * nrm).astype(np.float32)
            if info["to_local"] is not None:
                pts = info["to_local"].points(pts)
            values = {"points": Vt.Vec3fArray.FromNumpy(pts), "extent": Vt.Vec3fArray.FromNumpy(_extent(pts))}
        # every value is checked before the frame is started: a frame with a bad value is not written
        if normals is not None:
            nrm = _check(normals, (v, 3), name, frame, "normals")
            values["normals"] = Vt.Vec3fArray.FromNumpy(nrm if info["to_local"] is None else info["to_local"].normals(nrm))
        if colors is not None:
            values["primvars:displayColor"] = Vt.Vec3fArray.FromNumpy(_check(colors, (v, 3), name, frame, "colors"))
        if transfer is not None:
            n2 = info["transfer"]
            if n2 is None:
                raise ValueError(f"{self.path}: mesh '{name}': transfer given but add_mesh had no transfer_order")
            values["primvars:warpshade:transfer"] = Vt.FloatArray.FromNumpy(
                _check(transfer, (v, n2), name, frame, "transfer").reshape(-1))
        if self._frame is None or frame > self._frame:
            self._start_frame(frame)
        self._frame_meshes.add(name)
        layer = self._chunk_layer
        prim = layer.GetPrimAtPath(info["path"]) or Sdf.CreatePrimInLayer(layer, info["path"])
        for attr, value in values.items():
            spec = prim.attributes.get(attr) if attr in prim.attributes else None
            if spec is None:
                spec = Sdf.AttributeSpec(prim, attr, _ANIMATED[attr])
            layer.SetTimeSample(spec.path, float(frame), value)
            self._attrs.add((name, attr))

    def _start_frame(self, frame: int) -> None:
        if self._frame is not None:
            self._animated_meshes |= self._frame_meshes
        if self._chunk_layer is not None and frame >= self._chunk_start + self.chunk:
            self._commit(self._frame)
        if self._chunk_layer is None:
            self._make_run_dir()
            self._chunk_start = frame
            self._chunk_tmp = os.path.join(self._run_dir, f"chunk_{frame:06d}.partial.usdc")
            self._chunk_layer = Sdf.Layer.CreateAnonymous(".usdc")
        if self._first is None:
            self._first = frame
        self._frame = frame
        self._frame_meshes = set()

    def _commit(self, last: int) -> None:
        """Save the open chunk and rewrite the top-level file to include frames up to ``last``.

        On a write error (:class:`OutputWriteError`) the chunk is dropped, its files removed, and the
        output on disk still holds exactly the frames committed before. Stop signals wait until the
        commit is done.
        """
        with _signals_held():
            self._commit_chunk(last)

    def _commit_chunk(self, last: int) -> None:
        layer, self._chunk_layer = self._chunk_layer, None  # never saved twice, whatever happens
        final = os.path.join(self._run_dir, f"chunk_{self._chunk_start:06d}.usdc")
        # Drop samples after ``last`` (an unfinished frame on abort) before saving.
        for prim in list(layer.rootPrims):
            for spec in _walk_attrs(prim):
                for t in layer.ListTimeSamplesForPath(spec.path):
                    if t > last:
                        layer.EraseTimeSample(spec.path, t)
        _write_file(layer.Export, self._chunk_tmp, "clip file", final)
        del layer
        clips, committed = list(self._clips), self._last_committed
        try:
            os.replace(self._chunk_tmp, final)
            self._clips.append((self._chunk_start, f"{self._rel_run}/chunk_{self._chunk_start:06d}.usdc"))
            self._last_committed = last
            if len(self._clips) == 1:
                self._write_manifest()
            self._write_top()
        except BaseException:
            self._clips, self._last_committed = clips, committed
            for f in (self._chunk_tmp, final):
                try:
                    os.remove(f)
                except OSError:
                    pass
            raise
        if len(self._clips) == 1:
            self._remove_old_runs()

    def _write_manifest(self) -> None:
        def write(tmp):
            man = Sdf.Layer.CreateNew(tmp)
            for name, attr in sorted(self._attrs):
                path = self._meshes[name]["path"]
                prim = man.GetPrimAtPath(path) or Sdf.CreatePrimInLayer(man, path)
                if attr not in prim.attributes:
                    Sdf.AttributeSpec(prim, attr, _ANIMATED[attr])
            return man.Save()

        replace_atomically(write, os.path.join(self._run_dir, "manifest.usda"), "clip manifest")

    def _write_top(self) -> None:
        root = self.stage.GetRootLayer()
        out = Sdf.Layer.CreateAnonymous(".usda")
        out.TransferContent(root)
        anchors = set()
        for name, attr in self._attrs:  # animated values come from the clips: no default may hide them
            spec = out.GetPropertyAtPath(f"{self._meshes[name]['path']}.{attr}")
            if spec is not None and spec.HasDefaultValue():
                spec.ClearDefaultValue()
            anchors.add(Sdf.Path(self._meshes[name]["path"]).GetPrefixes()[0])
        for root in sorted(anchors):  # one clip set per root prim holding meshes, same files
            out.GetPrimAtPath(root).SetInfo("clips", {"default": {
                "assetPaths": Sdf.AssetPathArray([Sdf.AssetPath(p) for _, p in self._clips]),
                "active": Vt.Vec2dArray([Gf.Vec2d(s, i) for i, (s, _) in enumerate(self._clips)]),
                "times": Vt.Vec2dArray([Gf.Vec2d(self._first, self._first),
                                        Gf.Vec2d(self._last_committed, self._last_committed)]),
                "primPath": str(root),
                "manifestAssetPath": Sdf.AssetPath(f"{self._rel_run}/manifest.usda"),
            }})
        out.startTimeCode = float(self._first)
        out.endTimeCode = float(self._last_committed)
        replace_atomically(out.Export, self.path)

    def _remove_old_runs(self) -> None:
        for entry in os.listdir(self._frames_dir):
            if entry != self._run and entry.startswith("run-"):
                shutil.rmtree(os.path.join(self._frames_dir, entry), ignore_errors=True)

    # -- end --------------------------------------------------------------------------------
    def close(self) -> str:
        """Commit the remaining frames and finish the file. Returns the output path.

        A writer that received no frames writes a static stage (topology, lights, materials).
        Raises :class:`OutputWriteError` if a file cannot be written (the frames committed before
        stay in the output); the writer is then finished (:meth:`abort` does nothing more).
        """
        if self._closed:
            return self.path
        try:
            if self._chunk_layer is not None:
                self._commit(self._frame)
            elif not self._clips:
                out = Sdf.Layer.CreateAnonymous(".usda")
                out.TransferContent(self.stage.GetRootLayer())
                replace_atomically(out.Export, self.path)
        except BaseException:
            self._finish_failed()
            raise
        self._closed = True
        self._lock.release()
        return self.path

    def abort(self) -> str | None:
        """Stop after an error: keep every complete frame (a valid file) or, if none was committed
        and none is complete, leave any previous output untouched. Never raises for a file it cannot
        write (the error that made the run stop is the one to report): the frames it cannot commit
        are dropped. Returns the path if a file was written by this run, else None."""
        if self._closed:
            return self.path if self._clips else None
        if self._chunk_layer is not None:
            done = self._frame
            if not self._frame_meshes >= self._animated_meshes:
                done = self._frame - 1  # the current frame is missing some meshes: drop it
            if done >= self._chunk_start:
                try:
                    self._commit(done)
                except OutputWriteError:
                    pass  # _commit left the output as it was before this chunk
            self._chunk_layer = None
        self._finish_failed()
        return self.path if self._clips else None

    def _finish_failed(self) -> None:
        """End a writer that cannot go on: no half-written chunk, no clip folder of a run that
        committed nothing, the lock released."""
        self._closed = True
        self._chunk_layer = None
        if self._chunk_tmp:
            try:
                os.remove(self._chunk_tmp)
            except OSError:
                pass
        if not self._clips:
            shutil.rmtree(self._run_dir, ignore_errors=True)
            try:
                os.rmdir(self._frames_dir)  # only if no other run of this output has files there
            except OSError:
                pass
        self._lock.release()
        if not self._clips and not os.path.exists(self.path):
            for d in self._made_dirs:
                try:
                    os.rmdir(d)  # only if still empty: nothing of anyone else's is removed
                except OSError:
                    break

    @property
    def frames_committed(self) -> int:
        """Number of frames the file on disk holds."""
        return 0 if self._last_committed is None else self._last_committed - self._first + 1

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        if exc_type is None:
            self.close()
        else:
            self.abort()
        return False


def _set_transform(xformable, local: np.ndarray, resets: bool) -> None:
    """Author ``local`` (column vectors, shape (4, 4)) as the prim's only op, ``xformOp:transform``."""
    xf = UsdGeom.Xformable(xformable)
    # USD matrices act on row vectors, ours on column vectors: transpose.
    xf.MakeMatrixXform().Set(Gf.Matrix4d(*np.asarray(local, dtype=np.float64).T.reshape(-1).tolist()))
    if resets:
        xf.SetResetXformStack(True)


class _LocalFrame:
    """World-to-local conversion of a mesh written under transforms (points, and normals by the
    transpose of the local-to-world linear part)."""

    def __init__(self, to_world: np.ndarray, path: str):
        lin = to_world[:3, :3]
        if abs(np.linalg.det(lin)) < 1e-300:
            raise ValueError(f"{path}: its input transform is singular (a zero scale?); it cannot be written "
                             "in its prim's local space")
        self._inv, self._lin, self._t = np.linalg.inv(lin), lin, to_world[:3, 3].copy()

    def points(self, pts: np.ndarray) -> np.ndarray:
        """Local positions of world ``pts``, shape (V, 3), float32."""
        return np.ascontiguousarray((pts.astype(np.float64) - self._t) @ self._inv.T, dtype=np.float32)

    def normals(self, nrm: np.ndarray) -> np.ndarray:
        """Unit local normals of world normals ``nrm``, shape (V, 3), float32."""
        n = nrm.astype(np.float64) @ self._lin
        length = np.linalg.norm(n, axis=1, keepdims=True)
        return np.ascontiguousarray(n / np.where(length > 0, length, 1.0), dtype=np.float32)


def _extent(pts: np.ndarray) -> np.ndarray:
    if len(pts) == 0:
        return np.zeros((2, 3), dtype=np.float32)
    return np.stack([pts.min(axis=0), pts.max(axis=0)]).astype(np.float32)


def _check(a, shape, name, frame, what) -> np.ndarray:
    """``a`` as a native, C-contiguous float32 array of ``shape`` whose values are all finite."""
    a = np.ascontiguousarray(a, dtype=np.float32)
    if a.shape != shape:
        if a.size != shape[0] * shape[1]:
            raise ValueError(f"mesh '{name}' frame {frame}: {what} must have shape {shape}, got {a.shape}")
        a = a.reshape(shape)
    finite = np.isfinite(a)
    if not finite.all():
        v = int(np.flatnonzero(~finite.all(axis=1))[0])
        raise ValueError(f"mesh '{name}' frame {frame}: {what} of vertex {v} are not finite {a[v].tolist()}; "
                         f"the frame is not written")
    return a


def _walk_attrs(prim: Sdf.PrimSpec):
    yield from prim.attributes
    for child in prim.nameChildren:
        yield from _walk_attrs(child)
