"""The public reading and checking functions: :func:`read_usd`, :func:`check_usd` and
:func:`inspect_usd`, each in this process or isolated in a child process."""
from __future__ import annotations

import os
import warnings

from ...model import SplatAsset
from .checks import inspect_in_process
from .isolation import inspect_isolated, read_isolated
from .problems import UsdInspection, UsdProblem, UsdReadWarning
from .reader import read_in_process

__all__ = ["read_usd", "check_usd", "inspect_usd"]


def read_usd(path: str | os.PathLike[str], *, isolate: bool = False,
             timeout: float | None = None) -> SplatAsset:
    """Read every ``ParticleField3DGaussianSplat`` prim of a USD file as a splat primitive.

    Prims with ``GsVerseMeshAnchorAPI`` get their :class:`Anchoring` (prims targeting the same
    ``Mesh`` share one :class:`TriangleMesh`); the rest pose is always the default values,
    never time samples. Foreign data follows the USD schema's rules (spec/usd.md §Foreign
    data), each replacement reported as a :class:`UsdReadWarning`; Z-up stages and other
    units are converted to glTF's frame. The name of a primitive is the prim's
    ``displayName``, else its name. Raises :class:`FormatError` (one line naming ``path`` and
    the USD property) for unreadable files and invalid anchored prims, :class:`UsageError`
    without usd-core.

    USD's binary reader can crash the process or exhaust its memory on some corrupted
    ``.usdc`` data (observed with usd-core 26.11). ``isolate=True`` reads in a child process
    (with a memory cap, and ``timeout`` seconds at most), so that such a file becomes a
    :class:`FormatError` too; use it for untrusted files. An unexpected exception in the child
    (a bug, not bad input) raises :class:`~.isolation.UsdInternalError`.
    """
    spath = os.fspath(path)
    if isolate:
        asset, problems = read_isolated(spath, timeout)
    else:
        asset, problems = read_in_process(spath)
    for p in problems:
        warnings.warn(f"{spath}: {p.location + ': ' if p.location else ''}{p.message}",
                      UsdReadWarning, stacklevel=2)
    return asset


def check_usd(path: str | os.PathLike[str], *, usd_validation: bool = True,
              isolate: bool = True, timeout: float | None = None) -> list[UsdProblem]:
    """Every problem of a USD splat file against spec/usd.md, for validators.

    Runs what :func:`read_usd` checks (errors it would raise, data it would replace) plus the
    writer rules (stage metadata and layout, API schema authoring, anchor-mesh and baked
    animation rules) and, with ``usd_validation``, OpenUSD's own validators
    (``pxr.UsdValidation``; code ``USD_VALIDATOR_ERROR`` or ``USD_VALIDATOR_WARNING``, the
    validator's name in :attr:`UsdProblem.validator`). A file whose list has no ``"error"``
    entry conforms. A file whose composition arcs leave its folder is not opened (one
    ``USD_LAYER_OUTSIDE_FOLDER`` error). Raises :class:`FormatError` only when the file cannot
    be opened as a USD stage at all, :class:`UsageError` without usd-core.

    By default the file is checked in a child process (see :func:`read_usd`), which also
    guarantees that the GsVerse schemas are registered there, so that OpenUSD's
    ``AttributeTypeMismatch`` validator checks the ``gsverse:`` attributes.
    """
    return inspect_usd(path, usd_validation=usd_validation, isolate=isolate, timeout=timeout,
                       data=False).problems


def inspect_usd(path: str | os.PathLike[str], *, usd_validation: bool = True,
                isolate: bool = True, timeout: float | None = None,
                data: bool = True) -> UsdInspection:
    """:func:`check_usd` plus the data it read (``data=False``: problems only, empty asset).

    Validators use the data to run the checks that do not depend on the file format (unit
    quaternions, triangle quality, rest-pose consistency). Raises like :func:`check_usd`.
    """
    spath = os.fspath(path)
    if isolate:
        return inspect_isolated(spath, timeout, usd_validation=usd_validation, data=data)
    found = inspect_in_process(spath, usd_validation_too=usd_validation)
    if not data:
        return UsdInspection(found.problems, SplatAsset([]), [])
    return found
