"""The documented limits on what one input may make the readers allocate or compute.

Every reader checks declared sizes (counts, lengths, instancing) against these numbers, and
against the size of the file itself, *before* it allocates or expands anything, so that a
small hostile file cannot take gigabytes of memory or minutes of time. The README's "Limits"
section lists them; ``benchmarks/hostile.py`` measures the refusals.
"""
from __future__ import annotations

__all__ = ["MAX_ASSET_BYTES", "MAX_GLTF_ARRAY_ITEMS", "MAX_DATA_URI_BYTES",
           "MAX_SCENE_INSTANCES", "MAX_SCENE_VERTICES", "MAX_SCENE_TRIANGLES",
           "MAX_READ_AMPLIFICATION", "READ_AMPLIFICATION_SLACK", "MAX_SPZ_AMPLIFICATION",
           "MAX_MESH_FILE_BYTES",
           "MAX_USD_TEXT_BYTES", "MAX_USD_TEXT_PRIMS",
           "MAX_USD_TEXT_NESTING", "MAX_PLY_RAGGED_ROWS", "USD_CHILD_MEMORY_BASE",
           "USD_CHILD_SECONDS_BASE", "USD_CHILD_SECONDS_PER_MIB", "usd_child_seconds",
           "MAX_VAT_WIDTH", "MAX_RENDER_PIXELS", "MAX_RENDER_SIDE", "MAX_POSES",
           "MAX_NODE_DEPTH", "MAX_MORPH_AMPLIFICATION", "MAX_NPZ_RATIO", "NPZ_SLACK"]

#: glTF: bytes one asset may occupy, the file plus every buffer it loads (8 GiB;
#: ``gsverse-validate --max-bytes`` changes it for the validator).
MAX_ASSET_BYTES = 2 ** 33

#: glTF: elements of one top-level JSON array (``accessors``, ``bufferViews``, ``nodes``,
#: ``meshes``, ...) and primitives of one mesh. Checked on the raw JSON before anything is
#: decoded: a splat asset needs a few dozen accessors per primitive.
MAX_GLTF_ARRAY_ITEMS = 100_000

#: glTF: decoded bytes of one base64 ``data:`` URI (256 MiB; GLB or external ``.bin`` files
#: suit larger buffers; ``gsverse-validate --max-data-uri-bytes`` changes it).
MAX_DATA_URI_BYTES = 2 ** 28

#: glTF scene flattened as an anchor mesh (or posed): node instances (paths from the scene's
#: roots to a node, mesh or not), counted over the node graph before anything is expanded.
MAX_SCENE_INSTANCES = 100_000
#: glTF scene flattened as an anchor mesh: vertices and triangles after instancing.
MAX_SCENE_VERTICES = 2 ** 24
MAX_SCENE_TRIANGLES = 2 ** 25

#: glTF splat primitives: the accessor bytes all primitives read together (an accessor
#: shared by several primitives counted once per use) may be at most this many times the
#: bytes of the buffers they lie in, plus :data:`READ_AMPLIFICATION_SLACK`.
MAX_READ_AMPLIFICATION = 4
READ_AMPLIFICATION_SLACK = 2 ** 26

#: SPZ-compressed splat primitives (spec §SPZ-compressed rest pose): the float32 attributes a
#: stream decodes to may be at most this many times the stream's bytes plus
#: :data:`READ_AMPLIFICATION_SLACK`, checked before inflating (real streams decode to 5–15
#: times their size; a stream of identical splats to far more); inflation itself stops at
#: the bytes the declared splat count needs.
MAX_SPZ_AMPLIFICATION = 64

#: Morph targets of an animated ``--mesh`` glTF: the accessor bytes the targets read are held
#: to :data:`MAX_READ_AMPLIFICATION` as above, and the deltas kept (a float32 (V, 3) array per
#: target over the whole anchor mesh, zero on the parts the targets do not move) to this many
#: times the buffers' bytes plus :data:`READ_AMPLIFICATION_SLACK`: targets on a small part of
#: a large scene keep more than they read, 50,000 targets sharing one accessor far more.
MAX_MORPH_AMPLIFICATION = 32

#: OBJ, STL and OFF meshes (read by trimesh, whose text parsers take about ten times the
#: file's size): the largest file accepted (1 GiB).
MAX_MESH_FILE_BYTES = 2 ** 30

#: USD text layers (``#usda``, any suffix): the largest file accepted (256 MiB; the USD
#: text parser takes up to about 100 times a layer's size in memory: store large data as
#: ``.usdc``), the most prims (``def``/``over``/``class`` words) one text layer may declare,
#: and the deepest nesting of brackets (``{[(``; the parser recurses, and 20,000 nested
#: prims overflow its stack); counted on the text before the USD library parses it.
MAX_USD_TEXT_BYTES = 2 ** 28
MAX_USD_TEXT_PRIMS = 250_000
MAX_USD_TEXT_NESTING = 256

#: Animated anchor meshes (``--mesh X.glb``) and glTF pose sources: the deepest node chain
#: (levels from a scene root) whose global matrices are composed. Checked on the node graph
#: before any matrix is computed; a 90,000-node chain took 55 s a pose.
MAX_NODE_DEPTH = 1024

#: ``gsverse-pose --vat-width``: the widest vertex-animation texture written (16,384 texels,
#: the largest texture width current GPUs accept; a width of 10⁹ would allocate 12 GB a row).
MAX_VAT_WIDTH = 16384

#: ``gsverse-render --size WxH``: the most pixels of one picture (2²⁴, 4096²; the renderer keeps
#: about 80 bytes a pixel: 8192² took 5.5 GB) and the longest side (16,384).
MAX_RENDER_PIXELS = 2 ** 24
MAX_RENDER_SIDE = 16384

#: ``gsverse-pose``: the most poses one command writes or bakes (``--fps`` times the duration,
#: or ``--times``), counted before any pose is sampled: a typo, or a pose source whose key
#: times run to hours, should not fill a disk.
MAX_POSES = 10_000

#: ``.npz`` vertex caches: the arrays' bytes, read from the ``.npy`` headers inside the zip
#: before anything is loaded, may be at most ``MAX_NPZ_RATIO`` times the file's size plus
#: ``NPZ_SLACK`` (64 MiB): vertex positions compress at most a few times, a 314-byte file of
#: zeros declaring 10¹¹ elements does not pass.
MAX_NPZ_RATIO = 100
NPZ_SLACK = 2 ** 26

#: PLY: rows of one element whose list properties vary in length (each row is then held as a
#: separate array, about 0.5 KiB of memory for a few bytes of file, and parsed one by one).
#: Lists of one common length (triangle faces) are read as one array and have no such limit.
MAX_PLY_RAGGED_ROWS = 1 << 20

#: USD files are read in a child process (``io/usd/isolation.py``) with an address-space cap
#: of ``USD_CHILD_MEMORY_BASE`` (4 GiB) plus 32 times the file's size, and, unless the caller
#: gives its own time limit (``gsverse-validate --timeout``), ``USD_CHILD_SECONDS_BASE`` (60 s)
#: plus ``USD_CHILD_SECONDS_PER_MIB`` (1 s) per MiB of file: some corrupt ``.usdc`` files of
#: a few kilobytes make the USD library loop for minutes and allocate gigabytes.
USD_CHILD_MEMORY_BASE = 4 * 2 ** 30
USD_CHILD_SECONDS_BASE = 60.0
USD_CHILD_SECONDS_PER_MIB = 1.0


def usd_child_seconds(file_bytes: int) -> float:
    """The default time limit of the USD child process for a file of ``file_bytes``."""
    return USD_CHILD_SECONDS_BASE + USD_CHILD_SECONDS_PER_MIB * file_bytes / 2 ** 20
