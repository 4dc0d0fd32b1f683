"""Asset validation (installed as ``gsverse_format.validators``).

``gsverse-validate FILE...`` (:mod:`.cli`) and :func:`validate_file` check ``.glb``/``.gltf``
assets (the container, ``KHR_gaussian_splatting``, the ``GSVERSE_gaussian_splatting_mesh_anchor``
extension, the anchor mesh and the rest-pose consistency) and USD files (:mod:`.usd`: the
checks of spec/usd.md, OpenUSD's validators, and the same value checks, :mod:`.values`). Every finding has a stable code from
:data:`CATALOGUE` (documented in ``spec/validation.md``), a severity, a location and a message.
"""
from .container import Options
from .issues import CATALOGUE, Finding, Severity
from .validate import Report, validate_file

__all__ = ["validate_file", "Report", "Options", "Finding", "Severity", "CATALOGUE"]
