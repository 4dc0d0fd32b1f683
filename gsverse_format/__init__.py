"""gsverse-format: mesh-anchored Gaussian splats for any engine.

The rest pose is plain ``KHR_gaussian_splatting``; the anchoring (which triangle each
splat follows and how) is the ``GSVERSE_gaussian_splatting_mesh_anchor`` extension.
See ``spec/README.md`` for the normative text.
"""
from .errors import BindingError, FormatError, GsverseError, UsageError
from .model import (Anchoring, GamesAnchors, LocalAnchors, SplatAsset, SplatCloud,
                    SplatPrimitive, TriangleMesh)

__version__ = "0.1.0"

#: Name of the glTF extension defined by this project.
EXTENSION_NAME = "GSVERSE_gaussian_splatting_mesh_anchor"

__all__ = [
    "Anchoring", "GamesAnchors", "LocalAnchors", "SplatAsset", "SplatCloud", "SplatPrimitive",
    "TriangleMesh", "GsverseError", "FormatError", "UsageError", "BindingError",
    "EXTENSION_NAME", "__version__",
]
