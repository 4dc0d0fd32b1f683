"""Writing a :class:`SplatAsset` as a USD stage (spec/usd.md §Writing), atomically.

Each primitive becomes a ``ParticleField3DGaussianSplat`` prim under the ``/Asset`` Xform with
the rest pose as default values and ``GsVerseMeshAnchorAPI`` (anchored) or
``GsVerseColorSpaceAPI`` (static); each anchor mesh a ``Mesh`` of triangles. Optionally the
remap of a sequence of anchor-mesh poses is baked into time samples (:class:`BakedPoses`).
"""
from __future__ import annotations

import os
import types
from typing import Any, Iterable

import numpy as np

from ...version import __version__
from ...atomic import check_target, file_mode, output_error, temporary_folder
from ...errors import GsverseError, UsageError
from ...model import Collider, LocalAnchors, SplatAsset, SplatPrimitive, TriangleMesh, check_primitive
from ...quaternion import unit_quaternions
from ...vocabulary import USD_DEFORMATION, USD_PROFILE, allowed_fields, frame_record
from .poses import BakedPoses
from .schema import (ANCHOR_API, COLOR_SPACE_API, COLOR_SPACE_ATTR, INT32_MAX, MESH_REL,
                     ROOT_PRIM, USD_SUFFIXES, USD_TYPES, pxr, pxr_errors, pxr_message,
                     schema_registered)

__all__ = ["write_usd"]


def _check_asset(asset: SplatAsset) -> None:
    for i, prim in enumerate(asset.primitives):
        check_primitive(i, prim)
        if prim.anchoring is not None:
            mesh = prim.anchoring.mesh
            if mesh.face_count > INT32_MAX or len(mesh.vertices) > INT32_MAX:
                raise UsageError(f"primitive {i}: anchor mesh too large for USD int indices")


def _check_poses(asset: SplatAsset, poses: BakedPoses | None) -> TriangleMesh | None:
    """The anchor mesh the poses deform (exactly one per asset), or None without poses."""
    if poses is None:
        return None
    if not isinstance(poses, BakedPoses):
        raise UsageError("bake_poses must be a BakedPoses (see load_poses)")
    meshes = {id(p.anchoring.mesh): p.anchoring.mesh for p in asset.anchored
              if p.anchoring is not None}
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


def _anchor_values(px: types.SimpleNamespace, prim: SplatPrimitive) -> list[tuple[str, Any, Any]]:
    """(name, Sdf type, value) of the API schema attributes of one primitive, in writing order."""
    T, Vt = px.Sdf.ValueTypeNames, px.Vt
    out: list[tuple[str, Any, Any]] = [(COLOR_SPACE_ATTR, T.Token, prim.splats.color_space)]
    if prim.anchoring is None:
        return out
    a = prim.anchoring.anchors
    out.append((USD_PROFILE, T.Token, a.profile))
    if isinstance(a, LocalAnchors):
        out.append((USD_DEFORMATION, T.Token, a.deformation))
    for field in allowed_fields(a.profile):
        values = np.asarray(getattr(a, field.attribute))
        if field.attribute == "local_scale" and np.array_equal(values, prim.splats.scales):
            continue  # the rest scales stand for it (spec/usd.md)
        if field.attribute == "local_rotation":
            values = unit_quaternions(values)
        usd_type = USD_TYPES[field.attribute]
        if usd_type.sdf == "IntArray":
            values = values.astype(np.int32)
        out.append((field.usd, getattr(T, usd_type.sdf),
                    getattr(Vt, usd_type.vt).FromNumpy(values)))
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
    gs.CreateOrientationsAttr(Vt.QuatfArray.FromNumpy(unit_quaternions(c.rotations)))
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
    values = _anchor_values(px, prim)
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
          splat_prims: list[tuple[SplatPrimitive, Any]]) -> None:
    """Time samples of the remap at every pose (spec/usd.md §Baked animation)."""
    from ...remapping.reference import prepare_rest, remap

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
        assert anchoring is not None  # only anchored primitives are baked
        rest = (prepare_rest(anchoring.mesh.triangles())
                if isinstance(anchoring.anchors, LocalAnchors) else None)
        previous = unit_quaternions(prim.splats.rotations)
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
    Usd, UsdGeom = px.Usd, px.UsdGeom
    stage = Usd.Stage.CreateInMemory()
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = UsdGeom.Xform.Define(stage, "/" + ROOT_PRIM)
    Usd.ModelAPI(root.GetPrim()).SetKind(px.Kind.Tokens.component)
    stage.SetDefaultPrim(root.GetPrim())
    layer_data: dict[str, Any] = {"generator": f"gsverse-format {__version__}"}
    record = frame_record(asset.frame)
    if record is not None:
        layer_data["gsverse"] = record
    stage.GetRootLayer().customLayerData = layer_data
    names = _Names(px)
    root_path = root.GetPath()
    mesh_paths: dict[int, Any] = {}
    mesh_schemas: dict[int, Any] = {}
    anchored: list[tuple[SplatPrimitive, Any]] = []
    # Several anchor meshes (a scene of objects) are named after their first primitive.
    several = len({id(p.anchoring.mesh) for p in asset.anchored if p.anchoring}) > 1
    for prim in asset.primitives:
        mesh_path = None
        if prim.anchoring is not None:
            key = id(prim.anchoring.mesh)
            if key not in mesh_paths:
                wanted = f"{prim.name}_anchor_mesh" if several and prim.name else None
                mesh_paths[key] = root_path.AppendChild(names.take(wanted, "anchor_mesh"))
                mesh_schemas[key] = _define_mesh(px, stage, mesh_paths[key], prim.anchoring.mesh)
            mesh_path = mesh_paths[key]
        name = names.take(prim.name, "splats")
        gs = _define_splats(px, stage, root_path.AppendChild(name), prim, mesh_path, registered)
        if prim.name and name != prim.name:
            gs.GetPrim().SetDisplayName(prim.name)
        if prim.anchoring is not None:
            anchored.append((prim, gs))
    for collider in asset.colliders:
        if id(collider.anchor) in mesh_paths:
            _define_collider(px, stage, names, mesh_paths[id(collider.anchor)], collider)
    if poses is not None:
        (key,) = mesh_schemas  # _check_poses guarantees exactly one anchor mesh
        _bake(px, stage, poses, mesh_schemas[key], anchored)
    return stage


def _define_collider(px: types.SimpleNamespace, stage, names: _Names, anchor_path,
                     collider: Collider) -> None:
    """A collider beside its anchor mesh: a guide ``Mesh`` with UsdPhysics ``CollisionAPI``
    and ``MeshCollisionAPI`` (approximation ``convexHull`` for a hull), and
    ``customData = {"gsverse": {"collider": kind, "for": <anchor mesh path>}}``
    (spec/README.md §Colliders)."""
    from pxr import UsdPhysics

    path = anchor_path.GetParentPath().AppendChild(
        names.take(f"{anchor_path.name}_{collider.kind}_collider", "collider"))
    mesh = _define_mesh(px, stage, path, collider.mesh)
    prim = mesh.GetPrim()
    UsdPhysics.CollisionAPI.Apply(prim)
    approximation = {"hull": UsdPhysics.Tokens.convexHull}.get(collider.kind,
                                                               UsdPhysics.Tokens.none)
    UsdPhysics.MeshCollisionAPI.Apply(prim).CreateApproximationAttr(approximation)
    prim.SetCustomDataByKey("gsverse", {"collider": collider.kind, "for": str(anchor_path)})


def _check_protect(path: str, protect: Iterable) -> None:
    check_target(path, tuple(protect))


def _save(px: types.SimpleNamespace, layer, path: str, ext: str) -> None:
    """Export ``layer`` atomically: a temporary folder beside the target (named and cleaned
    up as :mod:`gsverse_format.atomic` names them), whose result file is committed into place by
    the same step as every atomic write (interruptions included)."""
    mode = file_mode()
    name = "package.usdz" if ext == ".usdz" else "asset" + ext
    try:
        with temporary_folder(path, result=name) as work:
            result = os.path.join(work, name)
            if ext == ".usdz":
                stem = os.path.splitext(os.path.basename(path))[0]
                inner = os.path.join(work, px.Tf.MakeValidIdentifier(stem or "asset") + ".usdc")
                if not layer.Export(inner):
                    raise GsverseError("cannot write the USD layer", path)
                if not px.UsdUtils.CreateNewUsdzPackage(px.Sdf.AssetPath(inner), result):
                    raise GsverseError("cannot create the USDZ package", path)
            elif not layer.Export(result):
                raise GsverseError("cannot write the USD layer", path)
            os.chmod(result, mode)
    except GsverseError:
        raise
    except OSError as err:
        raise output_error(err, path) or GsverseError(f"cannot write: {err.strerror or err}",
                                                      path) from None
    except pxr_errors() as err:
        raise GsverseError(f"cannot write USD: {pxr_message(err)}", path) from None


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
        px = pxr()
        _check_asset(asset)
        _check_poses(asset, bake_poses)
        _check_protect(spath, protect)
        stage = _build_stage(px, asset, bake_poses, schema_registered())
        _save(px, stage.GetRootLayer(), spath, ext)
    except GsverseError as err:
        raise err.with_path(spath) from None
