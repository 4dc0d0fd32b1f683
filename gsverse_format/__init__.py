"""gsverse-format: mesh-anchored Gaussian splats for any engine.

The rest pose is plain ``KHR_gaussian_splatting``; the anchoring (which triangle each
splat follows and how) is the ``GSVERSE_gaussian_splatting_mesh_anchor`` extension.
See ``spec/README.md`` for the normative text.

The public API is :func:`read`, :func:`write`, :func:`convert`, :func:`remap`,
:func:`validate` and :func:`bind` (:mod:`gsverse_format.api`) and the data model
(:mod:`gsverse_format.model`); ``ARCHITECTURE.md`` says where everything else lives.
"""
from .api import bind, convert, read, remap, validate, write
from .errors import BindingError, FormatError, GsverseError, UsageError
from .model import (Anchoring, GamesAnchors, LocalAnchors, SplatAsset, SplatCloud,
                    SplatPrimitive, TriangleMesh)
from .version import __version__
from .vocabulary import EXTENSION as EXTENSION_NAME

__all__ = [
    "read", "write", "convert", "remap", "validate", "bind",
    "Anchoring", "GamesAnchors", "LocalAnchors", "SplatAsset", "SplatCloud", "SplatPrimitive",
    "TriangleMesh", "GsverseError", "FormatError", "UsageError", "BindingError",
    "EXTENSION_NAME", "__version__",
]
