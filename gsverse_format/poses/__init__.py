"""Deformation sources for anchor meshes, and the posed splats they give.

* :mod:`.gltf_animation`: glTF 2.0 animations with glTF semantics (``LINEAR``/``STEP``/
  ``CUBICSPLINE`` keys, slerp for rotations, morph targets, linear blend skinning);
  :mod:`.gltf_source` applies them to an anchor mesh (the asset's own skinned/morphed anchor
  mesh, or another glTF file with the same vertices);
* :mod:`.caches`: vertex caches (``.npz`` T×V×3, OBJ/PLY sequences);
* :mod:`.vat`: vertex-animation textures in OpenEXR (read and write);
* :mod:`.analytic`: stretch, twist, bend and shake, for quick looks;
* :mod:`.sources`: one interface over all of them (:func:`open_source`).

``gsverse-pose`` (:mod:`gsverse_format.cli.pose`) samples them and writes posed splats.
"""
from __future__ import annotations

from .analytic import QuickLook, parse_deformations
from .caches import VertexCache, read_npz, read_sequence
from .gltf_animation import GltfAnimation, Instance, sample_channel, slerp
from .gltf_source import GltfSource, open_gltf_source
from .sources import CacheSource, Source, open_source
from .vat import read_vat, write_vat

__all__ = ["GltfAnimation", "Instance", "sample_channel", "slerp", "GltfSource",
           "open_gltf_source", "VertexCache", "read_npz", "read_sequence", "read_vat",
           "write_vat", "QuickLook", "parse_deformations", "CacheSource", "Source",
           "open_source"]
