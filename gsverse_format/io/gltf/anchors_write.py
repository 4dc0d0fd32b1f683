"""The anchor extension object as the glTF writer stores it: the quantization and layout
choices (explicit or compact anchors), the anchors encoded for them, and their accessors.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from ...anchors_derive import degenerate_splats
from ...errors import UsageError
from ...model import (Anchoring, GamesAnchors, LocalAnchors, SplatAsset, SplatCloud,
                      SplatPrimitive, TriangleMesh, face_order)
from ...quaternion import unit_quaternions
from ...vocabulary import ANCHOR_ENCODINGS as VOCAB_ENCODINGS
from ...vocabulary import BYTE, FLOAT, SHORT, UNSIGNED_BYTE, UNSIGNED_INT, UNSIGNED_SHORT
from .buffer import BufferBuilder

__all__ = ["QUANTIZE_OPTIONS", "QUANTIZE_BITS", "ANCHOR_ENCODINGS", "EncodedAnchors",
           "check_quantize", "check_encoding", "encode_anchors", "sorted_for_counts",
           "compact_problem", "quantize_notes", "rest_pose_of", "index_type", "write_anchors"]

#: Component-type choices for ``quantize=``: property -> {option: (componentType, scale)}.
#: ``ROTATION`` is the rest pose's ``KHR_gaussian_splatting:ROTATION`` (the normalized types
#: that extension allows), quantized only where no stored anchor depends on it: plain
#: primitives and derived ``local`` anchors (compact). Explicit anchors fix the rest pose to
#: their remap (spec §Rest-pose consistency), which a quantized ``ROTATION`` would miss by a
#: quantization step. (``OPACITY``, SCALAR, gains nothing: glTF aligns every vertex attribute
#: element to 4 bytes, the size of a FLOAT.)
QUANTIZE_OPTIONS: dict[str, dict[str, tuple[int, float] | None]] = {
    "barycentrics": {"float": None, "unsigned_short": (UNSIGNED_SHORT, 65535.0),
                     "unsigned_byte": (UNSIGNED_BYTE, 255.0)},
    "localRotation": {"float": None, "short": (SHORT, 32767.0), "byte": (BYTE, 127.0)},
    "ROTATION": {"float": None, "short": (SHORT, 32767.0), "byte": (BYTE, 127.0)},
}
#: ``gsverse-convert --quantize BITS``: the ``quantize=`` choices of each bit depth.
QUANTIZE_BITS: dict[int, dict[str, str]] = {
    16: {"barycentrics": "unsigned_short", "localRotation": "short", "ROTATION": "short"},
    8: {"barycentrics": "unsigned_byte", "localRotation": "byte", "ROTATION": "byte"},
}
#: ``anchors=`` choices: the version 1.1 layout, or ``faceCounts`` + derived ``local`` anchors.
ANCHOR_ENCODINGS = VOCAB_ENCODINGS

def check_quantize(quantize: dict | None) -> dict[str, tuple[int, float] | None]:
    chosen: dict[str, tuple[int, float] | None] = {}
    for key, value in (quantize or {}).items():
        if key not in QUANTIZE_OPTIONS:
            raise UsageError(f"cannot quantize {key!r}; choose from {', '.join(QUANTIZE_OPTIONS)}")
        if value not in QUANTIZE_OPTIONS[key]:
            raise UsageError(f"quantize[{key!r}] must be one of "
                             f"{', '.join(QUANTIZE_OPTIONS[key])}, got {value!r}")
        chosen[key] = QUANTIZE_OPTIONS[key][value]
    return chosen


def check_encoding(anchors: str) -> bool:
    """True for ``compact`` anchors; :class:`UsageError` for an unknown encoding."""
    if anchors not in ANCHOR_ENCODINGS:
        raise UsageError(f"anchors must be one of {', '.join(ANCHOR_ENCODINGS)}, got {anchors!r}")
    return anchors == "compact"


@dataclass
class EncodedAnchors:
    """Anchor data as the writer stores them: normalized-integer codes for the quantized
    properties (None: stored as FLOAT), and ``anchors`` as a reader dequantizes them.
    ``counts`` (compact): splats per face, the splats grouped by face in face order;
    ``derived`` (compact ``local``): only the faces are stored, the rest is derived from the
    rest pose (spec §Derived `local` anchors)."""

    anchors: LocalAnchors | GamesAnchors
    barycentrics: tuple[np.ndarray, int] | None = None
    local_rotation: tuple[np.ndarray, int] | None = None
    counts: np.ndarray | None = None
    derived: bool = False


def _bary_in_unit_range(bary: np.ndarray) -> bool:
    return bool(np.all((bary >= 0.0) & (bary <= 1.0)))


def encode_anchors(anchors: LocalAnchors | GamesAnchors,
                    quant: dict[str, tuple[int, float] | None], *, faces: int = 0,
                    compact: bool = False) -> EncodedAnchors:
    """Quantize the anchors as ``quant`` asks; dequantize the codes as glTF 2.0 §3.11 says
    (``c / 255``, ``max(c / 127, -1)``, ...; quaternions renormalized, as readers do).
    ``compact`` anchors (sorted by face already) store ``faces`` counts, and ``local`` ones
    nothing else: derived anchors have no quantization error."""
    counts = None
    if compact:
        counts = np.bincount(anchors.face_index.astype(np.int64), minlength=faces)
        if isinstance(anchors, LocalAnchors):
            return EncodedAnchors(anchors, counts=counts, derived=True)
    out = EncodedAnchors(anchors, counts=counts)
    bary = anchors.barycentrics
    q = quant.get("barycentrics")
    if q is not None and _bary_in_unit_range(bary):
        ctype, top = q
        codes = np.round(bary.astype(np.float64) * top)
        out.barycentrics = (codes, ctype)
        bary = (codes.astype(np.float32) / np.float32(top)).astype(np.float32)
    if isinstance(anchors, LocalAnchors):
        rot = unit_quaternions(anchors.local_rotation)
        q = quant.get("localRotation")
        if q is not None:
            ctype, top = q
            codes = np.clip(np.round(rot.astype(np.float64) * top), -top, top)
            out.local_rotation = (codes, ctype)
            rot = unit_quaternions(np.maximum(codes / top, -1.0).astype(np.float32))
        out.anchors = LocalAnchors(anchors.face_index, bary, anchors.normal_offset, rot,
                                   anchors.local_scale, anchors.deformation)
    else:
        out.anchors = GamesAnchors(anchors.face_index, bary, anchors.rho)
    return out


def sorted_for_counts(prim: SplatPrimitive, i: int) -> tuple[SplatCloud, Anchoring]:
    """The splats and anchors of ``prim`` grouped by face in face order (stable), as
    ``faceCounts`` stores them; :class:`UsageError` where ``local`` anchors could not be
    derived back (splats on faces degenerate at rest)."""
    anchoring = prim.anchoring
    assert anchoring is not None
    anchors, c = anchoring.anchors, prim.splats
    face = anchors.face_index.astype(np.int64)
    if face.size > 1 and bool(np.any(face[1:] < face[:-1])):
        order = face_order(face)
        c = c.subset(order)
        anchors = anchors.subset(order)
    problem = _compact_problem(Anchoring(anchoring.mesh, anchors))
    if problem is not None:
        raise UsageError(f"primitive {i}: {problem}: write explicit anchors")
    return c, Anchoring(anchoring.mesh, anchors)


def _compact_problem(anchoring: Anchoring) -> str | None:
    """Why ``anchoring`` cannot be stored compactly, or None: derived ``local`` anchors need
    every splat on a face regular at rest; ``games`` ones only gain ``faceCounts``."""
    a = anchoring.anchors
    if not isinstance(a, LocalAnchors):
        return None
    bad = degenerate_splats(anchoring.mesh, a.face_index)
    return None if not len(bad) else (
        f"{len(bad)} splat(s) are bound to triangles degenerate at rest (face "
        f"{int(a.face_index[bad[0]])}); compact anchors cannot derive them")


def compact_problem(asset: SplatAsset) -> str | None:
    """Why ``asset`` cannot be written with ``anchors="compact"`` (one line, the first
    primitive that cannot), or None; the rule :func:`asset_to_gltf` refuses by."""
    problems = (f"primitive {i}: {p}" for i, prim in enumerate(asset.primitives)
                if prim.anchoring is not None and (p := _compact_problem(prim.anchoring)))
    return next(problems, None)


def quantize_notes(asset: SplatAsset, quantize: dict | None,
                   anchors: str = "explicit") -> list[str]:
    """What ``quantize`` leaves as FLOAT when ``asset`` is written (one line each): explicit
    barycentrics outside [0, 1], which no normalized unsigned type holds."""
    quant = check_quantize(quantize)
    if quant.get("barycentrics") is None:
        return []
    compact = check_encoding(anchors)
    notes = []
    for i, prim in enumerate(asset.primitives):
        a = prim.anchoring
        if a is None or (compact and isinstance(a.anchors, LocalAnchors)):
            continue
        bary = a.anchors.barycentrics
        if not _bary_in_unit_range(bary):
            outside = int(np.count_nonzero(np.any((bary < 0.0) | (bary > 1.0), axis=1)))
            notes.append(f"primitive {i}: barycentrics stay FLOAT: {outside} of {len(bary)} "
                         f"splats have barycentrics outside [0, 1] (--anchors compact stores "
                         f"none for the local profile)")
    return notes


def rest_pose_of(c: SplatCloud, mesh: TriangleMesh, encoded: EncodedAnchors) -> SplatCloud:
    """The splats with the rest pose remapped from the anchors as stored (spec §Rest-pose
    consistency), for quantized anchors; otherwise (derived anchors included: they come from
    the rest pose) the splats unchanged."""
    if encoded.barycentrics is None and encoded.local_rotation is None:
        return c
    from ...remapping.reference import remap

    rest = remap(Anchoring(mesh, encoded.anchors))
    return SplatCloud(rest.means.astype(np.float32), rest.rotations.astype(np.float32),
                      rest.scales.astype(np.float32), c.opacities, c.sh, c.color_space,
                      dict(c.extra))


def index_type(largest: int) -> int:
    """The smallest unsigned component type holding ``largest``."""
    return UNSIGNED_BYTE if largest < 256 else UNSIGNED_SHORT if largest < 65536 else UNSIGNED_INT


def write_anchors(b: BufferBuilder, faces: int, encoded: EncodedAnchors,
                   splats: SplatCloud, mesh_index: int, scale_accessor: int) -> dict[str, Any]:
    anchors = encoded.anchors
    obj: dict[str, Any] = {"mesh": mesh_index, "primitive": 0, "profile": anchors.profile}
    if isinstance(anchors, LocalAnchors):
        obj["deformation"] = anchors.deformation
    if encoded.counts is not None:
        largest = int(encoded.counts.max()) if encoded.counts.size else 0
        obj["faceCounts"] = b.add(encoded.counts, index_type(largest), "SCALAR")
    else:
        obj["faceIndex"] = b.add(anchors.face_index, index_type(max(faces - 1, 0)), "SCALAR")
    if encoded.derived:
        return obj
    if encoded.barycentrics is not None:
        codes, ctype = encoded.barycentrics
        obj["barycentrics"] = b.add(codes, ctype, "VEC2", normalized=True)
    else:
        obj["barycentrics"] = b.add(anchors.barycentrics, FLOAT, "VEC2")
    if isinstance(anchors, LocalAnchors):
        obj["normalOffset"] = b.add(anchors.normal_offset, FLOAT, "SCALAR")
        if encoded.local_rotation is not None:
            codes, ctype = encoded.local_rotation
            obj["localRotation"] = b.add(codes, ctype, "VEC4", normalized=True)
        else:
            obj["localRotation"] = b.add(anchors.local_rotation, FLOAT, "VEC4")
        if np.array_equal(anchors.local_scale, splats.scales):
            obj["localScale"] = scale_accessor
        else:
            obj["localScale"] = b.add(anchors.local_scale, FLOAT, "VEC3")
    else:
        obj["rho"] = b.add(anchors.rho, FLOAT, "SCALAR")
    return obj
