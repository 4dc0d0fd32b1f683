"""The conversion pipeline behind ``gsverse-convert``: read splats, bind to a mesh, write.

Library users call :func:`convert`; the command line (:mod:`gsverse_format.cli.convert`) only
parses options and prints the returned :class:`ConvertSummary`.
"""
from __future__ import annotations

import os
import time
from dataclasses import asdict, dataclass, field

import numpy as np

from .binding import bind_local
from .errors import GsverseError, UsageError
from .io.mesh import read_mesh
from .io.registry import read_asset, write_asset
from .model import Anchoring, SplatAsset, SplatCloud, SplatPrimitive
from .progress import Progress
from .transform import PLY_TO_GLTF, rotate_mesh


@dataclass
class ConvertOptions:
    """Options of :func:`convert` (the command-line flags map one to one)."""

    mesh: str | None = None
    deformation: str = "affine"
    frame_change: bool = True
    keep_order: bool = False
    sh_degree: int | None = None


@dataclass
class ConvertSummary:
    """What a conversion did; ``as_dict()`` is the ``--json`` output."""

    input: str
    output: str
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
    output_bytes: int = 0
    seconds: float = 0.0

    def as_dict(self) -> dict:
        return asdict(self)

    def lines(self) -> list[str]:
        out = [f"{self.input} -> {self.output}",
               f"  splats     {self.splats} (anchored {self.anchored}, static {self.static}, "
               f"dropped {self.dropped}), SH degree {self.sh_degree}"]
        if self.profile:
            out.append(f"  anchoring  profile {self.profile}, deformation {self.deformation}, "
                       f"{self.mesh_faces} faces ({self.degenerate_faces} degenerate, never bound)")
        if self.distance:
            d = self.distance
            out.append(f"  distance   to mesh p50 {d['p50']:.3g}, p95 {d['p95']:.3g}, max {d['max']:.3g} "
                       f"(mesh diagonal {d['mesh_diagonal']:.3g})")
        out.append(f"  wrote      {self.output_bytes} bytes in {self.seconds:.2f} s")
        return out


def _distance_stats(distance: np.ndarray, diagonal: float) -> dict:
    if distance.size == 0:
        return {}
    p50, p95, p99 = np.percentile(distance, [50, 95, 99])
    return {"p50": float(p50), "p95": float(p95), "p99": float(p99),
            "max": float(distance.max()), "mesh_diagonal": float(diagonal)}


def convert(input_path: str, output_path: str, options: ConvertOptions | None = None,
            progress: Progress | None = None) -> ConvertSummary:
    """Convert ``input_path`` (PLY/GLB/glTF splats) to ``output_path`` (GLB/glTF/PLY)."""
    options = options or ConvertOptions()
    progress = progress or Progress(enabled=False)
    start = time.perf_counter()
    summary = ConvertSummary(os.fspath(input_path), os.fspath(output_path))
    if options.deformation not in ("affine", "rigid"):
        raise UsageError(f"--deformation must be affine or rigid, not {options.deformation!r}")
    for p in (input_path, options.mesh):
        if p is not None and not os.path.isfile(p):
            raise UsageError("file not found", p)

    progress.stage(f"reading {os.path.basename(input_path)}")
    asset = read_asset(input_path, frame_change=options.frame_change)
    if options.sh_degree is not None:
        if options.sh_degree not in (0, 1, 2, 3):
            raise UsageError(f"--sh-degree must be 0..3, not {options.sh_degree}")
        for prim in asset.primitives:
            if prim.splats.sh_degree > options.sh_degree:
                prim.splats = prim.splats.with_sh_degree(options.sh_degree)

    if options.mesh is not None:
        asset = _bind_to_mesh(asset, options, progress, summary)

    summary.splats = asset.splat_count()
    summary.anchored = sum(len(p.splats) for p in asset.anchored)
    summary.static = sum(len(p.splats) for p in asset.static)
    summary.sh_degree = max((p.splats.sh_degree for p in asset.primitives), default=0)
    if asset.anchored and summary.profile is None:
        summary.profile = asset.anchored[0].anchoring.anchors.profile
        summary.deformation = getattr(asset.anchored[0].anchoring.anchors, "deformation", None)
        summary.mesh_faces = asset.anchored[0].anchoring.mesh.face_count

    progress.stage(f"writing {os.path.basename(output_path)}")
    protect = tuple(p for p in (input_path, options.mesh) if p is not None)
    write_asset(asset, output_path, frame_change=options.frame_change, protect=protect)
    progress.close()
    summary.output_bytes = os.path.getsize(output_path)
    summary.seconds = time.perf_counter() - start
    return summary


def _bind_to_mesh(asset: SplatAsset, options: ConvertOptions, progress: Progress,
                  summary: ConvertSummary) -> SplatAsset:
    progress.stage(f"reading {os.path.basename(options.mesh)}")
    mesh = read_mesh(options.mesh)
    if options.frame_change and os.path.splitext(summary.input)[1].lower() == ".ply":
        # The mesh comes in the same frame as the PLY splats it belongs to.
        mesh = rotate_mesh(mesh, PLY_TO_GLTF)
    clouds = [p.splats for p in asset.primitives]
    if not clouds:
        raise UsageError("the input holds no splats", summary.input)
    cloud = SplatCloud.concatenate(clouds)
    progress.stage("binding to the nearest triangles")
    try:
        bound = bind_local(cloud, mesh, deformation=options.deformation, progress=progress.update)
    except GsverseError as exc:
        raise exc.with_path(options.mesh)
    anchors = bound.anchors
    if not options.keep_order:
        order = np.argsort(anchors.face_index, kind="stable")
        cloud, anchors = cloud.subset(order), anchors.subset(order)
    lo, hi = mesh.vertices.min(axis=0), mesh.vertices.max(axis=0)
    summary.distance = _distance_stats(bound.distance, float(np.linalg.norm(hi - lo)))
    summary.profile, summary.deformation = "local", options.deformation
    summary.mesh_faces, summary.degenerate_faces = mesh.face_count, bound.degenerate_faces
    name = asset.primitives[0].name
    return SplatAsset([SplatPrimitive(cloud, Anchoring(mesh, anchors), name)], asset.generator)
