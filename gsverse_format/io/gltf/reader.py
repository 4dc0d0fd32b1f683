"""Reading splats: ``KHR_gaussian_splatting`` primitives and the anchor extension.

Every ``KHR_gaussian_splatting`` ``POINTS`` primitive of the file becomes a
:class:`SplatPrimitive`; one carrying ``GSVERSE_gaussian_splatting_mesh_anchor`` (nested in the
``KHR_gaussian_splatting`` extension object) gets its :class:`Anchoring`, with the properties
each profile requires and the accessor formats it allows taken from
:mod:`gsverse_format.vocabulary`. Primitives referencing the same anchor primitive share one
:class:`TriangleMesh`. Problems are :class:`~.container.GltfFormatError` with their issue code.
"""
from __future__ import annotations

import copy
import math
import os
import re
from contextlib import contextmanager
from typing import Any, Iterator

import numpy as np

from ...codes import Code
from ...errors import FormatError, GsverseError
from ...model import (Anchoring, GamesAnchors, KhrProperties, LocalAnchors, SplatAsset,
                      SplatCloud, SplatPrimitive, TriangleMesh)
from ...anchors_derive import degenerate_splats, derive_local
from ...frames import local_frames
from ...vocabulary import recorded_frame
from ...vocabulary import (DERIVED_KEYS, DEFORMATIONS, EXTENSION, FACE_COUNTS, FIELDS_BY_KEY,
                           FLOAT, KHR, PROFILES, SH_C0, SPZ_EXTENSION, UNSIGNED_BYTE,
                           UNSIGNED_SHORT, gltf_required_keys)
from .accessors import Accessors
from .attributes import OPACITY, POINTS, ROTATION, SCALE, TRIANGLES, sh_attribute
from .container import DEFAULT_MAX_BYTES, GltfFormatError, as_index, gltf_error, pointer_token
from .physics import read_physics
from .spz import decode_primitive as decode_compressed, is_compressed, placeholder_count
from .document import Document, open_document

__all__ = ["ROTATION", "SCALE", "OPACITY", "sh_attribute", "POINTS", "TRIANGLES",
           "sh_degree_of", "SplatReader", "read_document", "read_gltf", "as_format_error"]

_SH_RE = re.compile(rf"^{KHR}:SH_DEGREE_(\d+)_COEF_(\d+)$")


def _linear_to_srgb(c: np.ndarray) -> np.ndarray:
    """IEC 61966-2-1 sRGB encoding of values in [0, 1]."""
    c = np.clip(c, 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * c ** (1 / 2.4) - 0.055)


def sh_degree_of(attrs: dict[str, Any], where: str, pointer: str) -> int:
    """Highest complete SH degree (−1 if there is no SH at all)."""
    present: set[tuple[int, int]] = set()
    for name in attrs:
        m = _SH_RE.match(name)
        if m:
            degree, coef = int(m.group(1)), int(m.group(2))
            if degree > 3:
                raise gltf_error(Code.KHR_UNKNOWN_SEMANTIC, f"{where}: SH degree {degree} is "
                                 f"not supported (0..3)", f"{pointer}/{pointer_token(name)}")
            if coef > 2 * degree:
                raise gltf_error(Code.KHR_UNKNOWN_SEMANTIC, f"{where}: attribute {name} does not "
                                 f"exist in degree {degree}", f"{pointer}/{pointer_token(name)}")
            present.add((degree, coef))
    degree = -1
    for level in range(4):
        have = [(level, n) in present for n in range(2 * level + 1)]
        if all(have):
            if degree != level - 1:
                raise gltf_error(Code.KHR_SH_INCOMPLETE, f"{where}: SH degree {level} is present "
                                 f"but degree {level - 1} is missing", pointer)
            degree = level
        elif any(have):
            missing = [n for n in range(2 * level + 1) if not have[n]]
            raise gltf_error(Code.KHR_SH_INCOMPLETE, f"{where}: SH degree {level} is partially "
                             f"defined (missing COEF_{', COEF_'.join(map(str, missing))})", pointer)
    return degree


def _khr_properties(khr: dict, where: str, pointer: str, required: list,
                    attrs: dict) -> KhrProperties:
    """``kernel``, ``projection``, ``sortingMethod`` (open enumerations: any string is kept;
    an absent optional one is its default, an absent ``kernel`` the base ``ellipse``) and the
    nested extensions other than the anchor extension, copied as JSON. A nested extension the
    asset lists in ``extensionsRequired`` has no fallback: the data cannot be read without
    it, and the file is refused."""
    values: dict[str, str] = {}
    for key, default in (("kernel", "ellipse"), ("projection", "perspective"),
                         ("sortingMethod", "cameraDistance")):
        value = khr.get(key, default)
        if not isinstance(value, str):
            raise gltf_error(Code.KHR_PROPERTY_INVALID, f"{where}: {KHR}.{key} must be a "
                             f"string, got {value!r}", f"{pointer}/{key}")
        values[key] = value
    nested = khr.get("extensions") or {}
    others = {name: copy.deepcopy(obj) for name, obj in nested.items()
              if name not in (EXTENSION, SPZ_EXTENSION)}
    for name in others:
        if name in required:
            raise gltf_error(Code.UNSUPPORTED_REQUIRED_EXTENSION, f"{where}: the nested "
                             f"extension {name} is in extensionsRequired and is not supported",
                             f"{pointer}/extensions/{pointer_token(name)}")
    own = tuple(sorted(a for a in attrs if isinstance(a, str) and a.split(":")[0] in others))
    return KhrProperties(values["kernel"], values["projection"], values["sortingMethod"], others,
                         own)


def _faces_from_counts(counts: np.ndarray, faces: int, splats: int, what: str,
                       pointer: str) -> np.ndarray:
    """Face index per splat from per-face splat counts (spec §Properties, ``faceCounts``):
    ``counts`` must hold one count per triangle and sum (in 64-bit integers) to ``splats``."""
    if len(counts) != faces:
        raise gltf_error(Code.ANCHOR_FACE_COUNTS_COUNT, f"{what} has {len(counts)} elements but "
                         f"the anchor mesh has {faces} triangles (one count per triangle)",
                         pointer)
    total = int(counts.astype(np.int64).sum())
    if total != splats:
        raise gltf_error(Code.ANCHOR_FACE_COUNTS_SUM, f"{what} sums to {total} but the "
                         f"primitive has {splats} splats", pointer)
    return np.repeat(np.arange(faces, dtype=np.uint32), counts.astype(np.int64))


def _derived_anchors(mesh: TriangleMesh, face: np.ndarray, rest: SplatCloud, deformation: str,
                     where: str, pointer: str) -> LocalAnchors:
    """``local`` anchors derived from the rest pose (spec §Derived `local` anchors)."""
    frames = local_frames(mesh.triangles())
    bad = degenerate_splats(mesh, face, frames)
    if bad.size:
        raise gltf_error(Code.ANCHOR_DERIVED_ON_DEGENERATE, f"{where}: {bad.size} splat(s) "
                         f"without barycentrics lie on triangles degenerate at rest (splat "
                         f"{int(bad[0])}, face {int(face[bad[0]])}); their anchors cannot be "
                         f"derived", pointer)
    # used exactly as stored anchors: the rules on localRotation and localScale apply
    zero = np.flatnonzero(~np.any(rest.rotations != 0, axis=1))
    if zero.size:
        raise gltf_error(Code.ROTATION_NOT_UNIT, f"{where}: the rest ROTATION of {zero.size} "
                         f"splat(s) without stored anchors is zero (splat {int(zero[0])}); "
                         f"their derived localRotation has no rotation", pointer)
    negative = np.flatnonzero(np.any(rest.scales < 0, axis=1))
    if negative.size:
        raise gltf_error(Code.SCALE_NEGATIVE, f"{where}: the rest SCALE of {negative.size} "
                         f"splat(s) without stored anchors is negative (splat "
                         f"{int(negative[0])}); derived local scales must be >= 0", pointer)
    derived = derive_local(mesh, face, rest.means, rest.rotations, frames=frames)
    return LocalAnchors(face, derived.barycentrics, derived.normal_offset,
                        derived.local_rotation, rest.scales, deformation)  # type: ignore[arg-type]


class SplatReader:
    """Reads the splat primitives, their anchoring and anchor meshes of one document."""

    def __init__(self, document: Document) -> None:
        self.document = document
        self.r: Accessors = document.reader
        self.meshes: list[dict] = document.doc.get("meshes", [])
        self.nodes: list[dict] = document.doc.get("nodes", [])
        self._triangles: dict[tuple[int, int], TriangleMesh] = {}

    def primitive(self, m: int, p: int) -> dict:
        """The raw JSON of primitive ``p`` of mesh ``m`` (both indices already checked)."""
        return self.meshes[m].get("primitives", [])[p]

    def triangles(self, m: int, p: int) -> TriangleMesh:
        """The TRIANGLES primitive ``p`` of mesh ``m`` (an anchor mesh), read once."""
        key = (m, p)
        if key in self._triangles:
            return self._triangles[key]
        where = f"anchor mesh meshes[{m}].primitives[{p}]"
        pointer = f"/meshes/{m}/primitives/{p}"
        prim = self.primitive(m, p)
        mode = prim.get("mode", TRIANGLES)
        if mode != TRIANGLES:
            raise gltf_error(Code.ANCHOR_MESH_NOT_TRIANGLES, f"{where} has mode {mode!r}; anchor "
                             f"primitives must be TRIANGLES (4)", f"{pointer}/mode")
        attrs = prim.get("attributes", {})
        if "POSITION" not in attrs:
            raise gltf_error(Code.ANCHOR_MESH_POSITION_INVALID,
                             f"{where} has no POSITION attribute", f"{pointer}/attributes")
        vertices = self.r.floats(attrs["POSITION"], f"{where} POSITION", ("VEC3",),
                                 allowed=[(FLOAT, False)], code=Code.ANCHOR_MESH_POSITION_INVALID)
        bad_indices = Code.ANCHOR_MESH_INDICES_INVALID
        if prim.get("indices") is not None:
            idx = self.r.integers(prim["indices"], f"{where} indices", code=bad_indices)
            if len(idx) % 3:
                raise gltf_error(bad_indices, f"{where} has {len(idx)} indices, not a multiple "
                                 f"of 3", f"{pointer}/indices")
            if idx.size and int(idx.max()) >= len(vertices):
                raise gltf_error(bad_indices, f"{where}: index {int(idx.max())} out of range for "
                                 f"{len(vertices)} vertices", f"{pointer}/indices")
            faces = idx.reshape(-1, 3)
        else:
            if len(vertices) % 3:
                raise gltf_error(bad_indices, f"{where} is not indexed and has {len(vertices)} "
                                 f"vertices, not a multiple of 3", f"{pointer}/attributes/POSITION")
            faces = np.arange(len(vertices), dtype=np.uint32).reshape(-1, 3)
        mesh = TriangleMesh(vertices, faces)
        self._triangles[key] = mesh
        return mesh

    def anchoring(self, obj: Any, rest: SplatCloud, where: str, pointer: str) -> Anchoring:
        """The anchoring of the splat primitive with rest pose ``rest`` from its anchor
        extension object ``obj`` (found at ``pointer``): explicit anchors, or (version 1.2)
        face indices from ``faceCounts`` and ``local`` anchors derived from the rest pose."""
        count = len(rest)
        where = f"{where} {EXTENSION}"
        if not isinstance(obj, dict):
            raise gltf_error(Code.ANCHOR_SCHEMA_VIOLATION, f"{where} must be an object", pointer)
        m = as_index(obj.get("mesh"), len(self.meshes), f"{where}.mesh", f"{pointer}/mesh")
        prims = self.meshes[m].get("primitives", [])
        p = as_index(obj.get("primitive", 0), len(prims), f"{where}.primitive",
                     f"{pointer}/primitive")
        mesh = self.triangles(m, p)
        instances = [n for n, node in enumerate(self.nodes) if node.get("mesh") == m]
        if len(instances) > 1:
            raise gltf_error(Code.ANCHOR_MESH_MULTIPLE_INSTANCES, f"{where}: the anchor mesh {m} "
                             f"is instantiated by {len(instances)} nodes "
                             f"({', '.join(map(str, instances))}); at most one may instantiate "
                             f"it (which instance deforms the splats is ambiguous)",
                             f"/nodes/{instances[1]}/mesh")
        profile = obj.get("profile")
        if profile not in PROFILES:
            raise gltf_error(Code.ANCHOR_SCHEMA_VIOLATION, f"{where}.profile must be 'local' or "
                             f"'games', got {profile!r}", f"{pointer}/profile")
        counts_key = FACE_COUNTS.key
        if ("faceIndex" in obj) == (counts_key in obj):
            raise gltf_error(Code.ANCHOR_SCHEMA_VIOLATION, f"{where} must have exactly one of "
                             f"faceIndex and {counts_key}, not "
                             f"{'both' if 'faceIndex' in obj else 'neither'}", pointer)
        derived = profile == "local" and "barycentrics" not in obj
        if derived:
            present = [k for k in DERIVED_KEYS if k in obj]
            if present:
                raise gltf_error(Code.ANCHOR_SCHEMA_VIOLATION, f"{where}: without barycentrics "
                                 f"(derived local anchors) {', '.join(present)} must be absent",
                                 f"{pointer}/{present[0]}")
        required = gltf_required_keys(profile, counts=counts_key in obj, derived=derived)
        missing = [key for key in required if key not in obj]
        if missing:
            raise gltf_error(Code.ANCHOR_SCHEMA_VIOLATION,
                             f"{where} ({profile} profile) lacks {', '.join(missing)}", pointer)
        r = self.r

        def checked(key: str, values: np.ndarray) -> np.ndarray:
            if len(values) != count:
                raise gltf_error(Code.ANCHOR_ACCESSOR_COUNT, f"{where}.{key} has {len(values)} "
                                 f"elements but the primitive has {count} splats (accessor "
                                 f"count mismatch)", f"{pointer}/{key}")
            return values

        def floats(key: str, **kw: Any) -> np.ndarray:
            field = FIELDS_BY_KEY[key]
            return checked(key, r.floats(obj[key], f"{where}.{key}", (field.accessor,),
                                         field.formats, code=Code.ANCHOR_ACCESSOR_FORMAT, **kw))

        if counts_key in obj:
            face = _faces_from_counts(r.integers(obj[counts_key], f"{where}.{counts_key}",
                                                 code=Code.ANCHOR_ACCESSOR_FORMAT),
                                      mesh.face_count, count, f"{where}.{counts_key}",
                                      f"{pointer}/{counts_key}")
        else:
            face = checked("faceIndex", r.integers(obj["faceIndex"], f"{where}.faceIndex",
                                                   code=Code.ANCHOR_ACCESSOR_FORMAT))
        if face.size and int(face.max()) >= mesh.face_count:
            raise gltf_error(Code.ANCHOR_FACE_OUT_OF_RANGE, f"{where}.faceIndex value "
                             f"{int(face.max())} out of range for an anchor mesh with "
                             f"{mesh.face_count} triangles", f"{pointer}/faceIndex")
        if profile == "games":
            bary = floats("barycentrics")
            if "deformation" in obj:
                raise gltf_error(Code.ANCHOR_SCHEMA_VIOLATION, f"{where}: 'deformation' must not "
                                 f"be present with the games profile", f"{pointer}/deformation")
            return Anchoring(mesh, GamesAnchors(face, bary, floats("rho")[:, 0]))
        deformation = obj.get("deformation", DEFORMATIONS[0])
        if deformation not in DEFORMATIONS:
            raise gltf_error(Code.ANCHOR_SCHEMA_VIOLATION, f"{where}.deformation must be "
                             f"'affine' or 'rigid', got {deformation!r}", f"{pointer}/deformation")
        if derived:
            face_key = counts_key if counts_key in obj else "faceIndex"
            return Anchoring(mesh, _derived_anchors(mesh, face, rest, deformation, where,
                                                    f"{pointer}/{face_key}"))
        bary = floats("barycentrics")
        offset = floats("normalOffset")
        _, ctype, _ = r.raw(obj["localRotation"], f"{where}.localRotation", ("VEC4",),
                            code=Code.ANCHOR_ACCESSOR_FORMAT)
        rotation = floats("localRotation", renormalize=ctype != FLOAT)
        scale = floats("localScale")
        zero = np.flatnonzero(~np.any(rotation != 0, axis=1))
        if zero.size:
            raise gltf_error(Code.ROTATION_NOT_UNIT, f"{where}.localRotation: {zero.size} zero "
                             f"quaternion(s) (splat {int(zero[0])}); a rotation must have "
                             f"non-zero length", f"{pointer}/localRotation")
        negative = np.flatnonzero(np.any(scale < 0, axis=1))
        if negative.size:
            raise gltf_error(Code.SCALE_NEGATIVE, f"{where}.localScale: {negative.size} splat(s) "
                             f"with a negative scale (splat {int(negative[0])}); scales are "
                             f"linear, >= 0", f"{pointer}/localScale")
        anchors = LocalAnchors(face, bary, offset[:, 0], rotation, scale, deformation)
        return Anchoring(mesh, anchors)

    def _stored_cloud(self, attrs: dict[str, int], color_space: str, where: str,
                      pointer: str) -> SplatCloud:
        """The rest pose of an uncompressed splat primitive, from its accessors."""
        r = self.r
        apointer = f"{pointer}/attributes"
        bad_format = Code.KHR_ATTRIBUTE_FORMAT
        means = r.floats(attrs["POSITION"], f"{where} POSITION", ("VEC3",), code=bad_format)
        count = len(means)

        def attr(name: str, gtypes: tuple[str, ...], **kw: Any) -> np.ndarray:
            values = r.floats(attrs[name], f"{where} {name}", gtypes, code=bad_format, **kw)
            if len(values) != count:
                raise gltf_error(Code.ATTRIBUTE_COUNT_MISMATCH, f"{where}: {name} has "
                                 f"{len(values)} elements, POSITION has {count} (accessor count "
                                 f"mismatch)", f"{apointer}/{pointer_token(name)}")
            return values

        _, rot_type, _ = r.raw(attrs[ROTATION], f"{where} {ROTATION}", ("VEC4",), code=bad_format)
        rotations = attr(ROTATION, ("VEC4",), renormalize=rot_type != FLOAT)
        scales = attr(SCALE, ("VEC3",))
        opacities = attr(OPACITY, ("SCALAR",))[:, 0]
        degree = sh_degree_of(attrs, where, apointer)
        sh: np.ndarray
        if degree >= 0:
            sh = np.empty((count, (degree + 1) ** 2, 3), np.float32)
            for k in range(sh.shape[1]):
                level = math.isqrt(k)
                sh[:, k] = attr(sh_attribute(level, k - level * level), ("VEC3",))
        elif "COLOR_0" in attrs:
            # No SH at all (not valid KHR_gaussian_splatting): rebuild the DC term from the
            # fallback colour so that the splats keep their colour.
            color = attr("COLOR_0", ("VEC3", "VEC4"), allowed=[
                (FLOAT, False), (UNSIGNED_BYTE, True), (UNSIGNED_SHORT, True)])
            rgb = np.clip(color[:, :3].astype(np.float64), 0.0, 1.0)
            if color_space == "srgb_rec709_display":
                rgb = _linear_to_srgb(rgb)
            sh = ((rgb - 0.5) / SH_C0)[:, None, :]
        else:
            raise gltf_error(Code.KHR_ATTRIBUTE_MISSING, f"{where}: required {KHR} attribute "
                             f"missing: {sh_attribute(0, 0)}", apointer)
        return SplatCloud(means, rotations, scales, opacities, sh, color_space)

    def _compressed_cloud(self, khr: dict, attrs: dict[str, int], color_space: str, where: str,
                          pointer: str) -> SplatCloud:
        """The rest pose of a primitive stored through ``KHR_gaussian_splatting_compression_
        spz_2``: the placeholder accessors' counts and types checked, then the stream decoded
        (spec §SPZ-compressed rest pose)."""
        degree = sh_degree_of(attrs, where, f"{pointer}/attributes")
        count = placeholder_count(self.r, attrs, degree, where, pointer)
        return decode_compressed(self.r, khr, attrs, count, degree, color_space, where, pointer)

    def splat_primitive(self, m: int, p: int, name: str | None) -> SplatPrimitive:
        """The splat primitive ``p`` of mesh ``m`` (a ``KHR_gaussian_splatting`` POINTS one)."""
        where = f"meshes[{m}].primitives[{p}]"
        pointer = f"/meshes/{m}/primitives/{p}"
        prim = self.primitive(m, p)
        khr = prim["extensions"][KHR]
        kpointer = f"{pointer}/extensions/{KHR}"
        if not isinstance(khr, dict):
            raise gltf_error(Code.KHR_PROPERTY_INVALID, f"{where}: {KHR} extension must be an "
                             f"object", kpointer)
        color_space = khr.get("colorSpace")
        if not isinstance(color_space, str):
            raise gltf_error(Code.KHR_PROPERTY_MISSING if color_space is None
                             else Code.KHR_PROPERTY_INVALID, f"{where}: {KHR}.colorSpace is "
                             f"missing or not a string", kpointer)
        attrs: dict[str, int] = prim.get("attributes", {})
        apointer = f"{pointer}/attributes"
        missing = [a for a in ("POSITION", ROTATION, SCALE, OPACITY) if a not in attrs]
        if missing:
            raise gltf_error(Code.KHR_ATTRIBUTE_MISSING, f"{where}: required {KHR} attribute(s) "
                             f"missing: {', '.join(missing)}", apointer)
        if is_compressed(khr):
            cloud = self._compressed_cloud(khr, attrs, color_space, where, pointer)
        else:
            cloud = self._stored_cloud(attrs, color_space, where, pointer)
        anchoring = None
        nested = khr.get("extensions")
        if nested is not None and not isinstance(nested, dict):
            raise gltf_error(Code.KHR_PROPERTY_INVALID, f"{where}: {KHR}.extensions must be an "
                             f"object", f"{kpointer}/extensions")
        if nested and EXTENSION in nested:
            anchoring = self.anchoring(nested[EXTENSION], cloud, where,
                                       f"{kpointer}/extensions/{EXTENSION}")
        required = self.document.doc.get("extensionsRequired")
        return SplatPrimitive(cloud, anchoring, name, _khr_properties(
            khr, where, kpointer, required if isinstance(required, list) else [], attrs))

    def node_names(self) -> dict[int, str]:
        """mesh index -> the name of the first node instantiating it."""
        names: dict[int, str] = {}
        for node in self.nodes:
            mesh, name = node.get("mesh"), node.get("name")
            if mesh is not None and isinstance(name, str) and mesh not in names:
                names[mesh] = name
        return names

    def asset(self) -> SplatAsset:
        """Every splat primitive of the document."""
        node_names = self.node_names()
        primitives: list[SplatPrimitive] = []
        sources: list[tuple[int, int]] = []
        for m, mesh in enumerate(self.meshes):
            name = mesh.get("name")
            if not isinstance(name, str):
                name = node_names.get(m)
            for p, prim in enumerate(mesh.get("primitives", [])):
                extensions = prim.get("extensions", {})
                if KHR not in extensions:
                    continue
                mode = prim.get("mode", TRIANGLES)
                if mode != POINTS:
                    khr = extensions[KHR]
                    nested = khr.get("extensions") if isinstance(khr, dict) else None
                    if isinstance(nested, dict) and EXTENSION in nested:
                        raise gltf_error(Code.KHR_PRIMITIVE_NOT_POINTS, f"meshes[{m}]."
                                         f"primitives[{p}]: an anchored splat primitive must "
                                         f"have mode POINTS (0), not {mode!r}",
                                         f"/meshes/{m}/primitives/{p}/mode")
                    continue
                primitives.append(self.splat_primitive(m, p, name))
                sources.append((m, p))
        generator = getattr(self.document.gltf.asset, "generator", None)
        extras = (self.document.doc.get("asset") or {}).get("extras")
        colliders, ground = read_physics(self, primitives, sources)
        return SplatAsset(primitives, generator if isinstance(generator, str) else None,
                          colliders, frame=recorded_frame(extras.get("gsverse")
                                                          if isinstance(extras, dict) else None),
                          ground=ground)


def read_document(document: Document) -> SplatAsset:
    """Every ``KHR_gaussian_splatting`` primitive of an opened document."""
    return SplatReader(document).asset()


def read_gltf(path: str | os.PathLike, *, max_bytes: int = DEFAULT_MAX_BYTES) -> SplatAsset:
    """Read every ``KHR_gaussian_splatting`` primitive of a ``.glb``/``.gltf`` file.

    Primitives carrying ``GSVERSE_gaussian_splatting_mesh_anchor`` get their
    :class:`Anchoring`; primitives referencing the same anchor primitive share one
    :class:`TriangleMesh`. ``max_bytes`` caps the file plus all buffers it loads.
    Raises :class:`FormatError` (naming ``path``; a :class:`GltfFormatError` carrying the
    issue code where there is one) for any problem with the input. Any other exception is a
    bug of the reader and propagates as it is.
    """
    spath = os.fspath(path)
    with input_errors(spath):
        asset = read_document(open_document(spath, max_bytes))
    return asset


@contextmanager
def input_errors(path: str, what: str = "asset") -> Iterator[None]:
    """What reading ``path`` raises for bad input, as one :class:`FormatError` naming it (our
    own errors keep their issue code; unreadable files and running out of memory get a
    cause). Anything else is a bug of the reader and propagates as it is."""
    try:
        yield
    except GsverseError as err:
        raise as_format_error(err, path) from None
    except OSError as err:
        raise FormatError(f"cannot read: {err.strerror or err}", path) from None
    except MemoryError:
        raise FormatError(f"not enough memory to read the {what}", path) from None


def as_format_error(err: GsverseError, path: str) -> FormatError:
    """``err`` as a :class:`FormatError` naming ``path`` (codes kept)."""
    if isinstance(err, GltfFormatError):
        return err.with_path(path)
    return FormatError(err.cause, path)
