"""OpenUSD splat assets (``.usda``, ``.usdc``, ``.usd``, ``.usdz``), as ``spec/usd.md`` maps them.

Each splat primitive is a ``ParticleField3DGaussianSplat`` prim holding the rest pose as default
values; an anchored primitive additionally has the codeless single-apply API schema
``GsVerseMeshAnchorAPI`` (``gsverse:anchor:*`` attributes and the relationship
``gsverse:anchor:mesh`` to a ``UsdGeom.Mesh`` of triangles), a static one
``GsVerseColorSpaceAPI``. Both carry the ``KHR_gaussian_splatting`` colour space in
``gsverse:colorSpace``. Units and axes are glTF's (metres, +Y up): no conversion on writing.

Optionally, :func:`write_usd` bakes the remap for a sequence of anchor-mesh poses into time
samples of ``positions``, ``orientations``, ``scales`` and ``extent`` (and of the anchor mesh's
``points``), for USD renderers that know nothing about anchors; the default values stay the
rest pose.

``usd-core`` (``pxr``) is an optional dependency: it is imported on first use, and the schema
plugin in ``gsverse_format/usd_schema`` is registered right then (:func:`register_schema`). If
the process used USD's schema registry before, the schemas cannot be registered any more; the
writer then authors the same file by hand (``spec/usd.md`` §Writing without the registered
schema) and a :class:`UsdSchemaWarning` says so. Reading never needs the schemas.

Public API: :func:`write_usd`, :func:`read_usd`, :func:`check_usd` (every problem of a file,
with USD paths as locations, for validators), :func:`inspect_usd` (the problems and the data
as authored), :func:`load_poses` / :class:`BakedPoses` (the
``--bake-poses`` file) and :func:`register_schema`. ``read_usd(..., isolate=True)`` and
:func:`check_usd` parse the file in a child process: usd-core's binary reader can crash on
some corrupted files, and a crash there becomes a :class:`FormatError` here.
"""
from __future__ import annotations

import json
import math
import os
import pathlib
import re
import shutil
import tempfile
import types
import warnings
from dataclasses import dataclass
from typing import Iterable

import numpy as np

from .. import __version__
from ..errors import FormatError, GsverseError, UsageError
from ..model import (Anchoring, GamesAnchors, LocalAnchors, SplatAsset, SplatCloud,
                     SplatPrimitive, TriangleMesh, sh_coefficient_count)

__all__ = ["USD_SUFFIXES", "MISSING_USD_CORE", "SCHEMA_DIR", "ANCHOR_API", "COLOR_SPACE_API",
           "UsdSchemaWarning", "UsdReadWarning", "UsdProblem", "UsdInspection", "UsdPrimInfo",
           "BakedPoses",
           "register_schema", "write_usd", "read_usd", "check_usd", "inspect_usd", "load_poses"]

#: File suffixes handled here (``.usd`` is written as binary ``usdc``).
USD_SUFFIXES = (".usda", ".usdc", ".usd", ".usdz")

#: The one-line message when ``pxr`` cannot be imported.
MISSING_USD_CORE = "USD support needs usd-core: pip install 'gsverse-format[usd]'"

#: The codeless schema plugin (``plugInfo.json`` + ``generatedSchema.usda``).
SCHEMA_DIR = pathlib.Path(__file__).resolve().parents[1] / "usd_schema"

ANCHOR_API = "GsVerseMeshAnchorAPI"
COLOR_SPACE_API = "GsVerseColorSpaceAPI"
ROOT_PRIM = "Asset"
DEFAULT_COLOR_SPACE = "srgb_rec709_display"
MESH_REL = "gsverse:anchor:mesh"
COLOR_SPACE_ATTR = "gsverse:colorSpace"

_SPLAT_TYPE = "ParticleField3DGaussianSplat"
_SH_COEFFS = "radiance:sphericalHarmonicsCoefficients"
_SH_DEGREE = "radiance:sphericalHarmonicsDegree"
_INT32_MAX = 2 ** 31 - 1

#: ``gsverse:anchor:*`` attributes: name -> (Sdf value type name, per-splat component count).
_ANCHOR_ATTRS = {
    "gsverse:anchor:profile": ("Token", None),
    "gsverse:anchor:deformation": ("Token", None),
    "gsverse:anchor:faceIndices": ("IntArray", 0),
    "gsverse:anchor:barycentrics": ("Float2Array", 2),
    "gsverse:anchor:normalOffsets": ("FloatArray", 0),
    "gsverse:anchor:localOrientations": ("QuatfArray", 4),
    "gsverse:anchor:localScales": ("Float3Array", 3),
    "gsverse:anchor:rho": ("FloatArray", 0),
}
_PROFILE_ATTRS = {
    "local": ("gsverse:anchor:faceIndices", "gsverse:anchor:barycentrics",
              "gsverse:anchor:normalOffsets", "gsverse:anchor:localOrientations"),
    "games": ("gsverse:anchor:faceIndices", "gsverse:anchor:barycentrics", "gsverse:anchor:rho"),
}
_PROFILE_OPTIONAL = {"local": ("gsverse:anchor:deformation", "gsverse:anchor:localScales"),
                     "games": ()}

#: Rest-pose attributes: name -> (half-precision variant, components per particle, default).
_REST_ATTRS = {
    "positions": ("positionsh", 3, None),
    "orientations": ("orientationsh", 4, (0.0, 0.0, 0.0, 1.0)),
    "scales": ("scalesh", 3, (1.0, 1.0, 1.0)),
    "opacities": ("opacitiesh", 0, 1.0),
}

_SCHEMA_TOO_LATE = (
    "the GsVerse USD schemas could not be registered: this process used USD's schema registry "
    "before gsverse_format.io.usd did; files are written identically without them, but to use "
    "the schema API here, call gsverse_format.io.usd.register_schema() before any other USD "
    f"use, or set PXR_PLUGINPATH_NAME={SCHEMA_DIR} before the process starts")


class UsdSchemaWarning(UserWarning):
    """The GsVerse schemas could not be registered in this process (see :func:`register_schema`)."""


class UsdReadWarning(UserWarning):
    """:func:`read_usd` replaced or skipped data (foreign files; see ``spec/usd.md`` §Reading)."""


@dataclass(frozen=True)
class UsdProblem:
    """One finding of :func:`check_usd`.

    ``severity`` is ``"error"`` (the file breaks a MUST of ``spec/usd.md`` or cannot be read as
    written) or ``"warning"`` (a SHOULD, or data a reader replaces). ``location`` is a USD path:
    a prim (``/Asset/splats``), a property (``/Asset/splats.gsverse:anchor:faceIndices``) or
    ``""`` for the stage's root layer. ``code`` is a short stable identifier.
    """

    severity: str
    location: str
    message: str
    code: str

    def __str__(self) -> str:
        where = f"{self.location}: " if self.location else ""
        return f"{self.severity}: {where}{self.message} [{self.code}]"


@dataclass
class BakedPoses:
    """Anchor-mesh poses to bake (``--bake-poses``).

    * ``times``    (P,) float64 USD time codes, finite and strictly increasing;
    * ``vertices`` (P, V, 3) float32 anchor-mesh vertex positions at each time code, in the
      frame and vertex order of the anchor mesh as written (glTF/USD frame: metres, +Y up);
    * ``time_codes_per_second`` the stage's ``timeCodesPerSecond`` (playback rate), > 0.
    """

    times: np.ndarray
    vertices: np.ndarray
    time_codes_per_second: float = 24.0

    def __post_init__(self) -> None:
        self.times = np.asarray(self.times, dtype=np.float64).reshape(-1)
        v = np.asarray(self.vertices, dtype=np.float32)
        if v.ndim != 3 or v.shape[2] != 3:
            raise UsageError(f"poses: vertices must have shape (P, V, 3), got {v.shape}")
        if v.shape[0] != self.times.shape[0]:
            raise UsageError(f"poses: {v.shape[0]} vertex sets but {self.times.shape[0]} times")
        if v.shape[0] == 0:
            raise UsageError("poses: no poses given")
        if not np.all(np.isfinite(self.times)) or np.any(np.diff(self.times) <= 0):
            raise UsageError("poses: times must be finite and strictly increasing")
        if not np.all(np.isfinite(v)):
            raise UsageError("poses: vertices contain NaN or infinite values")
        fps = float(self.time_codes_per_second)
        if not (math.isfinite(fps) and fps > 0):
            raise UsageError(f"poses: time_codes_per_second must be > 0, got {fps}")
        self.time_codes_per_second = fps
        self.vertices = np.ascontiguousarray(v)


# ----------------------------------------------------------------------------------------
# pxr import and schema registration
# ----------------------------------------------------------------------------------------

_PXR: types.SimpleNamespace | None = None
_REGISTERED: bool | None = None


def _import_pxr() -> types.SimpleNamespace:
    global _PXR
    if _PXR is None:
        try:
            from pxr import Gf, Kind, Plug, Sdf, Tf, Usd, UsdGeom, UsdUtils, UsdVol, Vt
        except ImportError:
            raise UsageError(MISSING_USD_CORE) from None
        if not hasattr(UsdVol, _SPLAT_TYPE):
            raise UsageError("USD support needs usd-core 26.03 or later (for UsdVol."
                             f"{_SPLAT_TYPE}): pip install -U 'gsverse-format[usd]'")
        _PXR = types.SimpleNamespace(Gf=Gf, Kind=Kind, Plug=Plug, Sdf=Sdf, Tf=Tf, Usd=Usd,
                                     UsdGeom=UsdGeom, UsdUtils=UsdUtils, UsdVol=UsdVol, Vt=Vt)
    return _PXR


def register_schema() -> bool:
    """Register the GsVerse schema plugin with USD; return whether the schemas are known.

    Called by every function of this module before it touches a USD stage. Registration only
    takes effect if USD's schema registry has not been used yet in this process (opening a
    stage with prims or defining a prim counts as a use); otherwise this returns ``False`` and
    issues a :class:`UsdSchemaWarning` once, and the writer authors the schema metadata by
    hand, producing the same file. Call it early (or set ``PXR_PLUGINPATH_NAME`` to
    :data:`SCHEMA_DIR`) in applications that use USD themselves. Raises :class:`UsageError`
    without usd-core.
    """
    global _REGISTERED
    if _REGISTERED is None:
        px = _import_pxr()
        px.Plug.Registry().RegisterPlugins(str(SCHEMA_DIR))
        # The check must come after the registration: it initialises the registry itself.
        _REGISTERED = px.Usd.SchemaRegistry().FindAppliedAPIPrimDefinition(ANCHOR_API) is not None
        if not _REGISTERED:
            warnings.warn(_SCHEMA_TOO_LATE, UsdSchemaWarning, stacklevel=2)
    return _REGISTERED


def _pxr() -> types.SimpleNamespace:
    px = _import_pxr()
    register_schema()
    return px


def _pxr_message(err: BaseException) -> str:
    """The first message of a ``Tf.ErrorException`` (or any exception), on one line."""
    text = str(err)
    found = re.search(r" : '(.*?)'(?:\n|$)", text, re.S)
    if found:
        text = found.group(1)
    return " ".join(text.split()) or type(err).__name__


# ----------------------------------------------------------------------------------------
# Poses file (--bake-poses)
# ----------------------------------------------------------------------------------------


def load_poses(path: str | os.PathLike) -> BakedPoses:
    """Read a ``--bake-poses`` file.

    * ``.npz``: arrays ``vertices`` (P, V, 3), ``times`` (P,) and optionally
      ``time_codes_per_second`` (a scalar, default 24);
    * ``.json``: a list of poses ``[{"time": t, "vertices": [[x, y, z], ...]}, ...]``, or an
      object ``{"timeCodesPerSecond": 24, "poses": [...]}`` with such a list.

    Times are USD time codes; vertices are in the frame and vertex order of the anchor mesh as
    written (see :class:`BakedPoses`). Raises :class:`UsageError` naming ``path``.
    """
    spath = os.fspath(path)
    ext = os.path.splitext(spath)[1].lower()
    try:
        if ext == ".npz":
            with np.load(spath, allow_pickle=False) as data:
                missing = [k for k in ("vertices", "times") if k not in data.files]
                if missing:
                    raise UsageError(f"poses .npz lacks array(s) {', '.join(missing)} "
                                     f"(needs vertices (P, V, 3) and times (P,))")
                fps = float(data["time_codes_per_second"]) if "time_codes_per_second" in \
                    data.files else 24.0
                return BakedPoses(data["times"], data["vertices"], fps)
        if ext == ".json":
            with open(spath, "rb") as handle:
                doc = json.loads(handle.read().decode("utf-8"))
            fps = 24.0
            if isinstance(doc, dict):
                fps = doc.get("timeCodesPerSecond", 24.0)
                if not isinstance(fps, (int, float)) or isinstance(fps, bool):
                    raise UsageError("poses JSON: timeCodesPerSecond must be a number")
                doc = doc.get("poses")
            if not isinstance(doc, list) or not all(
                    isinstance(p, dict) and "time" in p and "vertices" in p for p in doc):
                raise UsageError('poses JSON must be a list of {"time": t, "vertices": '
                                 '[[x, y, z], ...]} objects')
            try:
                times = np.array([p["time"] for p in doc], dtype=np.float64)
                vertices = np.array([p["vertices"] for p in doc], dtype=np.float32)
            except (TypeError, ValueError):
                raise UsageError("poses JSON: every time must be a number and every pose the "
                                 "same number of [x, y, z] vertices") from None
            return BakedPoses(times, vertices, fps)
    except GsverseError as err:
        raise err.with_path(spath) from None
    except (OSError, ValueError, UnicodeDecodeError) as err:
        raise UsageError(f"cannot read poses: {' '.join(str(err).split())}", spath) from None
    raise UsageError(f"poses must be a .npz or .json file, not {ext or '(no extension)'}", spath)


# ----------------------------------------------------------------------------------------
# Writing
# ----------------------------------------------------------------------------------------


def _unit_quaternions(q: np.ndarray) -> np.ndarray:
    from ..quaternion import unit_quaternions as unit

    return unit(q)


def _check_asset(asset: SplatAsset) -> None:
    from ..model import check_primitive

    for i, prim in enumerate(asset.primitives):
        check_primitive(i, prim)
        if prim.anchoring is not None:
            mesh = prim.anchoring.mesh
            if mesh.face_count > _INT32_MAX or len(mesh.vertices) > _INT32_MAX:
                raise UsageError(f"primitive {i}: anchor mesh too large for USD int indices")


def _check_poses(asset: SplatAsset, poses: BakedPoses | None) -> TriangleMesh | None:
    """The anchor mesh the poses deform (exactly one per asset), or None without poses."""
    if poses is None:
        return None
    if not isinstance(poses, BakedPoses):
        raise UsageError("bake_poses must be a BakedPoses (see load_poses)")
    meshes = {id(p.anchoring.mesh): p.anchoring.mesh for p in asset.anchored}
    if len(meshes) != 1:
        raise UsageError("baking poses needs an asset with exactly one anchor mesh, this one has "
                         f"{len(meshes)}" + ("" if meshes else " (convert with --mesh first)"))
    (mesh,) = meshes.values()
    if poses.vertices.shape[1] != len(mesh.vertices):
        raise UsageError(f"poses have {poses.vertices.shape[1]} vertices but the anchor mesh "
                         f"has {len(mesh.vertices)}: give every vertex of the written anchor mesh, "
                         f"in its order (without --faces decimation)")
    return mesh


class _Names:
    """Unique, valid child names under one parent (spec/usd.md §Names)."""

    def __init__(self, px: types.SimpleNamespace) -> None:
        self.px = px
        self.used: set[str] = set()

    def take(self, wanted: str | None, fallback: str) -> str:
        name = wanted if wanted else fallback
        if not self.px.Sdf.Path.IsValidIdentifier(name):
            name = self.px.Tf.MakeValidIdentifier(name)
        base, i = name, 0
        while name in self.used:
            i += 1
            name = f"{base}_{i}"
        self.used.add(name)
        return name


def _extent(px: types.SimpleNamespace, points: np.ndarray):
    p = np.asarray(points, dtype=np.float32)
    return px.Vt.Vec3fArray.FromNumpy(np.stack([p.min(axis=0), p.max(axis=0)]))


def _anchor_values(px: types.SimpleNamespace, prim: SplatPrimitive,
                   mesh_path) -> list[tuple[str, object, object]]:
    """(name, Sdf type, value) of the API schema attributes of one primitive, in writing order."""
    T, Vt = px.Sdf.ValueTypeNames, px.Vt
    out: list[tuple[str, object, object]] = [(COLOR_SPACE_ATTR, T.Token, prim.splats.color_space)]
    if prim.anchoring is None:
        return out
    a = prim.anchoring.anchors
    out.append(("gsverse:anchor:profile", T.Token, a.profile))
    if isinstance(a, LocalAnchors):
        out.append(("gsverse:anchor:deformation", T.Token, a.deformation))
    out += [("gsverse:anchor:faceIndices", T.IntArray,
             Vt.IntArray.FromNumpy(a.face_index.astype(np.int32))),
            ("gsverse:anchor:barycentrics", T.Float2Array,
             Vt.Vec2fArray.FromNumpy(a.barycentrics))]
    if isinstance(a, LocalAnchors):
        out += [("gsverse:anchor:normalOffsets", T.FloatArray,
                 Vt.FloatArray.FromNumpy(a.normal_offset)),
                ("gsverse:anchor:localOrientations", T.QuatfArray,
                 Vt.QuatfArray.FromNumpy(_unit_quaternions(a.local_rotation)))]
        if not np.array_equal(a.local_scale, prim.splats.scales):
            out.append(("gsverse:anchor:localScales", T.Float3Array,
                        Vt.Vec3fArray.FromNumpy(a.local_scale)))
    else:
        out.append(("gsverse:anchor:rho", T.FloatArray, Vt.FloatArray.FromNumpy(a.rho)))
    return out


def _define_mesh(px: types.SimpleNamespace, stage, path, mesh: TriangleMesh):
    UsdGeom, Vt = px.UsdGeom, px.Vt
    m = UsdGeom.Mesh.Define(stage, path)
    m.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(mesh.vertices))
    m.CreateFaceVertexCountsAttr(Vt.IntArray.FromNumpy(np.full(mesh.face_count, 3, np.int32)))
    m.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(mesh.faces.reshape(-1).astype(np.int32)))
    m.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    m.CreatePurposeAttr(UsdGeom.Tokens.guide)
    m.CreateExtentAttr(_extent(px, mesh.vertices))
    return m


def _define_splats(px: types.SimpleNamespace, stage, path, prim: SplatPrimitive, mesh_path,
                   registered: bool):
    Vt, Sdf = px.Vt, px.Sdf
    c = prim.splats
    gs = px.UsdVol.ParticleField3DGaussianSplat.Define(stage, path)
    gs.CreatePositionsAttr(Vt.Vec3fArray.FromNumpy(c.means))
    gs.CreateOrientationsAttr(Vt.QuatfArray.FromNumpy(_unit_quaternions(c.rotations)))
    gs.CreateScalesAttr(Vt.Vec3fArray.FromNumpy(c.scales))
    gs.CreateOpacitiesAttr(Vt.FloatArray.FromNumpy(c.opacities))
    gs.CreateRadianceSphericalHarmonicsDegreeAttr(int(c.sh_degree))
    gs.CreateRadianceSphericalHarmonicsCoefficientsAttr(
        Vt.Vec3fArray.FromNumpy(c.sh.reshape(-1, 3)))
    gs.CreateProjectionModeHintAttr("perspective")
    gs.CreateSortingModeHintAttr("cameraDistance")
    gs.CreateExtentAttr(_extent(px, c.means))
    usd_prim = gs.GetPrim()
    api = ANCHOR_API if prim.anchoring is not None else COLOR_SPACE_API
    values = _anchor_values(px, prim, mesh_path)
    if registered:
        usd_prim.ApplyAPI(api)
        for name, _, value in values:
            usd_prim.GetAttribute(name).Set(value)
        if mesh_path is not None:
            usd_prim.GetRelationship(MESH_REL).SetTargets([mesh_path])
    else:  # spec/usd.md §Writing without the registered schema: the same layer, by hand
        usd_prim.AddAppliedSchema(api)
        for name, type_name, value in values:
            usd_prim.CreateAttribute(name, type_name, custom=False,
                                     variability=Sdf.VariabilityUniform).Set(value)
        if mesh_path is not None:
            usd_prim.CreateRelationship(MESH_REL, custom=False).SetTargets([mesh_path])
    return gs


def _bake(px: types.SimpleNamespace, stage, poses: BakedPoses, mesh_schema,
          splat_prims: list[tuple[SplatPrimitive, object]]) -> None:
    """Time samples of the remap at every pose (spec/usd.md §Baked animation)."""
    from ..remap import prepare_rest, remap

    Vt = px.Vt
    times = [float(t) for t in poses.times]
    stage.SetStartTimeCode(times[0])
    stage.SetEndTimeCode(times[-1])
    stage.SetTimeCodesPerSecond(poses.time_codes_per_second)
    for t, vertices in zip(times, poses.vertices):
        mesh_schema.GetPointsAttr().Set(Vt.Vec3fArray.FromNumpy(vertices), t)
        mesh_schema.GetExtentAttr().Set(_extent(px, vertices), t)
    for prim, gs in splat_prims:
        anchoring = prim.anchoring
        rest = (prepare_rest(anchoring.mesh.triangles())
                if isinstance(anchoring.anchors, LocalAnchors) else None)
        previous = _unit_quaternions(prim.splats.rotations)
        for t, vertices in zip(times, poses.vertices):
            r = remap(anchoring, vertices, rest=rest)
            means = r.means.astype(np.float32)
            rotations = r.rotations.astype(np.float32)
            # Same hemisphere as the previous sample, so interpolation takes the short arc.
            flip = np.einsum("ij,ij->i", rotations, previous) < 0
            rotations[flip] *= -1
            previous = rotations
            gs.GetPositionsAttr().Set(Vt.Vec3fArray.FromNumpy(means), t)
            gs.GetOrientationsAttr().Set(Vt.QuatfArray.FromNumpy(rotations), t)
            gs.GetScalesAttr().Set(Vt.Vec3fArray.FromNumpy(r.scales.astype(np.float32)), t)
            gs.GetExtentAttr().Set(_extent(px, means), t)


def _build_stage(px: types.SimpleNamespace, asset: SplatAsset, poses: BakedPoses | None,
                 registered: bool):
    Usd, UsdGeom, Sdf = px.Usd, px.UsdGeom, px.Sdf
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = UsdGeom.Xform.Define(stage, "/" + ROOT_PRIM)
    Usd.ModelAPI(root.GetPrim()).SetKind(px.Kind.Tokens.component)
    stage.SetDefaultPrim(root.GetPrim())
    stage.GetRootLayer().customLayerData = {"generator": f"gsverse-format {__version__}"}
    names = _Names(px)
    root_path = root.GetPath()
    mesh_paths: dict[int, object] = {}
    mesh_schemas: dict[int, object] = {}
    anchored: list[tuple[SplatPrimitive, object]] = []
    for prim in asset.primitives:
        mesh_path = None
        if prim.anchoring is not None:
            key = id(prim.anchoring.mesh)
            if key not in mesh_paths:
                mesh_paths[key] = root_path.AppendChild(names.take(None, "anchor_mesh"))
                mesh_schemas[key] = _define_mesh(px, stage, mesh_paths[key], prim.anchoring.mesh)
            mesh_path = mesh_paths[key]
        name = names.take(prim.name, "splats")
        gs = _define_splats(px, stage, root_path.AppendChild(name), prim, mesh_path, registered)
        if prim.name and name != prim.name:
            gs.GetPrim().SetDisplayName(prim.name)
        if prim.anchoring is not None:
            anchored.append((prim, gs))
    if poses is not None:
        (key,) = mesh_schemas  # _check_poses guarantees exactly one anchor mesh
        _bake(px, stage, poses, mesh_schemas[key], anchored)
    return stage


def _check_protect(path: str, protect: Iterable) -> None:
    target = os.path.realpath(path)
    for other in protect:
        if other is not None and os.path.exists(other) and os.path.exists(target) \
                and os.path.samefile(other, target):
            raise UsageError("output would overwrite an input file", path)


def _current_umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


def _save(px: types.SimpleNamespace, layer, path: str, ext: str) -> None:
    """Export ``layer`` atomically: a temporary file in the target's folder, then a rename."""
    folder = os.path.dirname(os.path.abspath(path)) or "."
    if not os.path.isdir(folder):
        raise UsageError(f"output folder {folder!r} does not exist", path)
    mode = 0o666 & ~_current_umask()
    work = tempfile.mkdtemp(prefix=".tmp-", dir=folder)
    try:
        if ext == ".usdz":
            stem = os.path.splitext(os.path.basename(path))[0]
            inner = os.path.join(work, px.Tf.MakeValidIdentifier(stem or "asset") + ".usdc")
            result = os.path.join(work, "package.usdz")
            if not layer.Export(inner):
                raise GsverseError("cannot write the USD layer", path)
            if not px.UsdUtils.CreateNewUsdzPackage(px.Sdf.AssetPath(inner), result):
                raise GsverseError("cannot create the USDZ package", path)
        else:
            result = os.path.join(work, "asset" + ext)
            if not layer.Export(result):
                raise GsverseError("cannot write the USD layer", path)
        os.chmod(result, mode)
        os.replace(result, path)
    except GsverseError:
        raise
    except OSError as err:
        raise GsverseError(f"cannot write: {err.strerror or err}", path) from None
    except Exception as err:  # pxr.Tf.ErrorException and friends
        raise GsverseError(f"cannot write USD: {_pxr_message(err)}", path) from None
    finally:
        shutil.rmtree(work, ignore_errors=True)


def write_usd(asset: SplatAsset, path: str | os.PathLike, *,
              protect: Iterable[str | os.PathLike] = (),
              bake_poses: BakedPoses | None = None) -> None:
    """Write ``asset`` as a USD stage (spec/usd.md) to ``path`` (``.usda``, ``.usdc``, ``.usd``
    or ``.usdz``), atomically; ``protect`` lists input files it must not overwrite.

    ``bake_poses`` (:class:`BakedPoses`, see :func:`load_poses`) adds time samples of the
    remapped splats for each pose of the asset's (single) anchor mesh. Raises
    :class:`UsageError` for data USD cannot hold, for bad poses and without usd-core.
    """
    spath = os.fspath(path)
    ext = os.path.splitext(spath)[1].lower()
    try:
        if ext not in USD_SUFFIXES:
            raise UsageError(f"USD output must end in {', '.join(USD_SUFFIXES)}, not "
                             f"{ext or '(nothing)'}")
        px = _pxr()
        _check_asset(asset)
        _check_poses(asset, bake_poses)
        _check_protect(spath, protect)
        stage = _build_stage(px, asset, bake_poses, bool(_REGISTERED))
        _save(px, stage.GetRootLayer(), spath, ext)
    except GsverseError as err:
        raise err.with_path(spath) from None


# ----------------------------------------------------------------------------------------
# Reading and checking
# ----------------------------------------------------------------------------------------


class _Invalid(Exception):
    """Aborts reading one prim after an error was recorded."""


class _Reader:
    """Reads the splat prims of an open stage; records problems instead of stopping.

    ``errors`` stop the prim concerned (an anchored prim is never read without its anchors);
    ``warnings`` note data replaced by the schema's defaults. With ``conformance`` it also
    checks the writer rules of spec/usd.md that a reader does not need, and keeps
    orientations, scales and opacities as authored (not normalized, made positive or
    clamped), so that validators can check the values themselves.
    """

    def __init__(self, px: types.SimpleNamespace, stage, conformance: bool = False) -> None:
        self.px = px
        self.stage = stage
        self.conformance = conformance
        self.problems: list[UsdProblem] = []
        self.meshes: dict[str, TriangleMesh | _Invalid] = {}
        self.mesh_prims: list = []
        #: Where every primitive read came from, in order.
        self.locations: list[UsdPrimInfo] = []
        self._mesh_key: str | None = None

    # -- recording
    def error(self, location, message: str, code: str, *, stop: bool = True) -> None:
        self.problems.append(UsdProblem("error", str(location), message, code))
        if stop:
            raise _Invalid(message)

    def warn(self, location, message: str, code: str) -> None:
        self.problems.append(UsdProblem("warning", str(location), message, code))

    def rule(self, strict: bool, location, message: str, code: str) -> None:
        """A writer rule: an error for prims that claim conformance, else a warning."""
        if strict:
            self.error(location, message, code, stop=False)
        else:
            self.warn(location, message, code)

    # -- values
    def specs(self, attr) -> list:
        """The attribute's authored specs, strongest first.

        With the schemas registered, ``UsdAttribute.GetTypeName`` and ``IsCustom`` report the
        schema's declaration, not what the file authored; the specs tell the truth.
        """
        try:
            return list(attr.GetPropertyStack(self.px.Usd.TimeCode.Default()))
        except Exception:
            return []

    def authored_type(self, attr):
        for spec in self.specs(attr):
            if spec.typeName:
                return spec.typeName
        return attr.GetTypeName()

    def value(self, attr):
        """The default value (the rest pose) of ``attr`` if authored, else None."""
        if not attr or not attr.HasAuthoredValue():
            return None
        return attr.Get(self.px.Usd.TimeCode.Default())

    def array(self, attr, components: int, *, exact_type: str | None = None):
        """Default value of ``attr`` as a float/int numpy array, checked for shape and NaN.

        Returns None when unauthored (or authored only as time samples). Raises through
        :meth:`error` for a wrong type (``exact_type``: the Sdf type name required) or
        non-finite values.
        """
        value = self.value(attr)
        if value is None:
            return None
        where = attr.GetPath()
        if exact_type is not None:
            expected = getattr(self.px.Sdf.ValueTypeNames, exact_type)
            authored = self.authored_type(attr)
            if authored != expected:
                self.error(where, f"has type {authored}, expected {expected}", "TYPE_MISMATCH")
        try:
            a = np.array(value)
        except Exception:
            a = None
        expected = (-1,) if components == 0 else (-1, components)
        if a is None or a.dtype.kind not in "fiu" or a.ndim != len(expected) or (
                components and a.shape[1] != components):
            self.error(where, f"has type {attr.GetTypeName()}, not an array of "
                              f"{'scalars' if components == 0 else f'{components}-vectors'}",
                       "TYPE_MISMATCH")
        if a.dtype.kind == "f" and not np.all(np.isfinite(a)):
            self.error(where, "contains NaN or infinite values", "NOT_FINITE")
        return a

    def token(self, attr) -> str | None:
        value = self.value(attr)
        if value is None:
            return None
        if not isinstance(value, str):
            self.error(attr.GetPath(), f"has type {attr.GetTypeName()}, expected token",
                       "TYPE_MISMATCH")
        return value

    # -- stage
    def read(self) -> SplatAsset:
        px = self.px
        splat_type = px.UsdVol.ParticleField3DGaussianSplat
        self.stage_checks()
        primitives: list[SplatPrimitive] = []
        for prim in self.stage.Traverse():
            if prim.IsA(splat_type):
                self._mesh_key = None
                try:
                    result = self.splat_prim(prim)
                except _Invalid:
                    continue
                if result is not None:
                    primitives.append(result)
                    apis = prim.GetPrimTypeInfo().GetAppliedAPISchemas()
                    self.locations.append(UsdPrimInfo(
                        str(prim.GetPath()),
                        self._mesh_key if result.anchoring is not None else None,
                        ANCHOR_API in apis or COLOR_SPACE_API in apis))
            elif prim.IsA(px.UsdVol.ParticleField):
                self.warn(prim.GetPath(), f"{prim.GetTypeName() or 'ParticleField'} prim is not a "
                          f"{_SPLAT_TYPE} (no KHR_gaussian_splatting equivalent): skipped",
                          "SKIPPED_PARTICLE_FIELD")
        asset = SplatAsset(primitives, self.generator())
        return self.convert_units(asset)

    def generator(self) -> str | None:
        data = self.stage.GetRootLayer().customLayerData or {}
        value = data.get("generator")
        return value if isinstance(value, str) else None

    def stage_checks(self) -> None:
        """Stage metadata: what a reader must honour, plus (conformance) the writer rules."""
        px, stage = self.px, self.stage
        self.up_axis = "Y"
        self.meters = 1.0
        if stage.HasAuthoredMetadata("upAxis"):
            self.up_axis = str(px.UsdGeom.GetStageUpAxis(stage))
            if self.up_axis not in ("Y", "Z"):
                self.error("", f"upAxis {self.up_axis!r} is neither 'Y' nor 'Z'", "BAD_UP_AXIS")
            if self.up_axis == "Z":
                self.warn("", "upAxis is 'Z': read rotated into +Y up", "CONVERTED_UP_AXIS")
        elif self.conformance:
            self.error("", "stage does not author upAxis (must be 'Y')", "MISSING_UP_AXIS",
                       stop=False)
        else:
            self.warn("", "stage does not author upAxis: read as 'Y'", "MISSING_UP_AXIS")
        if stage.HasAuthoredMetadata("metersPerUnit"):
            self.meters = float(px.UsdGeom.GetStageMetersPerUnit(stage))
            if not (math.isfinite(self.meters) and self.meters > 0):
                self.error("", f"metersPerUnit {self.meters} is not a positive number",
                           "BAD_METERS_PER_UNIT")
            if self.meters != 1.0:
                self.warn("", f"metersPerUnit is {self.meters:g}: read scaled to metres",
                          "CONVERTED_UNITS")
        elif self.conformance:
            self.error("", "stage does not author metersPerUnit (must be 1)",
                       "MISSING_METERS_PER_UNIT", stop=False)
        else:
            self.warn("", "stage does not author metersPerUnit: read as metres (not the USD "
                          "fallback, centimetres)", "MISSING_METERS_PER_UNIT")
        if not self.conformance:
            return
        root = stage.GetDefaultPrim()
        if not root:
            self.error("", "stage has no valid defaultPrim", "MISSING_DEFAULT_PRIM", stop=False)
        elif root.GetTypeName() != "Xform":
            kind = root.GetTypeName() or "typeless prim"
            self.error(root.GetPath(), f"the defaultPrim is a {kind}, not an Xform",
                       "DEFAULT_PRIM_NOT_XFORM", stop=False)

    def convert_units(self, asset: SplatAsset) -> SplatAsset:
        """Z-up stages rotated to +Y up, other units scaled to metres (spec/usd.md)."""
        if self.up_axis == "Y" and self.meters == 1.0:
            return asset
        from ..transform import rotate_mesh, rotate_splats

        rotation = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]]) if self.up_axis == "Z" \
            else None
        m = self.meters
        meshes: dict[int, TriangleMesh] = {}

        def mesh_of(mesh: TriangleMesh) -> TriangleMesh:
            if id(mesh) not in meshes:
                out = rotate_mesh(mesh, rotation) if rotation is not None else mesh
                meshes[id(mesh)] = TriangleMesh(out.vertices.astype(np.float64) * m, out.faces)
            return meshes[id(mesh)]

        prims = []
        for p in asset.primitives:
            c = rotate_splats(p.splats, rotation) if rotation is not None else p.splats
            c = SplatCloud(c.means.astype(np.float64) * m, c.rotations,
                           c.scales.astype(np.float64) * m, c.opacities, c.sh, c.color_space,
                           dict(c.extra))
            anchoring = None
            if p.anchoring is not None:
                a = p.anchoring.anchors
                if isinstance(a, LocalAnchors):
                    a = LocalAnchors(a.face_index, a.barycentrics,
                                     a.normal_offset.astype(np.float64) * m, a.local_rotation,
                                     a.local_scale.astype(np.float64) * m, a.deformation)
                anchoring = Anchoring(mesh_of(p.anchoring.mesh), a)
            prims.append(SplatPrimitive(c, anchoring, p.name))
        return SplatAsset(prims, asset.generator)

    # -- splat prims
    def rest_array(self, prim, name: str, n: int | None, strict: bool):
        """A rest-pose array, float preferred to half; None if it must be replaced by defaults.

        ``strict`` (anchored prims): missing or wrong-length arrays are errors. Otherwise the
        USD schema's rules: longer arrays are truncated, shorter ones ignored (warning).
        """
        half, components, _ = _REST_ATTRS[name]
        attr = prim.GetAttribute(name)
        a = self.array(attr, components)
        if a is None:
            attr = prim.GetAttribute(half)
            a = self.array(attr, components)
        if a is None:
            if strict:
                self.error(prim.GetAttribute(name).GetPath(), "has no default value",
                           "MISSING_ATTRIBUTE")
            return None, attr
        a = a.astype(np.float32)
        if n is None:
            return a, attr
        if len(a) != n:
            if strict:
                self.error(attr.GetPath(), f"has {len(a)} elements, positions has {n}",
                           "LENGTH_MISMATCH")
            if len(a) < n:
                self.warn(attr.GetPath(), f"has {len(a)} elements for {n} particles: ignored, "
                          f"defaults used", "REPLACED_BY_DEFAULT")
                return None, attr
            self.warn(attr.GetPath(), f"has {len(a)} elements for {n} particles: truncated",
                      "TRUNCATED")
            a = a[:n]
        return a, attr

    def splat_prim(self, prim) -> SplatPrimitive | None:
        px = self.px
        path = prim.GetPath()
        authored_apis = list(prim.GetPrimTypeInfo().GetAppliedAPISchemas())
        anchored = ANCHOR_API in authored_apis
        ours = anchored or COLOR_SPACE_API in authored_apis
        if self.conformance:
            self.prim_rules(prim, authored_apis, ours)

        positions, pos_attr = self.rest_array(prim, "positions", None, anchored)
        if positions is None or len(positions) == 0:
            if anchored:
                self.error(prim.GetAttribute("positions").GetPath(), "has no particles",
                           "MISSING_ATTRIBUTE")
            self.warn(path, "has no particles (no positions): skipped", "EMPTY_PRIM")
            return None
        n = len(positions)
        rot, _ = self.rest_array(prim, "orientations", n, anchored)
        scales, _ = self.rest_array(prim, "scales", n, anchored)
        opac, _ = self.rest_array(prim, "opacities", n, anchored)
        sh = self.spherical_harmonics(prim, n, anchored)

        rot = np.tile(np.float32([0, 0, 0, 1]), (n, 1)) if rot is None else rot
        scales = np.ones((n, 3), np.float32) if scales is None else scales
        opac = np.ones(n, np.float32) if opac is None else opac
        if not self.conformance:  # validators check the values as authored
            negative = np.flatnonzero(np.any(scales < 0, axis=1))
            if anchored and negative.size:   # they are the local scales unless authored apart
                self.error(prim.GetAttribute("scales").GetPath(),
                           f"{negative.size} splat(s) with a negative scale (splat "
                           f"{int(negative[0])}); scales are linear, >= 0", "NEGATIVE_SCALE")
            rot, scales, opac = _unit_quaternions(rot), np.abs(scales), np.clip(opac, 0.0, 1.0)

        cs_attr = prim.GetAttribute(COLOR_SPACE_ATTR)
        color_space = self.token(cs_attr)
        if color_space is None:
            color_space = DEFAULT_COLOR_SPACE
        cloud = SplatCloud(positions, rot, scales, opac, sh, color_space)
        anchoring = self.anchoring(prim, cloud) if anchored else None
        name = prim.GetDisplayName() or prim.GetName()
        return SplatPrimitive(cloud, anchoring, name)

    def spherical_harmonics(self, prim, n: int, strict: bool) -> np.ndarray:
        degree_attr = prim.GetAttribute(_SH_DEGREE)
        degree = degree_attr.Get() if degree_attr else None
        if degree is None:
            degree = 3  # the schema's fallback
        if not isinstance(degree, int) or isinstance(degree, bool):
            self.error(degree_attr.GetPath(), f"has type {degree_attr.GetTypeName()}, expected int",
                       "TYPE_MISMATCH")
        coeffs = self.array(prim.GetAttribute(_SH_COEFFS), 3)
        if coeffs is None:
            coeffs = self.array(prim.GetAttribute(_SH_COEFFS + "h"), 3)
        where = prim.GetAttribute(_SH_COEFFS).GetPath()
        if strict:
            if not 0 <= degree <= 3:
                self.error(degree_attr.GetPath(), f"is {degree}, must be 0..3", "BAD_SH_DEGREE")
            k = sh_coefficient_count(degree)
            got = 0 if coeffs is None else len(coeffs)
            if got != n * k:
                hint = (" (author radiance:sphericalHarmonicsDegree: its fallback is 3)"
                        if not degree_attr.HasAuthoredValue() else "")
                self.error(where, f"has {got} elements, degree {degree} needs {n} x {k} = "
                                  f"{n * k}{hint}", "LENGTH_MISMATCH")
            return coeffs.astype(np.float32).reshape(n, k, 3)
        default = np.zeros((n, 1, 3), np.float32)
        if degree < 0:
            self.warn(degree_attr.GetPath(), f"is {degree}: SH ignored, colour 0.5 used",
                      "REPLACED_BY_DEFAULT")
            return default
        k_file = (degree + 1) ** 2
        if coeffs is None or len(coeffs) < n * k_file:
            got = 0 if coeffs is None else len(coeffs)
            self.warn(where, f"has {got} elements, degree {degree} needs {n * k_file}: ignored, "
                             f"colour 0.5 used", "REPLACED_BY_DEFAULT")
            return default
        sh = coeffs[: n * k_file].astype(np.float32).reshape(n, k_file, 3)
        if degree > 3:
            self.warn(degree_attr.GetPath(), f"is {degree}: truncated to 3", "TRUNCATED")
            sh = sh[:, :16]
        return sh

    def anchoring(self, prim, cloud: SplatCloud) -> Anchoring:
        n = len(cloud)
        attr = prim.GetAttribute
        profile = self.token(attr("gsverse:anchor:profile"))
        if profile not in ("local", "games"):
            self.error(attr("gsverse:anchor:profile").GetPath() if attr("gsverse:anchor:profile")
                       else prim.GetPath().AppendProperty("gsverse:anchor:profile"),
                       "is missing" if profile is None else
                       f"is {profile!r}, must be 'local' or 'games'", "BAD_PROFILE")
        allowed = set(_PROFILE_ATTRS[profile]) | set(_PROFILE_OPTIONAL[profile]) | {
            "gsverse:anchor:profile"}
        for name in _ANCHOR_ATTRS:
            a = attr(name)
            if name not in allowed and a and a.HasAuthoredValue():
                message = f"must not be authored with the {profile} profile: ignored"
                if self.conformance:
                    self.error(a.GetPath(), message, "EXCLUDED_ATTRIBUTE", stop=False)
                else:
                    self.warn(a.GetPath(), message, "EXCLUDED_ATTRIBUTE")

        def per_splat(name: str, required: bool = True):
            type_name, components = _ANCHOR_ATTRS[name]
            a = attr(name)
            values = self.array(a, components, exact_type=type_name) if a else None
            if values is None:
                if required:
                    self.error(prim.GetPath().AppendProperty(name),
                               f"is missing (required by the {profile} profile)",
                               "MISSING_ATTRIBUTE")
                return None
            if len(values) != n:
                self.error(a.GetPath(), f"has {len(values)} elements, the prim has {n} particles",
                           "LENGTH_MISMATCH")
            return values

        face = per_splat("gsverse:anchor:faceIndices")
        bary = per_splat("gsverse:anchor:barycentrics")
        mesh = self.anchor_mesh(prim)
        if face.size and (int(face.min()) < 0 or int(face.max()) >= mesh.face_count):
            bad = int(face.min()) if int(face.min()) < 0 else int(face.max())
            self.error(attr("gsverse:anchor:faceIndices").GetPath(),
                       f"value {bad} out of range for anchor mesh with {mesh.face_count} "
                       f"triangles", "FACE_INDEX_OUT_OF_RANGE")
        face = face.astype(np.uint32)
        if profile == "games":
            anchors = GamesAnchors(face, bary, per_splat("gsverse:anchor:rho"))
        else:
            deformation = self.token(attr("gsverse:anchor:deformation")) or "affine"
            if deformation not in ("affine", "rigid"):
                self.error(attr("gsverse:anchor:deformation").GetPath(),
                           f"is {deformation!r}, must be 'affine' or 'rigid'", "BAD_DEFORMATION")
            offsets = per_splat("gsverse:anchor:normalOffsets")
            rotations = per_splat("gsverse:anchor:localOrientations")
            local_scales = per_splat("gsverse:anchor:localScales", required=False)
            if local_scales is None:
                local_scales = cloud.scales
            if not self.conformance:  # validators check the values as authored
                zero = np.flatnonzero(~np.any(np.asarray(rotations) != 0, axis=1))
                if zero.size:
                    self.error(attr("gsverse:anchor:localOrientations").GetPath(),
                               f"{zero.size} zero quaternion(s) (splat {int(zero[0])}); a "
                               f"rotation must have non-zero length", "ZERO_ROTATION")
                negative = np.flatnonzero(np.any(np.asarray(local_scales) < 0, axis=1))
                if negative.size:
                    self.error(prim.GetPath(), f"{negative.size} splat(s) with a negative local "
                               f"scale (splat {int(negative[0])}); scales are linear, >= 0",
                               "NEGATIVE_SCALE")
                rotations = _unit_quaternions(rotations)
            anchors = LocalAnchors(face, bary, offsets, rotations, local_scales, deformation)
        return Anchoring(mesh, anchors)

    def anchor_mesh(self, prim) -> TriangleMesh:
        rel = prim.GetRelationship(MESH_REL)
        where = rel.GetPath() if rel else prim.GetPath().AppendProperty(MESH_REL)
        targets = list(rel.GetTargets()) if rel else []
        if len(targets) != 1:
            self.error(where, f"has {len(targets)} targets, must have exactly one (the anchor "
                              f"Mesh)", "BAD_MESH_TARGET")
        key = self._mesh_key = str(targets[0])
        if key not in self.meshes:
            try:
                self.meshes[key] = self.read_mesh(targets[0], where)
            except _Invalid as err:
                self.meshes[key] = err
                raise
        mesh = self.meshes[key]
        if isinstance(mesh, _Invalid):
            raise mesh
        return mesh

    def read_mesh(self, target, rel_path) -> TriangleMesh:
        px = self.px
        mesh_prim = self.stage.GetPrimAtPath(target)
        if not mesh_prim or not mesh_prim.IsA(px.UsdGeom.Mesh):
            self.error(rel_path, f"target {target} is not a Mesh prim", "BAD_MESH_TARGET")
        self.mesh_prims.append(mesh_prim)
        m = px.UsdGeom.Mesh(mesh_prim)
        points = self.array(m.GetPointsAttr(), 3)
        counts = self.array(m.GetFaceVertexCountsAttr(), 0, exact_type="IntArray")
        indices = self.array(m.GetFaceVertexIndicesAttr(), 0, exact_type="IntArray")
        for value, attr in ((points, m.GetPointsAttr()), (counts, m.GetFaceVertexCountsAttr()),
                            (indices, m.GetFaceVertexIndicesAttr())):
            if value is None:
                self.error(attr.GetPath(), "has no default value", "MISSING_ATTRIBUTE")
        if counts.size and np.any(counts != 3):
            bad = int(np.flatnonzero(counts != 3)[0])
            self.error(m.GetFaceVertexCountsAttr().GetPath(),
                       f"face {bad} has {int(counts[bad])} vertices: anchor meshes must be "
                       f"triangles only", "NOT_TRIANGLES")
        if counts.size == 0:
            self.error(m.GetFaceVertexCountsAttr().GetPath(), "has no faces", "NOT_TRIANGLES")
        if len(indices) != 3 * len(counts):
            self.error(m.GetFaceVertexIndicesAttr().GetPath(),
                       f"has {len(indices)} elements for {len(counts)} triangles",
                       "LENGTH_MISMATCH")
        if indices.size and (int(indices.min()) < 0 or int(indices.max()) >= len(points)):
            bad = int(indices.min()) if int(indices.min()) < 0 else int(indices.max())
            self.error(m.GetFaceVertexIndicesAttr().GetPath(),
                       f"index {bad} out of range for {len(points)} points",
                       "INDEX_OUT_OF_RANGE")
        holes = self.value(m.GetHoleIndicesAttr())
        if holes is not None and len(holes):
            self.error(m.GetHoleIndicesAttr().GetPath(), "must be empty for an anchor mesh",
                       "HOLES")
        return TriangleMesh(points.astype(np.float32), indices.reshape(-1, 3))

    # -- conformance (writer rules; check_usd only)
    def prim_rules(self, prim, authored_apis: list[str], ours: bool) -> None:
        path = prim.GetPath()
        if ANCHOR_API in authored_apis and COLOR_SPACE_API in authored_apis:
            self.error(path, f"applies both {ANCHOR_API} and {COLOR_SPACE_API} (the first "
                             f"includes the second)", "BOTH_APIS", stop=False)
        if not ours:
            self.warn(path, f"plain {_SPLAT_TYPE} without {COLOR_SPACE_API}: read with colour "
                            f"space {DEFAULT_COLOR_SPACE}", "PLAIN_SPLATS")
        else:
            cs = prim.GetAttribute(COLOR_SPACE_ATTR)
            if not cs or not cs.HasAuthoredValue():
                self.error(path.AppendProperty(COLOR_SPACE_ATTR), "must be authored",
                           "MISSING_ATTRIBUTE", stop=False)
        sorting = prim.GetAttribute("sortingModeHint")
        if self.value(sorting) != "cameraDistance":
            self.rule(ours, sorting.GetPath(), "should be authored as 'cameraDistance' "
                      "(KHR's sortingMethod; the USD fallback is zDepth)", "SORTING_MODE")
        if self.value(prim.GetAttribute("projectionModeHint")) is None:
            self.warn(path.AppendProperty("projectionModeHint"),
                      "not authored (SHOULD be 'perspective')", "PROJECTION_MODE")
        if not prim.GetAttribute(_SH_DEGREE).HasAuthoredValue():
            self.rule(ours, path.AppendProperty(_SH_DEGREE),
                      "is not authored (its fallback is 3)", "MISSING_SH_DEGREE")
        for full, (half, _, _) in _REST_ATTRS.items():
            a = prim.GetAttribute(half)
            if a and a.HasAuthoredValue():
                self.rule(ours, a.GetPath(), "half-precision variant authored (writers use "
                          f"{full})", "HALF_PRECISION")
            a = prim.GetAttribute(full)
            if a and a.HasAuthoredValue() and a.GetNumTimeSamples() and \
                    a.Get(self.px.Usd.TimeCode.Default()) is None:
                self.error(a.GetPath(), "has time samples but no default value (no rest pose)",
                           "NO_REST_POSE", stop=False)
        for name in ("opacities", _SH_COEFFS, _SH_DEGREE):
            a = prim.GetAttribute(name)
            if a and a.GetNumTimeSamples():
                self.error(a.GetPath(), "must not be time-sampled", "TIME_SAMPLED", stop=False)
        extent = self.value(prim.GetAttribute("extent"))
        positions = self.value(prim.GetAttribute("positions"))
        if extent is None:
            self.rule(ours, path.AppendProperty("extent"), "is not authored", "MISSING_EXTENT")
        elif positions is not None and len(positions):
            e = np.array(extent, dtype=np.float64)
            p = np.array(positions, dtype=np.float64)
            if e.shape != (2, 3) or np.any(p < e[0]) or np.any(p > e[1]):
                self.rule(ours, path.AppendProperty("extent"),
                          "does not contain every position", "BAD_EXTENT")
        for name in list(_ANCHOR_ATTRS) + [COLOR_SPACE_ATTR]:
            a = prim.GetAttribute(name)
            if not a or not a.IsAuthored():
                continue
            if any(spec.custom for spec in self.specs(a)):
                self.error(a.GetPath(), "is authored as a custom attribute (must be the "
                           "schema's non-custom property)", "CUSTOM_ATTRIBUTE", stop=False)
            if any(spec.variability != self.px.Sdf.VariabilityUniform
                   for spec in self.specs(a)):
                self.error(a.GetPath(), "must be uniform", "NOT_UNIFORM", stop=False)
            if a.GetNumTimeSamples():
                self.error(a.GetPath(), "must not be time-sampled", "TIME_SAMPLED", stop=False)
            expected = getattr(self.px.Sdf.ValueTypeNames,
                               _ANCHOR_ATTRS.get(name, ("Token", None))[0])
            authored = self.authored_type(a)
            if authored != expected:
                self.error(a.GetPath(), f"has type {authored}, expected {expected}",
                           "TYPE_MISMATCH", stop=False)
        rel = prim.GetRelationship(MESH_REL)
        if rel and any(spec.custom for spec in rel.GetPropertyStack()):
            self.error(rel.GetPath(), "is authored as a custom relationship (must be the "
                       "schema's non-custom property)", "CUSTOM_ATTRIBUTE", stop=False)
        if ANCHOR_API in authored_apis:
            local_scales = self.value(prim.GetAttribute("gsverse:anchor:localScales"))
            scales = self.value(prim.GetAttribute("scales"))
            if local_scales is not None and scales is not None and np.array_equal(
                    np.array(local_scales), np.array(scales)):
                self.warn(path.AppendProperty("gsverse:anchor:localScales"),
                          "equals scales: should not be authored", "REDUNDANT_LOCAL_SCALES")
        if prim.GetAttribute("xformOpOrder").HasAuthoredValue():
            self.warn(path, "authors xformOps (splat prims should not)", "XFORM_OPS")
        if prim.GetAttribute("colorSpace:name").HasAuthoredValue():
            self.warn(path, "UsdColorSpaceAPI colorSpace:name is ignored for splat prims",
                      "USD_COLOR_SPACE")

    def layout_rules(self, splat_paths: list) -> None:
        """Hierarchy and anchor-mesh rules (check_usd only)."""
        px = self.px
        root = self.stage.GetDefaultPrim()
        root_path = root.GetPath() if root else None
        gprim = px.UsdGeom.Gprim
        for path in splat_paths + [m.GetPath() for m in self.mesh_prims]:
            if root_path is not None and not path.HasPrefix(root_path):
                self.error(path, f"is not a descendant of the defaultPrim {root_path}",
                           "OUTSIDE_DEFAULT_PRIM", stop=False)
            parent = self.stage.GetPrimAtPath(path).GetParent()
            while parent and not parent.IsPseudoRoot():
                if parent.IsA(gprim):
                    self.error(path, f"is nested under the Gprim {parent.GetPath()}",
                               "NESTED_GPRIM", stop=False)
                    break
                parent = parent.GetParent()
        seen = set()
        for mesh_prim in self.mesh_prims:
            if mesh_prim.GetPath() in seen:
                continue
            seen.add(mesh_prim.GetPath())
            m = px.UsdGeom.Mesh(mesh_prim)
            path = mesh_prim.GetPath()
            if m.GetPurposeAttr().Get() != px.UsdGeom.Tokens.guide:
                self.warn(m.GetPurposeAttr().GetPath(), "should be 'guide'", "MESH_PURPOSE")
            if m.GetSubdivisionSchemeAttr().Get() != px.UsdGeom.Tokens.none:
                self.warn(m.GetSubdivisionSchemeAttr().GetPath(), "should be 'none'",
                          "MESH_SUBDIVISION")
            if not m.GetExtentAttr().HasAuthoredValue():
                self.error(m.GetExtentAttr().GetPath(), "is not authored", "MISSING_EXTENT",
                           stop=False)
            for a in (m.GetFaceVertexCountsAttr(), m.GetFaceVertexIndicesAttr()):
                if a.GetNumTimeSamples():
                    self.error(a.GetPath(), "topology must not be time-sampled",
                               "TIME_SAMPLED", stop=False)
            if m.GetOrientationAttr().Get() != px.UsdGeom.Tokens.rightHanded:
                self.warn(m.GetOrientationAttr().GetPath(), "should be 'rightHanded' (it is "
                          "ignored for anchoring)", "MESH_ORIENTATION")
            if mesh_prim.GetAttribute("xformOpOrder").HasAuthoredValue():
                self.warn(path, "authors xformOps (ignored for anchoring)", "XFORM_OPS")

    def animation_rules(self, splat_prims: list) -> None:
        stage = self.stage
        sampled = any(prim.GetAttribute(n).GetNumTimeSamples()
                      for prim in splat_prims for n in ("positions", "orientations", "scales"))
        if not sampled:
            return
        for key in ("startTimeCode", "endTimeCode", "timeCodesPerSecond"):
            if not stage.HasAuthoredMetadata(key):
                self.error("", f"baked animation without authored {key}", "MISSING_TIME_CODES",
                           stop=False)


def _check_path(path: str) -> None:
    if os.path.isdir(path):
        raise FormatError("is a folder, not a USD file", path)
    if not os.path.isfile(path):
        raise FormatError("file not found", path)
    ext = os.path.splitext(path)[1].lower()
    if ext not in USD_SUFFIXES:
        raise FormatError(f"not a USD file name (use one of {', '.join(USD_SUFFIXES)})", path)


#: At most this many layers are followed when checking a file's composition arcs.
_MAX_LAYERS = 4096


class _OutsideFolder(FormatError):
    """A composition arc of the file leads outside the file's folder."""


def _inside(resolved: str, folder: str) -> bool:
    outer = resolved.split("[", 1)[0]  # "pkg.usdz[inner.usdc]": the package is what counts
    real = os.path.realpath(outer)
    return real == folder or real.startswith(folder.rstrip(os.sep) + os.sep)


def _check_composition(px: types.SimpleNamespace, path: str) -> None:
    """Refuse files whose sublayers, references or payloads leave the file's folder.

    Like the glTF reader's URI rules: an asset path with a scheme (``http:``, ...), an
    absolute path, or a relative path that resolves (symbolic links followed) outside the
    folder of ``path`` is refused before USD composes anything, so that opening a file never
    reads files elsewhere. Layers inside a ``.usdz`` package are inside by definition.
    Dependencies are followed recursively (``_MAX_LAYERS`` at most); a dependency that does
    not exist or does not open is left to USD (which reports it as a warning).
    """
    folder = os.path.realpath(os.path.dirname(os.path.abspath(path)))
    root = px.Sdf.Layer.FindOrOpen(path)
    if root is None:
        return  # not a layer at all: Usd.Stage.Open says why
    todo, seen = [root], {root.identifier}
    while todo:
        layer = todo.pop()
        for dep in layer.GetCompositionAssetDependencies():
            scheme = re.match(r"^([A-Za-z][A-Za-z0-9+.-]*):", dep)
            if scheme and len(scheme.group(1)) > 1:
                raise _OutsideFolder(f"composition arc to {dep!r} in {layer.GetDisplayName()}: "
                                     f"URI schemes are not followed", path)
            if os.path.isabs(dep) or dep.startswith(("\\", "//")) or scheme:
                raise _OutsideFolder(f"composition arc to the absolute path {dep!r} in "
                                     f"{layer.GetDisplayName()}: only paths inside the "
                                     f"asset's folder are followed", path)
            resolved = layer.ComputeAbsolutePath(dep)
            if not _inside(resolved, folder):
                raise _OutsideFolder(f"composition arc to {dep!r} in {layer.GetDisplayName()} "
                                     f"leaves the asset's folder", path)
            if resolved in seen:
                continue
            seen.add(resolved)
            if len(seen) > _MAX_LAYERS:
                raise FormatError(f"more than {_MAX_LAYERS} layers in the composition", path)
            try:
                child = px.Sdf.Layer.FindOrOpen(resolved)
            except Exception:
                child = None
            if child is not None:
                todo.append(child)


def _open_stage(px: types.SimpleNamespace, path: str):
    """Open ``path`` as a USD stage; every failure is a one-line FormatError."""
    _check_path(path)
    try:
        existing = px.Sdf.Layer.Find(path)
        if existing is not None and not existing.dirty:
            existing.Reload(True)  # the file may have been replaced since it was opened
        _check_composition(px, path)
        stage = px.Usd.Stage.Open(path, px.Usd.Stage.LoadAll)
    except FormatError:
        raise
    except Exception as err:
        raise FormatError(f"not a readable USD file: {_pxr_message(err)}", path) from None
    if stage is None:
        raise FormatError("not a readable USD file", path)
    return stage


def _read_in_process(spath: str) -> tuple[SplatAsset, list[UsdProblem]]:
    try:
        px = _pxr()
        stage = _open_stage(px, spath)
        reader = _Reader(px, stage)
        try:
            asset = reader.read()
        except _Invalid:
            asset = None
    except GsverseError as err:
        raise err.with_path(spath) from None
    except MemoryError:
        raise FormatError("not enough memory to read the asset", spath) from None
    except Exception as err:  # last line of defence: malformed input never escapes as a crash
        raise FormatError(f"malformed USD ({type(err).__name__}: {_pxr_message(err)})",
                          spath) from None
    errors = [p for p in reader.problems if p.severity == "error"]
    if errors:
        first = errors[0]
        where = f"{first.location}: " if first.location else ""
        raise FormatError(f"{where}{first.message}", spath)
    return asset, reader.problems


def read_usd(path: str | os.PathLike, *, isolate: bool = False,
             timeout: float | None = None) -> SplatAsset:
    """Read every ``ParticleField3DGaussianSplat`` prim of a USD file as a splat primitive.

    Prims with ``GsVerseMeshAnchorAPI`` get their :class:`Anchoring` (prims targeting the same
    ``Mesh`` share one :class:`TriangleMesh`); the rest pose is always the default values,
    never time samples. Foreign data follows the USD schema's rules (spec/usd.md §Foreign
    data), each replacement reported as a :class:`UsdReadWarning`; Z-up stages and other
    units are converted to glTF's frame. The name of a primitive is the prim's
    ``displayName``, else its name. Raises :class:`FormatError` (one line naming ``path`` and
    the USD property) for unreadable files and invalid anchored prims, :class:`UsageError`
    without usd-core.

    USD's binary reader can crash the process or exhaust its memory on some corrupted
    ``.usdc`` data (observed with usd-core 26.11). ``isolate=True`` reads in a child process
    (with a memory cap, and ``timeout`` seconds at most), so that such a file becomes a
    :class:`FormatError` too; use it for untrusted files.
    """
    spath = os.fspath(path)
    if isolate:
        result = _run_isolated("read", spath, timeout)
        problems = [UsdProblem(**p) for p in result["problems"]]
        asset = result["asset"]
    else:
        asset, problems = _read_in_process(spath)
    for p in problems:
        warnings.warn(f"{spath}: {p.location + ': ' if p.location else ''}{p.message}",
                      UsdReadWarning, stacklevel=2)
    return asset


def check_usd(path: str | os.PathLike, *, usd_validation: bool = True, isolate: bool = True,
              timeout: float | None = None) -> list[UsdProblem]:
    """Every problem of a USD splat file against spec/usd.md, for validators.

    Runs what :func:`read_usd` checks (errors it would raise, data it would replace) plus the
    writer rules (stage metadata and layout, API schema authoring, anchor-mesh and baked
    animation rules) and, with ``usd_validation``, OpenUSD's own validators
    (``pxr.UsdValidation``, codes ``usd:<validator name>``). A file whose list has no
    ``"error"`` entry conforms. A file whose composition arcs leave its folder is not opened
    (one ``LAYER_OUTSIDE_FOLDER`` error). Raises :class:`FormatError` only when the file
    cannot be opened as a USD stage at all, :class:`UsageError` without usd-core.

    By default the file is checked in a child process (see :func:`read_usd`), which also
    guarantees that the GsVerse schemas are registered there, so that OpenUSD's
    ``AttributeTypeMismatch`` validator checks the ``gsverse:`` attributes.
    """
    return inspect_usd(path, usd_validation=usd_validation, isolate=isolate, timeout=timeout,
                       data=False).problems


@dataclass(frozen=True)
class UsdPrimInfo:
    """Where a primitive of :class:`UsdInspection` comes from: its splat prim, its anchor
    ``Mesh`` (None when static), and whether the prim applies a GsVerse API schema (else it
    is foreign data, to which the writer rules of spec/usd.md do not apply)."""

    path: str
    mesh_path: str | None
    gsverse: bool


@dataclass
class UsdInspection:
    """What :func:`inspect_usd` found in a USD file.

    ``problems`` as :func:`check_usd` returns them. ``asset`` holds the splat primitives that
    could be read (anchored prims with errors are left out), with orientations, scales,
    opacities and local orientations **as authored** (not normalized, made positive or
    clamped), converted to +Y up and metres like :func:`read_usd`. ``prims`` says where
    each primitive comes from.
    """

    problems: list[UsdProblem]
    asset: SplatAsset
    prims: list[UsdPrimInfo]


def inspect_usd(path: str | os.PathLike, *, usd_validation: bool = True, isolate: bool = True,
                timeout: float | None = None, data: bool = True) -> UsdInspection:
    """:func:`check_usd` plus the data it read (``data=False``: problems only, empty asset).

    Validators use the data to run the checks that do not depend on the file format (unit
    quaternions, triangle quality, rest-pose consistency). Raises like :func:`check_usd`.
    """
    spath = os.fspath(path)
    if isolate:
        mode = ("inspect" if data else "check") + ("-validate" if usd_validation else "")
        result = _run_isolated(mode, spath, timeout)
        problems = [UsdProblem(**p) for p in result["problems"]]
        if not data:
            return UsdInspection(problems, SplatAsset([]), [])
        return UsdInspection(problems, result["asset"],
                             [UsdPrimInfo(**p) for p in result["prims"]])
    try:
        px = _pxr()
        try:
            stage = _open_stage(px, spath)
        except _OutsideFolder as err:
            return UsdInspection([UsdProblem("error", "", err.cause, "LAYER_OUTSIDE_FOLDER")],
                                 SplatAsset([]), [])
        reader = _Reader(px, stage, conformance=True)
        try:
            asset = reader.read()
        except _Invalid:
            asset = SplatAsset([])
            reader.locations = []
        splats = [p for p in stage.Traverse() if p.IsA(px.UsdVol.ParticleField3DGaussianSplat)]
        reader.layout_rules([p.GetPath() for p in splats])
        reader.animation_rules(splats)
        problems = list(reader.problems)
        if usd_validation:
            problems += _usd_validation(stage)
    except GsverseError as err:
        raise err.with_path(spath) from None
    except MemoryError:
        raise FormatError("not enough memory to read the asset", spath) from None
    except Exception as err:
        raise FormatError(f"malformed USD ({type(err).__name__}: {_pxr_message(err)})",
                          spath) from None
    if not data:
        return UsdInspection(problems, SplatAsset([]), [])
    return UsdInspection(problems, asset, list(reader.locations))


# ----------------------------------------------------------------------------------------
# Isolated reading (child process)
# ----------------------------------------------------------------------------------------

#: Address-space cap of the child: this much plus 32 times the file size.
_CHILD_MEMORY_BASE = 8 * 2 ** 30
_CHILD_CODE = "from gsverse_format.io.usd import _child_main; _child_main()"


def _child_limits(memory: int):  # pragma: no cover - runs in the child before exec
    def apply() -> None:
        try:
            import resource

            resource.setrlimit(resource.RLIMIT_AS, (memory, memory))
            resource.setrlimit(resource.RLIMIT_CORE, (0, 0))
        except (ImportError, ValueError, OSError):
            pass
    return apply


def _run_isolated(mode: str, spath: str, timeout: float | None) -> dict:
    """Run ``mode`` on ``spath`` in a child interpreter: "read", or "check"/"inspect" with an
    optional "-validate" suffix (also run ``pxr.UsdValidation``)."""
    import signal
    import subprocess
    import sys

    try:
        _import_pxr()  # the missing-usd-core error belongs to the caller's process
        _check_path(spath)
    except GsverseError as err:
        raise err.with_path(spath) from None
    memory = _CHILD_MEMORY_BASE + 32 * os.path.getsize(spath)
    env = dict(os.environ)
    package_root = str(pathlib.Path(__file__).resolve().parents[2])
    env["PYTHONPATH"] = package_root + (os.pathsep + env["PYTHONPATH"]
                                        if env.get("PYTHONPATH") else "")
    with tempfile.TemporaryDirectory(prefix="gsverse-usd-") as work:
        out = os.path.join(work, "result")
        try:
            proc = subprocess.run(
                [sys.executable, "-c", _CHILD_CODE, mode, os.path.abspath(spath), out],
                env=env, stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL,
                stderr=subprocess.PIPE, timeout=timeout,
                preexec_fn=_child_limits(memory) if os.name == "posix" else None)
        except subprocess.TimeoutExpired:
            raise FormatError(f"reading the USD file took longer than {timeout} s",
                              spath) from None
        try:
            with open(out + ".json", encoding="utf-8") as handle:
                result = json.load(handle)
        except (OSError, ValueError):
            result = None
        if result is None:
            if proc.returncode < 0:
                try:
                    name = signal.Signals(-proc.returncode).name
                except ValueError:
                    name = f"signal {-proc.returncode}"
                raise FormatError(f"corrupt USD file: the USD library crashed reading it "
                                  f"({name})", spath)
            tail = proc.stderr.decode("utf-8", "replace").strip().splitlines()
            raise FormatError(f"corrupt USD file: the USD library failed reading it (exit "
                              f"code {proc.returncode}"
                              f"{': ' + tail[-1][:200] if tail else ''})", spath)
        if not result["ok"]:
            kind = UsageError if result["error"] == "UsageError" else FormatError
            raise kind(result["cause"], spath)
        if "asset" in result:
            result["asset"] = _load_asset(out + ".npz", result["asset"])
        return result


def _save_asset(asset: SplatAsset, path: str) -> dict:
    """Store ``asset`` as an uncompressed .npz (arrays) plus a JSON-able description."""
    arrays: dict[str, np.ndarray] = {}
    meshes: dict[int, int] = {}
    prims = []
    for i, p in enumerate(asset.primitives):
        c = p.splats
        arrays.update({f"p{i}_means": c.means, f"p{i}_rotations": c.rotations,
                       f"p{i}_scales": c.scales, f"p{i}_opacities": c.opacities,
                       f"p{i}_sh": c.sh})
        entry: dict = {"name": p.name, "color_space": c.color_space}
        if p.anchoring is not None:
            mesh, a = p.anchoring.mesh, p.anchoring.anchors
            if id(mesh) not in meshes:
                j = meshes[id(mesh)] = len(meshes)
                arrays.update({f"m{j}_vertices": mesh.vertices, f"m{j}_faces": mesh.faces})
            entry.update(mesh=meshes[id(mesh)], profile=a.profile)
            arrays.update({f"p{i}_face": a.face_index, f"p{i}_bary": a.barycentrics})
            if isinstance(a, LocalAnchors):
                entry["deformation"] = a.deformation
                arrays.update({f"p{i}_offset": a.normal_offset, f"p{i}_lrot": a.local_rotation,
                               f"p{i}_lscale": a.local_scale})
            else:
                arrays[f"p{i}_rho"] = a.rho
        prims.append(entry)
    np.savez(path, **arrays)
    return {"generator": asset.generator, "primitives": prims, "meshes": len(meshes)}


def _load_asset(path: str, meta: dict) -> SplatAsset:
    """Inverse of :func:`_save_asset`."""
    with np.load(path, allow_pickle=False) as z:
        meshes = [TriangleMesh(z[f"m{j}_vertices"], z[f"m{j}_faces"])
                  for j in range(meta["meshes"])]
        prims = []
        for i, e in enumerate(meta["primitives"]):
            cloud = SplatCloud(z[f"p{i}_means"], z[f"p{i}_rotations"], z[f"p{i}_scales"],
                               z[f"p{i}_opacities"], z[f"p{i}_sh"], e["color_space"])
            anchoring = None
            if "mesh" in e:
                if e["profile"] == "games":
                    anchors = GamesAnchors(z[f"p{i}_face"], z[f"p{i}_bary"], z[f"p{i}_rho"])
                else:
                    anchors = LocalAnchors(z[f"p{i}_face"], z[f"p{i}_bary"], z[f"p{i}_offset"],
                                           z[f"p{i}_lrot"], z[f"p{i}_lscale"], e["deformation"])
                anchoring = Anchoring(meshes[e["mesh"]], anchors)
            prims.append(SplatPrimitive(cloud, anchoring, e["name"]))
    return SplatAsset(prims, meta["generator"])


def _child_main() -> None:  # pragma: no cover - runs in a child interpreter
    import sys
    from dataclasses import asdict

    mode, path, out = sys.argv[1:4]
    result: dict = {"ok": True, "problems": []}
    try:
        if mode == "read":
            asset, problems = _read_in_process(path)
            result.update(asset=_save_asset(asset, out + ".npz"),
                          problems=[asdict(p) for p in problems])
        else:
            found = inspect_usd(path, usd_validation=mode.endswith("-validate"), isolate=False,
                                data=mode.startswith("inspect"))
            result["problems"] = [asdict(p) for p in found.problems]
            if mode.startswith("inspect"):
                result.update(asset=_save_asset(found.asset, out + ".npz"),
                              prims=[asdict(p) for p in found.prims])
    except GsverseError as err:
        result = {"ok": False, "error": type(err).__name__, "cause": err.cause}
    with open(out + ".json", "w", encoding="utf-8") as handle:
        json.dump(result, handle)


def _usd_validation(stage) -> list[UsdProblem]:
    from pxr import UsdValidation

    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    found = UsdValidation.ValidationContext(validators).Validate(stage)
    out = []
    for e in found:
        kind = e.GetType()
        if kind == UsdValidation.ValidationErrorType.Error:
            severity = "error"
        elif kind == UsdValidation.ValidationErrorType.Warn:
            severity = "warning"
        else:
            continue
        location = ""
        for site in e.GetSites():
            if site.IsProperty():
                location = str(site.GetProperty().GetPath())
            elif site.IsPrim():
                location = str(site.GetPrim().GetPath())
            if location:
                break
        validator = e.GetValidator()
        name = validator.GetMetadata().name if validator else e.GetName()
        out.append(UsdProblem(severity, location, " ".join(e.GetMessage().split()),
                              f"usd:{name}"))
    return out
