"""OpenUSD splat assets (``.usda``, ``.usdc``, ``.usd``, ``.usdz``), as ``spec/usd.md`` maps them.

Each splat primitive is a ``ParticleField3DGaussianSplat`` prim holding the rest pose as default
values; an anchored primitive additionally has the codeless single-apply API schema
``GsVerseMeshAnchorAPI`` (``gsverse:anchor:*`` attributes and the relationship
``gsverse:anchor:mesh`` to a ``UsdGeom.Mesh`` of triangles), a static one
``GsVerseColorSpaceAPI``. Both carry the ``KHR_gaussian_splatting`` colour space in
``gsverse:colorSpace``. Units and axes are glTF's (metres, +Y up): no conversion on writing.

Optionally, :func:`write_usd` bakes the remap for a sequence of anchor-mesh poses into time
samples of ``positions``, ``orientations``, ``scales`` and ``extent`` (and of the anchor mesh's
``points``), for USD renderers that know nothing about anchors; the default values stay the
rest pose.

``usd-core`` (``pxr``) is an optional dependency: it is imported on first use (importing this
package does not import it), and the schema plugin in ``gsverse_format/usd_schema`` is
registered right then (:func:`register_schema`). If the process used USD's schema registry
before, the schemas cannot be registered any more; the writer then authors the same file by
hand (``spec/usd.md`` §Writing without the registered schema) and a :class:`UsdSchemaWarning`
says so. Reading never needs the schemas.

Public API: :func:`write_usd`, :func:`read_usd`, :func:`check_usd` (every problem of a file,
with USD paths as locations and catalogue issue codes, for validators), :func:`inspect_usd`
(the problems and the data as authored), :func:`load_poses` / :class:`BakedPoses` (the
``--bake-poses`` file) and :func:`register_schema`. ``read_usd(..., isolate=True)`` and
:func:`check_usd` parse the file in a child process: usd-core's binary reader can crash on
some corrupted files, and a crash there becomes a :class:`FormatError` here.

Modules: :mod:`.schema` (names, value types, ``pxr`` import, schema registration),
:mod:`.writer`, :mod:`.poses`, :mod:`.stage` (opening a file safely), :mod:`.reader` (a stage
to a :class:`SplatAsset`), :mod:`.checks` (writer rules and OpenUSD validation),
:mod:`.isolation` (the child process), :mod:`.problems` (what they report) and :mod:`.api`.
"""
from __future__ import annotations

from .api import check_usd, inspect_usd, read_usd
from .isolation import UsdInternalError
from .poses import BakedPoses, load_poses
from .problems import UsdInspection, UsdPrimInfo, UsdProblem, UsdReadWarning
from .schema import (ANCHOR_API, COLOR_SPACE_API, MISSING_USD_CORE, SCHEMA_DIR, USD_SUFFIXES,
                     UsdSchemaWarning, register_schema)
from .writer import write_usd

__all__ = ["USD_SUFFIXES", "MISSING_USD_CORE", "SCHEMA_DIR", "ANCHOR_API", "COLOR_SPACE_API",
           "UsdSchemaWarning", "UsdReadWarning", "UsdProblem", "UsdInspection", "UsdPrimInfo",
           "UsdInternalError", "BakedPoses",
           "register_schema", "write_usd", "read_usd", "check_usd", "inspect_usd", "load_poses"]

from ..registry import register_format  # noqa: E402  (the format table; see io/registry.py)

register_format("usd", USD_SUFFIXES, read=read_usd, write=write_usd)
