"""Cases of the SPZ-compressed rest pose (``KHR_gaussian_splatting_compression_spz_2``, spec
§SPZ-compressed rest pose; tag ``encoding:spz``).

* ``local-*-spz*``: compact ``local`` assets (``faceCounts``, derived anchors) whose rest pose
  is one SPZ stream, for both laws and SH degrees 0 to 3. Their expected outputs are the remap
  of the *decoded* rest pose (the usual tolerances); the case also ships the remap of the
  *uncompressed* rest pose and, per pose and splat, the bound the spec states for the distance
  between the two (``‖M_f‖₂ |Δμ|``, ``‖M_f‖₂² ‖ΔΣ‖_F``; :mod:`.spz_export`), which ``check``
  tests as a second comparison;
* ``invalid-spz-*``: compressed assets a reader must refuse (a truncated gzip member, a count
  or SH degree that differs from the placeholders, a bad ``bufferView``, SPZ version 4, extension
  records, a stream inflating past what the splats need). Stored anchors on a compressed
  primitive are not among them: writers MUST NOT write them and validators report them
  (``SPZ_EXPLICIT_ANCHORS``), but a reader can remap them, as it remaps any asset whose rest
  pose is off its anchors.

A reader that skips the frame change, or derives the anchors from values other than the decoded
float32 rest pose, fails the remap cases (``tests/test_conformance_spz.py``).
"""
from __future__ import annotations

import gzip
import struct
from typing import Any, Callable

import numpy as np

from .case_tools import (Pose, RemapCase, bend, case_rng, faces_from_counts, law_tags,
                         make_anchors, make_case, random_barycentrics, rest_pose, stretch,
                         tube_mesh, twist)
from .glb import anchored_primitive
from .invalid_cases import InvalidCase

__all__ = ["spz_cases", "spz_invalid_cases", "SPZ", "TAG"]

SPZ = "KHR_gaussian_splatting_compression_spz_2"
TAG = "encoding:spz"


def _poses(mesh) -> list[Pose]:
    v = mesh.vertices.astype(np.float64)
    c = (0.0, 0.0, 0.0)
    return [rest_pose(mesh),
            Pose("twist 70", twist(v, 70, c, 0.0, 1.0), {"kind": "analytic", "name": "twist"}),
            Pose("bend 90 + stretch", stretch(bend(v, 90, c, 0.0, 1.0), (1.4, 0.8, 1.1), c),
                 {"kind": "analytic", "name": "bend+stretch"})]


def spz_cases() -> list[RemapCase]:
    """The compressed remap cases, in suite order."""
    out = []
    shapes: tuple[tuple[str, int, dict[str, Any]], ...] = (
        ("affine", 1, {}), ("rigid", 3, {}),
        ("affine", 0, {"rings": 3, "segments": 6, "radius": 0.6, "height": 2.5}),
        ("rigid", 2, {"rings": 4, "segments": 5, "radius": 0.15}))
    for law, degree, shape in shapes:
        cid = f"local-{law}-spz-sh{degree}"
        rng = case_rng(cid)
        mesh = tube_mesh(**shape)
        face = faces_from_counts(rng.integers(0, 5, mesh.face_count))
        bary = random_barycentrics(rng, len(face)) * 1.2 - 0.05
        anchors = make_anchors("local", law, mesh, face, bary, rng)
        out.append(make_case(cid, f"local profile, {law} law, SH degree {degree}: compact "
                             f"anchors derived from a rest pose stored as an SPZ stream; decode "
                             f"(frame change included), round to float32, then derive.",
                             law_tags("local", law) + ["encoding:derived", TAG], mesh, anchors,
                             _poses(mesh), rng, degree, encoding="compact", compress="spz"))
    return out


# --------------------------------------------------------------------------- invalid cases

def _stream(doc: dict, blob: bytes) -> bytes:
    view = doc["bufferViews"][_ext(doc)["bufferView"]]
    start = view.get("byteOffset", 0)
    return bytes(blob[start:start + view["byteLength"]])


def _ext(doc: dict) -> dict:
    return anchored_primitive(doc)["extensions"]["KHR_gaussian_splatting"]["extensions"][SPZ]


def _restream(edit: Callable[[bytes], bytes], inflated: bool = True):
    """A mutation replacing the stream by ``edit`` of it (of its inflated content, gzipped
    again, when ``inflated``), in a buffer view of its own."""
    def mutate(doc, blob):
        raw = _stream(doc, blob)
        new = gzip.compress(edit(gzip.decompress(raw)), mtime=0) if inflated else edit(raw)
        blob = bytes(blob) + b"\0" * (-len(blob) % 4)
        doc["bufferViews"].append({"buffer": 0, "byteOffset": len(blob), "byteLength": len(new)})
        blob += new + b"\0" * (-len(new) % 4)
        doc["buffers"][0]["byteLength"] = len(blob)
        _ext(doc)["bufferView"] = len(doc["bufferViews"]) - 1
        return doc, blob
    return mutate


def _header(offset: int, fmt: str, value) -> Callable[[bytes], bytes]:
    def edit(data: bytes) -> bytes:
        out = bytearray(data)
        struct.pack_into(fmt, out, offset, value)
        return bytes(out)
    return edit


def _m_view(doc, blob):
    _ext(doc)["bufferView"] = len(doc["bufferViews"]) + 3
    return doc, blob


def _m_bomb(doc, blob):
    # the declared splats need at most 16 + 65 N bytes; this inflates to 4 MiB
    return _restream(lambda raw: gzip.compress(b"NGSP" + b"\0" * (4 << 20), mtime=0),
                     inflated=False)(doc, blob)


def spz_invalid_cases() -> list[InvalidCase]:
    """Compressed assets a plugin must refuse (base ``local-spz``: compact, compressed)."""
    spec = "spec/README.md §SPZ-compressed rest pose"
    refuse = "readers MUST refuse"
    rows = [
        ("truncated", "The gzip member lacks its last 9 bytes (no end, no trailer).",
         f"{spec}: the buffer view holds one gzip member; {refuse} a broken or truncated "
         f"stream", _restream(lambda raw: raw[:-9], inflated=False), "SPZ_STREAM_INVALID"),
        ("count-mismatch", "The stream's header counts one splat fewer than the "
         "placeholders.", f"{spec}: {refuse} a compressed primitive where any placeholder "
         f"count differs from the stream's splat count",
         _restream(lambda d: _header(8, "<I", struct.unpack_from("<I", d, 8)[0] - 1)(d)),
         "SPZ_COUNT_MISMATCH"),
        ("sh-mismatch", "The stream's header says SH degree 1; the primitive has the SH "
         "attribute of degree 0 only.", f"{spec}: {refuse} SH attributes that are not exactly "
         f"degrees 0 to the stream's SH degree", _restream(_header(12, "<B", 1)),
         "SPZ_SH_MISMATCH"),
        ("buffer-view", "The extension's bufferView is past the end of bufferViews.",
         f"{spec}: the object's bufferView is the index of the view holding the stream",
         _m_view, "SPZ_BUFFER_VIEW_INVALID"),
        ("version-4", "The stream's header says SPZ version 4.", f"{spec}: version 4 MUST "
         f"be refused", _restream(_header(4, "<I", 4)), "SPZ_STREAM_INVALID"),
        ("extension-records", "The stream's flags set bit 1 (extension records).",
         f"{spec}: streams with extension records (flag bit 1) MUST be refused",
         _restream(_header(14, "<B", 2)), "SPZ_STREAM_INVALID"),
        ("inflation-bound", "The gzip member inflates to 4 MiB, far more than the declared "
         "splats can need.", f"{spec}: {refuse} a stream that inflates to more bytes than the "
         f"declared count needs, and stop inflating there", _m_bomb, "SPZ_STREAM_INVALID"),
    ]
    return [InvalidCase(f"invalid-spz-{name}", text, rule, "local-spz", mutate, code, [TAG])
            for name, text, rule, mutate, code in rows]
