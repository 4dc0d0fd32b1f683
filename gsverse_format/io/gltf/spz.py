"""``KHR_gaussian_splatting_compression_spz_2``: a splat primitive's rest pose as one SPZ stream.

spec/README.md §SPZ-compressed rest pose. The attributes keep placeholder accessors (type,
component type and count, no ``bufferView``); the extension object ``{"bufferView": v}``, nested
in the ``KHR_gaussian_splatting`` object, points at one gzip member holding an SPZ stream of
version 2 or 3 (:mod:`gsverse_format.io.spz_stream`). The stream's coordinates are SPZ's RUB
frame; glTF's is LUF, 180° about Y: x and z of positions and quaternions change sign, and SH
coefficient ``k`` is multiplied by :data:`SH_SIGNS` ``[k]``.

Writing (:func:`compress`) encodes the splats, decodes them back, and hands the writer the
decoded float32 splats, from which it writes and derives everything, so that what every reader
decodes and derives is what the writer checked.
"""
from __future__ import annotations

import math
from typing import Any

import numpy as np

from ...codes import Code
from ...errors import FormatError
from ...limits import MAX_SPZ_AMPLIFICATION, READ_AMPLIFICATION_SLACK
from ...model import SplatCloud
from ...vocabulary import FLOAT, KHR, SPZ_EXTENSION, UNSIGNED_BYTE
from .. import spz_stream
from ..spz_stream import SpzArrays
from .accessors import Accessors
from .attributes import OPACITY, ROTATION, SCALE, sh_attribute
from .buffer import BufferBuilder
from .container import as_index, gltf_error, pointer_token

__all__ = ["SPZ_EXTENSION", "SH_SIGNS", "AXIS_SIGNS", "compress", "write_placeholders",
           "decode_primitive", "is_compressed", "stream_limit", "decoded_bytes",
           "placeholder_count"]

#: Signs taking positions and quaternion (x, y, z) between SPZ's RUB frame and glTF's (both
#: ways: the rotation is its own inverse).
AXIS_SIGNS = np.array([-1.0, 1.0, -1.0])
#: The sign of each SH coefficient k = 0 .. 15 under the same rotation (180° about Y).
SH_SIGNS = np.array([1, 1, -1, -1, -1, -1, 1, 1, 1, 1, 1, 1, -1, -1, -1, -1], np.float64)


def is_compressed(khr: Any) -> bool:
    """True when the ``KHR_gaussian_splatting`` object ``khr`` nests the SPZ extension."""
    nested = khr.get("extensions") if isinstance(khr, dict) else None
    return isinstance(nested, dict) and SPZ_EXTENSION in nested


def _turn(means: np.ndarray, xyzw: np.ndarray, sh: np.ndarray) -> tuple[np.ndarray, ...]:
    """RUB <-> glTF (float64)."""
    q = np.array(xyzw, np.float64)
    q[:, :3] *= AXIS_SIGNS
    sh = np.asarray(sh)   # float32 stays float32: the signs are exact
    return (np.asarray(means, np.float64) * AXIS_SIGNS, q,
            sh * SH_SIGNS[:sh.shape[1], None].astype(sh.dtype))


def _from_stream(arrays: SpzArrays, color_space: str) -> SplatCloud:
    """Decoded stream values (RUB, float64) as the model's float32 splats in glTF's frame,
    rounded once; quaternions normalized."""
    means, q, sh = _turn(arrays.means, arrays.rotations, arrays.sh)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    return SplatCloud(means.astype(np.float32), q.astype(np.float32),
                      arrays.scales.astype(np.float32), arrays.opacities.astype(np.float32),
                      sh.astype(np.float32), color_space)


def compress(cloud: SplatCloud, *, level: int = 6) -> tuple[bytes, SplatCloud]:
    """The gzip member of ``cloud`` (glTF frame; zlib ``level``: 6, zlib's default, is within
    0.5 % of 9's size on splats at a third less time), the splats it decodes to (float32, glTF
    frame; what readers get). What encoding clamps is counted by the writer's
    ``compress_notes``."""
    means, q, sh = _turn(cloud.means, cloud.rotations, cloud.sh)
    arrays = SpzArrays(means, q, np.asarray(cloud.scales, np.float64),
                       np.asarray(cloud.opacities, np.float64), sh)
    payload = spz_stream.encode(arrays, level=level)
    data = spz_stream.inflate_bounded(payload, spz_stream.stream_bytes(3, len(cloud), 3),
                                      "SPZ stream")
    header = spz_stream.parse_header(data, "SPZ stream")
    parts, _ = spz_stream.split_stream(data, header, "SPZ stream")
    decoded = _from_stream(spz_stream.decode(header, parts), cloud.color_space)
    decoded.extra.update(cloud.extra)
    return payload, decoded


def write_placeholders(b: BufferBuilder, cloud: SplatCloud) -> dict[str, int]:
    """The placeholder accessors of the decoded splats ``cloud``: attribute -> accessor."""
    n = len(cloud)
    attrs = {"POSITION": b.placeholder(n, FLOAT, "VEC3", minmax=cloud.means),
             ROTATION: b.placeholder(n, FLOAT, "VEC4"), SCALE: b.placeholder(n, FLOAT, "VEC3"),
             OPACITY: b.placeholder(n, FLOAT, "SCALAR")}
    for k in range(cloud.sh.shape[1]):
        degree = math.isqrt(k)
        attrs[sh_attribute(degree, k - degree * degree)] = b.placeholder(n, FLOAT, "VEC3")
    attrs["COLOR_0"] = b.placeholder(n, UNSIGNED_BYTE, "VEC4", normalized=True)
    return attrs


def placeholder_count(r: Accessors, attrs: dict[str, Any], degree: int, where: str,
                      pointer: str) -> int:
    """The splat count of a compressed primitive's placeholders (``POSITION``'s), after
    checking that each attribute the stream supplies has the type the spec gives and that
    count (``SPZ_COUNT_MISMATCH``), and that SH degree 0 is present (``degree`` the highest
    complete degree of the attributes)."""
    apointer = f"{pointer}/attributes"
    expected: dict[str, tuple[str, ...]] = {
        "POSITION": ("VEC3",), ROTATION: ("VEC4",), SCALE: ("VEC3",), OPACITY: ("SCALAR",),
        "COLOR_0": ("VEC3", "VEC4")}
    expected.update({sh_attribute(level, n): ("VEC3",) for level in range(degree + 1)
                     for n in range(2 * level + 1)})
    counts: dict[str, int] = {}
    for name, gtypes in expected.items():
        if name not in attrs:
            continue
        i = as_index(attrs[name], len(r.accessors), f"{where} {name}: accessor",
                     f"{apointer}/{pointer_token(name)}")
        acc = r.accessors.item(i)
        if acc.get("type") not in gtypes:
            raise gltf_error(Code.KHR_ATTRIBUTE_FORMAT, f"{where} {name} (accessor {i}) has "
                             f"type {acc.get('type')!r}, not {' or '.join(gtypes)}",
                             f"/accessors/{i}/type")
        count = acc.get("count")
        counts[name] = count if isinstance(count, int) and not isinstance(count, bool) else -1
    if "POSITION" not in counts:
        raise gltf_error(Code.KHR_ATTRIBUTE_MISSING, f"{where}: required {KHR} attribute "
                         f"missing: POSITION", apointer)
    count = counts["POSITION"]
    wrong = next((n for n, c in counts.items() if c != count), None)
    if wrong is not None:
        raise gltf_error(Code.SPZ_COUNT_MISMATCH, f"{where}: {wrong} has {counts[wrong]} "
                         f"elements, POSITION has {count} (the placeholders of a compressed "
                         f"primitive must all have the stream's count)",
                         f"{apointer}/{pointer_token(wrong)}")
    if degree < 0:
        raise gltf_error(Code.KHR_ATTRIBUTE_MISSING, f"{where}: required {KHR} attribute "
                         f"missing: {sh_attribute(0, 0)}", apointer)
    return count


def decoded_bytes(count: int, degree: int) -> int:
    """Bytes of the float32 attributes (and the 4-byte ``COLOR_0``) ``count`` splats of SH
    degree ``degree`` decode to."""
    return count * (4 * (3 + 4 + 3 + 1 + 3 * (degree + 1) ** 2) + 4)


def stream_limit(count: int) -> int:
    """The most bytes the stream of ``count`` splats may inflate to (version 3, SH degree 3:
    the longest a stream of that many splats is); inflation stops there."""
    return spz_stream.stream_bytes(3, count, 3)


def decode_primitive(r: Accessors, khr: dict, attrs: dict[str, Any], count: int, degree: int,
                     color_space: str, where: str, pointer: str) -> SplatCloud:
    """The rest pose stored in the SPZ stream of the primitive at ``pointer`` (its
    ``KHR_gaussian_splatting`` object ``khr``): ``count`` splats (the placeholders' count,
    already checked equal) of SH degree ``degree`` (the attributes present)."""
    obj = khr["extensions"][SPZ_EXTENSION]
    epointer = f"{pointer}/extensions/{KHR}/extensions/{pointer_token(SPZ_EXTENSION)}"
    what = f"{where} {SPZ_EXTENSION}"
    if not isinstance(obj, dict) or "bufferView" not in obj:
        raise gltf_error(Code.SPZ_BUFFER_VIEW_INVALID, f"{what} must be an object with a "
                         f"bufferView", epointer)
    try:
        v = as_index(obj["bufferView"], len(r.views), f"{what}.bufferView",
                     f"{epointer}/bufferView")
    except FormatError as err:
        raise gltf_error(Code.SPZ_BUFFER_VIEW_INVALID, err.cause, f"{epointer}/bufferView") \
            from None
    b, offset, length = r.view_bounds(v)
    limit = stream_limit(count)
    decoded = decoded_bytes(count, degree)
    if decoded > MAX_SPZ_AMPLIFICATION * length + READ_AMPLIFICATION_SLACK:
        raise gltf_error(Code.SIZE_LIMIT_EXCEEDED, f"{what}: {count} splats would decode to "
                         f"{decoded} bytes, more than {MAX_SPZ_AMPLIFICATION} times the "
                         f"{length} bytes of their stream", epointer)
    raw = r.buffer(b)[offset:offset + length]
    where_stream = f"{what} (bufferViews[{v}])"
    try:
        data = spz_stream.inflate_bounded(raw, limit, where_stream)
        header = spz_stream.parse_header(data, where_stream)
    except FormatError as err:
        raise gltf_error(Code.SPZ_STREAM_INVALID, f"{where_stream}: {err.cause}",
                         f"{epointer}/bufferView") from None
    if header.count != count:
        raise gltf_error(Code.SPZ_COUNT_MISMATCH, f"{where_stream} holds {header.count} splats "
                         f"but the primitive's accessors have {count}", f"{pointer}/attributes")
    if header.degree != degree:
        raise gltf_error(Code.SPZ_SH_MISMATCH, f"{where_stream} has SH degree {header.degree} "
                         f"but the primitive's SH attributes are of degree {degree}",
                         f"{pointer}/attributes")
    if header.flags & 2:
        raise gltf_error(Code.SPZ_STREAM_INVALID, f"{where_stream} carries SPZ extension records "
                         f"(flag bit 1), which the glTF extension does not allow",
                         f"{epointer}/bufferView")
    need = spz_stream.stream_bytes(header.version, count, degree)
    if len(data) != need:
        raise gltf_error(Code.SPZ_STREAM_INVALID, f"{where_stream} inflates to {len(data)} "
                         f"bytes; {count} splats of SH degree {degree} in version "
                         f"{header.version} take {need}", f"{epointer}/bufferView")
    parts, _ = spz_stream.split_stream(data, header, where_stream)
    return _from_stream(spz_stream.decode(header, parts), color_space)
