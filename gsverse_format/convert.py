"""The conversion pipeline behind ``gsverse-convert``.

load the source (:mod:`gsverse_format.converters`) → truncate SH → decimate the mesh
(``faces``) → bind splats that have no exact anchors to their nearest triangle → keep only what
the scene requires (splats farther than ``max_distance`` from the mesh stay plain, or are
dropped) → sort anchored splats by face → write atomically.

Library users call :func:`convert`; the command line (:mod:`gsverse_format.cli.convert`) only
parses options and prints the returned :class:`ConvertSummary`.
"""
from __future__ import annotations

import os
import time
from dataclasses import asdict, dataclass, field, replace

import numpy as np

from .binding import bind_local
from .converters import detect_source, loader
from .converters.base import SourceOptions, SourceResult
from .errors import GsverseError, UsageError
from .io.registry import SPLAT_OUTPUTS, USD_SUFFIXES, read_asset, write_asset
from .model import Anchoring, LocalAnchors, SplatAsset, SplatCloud, SplatPrimitive, TriangleMesh
from .nearest import closest_points_on_triangles
from .progress import Progress


@dataclass
class ConvertOptions:
    """Options of :func:`convert` (the command-line flags map one to one).

    ``max_distance`` is relative to the anchor mesh's bounding-box diagonal unless
    ``absolute_distance``; ``None`` anchors every splat. ``plain`` converts formats only
    (no anchoring is added or kept). ``bake_poses`` names a poses file
    (:func:`gsverse_format.io.usd.load_poses`) baked into USD time samples (USD output only).
    """

    mesh: str | None = None
    source: str = "auto"
    deformation: str = "affine"
    frame_change: bool = True
    keep_order: bool = False
    sh_degree: int | None = None
    max_distance: float | None = None
    absolute_distance: bool = False
    drop_unanchored: bool = False
    faces: int | None = None
    pt_path: str | None = None
    k: int | None = None
    legacy_trellis_frame: bool = False
    plain: bool = False
    bake_poses: str | None = None


@dataclass
class ConvertSummary:
    """What a conversion did; ``as_dict()`` is the ``--json`` output."""

    input: str
    output: str
    source: str = ""
    splats: int = 0
    anchored: int = 0
    static: int = 0
    dropped: int = 0
    profile: str | None = None
    deformation: str | None = None
    sh_degree: int = 0
    mesh_faces: int = 0
    degenerate_faces: int = 0
    distance: dict = field(default_factory=dict)
    max_distance: float | None = None
    check: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    output_bytes: int = 0
    seconds: float = 0.0

    def as_dict(self) -> dict:
        return asdict(self)

    def lines(self) -> list[str]:
        out = [f"{self.input} -> {self.output}  (source: {self.source})",
               f"  splats     {self.splats} written: anchored {self.anchored}, static {self.static}; "
               f"dropped {self.dropped}; SH degree {self.sh_degree}"]
        if self.profile:
            law = f", deformation {self.deformation}" if self.deformation else ""
            out.append(f"  anchoring  profile {self.profile}{law}, {self.mesh_faces} faces "
                       f"({self.degenerate_faces} degenerate, never bound)")
        if self.distance:
            d = self.distance
            out.append(f"  distance   to mesh p50 {d['p50']:.3g}, p95 {d['p95']:.3g}, p99 {d['p99']:.3g}, "
                       f"max {d['max']:.3g} (mesh diagonal {d['mesh_diagonal']:.3g})")
        if self.max_distance is not None:
            out.append(f"  static     splats farther than {self.max_distance:.3g} from the mesh "
                       f"{'dropped' if self.dropped else 'kept as plain splats'}")
        for note in self.notes:
            out.append(f"  note       {note}")
        out.append(f"  wrote      {self.output_bytes} bytes in {self.seconds:.2f} s")
        return out


def _distance_stats(distance: np.ndarray, diagonal: float) -> dict:
    if distance.size == 0:
        return {}
    p50, p95, p99 = np.percentile(distance, [50, 95, 99])
    return {"p50": float(p50), "p95": float(p95), "p99": float(p99),
            "max": float(distance.max()), "mesh_diagonal": float(diagonal)}


def _check_options(input_path: str, output_path: str, options: ConvertOptions) -> None:
    if options.deformation not in ("affine", "rigid"):
        raise UsageError(f"--deformation must be affine or rigid, not {options.deformation!r}")
    if options.sh_degree is not None and options.sh_degree not in (0, 1, 2, 3):
        raise UsageError(f"--sh-degree must be 0..3, not {options.sh_degree}")
    if options.max_distance is not None and not (options.max_distance >= 0):
        raise UsageError(f"--max-distance must be >= 0, not {options.max_distance}")
    if options.drop_unanchored and options.max_distance is None:
        raise UsageError("--drop-unanchored needs --max-distance")
    if options.faces is not None and options.faces < 4:
        raise UsageError(f"--faces must be at least 4, not {options.faces}")
    if not os.path.exists(input_path):
        raise UsageError("file not found", input_path)
    for p in (options.mesh, options.pt_path, options.bake_poses):
        if p is not None and not os.path.isfile(p):
            raise UsageError("file not found", p)
    folder = os.path.dirname(os.path.abspath(output_path))
    if not os.path.isdir(folder):
        raise UsageError(f"output folder {folder!r} does not exist", output_path)
    ext = os.path.splitext(output_path)[1].lower()
    if ext not in SPLAT_OUTPUTS:
        raise UsageError(f"unsupported output format {ext or '(no extension)'}; "
                         f"use one of {', '.join(SPLAT_OUTPUTS)}", output_path)
    if options.bake_poses is not None and ext not in USD_SUFFIXES:
        raise UsageError(f"--bake-poses needs a USD output ({', '.join(USD_SUFFIXES)})",
                         output_path)


def convert(input_path: str, output_path: str, options: ConvertOptions | None = None,
            progress: Progress | None = None) -> ConvertSummary:
    """Convert ``input_path`` (any supported source) to ``output_path`` (GLB/glTF/PLY)."""
    options = options or ConvertOptions()
    progress = progress or Progress(enabled=False)
    start = time.perf_counter()
    input_path, output_path = os.fspath(input_path), os.fspath(output_path)
    summary = ConvertSummary(input_path, output_path)
    _check_options(input_path, output_path, options)
    protect = tuple(p for p in (input_path, options.mesh, options.pt_path, options.bake_poses)
                    if p is not None)

    in_ext = os.path.splitext(input_path)[1].lower()
    out_ext = os.path.splitext(output_path)[1].lower()
    format_only = options.plain or (options.mesh is None and options.source in ("auto", "khr")
                                    and (in_ext in (".glb", ".gltf") + USD_SUFFIXES
                                         or out_ext == ".ply"))
    if format_only:
        # Format conversion only (PLY <-> GLB <-> USD, GLB -> GLB, PLY -> PLY): no binding
        # involved; anchoring already present in a glTF or USD input is kept.
        if options.mesh is not None:
            raise UsageError("--plain writes splats without anchoring: drop --mesh or --plain")
        progress.stage(f"reading {os.path.basename(input_path)}")
        asset = _read_noting_usd_warnings(input_path, options, summary)
        if options.sh_degree is not None:
            for prim in asset.primitives:
                if prim.splats.sh_degree > options.sh_degree:
                    prim.splats = prim.splats.with_sh_degree(options.sh_degree)
        if options.plain:
            asset = SplatAsset([SplatPrimitive(p.splats, None, p.name) for p in asset.primitives],
                               asset.generator)
        summary.source = ("khr" if in_ext in (".glb", ".gltf") else
                          "usd" if in_ext in USD_SUFFIXES else "3dgs")
        return _finish(asset, output_path, options, protect, summary, progress, start)

    source = options.source
    if source == "auto":
        source, reason = detect_source(input_path, options.mesh)
        summary.notes.append(f"detected source {source}: {reason}")
    summary.source = source
    progress.stage(f"reading {source} input")
    load = loader(source)
    src_options = SourceOptions(frame_change=options.frame_change,
                                legacy_frame=options.legacy_trellis_frame, faces=options.faces,
                                pt_path=options.pt_path, k=options.k)
    result: SourceResult = load(input_path, options.mesh, src_options)
    summary.notes.extend(result.notes)
    summary.check = dict(result.check)
    asset = _anchor(result, options, progress, summary)
    return _finish(asset, output_path, options, protect, summary, progress, start)


def _read_noting_usd_warnings(input_path: str, options: ConvertOptions,
                              summary: ConvertSummary) -> SplatAsset:
    """``read_asset``; what the USD reader replaced in foreign data goes to the summary notes."""
    import warnings

    from .io.usd import UsdReadWarning

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", UsdReadWarning)
        asset = read_asset(input_path, frame_change=options.frame_change)
    for w in caught:
        if issubclass(w.category, UsdReadWarning):
            summary.notes.append(str(w.message))
        else:
            warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)
    return asset


def _finish(asset: SplatAsset, output_path: str, options: ConvertOptions, protect: tuple,
            summary: ConvertSummary, progress: Progress, start: float) -> ConvertSummary:
    summary.splats = asset.splat_count()
    summary.anchored = sum(len(p.splats) for p in asset.anchored)
    summary.static = sum(len(p.splats) for p in asset.static)
    summary.sh_degree = max((p.splats.sh_degree for p in asset.primitives), default=0)
    if asset.anchored and summary.profile is None:
        anchoring = asset.anchored[0].anchoring
        summary.profile = anchoring.anchors.profile
        summary.deformation = getattr(anchoring.anchors, "deformation", None)
        summary.mesh_faces = anchoring.mesh.face_count
    if os.path.splitext(output_path)[1].lower() == ".ply" and asset.anchored:
        summary.notes.append("PLY output stores plain splats: the anchoring is not written")
    poses = None
    if options.bake_poses is not None:
        from .io.usd import load_poses

        poses = load_poses(options.bake_poses)
        summary.notes.append(f"baked {len(poses.times)} anchor-mesh poses into USD time samples")
    progress.stage(f"writing {os.path.basename(output_path)}")
    write_asset(asset, output_path, frame_change=options.frame_change, protect=protect,
                bake_poses=poses)
    progress.close()
    summary.output_bytes = os.path.getsize(output_path)
    summary.seconds = time.perf_counter() - start
    return summary


def _face_distances(splats: SplatCloud, mesh: TriangleMesh, face: np.ndarray) -> np.ndarray:
    tri = mesh.triangles()[face.astype(np.intp)]
    _, _, dist = closest_points_on_triangles(splats.means.astype(np.float64), tri[:, 0], tri[:, 1], tri[:, 2])
    return dist


def _anchor(result: SourceResult, options: ConvertOptions, progress: Progress,
            summary: ConvertSummary) -> SplatAsset:
    splats, mesh, anchors = result.splats, result.mesh, result.anchors
    if mesh is None:
        raise UsageError("this source needs an anchor mesh: pass --mesh", summary.input)
    if options.sh_degree is not None and splats.sh_degree > options.sh_degree:
        splats = splats.with_sh_degree(options.sh_degree)
    if options.faces is not None and mesh.face_count > options.faces:
        from .meshops import decimate

        progress.stage(f"decimating {mesh.face_count} -> {options.faces} faces")
        mesh = decimate(mesh, options.faces)
        if anchors is not None:
            summary.notes.append(f"--faces: the source's exact binding was replaced by nearest-"
                                 f"triangle binding to the decimated mesh (local profile)")
            anchors = None
    if anchors is None:
        progress.stage("binding to the nearest triangles")
        try:
            bound = bind_local(splats, mesh, deformation=options.deformation, progress=progress.update)
        except GsverseError as exc:
            raise exc.with_path(options.mesh or summary.input)
        anchors, distance = bound.anchors, bound.distance
        summary.degenerate_faces = bound.degenerate_faces
    else:
        if isinstance(anchors, LocalAnchors) and anchors.deformation != options.deformation:
            anchors = replace(anchors, deformation=options.deformation)
        distance = _face_distances(splats, mesh, anchors.face_index)

    lo, hi = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
    diagonal = float(np.linalg.norm(hi.astype(np.float64) - lo))
    summary.distance = _distance_stats(distance, diagonal)
    summary.mesh_faces = mesh.face_count
    summary.profile = anchors.profile
    summary.deformation = getattr(anchors, "deformation", None)

    keep = np.ones(len(splats), bool)
    if options.max_distance is not None:
        limit = options.max_distance if options.absolute_distance else options.max_distance * diagonal
        summary.max_distance = float(limit)
        keep = distance <= limit
    if not options.keep_order:
        order = np.argsort(anchors.face_index, kind="stable")
        keep_idx = order[keep[order]]
    else:
        keep_idx = np.flatnonzero(keep)
    far_idx = np.flatnonzero(~keep)

    primitives = []
    name = os.path.splitext(os.path.basename(summary.input.rstrip(os.sep)))[0] or "splats"
    if keep_idx.size:
        primitives.append(SplatPrimitive(splats.subset(keep_idx),
                                         Anchoring(mesh, anchors.subset(keep_idx)), name))
    if far_idx.size:
        if options.drop_unanchored:
            summary.dropped = int(far_idx.size)
        else:
            primitives.append(SplatPrimitive(splats.subset(far_idx), None, f"{name} static"))
    return SplatAsset(primitives)
