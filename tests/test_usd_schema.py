"""The codeless USD schemas in ``gsverse_format/usd_schema`` (spec/usd.md), checked with OpenUSD.

A codeless schema is only picked up if it is registered before the process first uses the
USD schema registry, and several checks need a process in which the schemas are *not*
registered. Every check therefore runs its USD code in a fresh interpreter (the one running
pytest). The whole module is skipped when ``pxr`` is not importable or predates
``UsdVol.ParticleField3DGaussianSplat`` (OpenUSD 26.03).
"""
from __future__ import annotations

import json
import os
import pathlib
import re
import subprocess
import sys
import textwrap

import pytest

pytest.importorskip("pxr")

REPO = pathlib.Path(__file__).resolve().parents[1]
SCHEMA_DIR = REPO / "gsverse_format" / "usd_schema"
SPEC = REPO / "spec" / "usd.md"

#: Every property the schemas define: name -> (type, variability, fallback, allowedTokens).
ATTRIBUTES = {
    "gsverse:colorSpace": ("token", "uniform", "srgb_rec709_display", None),
    "gsverse:anchor:profile": ("token", "uniform", None, ["local", "games"]),
    "gsverse:anchor:deformation": ("token", "uniform", "affine", ["affine", "rigid"]),
    "gsverse:anchor:faceIndices": ("int[]", "uniform", None, None),
    "gsverse:anchor:barycentrics": ("float2[]", "uniform", None, None),
    "gsverse:anchor:normalOffsets": ("float[]", "uniform", None, None),
    "gsverse:anchor:localOrientations": ("quatf[]", "uniform", None, None),
    "gsverse:anchor:localScales": ("float3[]", "uniform", None, None),
    "gsverse:anchor:rho": ("float[]", "uniform", None, None),
}
RELATIONSHIPS = ["gsverse:anchor:mesh"]
COLOR_SPACE_API = ["gsverse:colorSpace"]

# Code shared by the child interpreters: imports, optional registration, and a deterministic
# test asset (two anchored primitives sharing one anchor mesh, plus a static one).
_PRELUDE = '''
import json, sys
import numpy as np
from pxr import Gf, Plug, Sdf, Usd, UsdGeom, UsdValidation, UsdVol, Vt

SCHEMA_DIR = {schema_dir!r}
ARGS = json.loads({args!r})
if {register!r}:
    Plug.Registry().RegisterPlugins(SCHEMA_DIR)


def registered():
    return Usd.SchemaRegistry().FindAppliedAPIPrimDefinition("GsVerseMeshAnchorAPI") is not None


def emit(obj):
    print(json.dumps(obj))


def validation_errors(stage):
    validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
    found = UsdValidation.ValidationContext(validators).Validate(stage)
    return [(e.GetName(), str(e.GetType()), e.GetMessage()) for e in found]


def make_data():
    """Rest pose and anchors in the gsverse-format (KHR) conventions: quaternions xyzw."""
    rng = np.random.default_rng(7)
    def quats(n):
        q = rng.normal(size=(n, 4)).astype(np.float32)
        return (q / np.linalg.norm(q, axis=1, keepdims=True)).astype(np.float32)
    mesh_points = np.array([[0, 0, 0], [2, 0, 0], [0, 1, 0], [2, 1, 0]], np.float32)
    mesh_indices = np.array([0, 1, 2, 1, 3, 2], np.int32)
    local = dict(
        n=4, degree=2,
        positions=rng.uniform(-1, 1, (4, 3)).astype(np.float32),
        orientations=quats(4),
        scales=rng.uniform(0.01, 0.2, (4, 3)).astype(np.float32),
        opacities=rng.uniform(0, 1, 4).astype(np.float32),
        sh=rng.normal(0, 0.3, (4, 9, 3)).astype(np.float32),
        faceIndices=np.array([0, 1, 1, 0], np.int32),
        barycentrics=rng.uniform(-0.2, 1.0, (4, 2)).astype(np.float32),
        normalOffsets=rng.normal(0, 0.05, 4).astype(np.float32),
        localOrientations=quats(4),
        deformation="rigid",
        colorSpace="srgb_rec709_display",
    )
    games = dict(
        n=3, degree=0,
        positions=rng.uniform(-1, 1, (3, 3)).astype(np.float32),
        orientations=quats(3),
        scales=rng.uniform(0.01, 0.2, (3, 3)).astype(np.float32),
        opacities=rng.uniform(0, 1, 3).astype(np.float32),
        sh=rng.normal(0, 0.3, (3, 1, 3)).astype(np.float32),
        faceIndices=np.array([1, 0, 1], np.int32),
        barycentrics=rng.uniform(0, 0.5, (3, 2)).astype(np.float32),
        rho=rng.uniform(0.5, 2, 3).astype(np.float32),
        colorSpace="lin_rec709_display",
    )
    static = dict(
        n=2, degree=1,
        positions=rng.uniform(-5, 5, (2, 3)).astype(np.float32),
        orientations=quats(2),
        scales=rng.uniform(0.1, 1, (2, 3)).astype(np.float32),
        opacities=rng.uniform(0, 1, 2).astype(np.float32),
        sh=rng.normal(0, 0.3, (2, 4, 3)).astype(np.float32),
        colorSpace="lin_rec709_display",
    )
    return mesh_points, mesh_indices, dict(local_splats=local, games_splats=games, background=static)


def anchor_values(d):
    """The GsVerseMeshAnchorAPI properties of one primitive (name, type, value)."""
    T = Sdf.ValueTypeNames
    out = [("gsverse:colorSpace", T.Token, d["colorSpace"])]
    if "rho" in d:
        out += [("gsverse:anchor:profile", T.Token, "games"),
                ("gsverse:anchor:faceIndices", T.IntArray, Vt.IntArray.FromNumpy(d["faceIndices"])),
                ("gsverse:anchor:barycentrics", T.Float2Array, Vt.Vec2fArray.FromNumpy(d["barycentrics"])),
                ("gsverse:anchor:rho", T.FloatArray, Vt.FloatArray.FromNumpy(d["rho"]))]
    elif "faceIndices" in d:
        out += [("gsverse:anchor:profile", T.Token, "local"),
                ("gsverse:anchor:deformation", T.Token, d["deformation"]),
                ("gsverse:anchor:faceIndices", T.IntArray, Vt.IntArray.FromNumpy(d["faceIndices"])),
                ("gsverse:anchor:barycentrics", T.Float2Array, Vt.Vec2fArray.FromNumpy(d["barycentrics"])),
                ("gsverse:anchor:normalOffsets", T.FloatArray, Vt.FloatArray.FromNumpy(d["normalOffsets"])),
                ("gsverse:anchor:localOrientations", T.QuatfArray,
                 Vt.QuatfArray.FromNumpy(d["localOrientations"]))]
                # localScales omitted: equal to the rest-pose scales (spec/usd.md)
    return out


def write_asset(path, use_schema):
    """Write the test asset; ``use_schema`` False = the path for an unregistered schema."""
    mesh_points, mesh_indices, prims = make_data()
    stage = Usd.Stage.CreateNew(path)
    UsdGeom.SetStageUpAxis(stage, UsdGeom.Tokens.y)
    UsdGeom.SetStageMetersPerUnit(stage, 1.0)
    root = UsdGeom.Xform.Define(stage, "/Asset")
    stage.SetDefaultPrim(root.GetPrim())
    mesh = UsdGeom.Mesh.Define(stage, "/Asset/anchor_mesh")
    mesh.CreatePointsAttr(Vt.Vec3fArray.FromNumpy(mesh_points))
    mesh.CreateFaceVertexCountsAttr(Vt.IntArray([3] * (len(mesh_indices) // 3)))
    mesh.CreateFaceVertexIndicesAttr(Vt.IntArray.FromNumpy(mesh_indices))
    mesh.CreateSubdivisionSchemeAttr(UsdGeom.Tokens.none)
    mesh.CreatePurposeAttr(UsdGeom.Tokens.guide)
    mesh.CreateExtentAttr(UsdGeom.Mesh.ComputeExtent(mesh.GetPointsAttr().Get()))
    for name, d in prims.items():
        gs = UsdVol.ParticleField3DGaussianSplat.Define(stage, "/Asset/" + name)
        gs.CreatePositionsAttr(Vt.Vec3fArray.FromNumpy(d["positions"]))
        gs.CreateOrientationsAttr(Vt.QuatfArray.FromNumpy(d["orientations"]))
        gs.CreateScalesAttr(Vt.Vec3fArray.FromNumpy(d["scales"]))
        gs.CreateOpacitiesAttr(Vt.FloatArray.FromNumpy(d["opacities"]))
        gs.CreateRadianceSphericalHarmonicsDegreeAttr(d["degree"])
        gs.CreateRadianceSphericalHarmonicsCoefficientsAttr(
            Vt.Vec3fArray.FromNumpy(d["sh"].reshape(-1, 3)))
        gs.CreateProjectionModeHintAttr("perspective")
        gs.CreateSortingModeHintAttr("cameraDistance")
        lo, hi = d["positions"].min(0), d["positions"].max(0)
        gs.CreateExtentAttr(Vt.Vec3fArray([Gf.Vec3f(*map(float, lo)), Gf.Vec3f(*map(float, hi))]))
        prim = gs.GetPrim()
        api = "GsVerseMeshAnchorAPI" if "faceIndices" in d else "GsVerseColorSpaceAPI"
        if use_schema:
            prim.ApplyAPI(api)
            for prop, _, value in anchor_values(d):
                prim.GetAttribute(prop).Set(value)
            if api == "GsVerseMeshAnchorAPI":
                prim.GetRelationship("gsverse:anchor:mesh").SetTargets([mesh.GetPath()])
        else:
            prim.AddAppliedSchema(api)
            for prop, type_name, value in anchor_values(d):
                prim.CreateAttribute(prop, type_name, custom=False,
                                     variability=Sdf.VariabilityUniform).Set(value)
            if api == "GsVerseMeshAnchorAPI":
                prim.CreateRelationship("gsverse:anchor:mesh", custom=False).SetTargets(
                    [mesh.GetPath()])
    stage.GetRootLayer().Save()
    return stage
'''


def _run(body: str, *, register: bool = False, env_plugin_path: bool = False, **args) -> dict:
    """Run ``body`` in a fresh interpreter; returns the JSON object it printed last."""
    code = _PRELUDE.format(schema_dir=str(SCHEMA_DIR), args=json.dumps(args, default=str),
                           register=register) + textwrap.dedent(body)
    env = dict(os.environ)
    env.pop("PXR_PLUGINPATH_NAME", None)
    if env_plugin_path:
        env["PXR_PLUGINPATH_NAME"] = str(SCHEMA_DIR)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=env, timeout=300)
    assert proc.returncode == 0, proc.stderr[-4000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _require_particle_fields() -> None:
    out = _run('emit({"ok": hasattr(UsdVol, "ParticleField3DGaussianSplat")})')
    if not out["ok"]:
        pytest.skip("this OpenUSD predates UsdVol.ParticleField3DGaussianSplat (26.03)")


@pytest.fixture(scope="module", autouse=True)
def _particle_fields():
    _require_particle_fields()


def _plug_info() -> dict:
    text = (SCHEMA_DIR / "plugInfo.json").read_text(encoding="utf-8")
    return json.loads("\n".join(line for line in text.splitlines() if not line.lstrip().startswith("#")))


def test_plug_info_declares_the_two_api_schemas():
    (plugin,) = _plug_info()["Plugins"]
    assert plugin["Type"] == "resource" and plugin["Name"] == "gsverseSchema"
    assert (SCHEMA_DIR / plugin["Root"] / plugin["ResourcePath"] / "generatedSchema.usda").is_file()
    types = plugin["Info"]["Types"]
    assert set(types) == {"GsVerseSchemaGsVerseMeshAnchorAPI", "GsVerseSchemaGsVerseColorSpaceAPI"}
    for tf_type, entry in types.items():
        identifier = tf_type[len("GsVerseSchema"):]
        assert entry["alias"] == {"UsdSchemaBase": identifier} != tf_type
        assert entry["schemaIdentifier"] == identifier
        assert entry["schemaKind"] == "singleApplyAPI"
        assert entry["bases"] == ["UsdAPISchemaBase"]
        assert entry["apiSchemaCanOnlyApplyTo"] == ["ParticleField3DGaussianSplat"]


def test_package_tables_match_the_schemas():
    """The USD package's attribute names (from gsverse_format.vocabulary) and value types are
    those the schemas declare, and the per-profile rules use the vocabulary's profiles."""
    from pxr import Sdf

    from gsverse_format.io.usd import schema as S
    from gsverse_format.vocabulary import ANCHOR_FIELDS, PROFILES, USD_PROFILE, allowed_fields

    assert set(S.USD_TYPES) == {f.attribute for f in ANCHOR_FIELDS}
    assert {name: str(getattr(Sdf.ValueTypeNames, t)) for name, t in
            S.API_ATTRIBUTE_TYPES.items()} == {name: a[0] for name, a in ATTRIBUTES.items()}
    assert [S.MESH_REL] == RELATIONSHIPS and [S.COLOR_SPACE_ATTR] == COLOR_SPACE_API
    for f in ANCHOR_FIELDS:
        vt = getattr(Sdf.ValueTypeNames, S.USD_TYPES[f.attribute].sdf).type.pythonClass
        assert vt is not None and vt.__name__ == S.USD_TYPES[f.attribute].vt, f.attribute
    assert ATTRIBUTES[USD_PROFILE][3] == list(PROFILES)
    for profile in PROFILES:
        assert {f.usd for f in S.usd_required(profile)} <= {f.usd for f in allowed_fields(profile)}
        assert S.usd_allowed_names(profile) <= set(S.anchor_attribute_names())


def test_generated_schema_matches_source():
    """generatedSchema.usda holds exactly the classes and properties schema.usda declares."""
    out = _run('''
        def describe(path):
            layer = Sdf.Layer.OpenAsAnonymous(path)
            classes = {}
            for prim in layer.rootPrims:
                if prim.name == "GLOBAL":
                    continue
                props = {}
                for prop in prim.properties:
                    if isinstance(prop, Sdf.AttributeSpec):
                        props[prop.name] = [str(prop.typeName), str(prop.variability),
                                            None if prop.default is None else str(prop.default),
                                            list(prop.allowedTokens) if prop.allowedTokens else None]
                    else:
                        props[prop.name] = "rel"
                api = prim.GetInfo("apiSchemas") if prim.HasInfo("apiSchemas") else None
                classes[prim.name] = {"props": props, "specifier": str(prim.specifier),
                                      "apiSchemas": list(api.ApplyOperations([])) if api else [],
                                      "canOnlyApplyTo": list(prim.customData.get(
                                          "apiSchemaCanOnlyApplyTo", []))}
            return classes
        emit({"source": describe(ARGS["src"]), "generated": describe(ARGS["gen"])})
    ''', src=str(SCHEMA_DIR / "schema.usda"), gen=str(SCHEMA_DIR / "generatedSchema.usda"))
    src, gen = out["source"], out["generated"]
    assert set(src) == set(gen) == {"GsVerseMeshAnchorAPI", "GsVerseColorSpaceAPI"}
    for name in src:
        assert src[name]["props"] == gen[name]["props"], name
        assert src[name]["apiSchemas"] == gen[name]["apiSchemas"], name
        assert src[name]["canOnlyApplyTo"] == ["ParticleField3DGaussianSplat"]
    assert gen["GsVerseMeshAnchorAPI"]["apiSchemas"] == ["GsVerseColorSpaceAPI"]
    assert set(src["GsVerseColorSpaceAPI"]["props"]) == set(COLOR_SPACE_API)
    assert set(src["GsVerseMeshAnchorAPI"]["props"]) == (set(ATTRIBUTES) | set(RELATIONSHIPS)) - set(COLOR_SPACE_API)


_APPLY_CHECKS = '''
    reg = Usd.SchemaRegistry()
    result = {"registered": registered()}
    tf_type = Usd.SchemaRegistry.GetTypeFromSchemaTypeName("GsVerseMeshAnchorAPI")
    result["tfType"] = tf_type.typeName
    result["kind"] = str(Usd.SchemaRegistry().GetSchemaKind(tf_type))
    stage = Usd.Stage.CreateInMemory()
    splat = UsdVol.ParticleField3DGaussianSplat.Define(stage, "/s").GetPrim()
    others = {"Xform": UsdGeom.Xform.Define(stage, "/x").GetPrim(),
              "ParticleField": UsdVol.ParticleField.Define(stage, "/p").GetPrim(),
              "Mesh": UsdGeom.Mesh.Define(stage, "/m").GetPrim()}
    result["canApply"] = {api: bool(splat.CanApplyAPI(api))
                          for api in ("GsVerseMeshAnchorAPI", "GsVerseColorSpaceAPI")}
    result["canApplyOthers"] = {k: bool(p.CanApplyAPI("GsVerseMeshAnchorAPI")) for k, p in others.items()}
    result["apply"] = bool(splat.ApplyAPI("GsVerseMeshAnchorAPI"))
    result["hasAPI"] = [splat.HasAPI("GsVerseMeshAnchorAPI"), splat.HasAPI("GsVerseColorSpaceAPI")]
    result["applied"] = list(splat.GetAppliedSchemas())
    result["listOp"] = list(stage.GetRootLayer().GetPrimAtPath("/s").GetInfo("apiSchemas").prependedItems)
    props = {}
    for name in ARGS["attributes"]:
        a = splat.GetAttribute(name)
        fallback = a.Get()
        props[name] = [str(a.GetTypeName()), str(a.GetVariability()),
                       None if fallback is None else str(fallback),
                       list(a.GetMetadata("allowedTokens")) if a.HasMetadata("allowedTokens") else None,
                       a.HasAuthoredValue()]
    result["props"] = props
    result["rels"] = [bool(splat.GetRelationship(n)) for n in ARGS["relationships"]]
    static = UsdVol.ParticleField3DGaussianSplat.Define(stage, "/static").GetPrim()
    static.ApplyAPI("GsVerseColorSpaceAPI")
    result["staticProps"] = sorted(p.GetName() for p in static.GetProperties()
                                   if p.GetName().startswith("gsverse"))
    emit(result)
'''


def _check_apply(out: dict) -> None:
    assert out["registered"]
    assert out["tfType"] == "GsVerseSchemaGsVerseMeshAnchorAPI"
    assert out["kind"].endswith("SingleApplyAPI")
    assert out["canApply"] == {"GsVerseMeshAnchorAPI": True, "GsVerseColorSpaceAPI": True}
    assert out["canApplyOthers"] == {"Xform": False, "ParticleField": False, "Mesh": False}
    assert out["apply"] and out["hasAPI"] == [True, True]
    assert out["applied"][-2:] == ["GsVerseMeshAnchorAPI", "GsVerseColorSpaceAPI"]
    assert out["listOp"] == ["GsVerseMeshAnchorAPI"]
    for name, (type_name, variability, fallback, tokens) in ATTRIBUTES.items():
        got = out["props"][name]
        assert got[0] == type_name, name
        assert got[1] == "Sdf.VariabilityUniform" and variability == "uniform", name
        assert got[2] == fallback, name
        assert got[3] == tokens, name
        assert got[4] is False, name  # fallbacks are not authored opinions
    assert all(out["rels"])
    assert out["staticProps"] == COLOR_SPACE_API


def test_registered_api_applies_to_splats_only():
    _check_apply(_run(_APPLY_CHECKS, register=True, attributes=list(ATTRIBUTES),
                      relationships=RELATIONSHIPS))


def test_registration_through_pxr_pluginpath_name():
    _check_apply(_run(_APPLY_CHECKS, env_plugin_path=True, attributes=list(ATTRIBUTES),
                      relationships=RELATIONSHIPS))


def test_unregistered_process_does_not_know_the_api():
    out = _run('emit({"registered": registered()})')
    assert out == {"registered": False}


@pytest.mark.parametrize("suffix", ["usda", "usdc"])
def test_asset_validates_and_reads_back_without_the_plugin(tmp_path, suffix):
    path = str(tmp_path / f"asset.{suffix}")
    written = _run('''
        assert registered()
        stage = write_asset(ARGS["path"], use_schema=True)
        emit({"errors": validation_errors(stage)})
    ''', register=True, path=path)
    assert written["errors"] == []

    out = _run('''
        assert not registered()
        stage = Usd.Stage.Open(ARGS["path"])
        mesh_points, mesh_indices, prims = make_data()
        result = {"errors": validation_errors(stage), "prims": {}}
        result["meta"] = [UsdGeom.GetStageUpAxis(stage), UsdGeom.GetStageMetersPerUnit(stage),
                          str(stage.GetDefaultPrim().GetPath())]
        mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Asset/anchor_mesh"))
        result["mesh"] = [bool(mesh), mesh.ComputePurpose(),
                          bool(np.array_equal(np.asarray(mesh.GetPointsAttr().Get()), mesh_points)),
                          list(mesh.GetFaceVertexCountsAttr().Get()),
                          bool(np.array_equal(np.asarray(mesh.GetFaceVertexIndicesAttr().Get()), mesh_indices))]
        for name, d in prims.items():
            prim = stage.GetPrimAtPath("/Asset/" + name)
            gs = UsdVol.ParticleField3DGaussianSplat(prim)
            r = {"typed": bool(gs) and prim.IsA(UsdVol.ParticleField3DGaussianSplat),
                 "builtins": [a for a in prim.GetAppliedSchemas() if a.startswith("ParticleField")],
                 "authoredApis": list(prim.GetPrimTypeInfo().GetAppliedAPISchemas()),
                 "composedApis": [a for a in prim.GetAppliedSchemas() if a.startswith("GsVerse")]}
            K = (d["degree"] + 1) ** 2
            r["rest"] = {
                "positions": bool(np.array_equal(np.asarray(gs.GetPositionsAttr().Get()), d["positions"])),
                "orientations": bool(np.array_equal(np.asarray(gs.GetOrientationsAttr().Get()), d["orientations"])),
                "scales": bool(np.array_equal(np.asarray(gs.GetScalesAttr().Get()), d["scales"])),
                "opacities": bool(np.array_equal(np.asarray(gs.GetOpacitiesAttr().Get()), d["opacities"])),
                "degree": gs.GetRadianceSphericalHarmonicsDegreeAttr().Get() == d["degree"],
                "sh": bool(np.array_equal(np.asarray(gs.GetRadianceSphericalHarmonicsCoefficientsAttr().Get()).reshape(d["n"], K, 3), d["sh"])),
                "sorting": gs.GetSortingModeHintAttr().Get() == "cameraDistance",
                "projection": gs.GetProjectionModeHintAttr().Get() == "perspective",
            }
            attrs = {}
            for prop, type_name, value in anchor_values(d):
                a = prim.GetAttribute(prop)
                got = a.Get()
                same = (got == value) if isinstance(value, str) else bool(np.array_equal(np.asarray(got), np.asarray(value)))
                attrs[prop] = [str(a.GetTypeName()), str(a.GetVariability()), a.HasAuthoredValue(), same]
            r["attrs"] = attrs
            rel = prim.GetRelationship("gsverse:anchor:mesh")
            r["meshTargets"] = [str(t) for t in rel.GetTargets()] if rel else []
            r["unauthored"] = {n: prim.GetAttribute(n).HasAuthoredValue()
                               for n in ("gsverse:anchor:deformation", "gsverse:anchor:localScales")}
            result["prims"][name] = r
        emit(result)
    ''', path=path)
    assert out["errors"] == []
    assert out["meta"] == ["Y", 1.0, "/Asset"]
    assert out["mesh"] == [True, "guide", True, [3, 3], True]
    builtins = ["ParticleFieldPositionAttributeAPI", "ParticleFieldPositionBaseAPI",
                "ParticleFieldOrientationAttributeAPI", "ParticleFieldScaleAttributeAPI",
                "ParticleFieldOpacityAttributeAPI", "ParticleFieldKernelGaussianEllipsoidAPI",
                "ParticleFieldKernelBaseAPI", "ParticleFieldSphericalHarmonicsAttributeAPI",
                "ParticleFieldRadianceBaseAPI"]
    apis = {"local_splats": "GsVerseMeshAnchorAPI", "games_splats": "GsVerseMeshAnchorAPI",
            "background": "GsVerseColorSpaceAPI"}
    for name, r in out["prims"].items():
        assert r["typed"], name
        assert r["builtins"] == builtins, name
        # Without the plugin the API is not composed, but its name stays in the prim's metadata.
        assert r["authoredApis"] == [apis[name]] and r["composedApis"] == [], name
        assert all(r["rest"].values()), (name, r["rest"])
        for prop, (type_name, variability, same_value_authored, same) in r["attrs"].items():
            assert type_name == ATTRIBUTES[prop][0], (name, prop)
            assert variability == "Sdf.VariabilityUniform", (name, prop)
            assert same_value_authored and same, (name, prop)
        expected_targets = [] if name == "background" else ["/Asset/anchor_mesh"]
        assert r["meshTargets"] == expected_targets, name
    assert out["prims"]["games_splats"]["unauthored"]["gsverse:anchor:deformation"] is False
    assert out["prims"]["local_splats"]["unauthored"]["gsverse:anchor:localScales"] is False


@pytest.mark.parametrize("suffix", ["usda", "usdc"])
def test_writing_without_registration_gives_the_same_file(tmp_path, suffix):
    """The fallback path for a process that used USD before it could register the schemas."""
    a, b = tmp_path / f"a.{suffix}", tmp_path / f"b.{suffix}"
    _run('''
        assert registered()
        write_asset(ARGS["path"], use_schema=True)
        emit({})
    ''', register=True, path=str(a))
    _run('''
        Usd.SchemaRegistry()                          # the registry is now in use ...
        Plug.Registry().RegisterPlugins(SCHEMA_DIR)   # ... so registering may come too late
        write_asset(ARGS["path"], use_schema=registered())
        emit({})
    ''', path=str(b))
    assert a.read_bytes() == b.read_bytes()
    if suffix == "usda":
        text = a.read_text(encoding="utf-8")
        assert "custom " not in text
        assert 'prepend apiSchemas = ["GsVerseMeshAnchorAPI"]' in text
        assert 'prepend apiSchemas = ["GsVerseColorSpaceAPI"]' in text


def test_quaternion_and_sh_conventions():
    out = _run('''
        xyzw = np.array([[0.1, 0.2, 0.3, 0.9273618495495704]], np.float32)
        arr = Vt.QuatfArray.FromNumpy(xyzw)
        stage = Usd.Stage.CreateInMemory()
        gs = UsdVol.ParticleField3DGaussianSplat.Define(stage, "/s")
        gs.CreateOrientationsAttr(arr)
        sh = np.arange(2 * 4 * 3, dtype=np.float32).reshape(2, 4, 3)
        gs.CreateRadianceSphericalHarmonicsCoefficientsAttr(Vt.Vec3fArray.FromNumpy(sh.reshape(-1, 3)))
        coeffs = gs.GetRadianceSphericalHarmonicsCoefficientsAttr().Get()
        text = stage.GetRootLayer().ExportToString()
        emit({"real": arr[0].GetReal(), "imaginary": list(arr[0].GetImaginary()),
              "numpy": np.asarray(gs.GetOrientationsAttr().Get()).tolist(),
              "gf": list(Gf.Quatf(0.5, 1, 2, 3).GetImaginary()) + [Gf.Quatf(0.5, 1, 2, 3).GetReal()],
              "line": [l.strip() for l in text.splitlines() if "orientations" in l][0],
              "coeff_1_2": list(coeffs[1 * 4 + 2]), "degreeFallback": gs.GetRadianceSphericalHarmonicsDegreeAttr().Get(),
              "sortingFallback": gs.GetSortingModeHintAttr().Get()})
    ''')
    assert out["real"] == pytest.approx(0.9273618495495704)
    assert out["imaginary"] == pytest.approx([0.1, 0.2, 0.3])
    assert out["numpy"] == [pytest.approx([0.1, 0.2, 0.3, 0.9273618495495704])]  # xyzw, no swizzle
    assert out["gf"] == [1, 2, 3, 0.5]  # Gf.Quatf(real, i, j, k)
    assert out["line"].startswith("quatf[] orientations = [(0.92736185, 0.1, 0.2, 0.3)]")  # text: (w, x, y, z)
    assert out["coeff_1_2"] == [18, 19, 20]  # sh[1, 2]: grouped by particle, coefficient-major
    assert out["degreeFallback"] == 3 and out["sortingFallback"] == "zDepth"


def test_baked_samples_keep_the_rest_pose_in_default_values(tmp_path):
    out = _run('''
        stage = write_asset(ARGS["path"], use_schema=True)
        _, _, prims = make_data()
        d = prims["local_splats"]
        gs = UsdVol.ParticleField3DGaussianSplat(stage.GetPrimAtPath("/Asset/local_splats"))
        moved = d["positions"] + np.float32(1)
        for t, p in ((0, d["positions"]), (1, moved)):
            gs.GetPositionsAttr().Set(Vt.Vec3fArray.FromNumpy(p), t)
            gs.GetOrientationsAttr().Set(Vt.QuatfArray.FromNumpy(d["orientations"]), t)
            gs.GetScalesAttr().Set(Vt.Vec3fArray.FromNumpy(d["scales"]), t)
        stage.SetStartTimeCode(0)
        stage.SetEndTimeCode(1)
        stage.Save()
        reopened = Usd.Stage.Open(ARGS["path"])
        attr = UsdVol.ParticleField3DGaussianSplat(reopened.GetPrimAtPath("/Asset/local_splats")).GetPositionsAttr()
        emit({"rest": bool(np.array_equal(np.asarray(attr.Get()), d["positions"])),
              "restDefault": bool(np.array_equal(np.asarray(attr.Get(Usd.TimeCode.Default())), d["positions"])),
              "t1": bool(np.array_equal(np.asarray(attr.Get(1)), moved)),
              "samples": list(attr.GetTimeSamples()),
              "errors": validation_errors(reopened)})
    ''', register=True, path=str(tmp_path / "baked.usda"))
    assert out["rest"] and out["restDefault"] and out["t1"]
    assert out["samples"] == [0.0, 1.0]
    assert out["errors"] == []


def test_spec_example_stage(tmp_path):
    """The USDA example printed in spec/usd.md is a valid stage with the documented values."""
    blocks = re.findall(r"```usda\n(.*?)```", SPEC.read_text(encoding="utf-8"), re.S)
    assert blocks, "spec/usd.md has no usda example"
    path = tmp_path / "example.usda"
    path.write_text(blocks[0], encoding="utf-8")
    body = '''
        stage = Usd.Stage.Open(ARGS["path"])
        prim = stage.GetPrimAtPath("/Asset/splats")
        gs = UsdVol.ParticleField3DGaussianSplat(prim)
        emit({"errors": validation_errors(stage), "registered": registered(),
              "typed": prim.IsA(UsdVol.ParticleField3DGaussianSplat),
              "hasAPI": registered() and prim.HasAPI("GsVerseMeshAnchorAPI"),
              "position": list(gs.GetPositionsAttr().Get()[0]),
              "orientation": np.asarray(gs.GetOrientationsAttr().Get()).tolist()[0],
              "bakedOrientation": np.asarray(gs.GetOrientationsAttr().Get(1)).tolist()[0],
              "bakedPosition": list(gs.GetPositionsAttr().Get(1)[0]),
              "profile": prim.GetAttribute("gsverse:anchor:profile").Get(),
              "bary": list(prim.GetAttribute("gsverse:anchor:barycentrics").Get()[0]),
              "localScales": prim.GetAttribute("gsverse:anchor:localScales").HasAuthoredValue(),
              "target": [str(t) for t in prim.GetRelationship("gsverse:anchor:mesh").GetTargets()],
              "restMesh": np.asarray(UsdGeom.Mesh(stage.GetPrimAtPath("/Asset/anchor_mesh")).GetPointsAttr().Get()).tolist()})
    '''
    with_plugin = _run(body, register=True, path=str(path))
    without = _run(body, path=str(path))
    assert with_plugin["registered"] and with_plugin["hasAPI"] and not without["registered"]
    for out in (with_plugin, without):
        assert out["errors"] == [] and out["typed"]
        assert out["position"] == [0.5, 0.5, 0.125]
        assert out["orientation"] == [0, 0, 0, 1]
        assert out["bakedOrientation"] == pytest.approx([0, 0, 0.70710677, 0.70710677])
        assert out["bakedPosition"] == pytest.approx([-0.5, 1, 0.1767767])
        assert out["profile"] == "local" and out["bary"] == [0.25, 0.5] and not out["localScales"]
        assert out["target"] == ["/Asset/anchor_mesh"]
        assert out["restMesh"] == [[0, 0, 0], [2, 0, 0], [0, 1, 0]]
