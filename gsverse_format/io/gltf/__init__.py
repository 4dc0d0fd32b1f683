"""glTF 2.0 (``.gltf``) and GLB (``.glb``) splat assets.

The rest pose of every splat primitive is plain ``KHR_gaussian_splatting``; the anchoring of
anchored primitives is the ``GSVERSE_gaussian_splatting_mesh_anchor`` extension nested in the
``KHR_gaussian_splatting`` extension object (``spec/README.md``). The package has one module
per layer:

* :mod:`.container`: GLB chunks, the JSON document, buffers, URIs, buffer views and limits;
* :mod:`.accessors`: accessor layout, reading and dequantization;
* :mod:`.document`: opening a file (container plus accessor access);
* :mod:`.reader`: ``KHR_gaussian_splatting`` primitives and the anchor extension;
* :mod:`.scene`: a scene's triangles as one mesh (anchor meshes supplied as glTF);
* :mod:`.writer`: the writer and the buffer builder.

Reading accepts any ``KHR_gaussian_splatting`` ``POINTS`` primitive, dequantizes normalized
integer accessors as glTF 2.0 prescribes, honours ``byteStride`` and accessor ``byteOffset``
and bounds-checks every access before it happens. Every problem with the input is a
:class:`~gsverse_format.errors.FormatError` naming the file (a :class:`GltfFormatError` with
its issue code where there is one); any other exception is a bug and propagates. Buffers come
from the GLB ``BIN`` chunk, base64 ``data:`` URIs, or files inside the asset's folder; nothing
is fetched from the network.
"""
from __future__ import annotations

from ...vocabulary import EXTENSION, KHR
from .accessors import (COMPONENT_DTYPES, QUANTIZED_POSITION_FORMATS, AccessorLayout, Accessors,
                        dequantize, describe_format, format_allowed)
from .container import (DEFAULT_MAX_BYTES, Buffers, GltfFormatError, glb_bytes, gltf_error,
                        header_problems, parse_glb, parse_json, pointer_token)
from .document import Document, load_document, open_document
from .reader import OPACITY, ROTATION, SCALE, read_document, read_gltf, sh_attribute
from .scene import read_gltf_triangles
from .writer import BufferBuilder, asset_to_gltf, gltf_to_bytes, write_gltf

#: The anchor extension's name (:data:`gsverse_format.vocabulary.EXTENSION`).
ANCHOR = EXTENSION

__all__ = ["write_gltf", "read_gltf", "read_gltf_triangles", "asset_to_gltf", "gltf_to_bytes",
           "read_document", "KHR", "ANCHOR", "DEFAULT_MAX_BYTES", "GltfFormatError",
           "gltf_error", "glb_bytes", "AccessorLayout", "Accessors", "Buffers", "Document",
           "parse_glb", "parse_json", "load_document", "open_document", "header_problems",
           "pointer_token", "BufferBuilder", "COMPONENT_DTYPES", "QUANTIZED_POSITION_FORMATS",
           "dequantize", "describe_format", "format_allowed", "ROTATION", "SCALE", "OPACITY",
           "sh_attribute"]

from ..registry import register_format  # noqa: E402  (the format registers itself last)

register_format("gltf", (".glb", ".gltf"), read=read_gltf, write=write_gltf, keeps_khr=True)
