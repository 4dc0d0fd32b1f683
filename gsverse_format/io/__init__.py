"""File formats: one package per splat format (``ply``, ``gltf``, ``usd``), plus anchor-mesh
reading (:mod:`.mesh`) and the format table (:mod:`.registry`).

Importing this package imports every format package, and each registers itself in
:data:`gsverse_format.io.registry.FORMATS`; the USD package imports ``pxr`` only when a USD
file is used.
"""
from . import gltf, ply, usd  # noqa: F401  (each registers itself in registry.FORMATS)
