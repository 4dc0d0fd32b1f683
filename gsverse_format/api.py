"""The public API: the six things most users do, each one call.

    import gsverse_format as gv

    asset = gv.read("scene.glb")                          # any registered format -> SplatAsset
    gv.write(asset, "scene.usdz")                         # SplatAsset -> any registered format
    summary = gv.convert("splats.ply", "out.glb", mesh="mesh.obj")   # the gsverse-convert pipeline
    posed = gv.remap(asset.anchored[0].anchoring, vertices)          # splats on a deformed mesh
    report = gv.validate("out.glb")                       # gsverse-validate findings
    anchoring = gv.bind(cloud, mesh)                      # anchor free splats to a mesh

Everything here delegates to the module that owns the work; the functions import it when
called, so that importing :mod:`gsverse_format` stays cheap and free of import cycles.

Paths are ``str`` or any path-like object (``pathlib.Path``), wherever a function takes one
(``mesh=``, ``meshes=``, ``pt_path=``, ``bake_poses=``, ``protect=`` included).

Existing outputs: :func:`write` and :func:`convert` replace an existing file at the output
path, as Python's own writers do (``open(path, "w")``, ``numpy.save``), so that a script or
notebook can be run again; ``overwrite=False`` refuses instead, as the command-line tools do
without ``-w``: a :class:`~gsverse_format.errors.UsageError` naming the output, nothing
written. Either way no input is ever replaced, and the replacement is atomic.
"""
from __future__ import annotations

import os
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover - annotations only
    import numpy as np

    from .pipeline import ConvertSummary
    from .model import Anchoring, SplatAsset, SplatCloud, TriangleMesh
    from .remapping.reference import RemapResult
    from .validators.validate import Report

__all__ = ["read", "write", "convert", "remap", "validate", "bind"]


def read(path: str | os.PathLike[str]) -> SplatAsset:
    """Read a splat asset (glTF/GLB, 3DGS PLY, USD) into the glTF frame (+Y up).

    Raises :class:`~gsverse_format.errors.FormatError` for bad input (one line naming the file
    and the cause) and :class:`~gsverse_format.errors.UsageError` for an unsupported suffix.
    """
    from .io.registry import read_asset

    return read_asset(path)


def write(asset: SplatAsset, path: str | os.PathLike[str], *, overwrite: bool = True,
          **options: Any) -> None:
    """Write ``asset`` in the format of ``path``'s suffix, atomically (a failed write leaves no
    file and never replaces an existing one half-written). An existing file at ``path`` is
    replaced, unless ``overwrite=False``: then it is a
    :class:`~gsverse_format.errors.UsageError`. ``options`` go to the format's writer (e.g.
    ``protect=`` paths that must not be overwritten)."""
    from .io.registry import write_asset

    _refuse_existing(path, overwrite)
    write_asset(asset, path, **options)


def convert(input: str | os.PathLike[str], output: str | os.PathLike[str], *,
            overwrite: bool = True, **options: Any) -> ConvertSummary:
    """Run the ``gsverse-convert`` pipeline: ``options`` are the fields of
    :class:`gsverse_format.pipeline.ConvertOptions` (``mesh=``, ``source=``, ``deformation=``,
    ``max_distance=``, ...). Returns the summary ``--json`` prints. An existing ``output`` is
    replaced, unless ``overwrite=False`` (``gsverse-convert`` without ``-w``): then it is a
    :class:`~gsverse_format.errors.UsageError`; inputs are never replaced."""
    from .pipeline import ConvertOptions, convert as run

    _refuse_existing(output, overwrite)
    return run(os.fspath(input), os.fspath(output), ConvertOptions(**options))


def _refuse_existing(path: str | os.PathLike[str], overwrite: bool) -> None:
    if not overwrite and os.path.lexists(path):
        from .errors import UsageError

        raise UsageError("output exists; pass overwrite=True to replace it", path)


def remap(anchoring: Anchoring, vertices: np.ndarray | None = None) -> RemapResult:
    """The float64 reference remap (spec §Remap) of ``anchoring``'s splats onto the anchor
    mesh posed at ``vertices`` (V, 3) (default: the rest pose): means, rotations, scales and
    covariances. For per-frame work use :class:`gsverse_format.remapping.fast.FastRemapper`."""
    from .remapping.reference import remap as reference

    return reference(anchoring, vertices)


def validate(path: str | os.PathLike[str], **options: Any) -> Report:
    """Validate a glTF/GLB or USD file as ``gsverse-validate`` does; ``report.findings`` lists
    the findings, ``report.exit_status`` is 0 (no errors), 1 (errors) or 2 (unreadable).
    ``options`` are the fields of :class:`gsverse_format.validators.validate.Options`."""
    from .validators.validate import Options, validate_file

    return validate_file(path, Options(**options) if options else None)


def bind(splats: SplatCloud, mesh: TriangleMesh, *, deformation: str = "affine") -> Anchoring:
    """Anchor free splats to ``mesh`` (``local`` profile): each splat to its exact nearest
    non-degenerate triangle, with the frame-relative rotation and scale that reproduce it at
    rest. Raises :class:`~gsverse_format.errors.BindingError` when no triangle is usable."""
    from .binding import bind_local
    from .model import Anchoring

    return Anchoring(mesh, bind_local(splats, mesh, deformation=deformation).anchors)
