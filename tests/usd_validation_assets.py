"""USD test assets for ``gsverse-validate``: valid files and one trigger per issue code that
applies to USD (the ``USD_*`` codes and the glTF codes with a USD location).

Every file is written here by :func:`gsverse_format.io.usd.write_usd` from the consistent
assets of :mod:`validation_assets`, then changed in one place, as ``.usda`` text or with
``pxr.Sdf``. Nothing binary is stored in the repository.
"""
from __future__ import annotations

import pathlib
from typing import Callable

import numpy as np

from gsverse_format.io.usd import write_usd
from gsverse_format.model import Anchoring, GamesAnchors, SplatAsset, SplatPrimitive, TriangleMesh

from validation_assets import Trigger, games_asset, local_asset

USD_TRIGGERS: dict[str, Callable[[pathlib.Path], Trigger]] = {}
BODY, STATIC, MESH = "/Asset/body", "/Asset/static", "/Asset/anchor_mesh"

#: Code for the USD child process (prepended to ``isolation.CHILD_CODE``) that breaks the
#: reader with an unexpected exception: a bug, which must be reported as a crash.
BROKEN_READER = ("from gsverse_format.io.usd import reader\n"
                 "def broken(self):\n    raise KeyError('injected')\n"
                 "reader.StageReader.read = broken\n")


def usd_trigger(code: str):
    def register(fn):
        assert code not in USD_TRIGGERS, code
        USD_TRIGGERS[code] = fn
        return fn
    return register


def clean_usd_assets(folder: pathlib.Path) -> list[pathlib.Path]:
    """Files of every kind the writer produces; they must validate without any finding."""
    folder = pathlib.Path(folder)
    out = []
    for name, asset in (("local_affine.usda", local_asset()),
                        ("local_rigid.usdc", local_asset(deformation="rigid")),
                        ("games.usdz", games_asset()),
                        ("games.usd", games_asset(seed=5))):
        path = folder / name
        write_usd(asset, path)
        out.append(path)
    return out


# ---------------------------------------------------------------------------- builders

def _write(folder, name: str, asset: SplatAsset | None = None) -> pathlib.Path:
    path = pathlib.Path(folder) / name
    write_usd(asset if asset is not None else local_asset(24), path)
    return path


def _text(folder, name: str, *edits: tuple[str, str], asset: SplatAsset | None = None,
          **options) -> Trigger:
    """The base asset as .usda with each ``(old, new)`` replaced once (``old`` must occur)."""
    path = _write(folder, name, asset)
    text = path.read_text(encoding="utf-8")
    for old, new in edits:
        assert old in text, old
        text = text.replace(old, new, 1)
    path.write_text(text, encoding="utf-8")
    return Trigger(path, options)


def _add_property(folder, name: str, prim: str, line: str, **kw) -> Trigger:
    """Insert the .usda property ``line`` at the top of the body of ``prim``."""
    path = _write(folder, name, kw.pop("asset", None))
    text = path.read_text(encoding="utf-8")
    leaf = prim.rsplit("/", 1)[1]
    start = text.index(f'"{leaf}"')
    brace = text.index("{\n", start) + 2
    text = text[:brace] + f"        {line}\n" + text[brace:]
    path.write_text(text, encoding="utf-8")
    return Trigger(path, kw)


def _sdf(folder, name: str, edit: Callable, asset: SplatAsset | None = None,
         **options) -> Trigger:
    """The base asset with ``edit(layer)`` applied through ``pxr.Sdf``."""
    from pxr import Sdf

    path = _write(folder, name, asset)
    layer = Sdf.Layer.FindOrOpen(str(path))
    layer.Reload(True)
    edit(layer)
    layer.Save()
    return Trigger(path, options)


def _set_default(layer, prop: str, change: Callable[[np.ndarray], np.ndarray]) -> None:
    spec = layer.GetAttributeAtPath(prop)
    kind = type(spec.default)
    value = np.array(spec.default)
    spec.default = kind.FromNumpy(np.ascontiguousarray(change(value.copy()), dtype=value.dtype))


def _with_mesh(asset: SplatAsset, vertices=None, faces=None) -> SplatAsset:
    """``asset`` with its anchor mesh given extra vertices and faces (anchors unchanged)."""
    p = asset.primitives[0]
    mesh = p.anchoring.mesh
    v = mesh.vertices if vertices is None else np.vstack([mesh.vertices, vertices])
    f = mesh.faces if faces is None else np.vstack([mesh.faces, faces])
    new = TriangleMesh(np.asarray(v, np.float32), np.asarray(f, np.int64))
    asset.primitives[0] = SplatPrimitive(p.splats, Anchoring(new, p.anchoring.anchors), p.name)
    return asset


# ---------------------------------------------------------------------------- shared codes

@usd_trigger("IO_ERROR")
def _(folder):
    return Trigger(pathlib.Path(folder) / "missing.usda")


@usd_trigger("SIZE_LIMIT_EXCEEDED")
def _(folder):
    return Trigger(_write(folder, "big.usda"), {"max_bytes": 1000})


@usd_trigger("SPLAT_COUNT_LIMIT")
def _(folder):
    return Trigger(_write(folder, "many.usdc"), {"max_splats": 10})


@usd_trigger("NON_FINITE_VALUE")
def _(folder):
    return _sdf(folder, "nan.usdc", lambda layer: _set_default(
        layer, f"{BODY}.positions", lambda v: np.where(np.arange(len(v))[:, None] == 2, np.nan, v)))


@usd_trigger("ROTATION_NOT_UNIT")
def _(folder):
    def edit(layer):
        spec = layer.GetAttributeAtPath(f"{BODY}.orientations")
        q = list(spec.default)
        q[1] = q[1] * 2.0
        spec.default = type(spec.default)(q)
    return _sdf(folder, "rotation.usda", edit)


@usd_trigger("SCALE_NEGATIVE")
def _(folder):
    return _sdf(folder, "scale.usda", lambda layer: _set_default(
        layer, f"{STATIC}.scales", lambda v: v * np.where(np.arange(len(v))[:, None] == 1, -1, 1)))


@usd_trigger("OPACITY_OUT_OF_RANGE")
def _(folder):
    return _sdf(folder, "opacity.usda", lambda layer: _set_default(
        layer, f"{STATIC}.opacities", lambda v: v + np.where(np.arange(len(v)) == 0, 1.0, 0.0)))


@usd_trigger("ANCHOR_MESH_NOT_TRIANGLES")
def _(folder):
    return _text(folder, "quad.usda", ("int[] faceVertexCounts = [3, 3", "int[] faceVertexCounts = [4, 2"))


@usd_trigger("ANCHOR_MESH_INDICES_INVALID")
def _(folder):
    return _text(folder, "index.usda", ("int[] faceVertexIndices = [0, ",
                                        "int[] faceVertexIndices = [9999, "))


@usd_trigger("MESH_DEGENERATE_TRIANGLES")
def _(folder):
    return Trigger(_write(folder, "degenerate.usda", _with_mesh(local_asset(24),
                                                                faces=[[0, 1, 1]])))


@usd_trigger("MESH_SLIVER_TRIANGLES")
def _(folder):
    asset = local_asset(24)
    n = len(asset.primitives[0].anchoring.mesh.vertices)
    return Trigger(_write(folder, "sliver.usda", _with_mesh(
        asset, vertices=[[-0.5, 2, 0], [0.5, 2, 0], [0, 2.0001, 0]], faces=[[n, n + 1, n + 2]])))


@usd_trigger("ANCHOR_MESH_NOT_MANIFOLD")
def _(folder):
    asset = local_asset(24)   # a lone triangle beside the closed mesh: three boundary edges
    n = len(asset.primitives[0].anchoring.mesh.vertices)
    return Trigger(_write(folder, "open.usda", _with_mesh(
        asset, vertices=[[3, 0, 0], [4, 0, 0], [3, 1, 0]], faces=[[n, n + 1, n + 2]])))


@usd_trigger("MESH_DUPLICATE_TRIANGLES")
def _(folder):
    asset = local_asset(24)
    first = asset.primitives[0].anchoring.mesh.faces[0]
    return Trigger(_write(folder, "duplicate.usda", _with_mesh(asset, faces=[first[[1, 2, 0]]])))


@usd_trigger("ANCHOR_FACE_OUT_OF_RANGE")
def _(folder):
    return _sdf(folder, "face.usda", lambda layer: _set_default(
        layer, f"{BODY}.gsverse:anchor:faceIndices", lambda v: np.where(v == v.max(), 10 ** 6, v)))


@usd_trigger("ANCHOR_BOUND_TO_DEGENERATE")
def _(folder):
    asset = local_asset(24)
    p = asset.primitives[0]
    mesh = p.anchoring.mesh
    faces = mesh.faces.copy()
    f = int(p.anchoring.anchors.face_index[0])
    faces[f] = [faces[f][0], faces[f][1], faces[f][1]]
    asset.primitives[0] = SplatPrimitive(
        p.splats, Anchoring(TriangleMesh(mesh.vertices, faces), p.anchoring.anchors), p.name)
    return Trigger(_write(folder, "bound.usda", asset))


@usd_trigger("ANCHOR_NOT_SORTED")
def _(folder):
    return Trigger(_write(folder, "unsorted.usda", local_asset(24, shuffle=True)))


@usd_trigger("GAMES_BARYCENTRICS_OUTSIDE_SIMPLEX")
def _(folder):
    asset = games_asset(12)
    p = asset.primitives[0]
    a = p.anchoring.anchors
    bary = np.array(a.barycentrics, np.float32)
    bary[0] = (1.2, 0.1)
    asset.primitives[0] = SplatPrimitive(p.splats, Anchoring(
        p.anchoring.mesh, GamesAnchors(a.face_index, bary, a.rho)), p.name)
    return Trigger(_write(folder, "simplex.usda", asset))


@usd_trigger("LOCAL_BARYCENTRICS_FAR")
def _(folder):
    return Trigger(_write(folder, "far.usda", local_asset(60, floater=True)))


@usd_trigger("ANCHOR_MESH_MISFIT")
def _(folder):
    return Trigger(_write(folder, "misfit.usda", local_asset(60, away=50.0)))


@usd_trigger("GAMES_RHO_NEGATIVE")
def _(folder):
    return Trigger(_write(folder, "rho.usda", games_asset(negative_rho=True)))


@usd_trigger("REST_POSE_MEAN_MISMATCH")
def _(folder):
    return _sdf(folder, "mean.usdc", lambda layer: _set_default(
        layer, f"{BODY}.positions", lambda v: v + np.where(np.arange(len(v))[:, None] == 3, 0.01, 0)))


@usd_trigger("REST_POSE_COVARIANCE_MISMATCH")
def _(folder):
    def edit(layer):
        spec = layer.GetAttributeAtPath(f"{BODY}.orientations")
        q = list(spec.default)
        q[2] = type(q[2])(0.0, 0.0, 0.0, 1.0) if q[2].GetReal() != 1.0 else type(q[2])(0.0, 1.0, 0.0, 0.0)
        spec.default = type(spec.default)(q)
    return _sdf(folder, "covariance.usda", edit)


@usd_trigger("INTERNAL_ERROR")
def _(folder):
    return Trigger(_write(folder, "fault.usda"), fault=True)


# ---------------------------------------------------------------------------- USD codes

@usd_trigger("USD_SUPPORT_MISSING")
def _(folder):
    return Trigger(_write(folder, "no-usd-core.usda"), {}, fault="block_pxr")


@usd_trigger("USD_UNREADABLE")
def _(folder):
    path = pathlib.Path(folder) / "garbage.usda"
    path.write_text("#usda 1.0\n(\n    upAxis = \n", encoding="utf-8")
    return Trigger(path)


@usd_trigger("USD_LAYER_OUTSIDE_FOLDER")
def _(folder):
    inner = pathlib.Path(folder) / "inner"
    inner.mkdir(exist_ok=True)
    _write(folder, "outside.usda")
    return _text(inner, "escape.usda", ('    defaultPrim = "Asset"\n',
                                        '    defaultPrim = "Asset"\n    subLayers = [@../outside.usda@]\n'))


@usd_trigger("USD_TYPE_MISMATCH")
def _(folder):
    return _text(folder, "type.usda", ("uniform int[] gsverse:anchor:faceIndices",
                                       "uniform float[] gsverse:anchor:faceIndices"))


@usd_trigger("USD_UP_AXIS_INVALID")
def _(folder):
    return _text(folder, "upx.usda", ('upAxis = "Y"', 'upAxis = "X"'))


@usd_trigger("USD_UP_AXIS_MISSING")
def _(folder):
    return _text(folder, "noup.usda", ('    upAxis = "Y"\n', ""))


@usd_trigger("USD_UP_AXIS_CONVERTED")
def _(folder):
    return _text(folder, "zup.usda", ('upAxis = "Y"', 'upAxis = "Z"'))


@usd_trigger("USD_METERS_PER_UNIT_INVALID")
def _(folder):
    return _text(folder, "mpu.usda", ("metersPerUnit = 1", "metersPerUnit = -1"))


@usd_trigger("USD_METERS_PER_UNIT_MISSING")
def _(folder):
    return _text(folder, "nompu.usda", ("    metersPerUnit = 1\n", ""))


@usd_trigger("USD_UNITS_CONVERTED")
def _(folder):
    return _text(folder, "cm.usda", ("metersPerUnit = 1", "metersPerUnit = 0.01"))


@usd_trigger("USD_DEFAULT_PRIM_MISSING")
def _(folder):
    return _text(folder, "nodefault.usda", ('    defaultPrim = "Asset"\n', ""))


@usd_trigger("USD_DEFAULT_PRIM_NOT_XFORM")
def _(folder):
    return _text(folder, "scope.usda", ('def Xform "Asset"', 'def Scope "Asset"'))


@usd_trigger("USD_OUTSIDE_DEFAULT_PRIM")
def _(folder):
    trigger = _text(folder, "outside_default.usda", ('defaultPrim = "Asset"', 'defaultPrim = "Other"'))
    with open(trigger.path, "a", encoding="utf-8") as handle:
        handle.write('\ndef Xform "Other"\n{\n}\n')
    return trigger


@usd_trigger("USD_NESTED_GPRIM")
def _(folder):
    def edit(layer):
        from pxr import Sdf
        Sdf.CopySpec(layer, STATIC, layer, f"{MESH}/static")
        del layer.GetPrimAtPath("/Asset").nameChildren["static"]
    return _sdf(folder, "nested.usda", edit)


@usd_trigger("USD_PROPERTY_MISSING")
def _(folder):
    return _sdf(folder, "missing_offsets.usda", lambda layer: layer.GetPrimAtPath(BODY).RemoveProperty(
        layer.GetPropertyAtPath(f"{BODY}.gsverse:anchor:normalOffsets")))


@usd_trigger("USD_PROPERTY_EXCLUDED")
def _(folder):
    n = len(local_asset(24).primitives[0].splats)
    return _add_property(folder, "excluded.usda", BODY,
                         f"uniform float[] gsverse:anchor:rho = [{', '.join(['1'] * n)}]")


@usd_trigger("USD_LENGTH_MISMATCH")
def _(folder):
    return _text(folder, "length.usda", ("uniform int[] gsverse:anchor:faceIndices = [",
                                         "uniform int[] gsverse:anchor:faceIndices = [0, "))


@usd_trigger("USD_SH_DEGREE_INVALID")
def _(folder):
    return _text(folder, "degree.usda", ("uniform int radiance:sphericalHarmonicsDegree = 1",
                                         "uniform int radiance:sphericalHarmonicsDegree = 7"))


@usd_trigger("USD_SH_DEGREE_MISSING")
def _(folder):
    return _sdf(folder, "nodegree.usda", lambda layer: layer.GetPrimAtPath(STATIC).RemoveProperty(
        layer.GetPropertyAtPath(f"{STATIC}.radiance:sphericalHarmonicsDegree")))


@usd_trigger("USD_PROFILE_INVALID")
def _(folder):
    return _text(folder, "profile.usda", ('gsverse:anchor:profile = "local"',
                                          'gsverse:anchor:profile = "cage"'))


@usd_trigger("USD_DEFORMATION_INVALID")
def _(folder):
    return _text(folder, "deformation.usda", ('gsverse:anchor:deformation = "affine"',
                                              'gsverse:anchor:deformation = "bent"'))


@usd_trigger("USD_MESH_TARGET_INVALID")
def _(folder):
    return _text(folder, "target.usda", ("rel gsverse:anchor:mesh = </Asset/anchor_mesh>",
                                         "rel gsverse:anchor:mesh = </Asset/static>"))


@usd_trigger("USD_MESH_HOLES")
def _(folder):
    return _add_property(folder, "holes.usda", MESH, "int[] holeIndices = [0]")


@usd_trigger("USD_BOTH_APIS")
def _(folder):
    return _text(folder, "both.usda", ('prepend apiSchemas = ["GsVerseMeshAnchorAPI"]',
                                       'prepend apiSchemas = ["GsVerseMeshAnchorAPI", '
                                       '"GsVerseColorSpaceAPI"]'))


def _static_colour_space(folder, name: str, new: str) -> Trigger:
    """Rewrite the static prim's gsverse:colorSpace declaration (the second one in the file)."""
    path = _write(folder, name)
    text = path.read_text(encoding="utf-8")
    old = 'uniform token gsverse:colorSpace = "srgb_rec709_display"'
    at = text.index(old, text.index('"static"'))
    path.write_text(text[:at] + new + text[at + len(old):], encoding="utf-8")
    return Trigger(path)


@usd_trigger("USD_CUSTOM_PROPERTY")
def _(folder):
    return _static_colour_space(folder, "custom.usda", 'custom uniform token gsverse:colorSpace '
                                                       '= "srgb_rec709_display"')


@usd_trigger("USD_NOT_UNIFORM")
def _(folder):
    return _static_colour_space(folder, "varying.usda",
                                'token gsverse:colorSpace = "srgb_rec709_display"')


@usd_trigger("USD_TIME_SAMPLED")
def _(folder):
    def edit(layer):
        spec = layer.GetAttributeAtPath(f"{STATIC}.opacities")
        layer.SetTimeSample(spec.path, 1.0, spec.default)
    return _sdf(folder, "sampled.usda", edit)


@usd_trigger("USD_NO_REST_POSE")
def _(folder):
    def edit(layer):
        spec = layer.GetAttributeAtPath(f"{STATIC}.positions")
        layer.SetTimeSample(spec.path, 1.0, spec.default)
        spec.ClearDefaultValue()
    return _sdf(folder, "norest.usda", edit)


@usd_trigger("USD_TIME_CODES_MISSING")
def _(folder):
    def edit(layer):
        spec = layer.GetAttributeAtPath(f"{STATIC}.positions")
        layer.SetTimeSample(spec.path, 1.0, spec.default)
    return _sdf(folder, "notimecodes.usda", edit)


def _remove(folder, name: str, prop: str) -> Trigger:
    prim, attr = prop.split(".", 1)
    return _sdf(folder, name, lambda layer: layer.GetPrimAtPath(prim).RemoveProperty(
        layer.GetPropertyAtPath(prop)))


@usd_trigger("USD_SORTING_MODE")
def _(folder):
    return _remove(folder, "sorting.usda", f"{STATIC}.sortingModeHint")


@usd_trigger("USD_PROJECTION_MODE")
def _(folder):
    return _remove(folder, "projection.usda", f"{STATIC}.projectionModeHint")


@usd_trigger("USD_HALF_PRECISION")
def _(folder):
    return _add_property(folder, "half.usda", STATIC, "half[] opacitiesh = [1, 1, 1, 1, 1]")


@usd_trigger("USD_EXTENT_MISSING")
def _(folder):
    return _remove(folder, "noextent.usda", f"{STATIC}.extent")


@usd_trigger("USD_EXTENT_INVALID")
def _(folder):
    return _sdf(folder, "extent.usda", lambda layer: _set_default(
        layer, f"{STATIC}.extent", lambda v: v * 0.5))


@usd_trigger("USD_XFORM_OPS")
def _(folder):
    trigger = _add_property(folder, "xform.usda", STATIC,
                            'uniform token[] xformOpOrder = ["xformOp:translate"]')
    text = trigger.path.read_text(encoding="utf-8").replace(
        'uniform token[] xformOpOrder', 'double3 xformOp:translate = (0, 0, 0)\n'
        '        uniform token[] xformOpOrder', 1)
    trigger.path.write_text(text, encoding="utf-8")
    return trigger


@usd_trigger("USD_COLOR_SPACE_API_IGNORED")
def _(folder):
    return _add_property(folder, "colorspace.usda", STATIC,
                         'uniform token colorSpace:name = "lin_rec709_scene"')


@usd_trigger("USD_LOCAL_SCALES_REDUNDANT")
def _(folder):
    def edit(layer):
        from pxr import Sdf
        scales = layer.GetAttributeAtPath(f"{BODY}.scales").default
        spec = Sdf.AttributeSpec(layer.GetPrimAtPath(BODY), "gsverse:anchor:localScales",
                                 Sdf.ValueTypeNames.Float3Array, Sdf.VariabilityUniform)
        spec.default = scales
    return _sdf(folder, "localscales.usda", edit)


@usd_trigger("USD_MESH_PURPOSE")
def _(folder):
    return _text(folder, "purpose.usda", ('uniform token purpose = "guide"',
                                          'uniform token purpose = "default"'))


@usd_trigger("USD_MESH_SUBDIVISION")
def _(folder):
    return _text(folder, "subdivision.usda", ('uniform token subdivisionScheme = "none"',
                                              'uniform token subdivisionScheme = "catmullClark"'))


@usd_trigger("USD_MESH_ORIENTATION")
def _(folder):
    return _add_property(folder, "lefthanded.usda", MESH,
                         'uniform token orientation = "leftHanded"')


@usd_trigger("USD_PLAIN_SPLATS")
def _(folder):
    return _text(folder, "plain.usda", ('def ParticleField3DGaussianSplat "static" (\n'
                                        '        prepend apiSchemas = ["GsVerseColorSpaceAPI"]\n'
                                        '    )\n', 'def ParticleField3DGaussianSplat "static"\n'))


@usd_trigger("USD_PARTICLE_FIELD_SKIPPED")
def _(folder):
    trigger = _write(folder, "other_field.usda")
    text = trigger.read_text(encoding="utf-8")
    at = text.rindex("}")
    trigger.write_text(text[:at] + '    def ParticleField "field"\n    {\n    }\n' + text[at:],
                       encoding="utf-8")
    return Trigger(trigger)


@usd_trigger("USD_EMPTY_PRIM")
def _(folder):
    return _sdf(folder, "empty.usda", lambda layer: _set_default(
        layer, f"{STATIC}.positions", lambda v: v[:0]))


@usd_trigger("USD_REPLACED_BY_DEFAULT")
def _(folder):
    return _sdf(folder, "short.usda", lambda layer: _set_default(
        layer, f"{STATIC}.opacities", lambda v: v[:-1]))


@usd_trigger("USD_TRUNCATED")
def _(folder):
    return _sdf(folder, "long.usda", lambda layer: _set_default(
        layer, f"{STATIC}.opacities", lambda v: np.concatenate([v, v[:1]])))


@usd_trigger("USD_VALIDATOR_ERROR")
def _(folder):
    return _add_property(folder, "binding.usda", MESH, "rel material:binding = </Asset>")


@usd_trigger("USD_VALIDATOR_WARNING")
def _(folder):
    """An AuthorshipAPI applied in a sublayer and shadowed by an explicit apiSchemas list."""
    base = _text(folder, "authored.usda", ('def Xform "Asset" (\n',
                                           'def Xform "Asset" (\n'
                                           '    prepend apiSchemas = ["AuthorshipAPI:a"]\n'))
    path = pathlib.Path(folder) / "shadowed.usda"
    path.write_text('#usda 1.0\n(\n    defaultPrim = "Asset"\n    metersPerUnit = 1\n'
                    '    upAxis = "Y"\n    subLayers = [@./authored.usda@]\n)\n\n'
                    'over "Asset" (\n    apiSchemas = []\n)\n{\n}\n', encoding="utf-8")
    assert base.path.exists()
    return Trigger(path)
