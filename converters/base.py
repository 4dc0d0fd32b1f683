"""What every source loader takes and returns.

A loader (``load`` of a module in :mod:`gsverse_format.converters`, found through
:mod:`gsverse_format.converters.registry`) reads one tool's output and returns the splats' rest
pose, the anchor mesh (or none: the pipeline then reconstructs one from the splats) and — where
the source defines the binding exactly, as SuGaR and GaMeS do — the anchors.

Loaders do not change coordinate frames on their own: they return splats and mesh in one
common frame of the source and name it in :attr:`SourceResult.frame` (a key of
:data:`gsverse_format.io.registry.FRAMES`). The conversion pipeline
(:mod:`gsverse_format.pipeline`) rotates the result into the glTF frame once, then decimates,
binds what has no anchors yet by nearest triangle, separates splats too far from the mesh, and
writes. (Anchors are relative to their triangles, so the rotation leaves them unchanged.)
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Literal

from gsverse_format.errors import FormatError
from gsverse_format.model import Anchors, KhrProperties, SplatCloud, TriangleMesh

__all__ = ["SourceOptions", "SourceResult", "TrellisFrame", "require_splats"]

#: Which rotation takes a TRELLIS PLY into the frame of the GLB of the same run.
TrellisFrame = Literal["current", "legacy", "none"]


@dataclass
class SourceOptions:
    """Options a loader may use (the pipeline fills them from the command-line flags).

    * ``pt_path`` — a PyTorch checkpoint (SuGaR refined ``.pt``, GaMeS ``model_params.pt``).
    * ``k`` — splats per face, overriding detection (SuGaR, GaMeS).
    * ``trellis_frame`` — the frame of a TRELLIS PLY relative to its GLB: ``"current"``
      (TRELLIS's export rotation since 2024-12-18), ``"legacy"`` (PLYs saved before it,
      ``--legacy-trellis-frame``) or ``"none"`` (already in the GLB's frame,
      ``--no-frame-change``).
    * ``keep_nonfinite`` — keep splats with non-finite values (``--drop-nonfinite``: the
      pipeline drops them) where the loader reads them row by row (3DGS, TRELLIS); other
      loaders refuse them.
    """

    pt_path: str | None = None
    k: int | None = None
    trellis_frame: TrellisFrame = "current"
    keep_nonfinite: bool = False


@dataclass
class SourceResult:
    """A loaded source: rest-pose splats, anchor mesh (None: reconstruct one from the splats),
    optional exact anchors, remarks, measurements, the coordinate frame all of it is in
    (a key of :data:`gsverse_format.io.registry.FRAMES`), and the ``KHR_gaussian_splatting``
    properties the splats are rendered with (a KHR glTF source's own; the defaults
    otherwise)."""

    splats: SplatCloud
    mesh: TriangleMesh | None
    anchors: Anchors | None = None
    notes: list[str] = field(default_factory=list)
    check: dict[str, Any] = field(default_factory=dict)
    frame: str = "gltf"
    khr: KhrProperties = field(default_factory=KhrProperties)
    #: Every file the loader read (a source folder's files: its PLY, parameters, mesh), which
    #: the output must not replace; empty: only the input path and the files named in the
    #: options (a folder input then protects every file inside it).
    inputs: tuple[str, ...] = ()


def require_splats(splats: SplatCloud, path: str, why: str = "the PLY holds none") -> None:
    """Refuse an input without splats (a :class:`FormatError` naming ``path``): there is
    nothing to convert, and an empty asset is never written."""
    if not len(splats):
        raise FormatError(f"no splats to convert ({why})", path)
