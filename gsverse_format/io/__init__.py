"""File formats: one package per splat format (``ply``, ``gltf``, ``usd``; ``splatformats`` holds
the read-only web formats, one module each), plus anchor-mesh reading (:mod:`.mesh`), the
format table (:mod:`.registry`) and the summary of a file (:mod:`.info`).

Importing this package imports every format package, and each registers itself in
:data:`gsverse_format.io.registry.FORMATS`; the USD package imports ``pxr`` only when a USD
file is used.
"""
from . import gltf, ply, usd  # noqa: F401  (each registers itself in registry.FORMATS)
from . import splatformats  # noqa: F401  (.splat, .ksplat, .spz, compressed PLY, SOG)
