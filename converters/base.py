"""What every source loader takes and returns.

A loader (``gsverse_format.converters.<source>.load``) reads one tool's output and returns the
splats' rest pose, the anchor mesh and — where the source defines the binding exactly, as SuGaR
and GaMeS do — the anchors. Everything is returned in the glTF frame (+Y up, right-handed).
The conversion pipeline (:mod:`gsverse_format.convert`) then decimates, binds what has no
anchors yet by nearest triangle, separates splats too far from the mesh, and writes.
"""
from __future__ import annotations

from dataclasses import dataclass, field

from ..model import Anchors, SplatCloud, TriangleMesh


@dataclass
class SourceOptions:
    """Options a loader may use (command-line flags map one to one).

    * ``frame_change`` — rotate from the source's frame into glTF's (default on).
    * ``legacy_frame`` — TRELLIS PLYs saved before 2024-12-18 (no export rotation).
    * ``faces`` — target face count when a loader builds or decimates the anchor mesh.
    * ``pt_path`` — a PyTorch checkpoint (SuGaR refined ``.pt``, GaMeS ``model_params.pt``).
    * ``k`` — splats per face, overriding detection (SuGaR, GaMeS).
    """

    frame_change: bool = True
    legacy_frame: bool = False
    faces: int | None = None
    pt_path: str | None = None
    k: int | None = None


@dataclass
class SourceResult:
    """A loaded source: rest-pose splats, anchor mesh, optional exact anchors, remarks."""

    splats: SplatCloud
    mesh: TriangleMesh | None
    anchors: Anchors | None = None
    notes: list[str] = field(default_factory=list)
    check: dict = field(default_factory=dict)
