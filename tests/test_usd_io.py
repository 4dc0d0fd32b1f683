"""USD reading and writing (``gsverse_format.io.usd``, spec/usd.md): round trips through the
converter, the API schemas, files opened without the schema plugin, OpenUSD validation, baked
poses and hardened reading.

Checks that need a process in which the schemas are (or are not) registered run their USD code
in a fresh interpreter. Skipped when ``pxr`` (usd-core) is not installed or predates
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
import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

pytest.importorskip("pxr")

from gsverse_format.codes import Code  # noqa: E402
from gsverse_format.errors import FormatError, UsageError  # noqa: E402
from gsverse_format.io import usd as usd_io  # noqa: E402
from gsverse_format.io.usd import isolation, reader  # noqa: E402

try:  # register before anything in this process uses the USD schema registry
    usd_io.register_schema()
except UsageError as exc:  # pragma: no cover - an OpenUSD without particle fields
    pytest.skip(str(exc), allow_module_level=True)

from gsverse_format import __version__  # noqa: E402
from gsverse_format.cli.convert import main  # noqa: E402
from gsverse_format.examples import make_example  # noqa: E402
from gsverse_format.io.gltf import read_gltf, write_gltf  # noqa: E402
from gsverse_format.io.ply import read_splat_ply, write_splat_ply  # noqa: E402
from gsverse_format.io.registry import read_asset, write_asset  # noqa: E402
from gsverse_format.io.usd import (USD_SUFFIXES, BakedPoses, UsdInternalError,  # noqa: E402
                                   UsdReadWarning, check_usd, load_poses, read_usd, write_usd)
from gsverse_format.model import (Anchoring, SplatAsset, SplatCloud,  # noqa: E402
                                  SplatPrimitive, TriangleMesh)
from gsverse_format.remapping.reference import remap  # noqa: E402
from gsverse_format.transform import rotate_mesh, rotate_splats  # noqa: E402

from usd_validation_assets import BROKEN_READER  # noqa: E402
from helpers import bumpy_sphere, max_rel_cov_error, random_splats, surface_splats  # noqa: E402
from test_convert_cli import assert_ply_roundtrip  # noqa: E402
from test_gltf import (_anchored_asset, _assert_anchoring_equal, _assert_cloud_equal,  # noqa: E402
                       _local_anchors, _tiny_asset)

REPO = pathlib.Path(__file__).resolve().parents[1]
SCHEMA_DIR = REPO / "gsverse_format" / "usd_schema"
PROFILES = [("local", "affine"), ("local", "rigid"), ("games", None)]


# ---------------------------------------------------------------------------- helpers

def _run_py(body: str, *, register_first: bool = False, block_pxr: bool = False,
            **args) -> dict:
    """Run ``body`` in a fresh interpreter (no PXR_PLUGINPATH_NAME); return its last JSON line.

    ``register_first`` imports gsverse_format.io.usd and registers the schemas before the body;
    otherwise nothing in the child has registered them. ``block_pxr`` makes ``import pxr`` fail.
    """
    prelude = "import json, sys\nARGS = json.loads(sys.argv[1])\n"
    if block_pxr:
        prelude += "sys.modules['pxr'] = None\n"
    if register_first:
        prelude += "from gsverse_format.io import usd as usd_io\nassert usd_io.register_schema()\n"
    prelude += "def emit(obj):\n    print(json.dumps(obj))\n"
    env = dict(os.environ)
    env.pop("PXR_PLUGINPATH_NAME", None)
    proc = subprocess.run([sys.executable, "-c", prelude + textwrap.dedent(body),
                           json.dumps(args)], capture_output=True, text=True, env=env,
                          timeout=300, cwd=str(REPO))
    assert proc.returncode == 0, proc.stderr[-4000:]
    return json.loads(proc.stdout.strip().splitlines()[-1])


def _assert_assets_equal(got: SplatAsset, want: SplatAsset, *, names: bool = True) -> None:
    assert len(got.primitives) == len(want.primitives)
    for g, w in zip(got.primitives, want.primitives):
        if names:
            assert g.name == w.name
        _assert_cloud_equal(g.splats, w.splats)
        assert (g.anchoring is None) == (w.anchoring is None)
        if w.anchoring is not None:
            _assert_anchoring_equal(g.anchoring, w.anchoring)


def _mixed_asset(profile: str = "local", deformation: str | None = "affine") -> SplatAsset:
    """An anchored primitive (SH 2), a static one in lin_rec709_display (SH 1)."""
    asset = _anchored_asset(profile, sh_degree=2, deformation=deformation or "affine")
    asset.primitives[1].splats = random_splats(7, 11, sh_degree=1)
    asset.primitives[1].splats.color_space = "lin_rec709_display"
    return asset


def _poses(mesh: TriangleMesh, count: int = 3, seed: int = 0) -> BakedPoses:
    """Rest pose at time 0, then bent and twisted poses at times 1, 2, ..."""
    rng = np.random.default_rng(seed)
    v = mesh.vertices.astype(np.float64)
    frames = [v]
    for i in range(1, count):
        twist = Rotation.from_rotvec([0, 0.4 * i, 0]).as_matrix()
        stretch = np.diag([1 + 0.2 * i, 1 - 0.1 * i, 1.0])
        frames.append(v @ (twist @ stretch).T + rng.normal(0, 0.01, v.shape) + [0.1 * i, 0, 0])
    return BakedPoses(np.arange(count, dtype=np.float64), np.stack(frames).astype(np.float32), 30)


def _usda(tmp_path, asset: SplatAsset, name: str = "asset.usda") -> pathlib.Path:
    path = tmp_path / name
    write_usd(asset, path)
    return path


def _edit(path: pathlib.Path, old: str, new: str, name: str = "bad.usda", count: int = 1):
    """A copy of the .usda ``path`` with ``old`` replaced (must occur) by ``new``."""
    text = path.read_text(encoding="utf-8")
    assert old in text, old
    out = path.with_name(name)
    out.write_text(text.replace(old, new, count), encoding="utf-8")
    return out


def _expect_read_error(path, *match) -> str:
    with pytest.raises(FormatError) as info:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UsdReadWarning)
            read_usd(path)
    message = str(info.value)
    assert "\n" not in message and path.name in message, message
    for m in match:
        assert m in message, message
    return message


def _read_warned(path) -> tuple[SplatAsset, list[str]]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        asset = read_usd(path)
    return asset, [str(w.message) for w in caught if issubclass(w.category, UsdReadWarning)]


@pytest.fixture(scope="module")
def example(tmp_path_factory):
    return make_example(str(tmp_path_factory.mktemp("example")))


# ---------------------------------------------------------------------------- round trips

@pytest.mark.parametrize("suffix", USD_SUFFIXES)
@pytest.mark.parametrize("sh_degree", [0, 1, 2, 3])
def test_ply_usd_glb_ply_roundtrip(tmp_path, suffix, sh_degree):
    """PLY -> USD -> GLB -> PLY holds the PLY <-> GLB tolerance, and USD adds nothing to it."""
    cloud = random_splats(200, seed=sh_degree, sh_degree=sh_degree)
    src = tmp_path / "in.ply"
    write_splat_ply(cloud, src)
    original = read_splat_ply(src)
    mid = tmp_path / f"mid{suffix}"
    assert main([str(src), str(mid), "--plain", "-q"]) == 0
    assert main([str(mid), str(tmp_path / "mid.glb"), "-q"]) == 0
    assert main([str(tmp_path / "mid.glb"), str(tmp_path / "out.ply"), "-q"]) == 0
    back = read_splat_ply(tmp_path / "out.ply")
    assert_ply_roundtrip(original, back)
    # The direct PLY -> GLB -> PLY route gives the very same numbers.
    assert main([str(src), str(tmp_path / "direct.glb"), "--plain", "-q"]) == 0
    assert main([str(tmp_path / "direct.glb"), str(tmp_path / "direct.ply"), "-q"]) == 0
    direct = read_splat_ply(tmp_path / "direct.ply")
    _assert_cloud_equal(back, direct)
    _assert_assets_equal(read_gltf(tmp_path / "mid.glb"), read_gltf(tmp_path / "direct.glb"))
    if suffix in (".usdc", ".usd"):
        assert mid.read_bytes().startswith(b"PXR-USDC")
    elif suffix == ".usda":
        assert mid.read_bytes().startswith(b"#usda 1.0")
    else:
        assert mid.read_bytes().startswith(b"PK\x03\x04")


@pytest.mark.parametrize("name", ["donut_mipsplatting_sh0_fused.ply",
                                  "404gen_tmp_model_dreamgaussian_sh0.ply",
                                  "schwa_test-splat.3-points-from-train.ply"])
def test_ply_usd_glb_ply_roundtrip_real_files(shared_data, tmp_path, name):
    src = shared_data / "3dgs" / name
    original = read_splat_ply(src)
    assert main([str(src), str(tmp_path / "mid.usdc"), "--plain", "-q"]) == 0
    assert main([str(tmp_path / "mid.usdc"), str(tmp_path / "mid.glb"), "-q"]) == 0
    assert main([str(tmp_path / "mid.glb"), str(tmp_path / "out.ply"), "-q"]) == 0
    assert_ply_roundtrip(original, read_splat_ply(tmp_path / "out.ply"))


def test_anchored_ply_usd_glb_ply_roundtrip(example, tmp_path):
    """Binding while writing USD gives the GLB that binding to GLB gives; PLY comes back."""
    ply, obj = example
    assert main([ply, str(tmp_path / "a.usda"), "--mesh", obj, "--keep-order", "-q"]) == 0
    assert main([str(tmp_path / "a.usda"), str(tmp_path / "a.glb"), "-q", "--anchors",
                 "explicit"]) == 0     # the layout --keep-order gives direct.glb
    assert main([ply, str(tmp_path / "direct.glb"), "--mesh", obj, "--keep-order", "-q"]) == 0
    via_usd, direct = read_gltf(tmp_path / "a.glb"), read_gltf(tmp_path / "direct.glb")
    assert len(via_usd.anchored) == 1
    _assert_assets_equal(via_usd, direct)
    assert main([str(tmp_path / "a.glb"), str(tmp_path / "out.ply"), "-q"]) == 0
    assert_ply_roundtrip(read_splat_ply(ply), read_splat_ply(tmp_path / "out.ply"))


@pytest.mark.parametrize("profile,deformation", PROFILES)
def test_glb_usdz_glb_roundtrip(tmp_path, profile, deformation):
    """GLB -> USDZ -> GLB through the converter: every number, name and colour space back."""
    asset = _mixed_asset(profile, deformation)
    write_gltf(asset, tmp_path / "in.glb")
    assert main([str(tmp_path / "in.glb"), str(tmp_path / "mid.usdz"), "-q"]) == 0
    assert main([str(tmp_path / "mid.usdz"), str(tmp_path / "out.glb"), "-q", "--anchors",
                 "explicit"]) == 0     # the layout of in.glb: stored anchors, not derived
    back = read_gltf(tmp_path / "out.glb")
    _assert_assets_equal(back, read_gltf(tmp_path / "in.glb"))
    _assert_assets_equal(back, asset)
    assert [p.splats.color_space for p in back.primitives] == ["srgb_rec709_display",
                                                               "lin_rec709_display"]


@pytest.mark.parametrize("suffix", USD_SUFFIXES)
def test_write_read_shared_meshes_and_local_scales(tmp_path, suffix):
    """Shared anchor meshes stay shared; localScales different from scales survive."""
    mesh, other = bumpy_sphere(1, 0), bumpy_sphere(1, 5)
    prims = []
    for i, m in enumerate((mesh, mesh, other)):
        cloud = surface_splats(m, 10 + i, i, sh_degree=i)
        anchors = _local_anchors(m, cloud, i)
        if i == 1:
            anchors.local_scale = anchors.local_scale * np.float32(1.5)
        prims.append(SplatPrimitive(cloud, Anchoring(m, anchors), f"p{i}"))
    asset = SplatAsset(prims)
    path = tmp_path / f"shared{suffix}"
    write_usd(asset, path)
    back = read_usd(path)
    _assert_assets_equal(back, asset)
    a, b, c = (p.anchoring.mesh for p in back.primitives)
    assert a is b and a is not c
    assert back.generator == f"gsverse-format {__version__}"
    if suffix == ".usda":
        text = path.read_text(encoding="utf-8")
        assert text.count("def Mesh ") == 2
        assert text.count("gsverse:anchor:localScales") == 1  # only where it differs


def test_names_are_valid_unique_and_kept(tmp_path):
    clouds = [random_splats(3, i, sh_degree=0) for i in range(5)]
    names = ["x static", "Körper", "a", "a", None]
    asset = SplatAsset([SplatPrimitive(c, None, n) for c, n in zip(clouds, names)])
    path = _usda(tmp_path, asset)
    text = path.read_text(encoding="utf-8")
    for prim_name in ('"x_static"', '"Körper"', '"a"', '"a_1"', '"splats"'):
        assert f"def ParticleField3DGaussianSplat {prim_name}" in text
    assert text.count("displayName") == 2  # "x static" and the second "a"
    assert [p.name for p in read_usd(path).primitives] == ["x static", "Körper", "a", "a", "splats"]


def test_empty_asset(tmp_path):
    path = _usda(tmp_path, SplatAsset([]))
    assert read_usd(path).primitives == []
    assert check_usd(path) == []


def test_registry_dispatch(tmp_path):
    asset = _tiny_asset()
    write_asset(asset, tmp_path / "r.usd")
    _assert_assets_equal(read_asset(tmp_path / "r.usd"), asset)
    with pytest.raises(UsageError, match="USD output"):
        write_asset(asset, tmp_path / "r.glb", bake_poses=_poses(asset.primitives[0].anchoring.mesh))


# ---------------------------------------------------------------------------- stage layout

def test_stage_layout(tmp_path):
    asset = _mixed_asset("games", None)
    path = _usda(tmp_path, asset)
    out = _run_py('''
        from pxr import Usd, UsdGeom, UsdVol
        stage = Usd.Stage.Open(ARGS["path"])
        root = stage.GetDefaultPrim()
        gs = UsdVol.ParticleField3DGaussianSplat(stage.GetPrimAtPath("/Asset/body"))
        mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Asset/anchor_mesh"))
        emit({"meta": [UsdGeom.GetStageUpAxis(stage), UsdGeom.GetStageMetersPerUnit(stage),
                       stage.HasAuthoredMetadata("metersPerUnit")],
              "root": [str(root.GetPath()), root.GetTypeName(), Usd.ModelAPI(root).GetKind()],
              "children": [c.GetName() for c in root.GetChildren()],
              "generator": stage.GetRootLayer().customLayerData.get("generator"),
              "hints": [gs.GetSortingModeHintAttr().Get(), gs.GetProjectionModeHintAttr().Get()],
              "degree": [gs.GetRadianceSphericalHarmonicsDegreeAttr().HasAuthoredValue(),
                         gs.GetRadianceSphericalHarmonicsDegreeAttr().Get()],
              "extent": [list(map(float, e)) for e in gs.GetExtentAttr().Get()],
              "half": [gs.GetPrim().GetAttribute(n).HasAuthoredValue() for n in
                       ("positionsh", "orientationsh", "scalesh", "opacitiesh")],
              "mesh": [mesh.GetPurposeAttr().Get(), mesh.GetSubdivisionSchemeAttr().Get(),
                       [list(map(float, e)) for e in mesh.GetExtentAttr().Get()]],
              "xformOps": [p.GetAttribute("xformOpOrder").HasAuthoredValue()
                           for p in stage.Traverse()]})
    ''', path=str(path))
    assert out["meta"] == ["Y", 1.0, True]
    assert out["root"] == ["/Asset", "Xform", "component"]
    assert out["children"] == ["anchor_mesh", "body", "bg"]
    assert out["generator"] == f"gsverse-format {__version__}"
    assert out["hints"] == ["cameraDistance", "perspective"]
    assert out["degree"] == [True, 2]
    means = asset.primitives[0].splats.means
    assert out["extent"] == [means.min(0).tolist(), means.max(0).tolist()]
    assert out["half"] == [False] * 4
    v = asset.primitives[0].anchoring.mesh.vertices
    assert out["mesh"] == ["guide", "none", [v.min(0).tolist(), v.max(0).tolist()]]
    assert not any(out["xformOps"])


# ---------------------------------------------------------------------------- schemas

@pytest.mark.parametrize("suffix", [".usda", ".usdz"])
def test_schema_applied_and_readable(tmp_path, suffix):
    """With the schemas registered, the prims have the APIs and typed schema properties."""
    path = tmp_path / f"schema{suffix}"
    asset = _mixed_asset("local", "rigid")
    write_usd(asset, path)
    out = _run_py('''
        import numpy as np
        from pxr import Usd
        stage = Usd.Stage.Open(ARGS["path"])
        reg = Usd.SchemaRegistry()
        definition = reg.FindAppliedAPIPrimDefinition("GsVerseMeshAnchorAPI")
        result = {}
        for name in ("body", "bg"):
            prim = stage.GetPrimAtPath("/Asset/" + name)
            props = {}
            for prop in definition.GetPropertyNames():
                spec = definition.GetAttributeDefinition(prop)
                a = prim.GetAttribute(prop)
                if spec:
                    props[prop] = [a.HasAuthoredValue(), str(a.GetTypeName()),
                                   str(spec.GetTypeName()), a.IsCustom(),
                                   str(a.GetVariability())]
            rel = prim.GetRelationship("gsverse:anchor:mesh")
            result[name] = {
                "hasAPI": [prim.HasAPI("GsVerseMeshAnchorAPI"), prim.HasAPI("GsVerseColorSpaceAPI")],
                "applied": [s for s in prim.GetAppliedSchemas() if s.startswith("GsVerse")],
                "props": props,
                "targets": [str(t) for t in rel.GetTargets()] if rel else [],
                "faces": np.asarray(prim.GetAttribute("gsverse:anchor:faceIndices").Get()).tolist()
                         if prim.GetAttribute("gsverse:anchor:faceIndices").HasAuthoredValue() else None,
                "deformation": prim.GetAttribute("gsverse:anchor:deformation").Get(),
                "colorSpace": prim.GetAttribute("gsverse:colorSpace").Get()}
        emit(result)
    ''', register_first=True, path=str(path))
    body, bg = out["body"], out["bg"]
    assert body["hasAPI"] == [True, True] and bg["hasAPI"] == [False, True]
    assert body["applied"] == ["GsVerseMeshAnchorAPI", "GsVerseColorSpaceAPI"]
    assert bg["applied"] == ["GsVerseColorSpaceAPI"]
    authored = {k for k, v in body["props"].items() if v[0]}
    assert authored == {"gsverse:colorSpace", "gsverse:anchor:profile", "gsverse:anchor:deformation",
                        "gsverse:anchor:faceIndices", "gsverse:anchor:barycentrics",
                        "gsverse:anchor:normalOffsets", "gsverse:anchor:localOrientations"}
    for name, (_, got, declared, custom, variability) in body["props"].items():
        if name in authored:
            assert got == declared and not custom and variability == "Sdf.VariabilityUniform", name
    assert body["targets"] == ["/Asset/anchor_mesh"] and bg["targets"] == []
    assert body["faces"] == asset.primitives[0].anchoring.anchors.face_index.tolist()
    assert body["deformation"] == "rigid"
    assert [body["colorSpace"], bg["colorSpace"]] == ["srgb_rec709_display", "lin_rec709_display"]


@pytest.mark.parametrize("suffix", [".usda", ".usdc"])
def test_late_registration_writes_the_same_file(tmp_path, suffix):
    """A process that used USD first cannot register the schemas: a warning, the same bytes."""
    asset = _mixed_asset("local", "affine")
    write_gltf(asset, tmp_path / "in.glb")
    registered = tmp_path / f"registered{suffix}"
    write_usd(asset, registered)
    out = _run_py('''
        import warnings
        from pxr import Usd
        Usd.SchemaRegistry()                       # the registry is in use before ...
        from gsverse_format.io import usd as usd_io
        from gsverse_format.io.gltf import read_gltf
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            ok = usd_io.register_schema()          # ... the schemas could be registered
        usd_io.write_usd(read_gltf(ARGS["glb"]), ARGS["out"])
        back = usd_io.read_usd(ARGS["out"])
        emit({"registered": ok, "warnings": [(w.category.__name__, str(w.message)) for w in caught],
              "anchored": len(back.anchored)})
    ''', glb=str(tmp_path / "in.glb"), out=str(tmp_path / f"late{suffix}"))
    assert out["registered"] is False and out["anchored"] == 1
    ((category, message),) = out["warnings"]
    assert category == "UsdSchemaWarning" and "PXR_PLUGINPATH_NAME" in message
    assert (tmp_path / f"late{suffix}").read_bytes() == registered.read_bytes()


@pytest.mark.parametrize("suffix", [".usda", ".usdc", ".usdz"])
def test_opens_as_plain_splats_without_the_plugin(tmp_path, suffix):
    """A process that never registered the schemas sees valid splat prims with the rest pose."""
    asset = _mixed_asset("local", "affine")
    path = tmp_path / f"plain{suffix}"
    write_usd(asset, path, bake_poses=_poses(asset.primitives[0].anchoring.mesh))
    reference = tmp_path / "reference.npz"
    arrays = {}
    for i, p in enumerate(asset.primitives):
        c = p.splats
        arrays.update({f"{i}_positions": c.means, f"{i}_orientations": c.rotations,
                       f"{i}_scales": c.scales, f"{i}_opacities": c.opacities,
                       f"{i}_sh": c.sh.reshape(-1, 3)})
    np.savez(reference, **arrays)
    out = _run_py('''
        import numpy as np
        from pxr import Usd, UsdValidation, UsdVol
        registered = Usd.SchemaRegistry().FindAppliedAPIPrimDefinition("GsVerseMeshAnchorAPI") is not None
        stage = Usd.Stage.Open(ARGS["path"])
        ref = np.load(ARGS["reference"])
        validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
        errors = [(e.GetName(), e.GetMessage()) for e in
                  UsdValidation.ValidationContext(validators).Validate(stage)]
        prims = []
        for i, prim in enumerate(p for p in stage.Traverse() if p.IsA(UsdVol.ParticleField3DGaussianSplat)):
            gs = UsdVol.ParticleField3DGaussianSplat(prim)
            same = {
                "positions": np.array_equal(np.asarray(gs.GetPositionsAttr().Get()), ref[f"{i}_positions"]),
                "orientations": np.array_equal(np.asarray(gs.GetOrientationsAttr().Get()), ref[f"{i}_orientations"]),
                "scales": np.array_equal(np.asarray(gs.GetScalesAttr().Get()), ref[f"{i}_scales"]),
                "opacities": np.array_equal(np.asarray(gs.GetOpacitiesAttr().Get()), ref[f"{i}_opacities"]),
                "sh": np.array_equal(np.asarray(gs.GetRadianceSphericalHarmonicsCoefficientsAttr().Get()), ref[f"{i}_sh"]),
            }
            prims.append({"name": prim.GetName(), "same": {k: bool(v) for k, v in same.items()},
                          "kernel": "ParticleFieldKernelGaussianEllipsoidAPI" in prim.GetAppliedSchemas(),
                          "hasAPI": prim.HasAPI("GsVerseMeshAnchorAPI"),
                          "composed": [s for s in prim.GetAppliedSchemas() if s.startswith("GsVerse")],
                          "authored": list(prim.GetPrimTypeInfo().GetAppliedAPISchemas()),
                          "degree": gs.GetRadianceSphericalHarmonicsDegreeAttr().Get(),
                          "sorting": gs.GetSortingModeHintAttr().Get()})
        emit({"registered": registered, "errors": errors, "prims": prims})
    ''', path=str(path), reference=str(reference))
    assert out["registered"] is False
    assert out["errors"] == []
    assert [p["name"] for p in out["prims"]] == ["body", "bg"]
    for p, apis, degree in zip(out["prims"], (["GsVerseMeshAnchorAPI"], ["GsVerseColorSpaceAPI"]),
                               (2, 1)):
        assert all(p["same"].values()), p
        assert p["kernel"] and not p["hasAPI"] and p["composed"] == []
        assert p["authored"] == apis
        assert p["degree"] == degree and p["sorting"] == "cameraDistance"


def test_reading_does_not_need_the_schemas(tmp_path):
    asset = _mixed_asset("games", None)
    write_gltf(asset, tmp_path / "in.glb")
    path = _usda(tmp_path, asset)
    _run_py('''
        import warnings
        from pxr import Usd
        Usd.Stage.CreateInMemory().DefinePrim("/x", "Xform")   # registry in use: no schemas
        from gsverse_format.io.gltf import read_gltf
        from gsverse_format.io.usd import read_usd
        warnings.simplefilter("ignore")
        got, want = read_usd(ARGS["path"]), read_gltf(ARGS["glb"])
        import numpy as np
        for g, w in zip(got.primitives, want.primitives):
            assert np.array_equal(g.splats.means, w.splats.means)
            assert np.array_equal(g.splats.sh, w.splats.sh)
            assert (g.anchoring is None) == (w.anchoring is None)
        a = got.primitives[0].anchoring.anchors
        assert a.profile == "games"
        assert np.array_equal(a.rho, want.primitives[0].anchoring.anchors.rho)
        emit({})
    ''', path=str(path), glb=str(tmp_path / "in.glb"))


def test_missing_usd_core_is_one_clear_line(tmp_path):
    write_splat_ply(random_splats(5, 0, sh_degree=0), tmp_path / "in.ply")
    out = _run_py('''
        import contextlib, io
        from gsverse_format.cli.convert import main
        from gsverse_format.errors import UsageError
        from gsverse_format.io.usd import read_usd, MISSING_USD_CORE
        from gsverse_format.install import missing_usd_core
        err = io.StringIO()
        with contextlib.redirect_stderr(err):
            code = main([ARGS["ply"], ARGS["out"], "--plain", "-q"])
        try:
            read_usd(ARGS["out"])
            raised = None
        except UsageError as exc:
            raised = str(exc)
        emit({"code": code, "stderr": err.getvalue(), "raised": raised, "message": MISSING_USD_CORE,
              "fitting": missing_usd_core()})
    ''', block_pxr=True, ply=str(tmp_path / "in.ply"), out=str(tmp_path / "out.usda"))
    assert out["message"] == "USD support needs usd-core: pip install 'gsverse-format[usd]'"
    assert out["code"] == 2
    lines = out["stderr"].strip().splitlines()
    assert len(lines) == 1 and lines[0].endswith(out["fitting"]) and "out.usda" in lines[0]
    assert out["raised"].endswith(out["fitting"])
    assert not (tmp_path / "out.usda").exists()


# ---------------------------------------------------------------------------- validation

@pytest.mark.parametrize("suffix", USD_SUFFIXES)
def test_usd_validation_clean(tmp_path, suffix):
    """OpenUSD's validators (schemas registered) and our own checks find nothing."""
    asset = _mixed_asset("local", "affine")
    path = tmp_path / f"valid{suffix}"
    write_usd(asset, path, bake_poses=_poses(asset.primitives[0].anchoring.mesh))
    assert check_usd(path) == []                       # child process: schemas registered
    assert check_usd(path, isolate=False) == []        # this process
    out = _run_py('''
        from pxr import Usd, UsdValidation
        stage = Usd.Stage.Open(ARGS["path"])
        validators = UsdValidation.ValidationRegistry().GetOrLoadAllValidators()
        emit({"names": sorted(v.GetMetadata().name for v in validators),
              "errors": [(e.GetName(), str(e.GetType()), e.GetMessage()) for e in
                         UsdValidation.ValidationContext(validators).Validate(stage)]})
    ''', register_first=True, path=str(path))
    assert "usdValidation:AttributeTypeMismatch" in out["names"]
    assert out["errors"] == []


def test_check_usd_reports_problems_with_usd_paths(tmp_path):
    good = _usda(tmp_path, _mixed_asset("local", "affine"))
    text = good.read_text(encoding="utf-8")
    text = text.replace('    upAxis = "Y"\n', "")
    text = text.replace('        uniform token sortingModeHint = "cameraDistance"\n', "", 1)
    text = text.replace("uniform float[] gsverse:anchor:normalOffsets",
                        "uniform float[] gsverse:anchor:rho = [1]\n"
                        "        uniform float[] gsverse:anchor:normalOffsets", 1)
    text = text.replace('uniform token gsverse:colorSpace = "lin_rec709_display"',
                        'custom uniform string gsverse:colorSpace = "lin_rec709_display"', 1)
    text = text.replace('uniform token subdivisionScheme = "none"', "")
    bad = tmp_path / "bad.usda"
    bad.write_text(text, encoding="utf-8")
    problems = check_usd(bad)
    found = {(p.severity, p.location, p.code) for p in problems}
    assert ("error", "", Code.USD_UP_AXIS_MISSING) in found
    assert ("error", "/Asset/body.sortingModeHint", Code.USD_SORTING_MODE) in found
    assert ("error", "/Asset/body.gsverse:anchor:rho", Code.USD_PROPERTY_EXCLUDED) in found
    assert ("error", "/Asset/bg.gsverse:colorSpace", Code.USD_CUSTOM_PROPERTY) in found
    assert ("error", "/Asset/bg.gsverse:colorSpace", Code.USD_TYPE_MISMATCH) in found
    assert ("warning", "/Asset/anchor_mesh.subdivisionScheme", Code.USD_MESH_SUBDIVISION) in found
    assert all(isinstance(p.code, Code) for p in problems)
    validators = {(p.code, p.validator) for p in problems if p.validator}
    assert (Code.USD_VALIDATOR_ERROR,                                   # OpenUSD agrees
            "usdGeomValidators:StageMetadataChecker") in validators
    assert (Code.USD_VALIDATOR_ERROR,                                   # schema registered there
            "usdValidation:AttributeTypeMismatch") in validators
    assert all(str(p).startswith(p.severity) for p in problems)
    # read_usd ignores the excluded attribute (warning) and reads the rest.
    asset, messages = _read_warned(bad)
    assert len(asset.anchored) == 1 and any("gsverse:anchor:rho" in m for m in messages)


def test_spec_example_conforms(tmp_path):
    """The USDA example of spec/usd.md passes every check and reads as documented."""
    text = (REPO / "spec" / "usd.md").read_text(encoding="utf-8")
    path = tmp_path / "example.usda"
    path.write_text(re.findall(r"```usda\n(.*?)```", text, re.S)[0], encoding="utf-8")
    assert check_usd(path) == []
    asset = read_usd(path)
    assert [p.name for p in asset.primitives] == ["splats", "background"]
    prim = asset.primitives[0]
    assert np.array_equal(prim.splats.means, [[0.5, 0.5, 0.125]])  # the rest pose, not t = 1
    a = prim.anchoring.anchors
    assert a.profile == "local" and a.deformation == "affine"
    assert np.array_equal(a.local_scale, prim.splats.scales)
    r = remap(prim.anchoring, np.array([[0, 0, 0], [0, 4, 0], [-1, 0, 0]], np.float32))
    assert np.allclose(r.means, [[-0.5, 1, 0.1767767]], atol=1e-6)
    assert asset.primitives[1].anchoring is None


def test_check_usd_plain_foreign_file(tmp_path):
    path = tmp_path / "foreign.usda"
    path.write_text(textwrap.dedent('''\
        #usda 1.0
        (
            defaultPrim = "World"
            metersPerUnit = 1
            upAxis = "Y"
        )
        def Xform "World"
        {
            def ParticleField3DGaussianSplat "gs"
            {
                float3[] extent = [(0, 0, 0), (1, 1, 1)]
                point3f[] positions = [(0, 0, 0), (1, 1, 1)]
                float3[] radiance:sphericalHarmonicsCoefficients = [(0.1, 0.2, 0.3), (0, 0, 0)]
                uniform int radiance:sphericalHarmonicsDegree = 0
            }
        }
    '''), encoding="utf-8")
    problems = check_usd(path)
    assert not [p for p in problems if p.severity == "error"], problems
    assert {Code.USD_PLAIN_SPLATS, Code.USD_SORTING_MODE} <= {p.code for p in problems}
    asset, messages = _read_warned(path)
    c = asset.primitives[0].splats
    assert c.color_space == "srgb_rec709_display" and asset.primitives[0].name == "gs"
    assert np.array_equal(c.rotations, [[0, 0, 0, 1]] * 2)
    assert np.array_equal(c.scales, np.ones((2, 3))) and np.array_equal(c.opacities, [1, 1])
    assert np.allclose(c.sh[:, 0], [[0.1, 0.2, 0.3], [0, 0, 0]])
    assert messages == []  # unauthored arrays take the schema's defaults silently


# ---------------------------------------------------------------------------- baked poses

@pytest.mark.parametrize("profile,deformation", PROFILES)
def test_baked_poses_equal_the_reference_remap(tmp_path, profile, deformation):
    asset = _mixed_asset(profile, deformation)
    prim = asset.primitives[0]
    poses = _poses(prim.anchoring.mesh, count=4)
    path = tmp_path / "baked.usdc"
    write_usd(asset, path, bake_poses=poses)
    from pxr import Usd, UsdGeom, UsdVol

    stage = Usd.Stage.Open(str(path))
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode(), stage.GetTimeCodesPerSecond()) == \
        (0.0, 3.0, 30.0)
    gs = UsdVol.ParticleField3DGaussianSplat(stage.GetPrimAtPath("/Asset/body"))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/Asset/anchor_mesh"))
    previous = prim.splats.rotations
    for t, vertices in zip(poses.times, poses.vertices):
        ref = remap(prim.anchoring, vertices)
        means = np.asarray(gs.GetPositionsAttr().Get(t))
        rotations = np.asarray(gs.GetOrientationsAttr().Get(t))
        scales = np.asarray(gs.GetScalesAttr().Get(t))
        assert np.array_equal(means, ref.means.astype(np.float32))
        assert np.array_equal(scales, ref.scales.astype(np.float32))
        sign = np.sign(np.sum(rotations.astype(np.float64) * ref.rotations, axis=1))
        assert np.all(sign != 0)
        assert np.array_equal(rotations, (ref.rotations * sign[:, None]).astype(np.float32))
        assert np.all(np.sum(rotations * previous, axis=1) >= 0)  # same hemisphere as before
        previous = rotations
        cloud = SplatCloud(means, rotations, scales, prim.splats.opacities, prim.splats.sh)
        assert max_rel_cov_error(cloud.covariances(), ref.covariances) < 1e-5
        assert np.array_equal(np.asarray(mesh.GetPointsAttr().Get(t)), vertices)
        assert np.array_equal(np.asarray(gs.GetExtentAttr().Get(t)),
                              [means.min(0), means.max(0)])
    # The rest pose stays in the default values; the rest does not move.
    assert np.array_equal(np.asarray(gs.GetPositionsAttr().Get()), prim.splats.means)
    assert np.array_equal(np.asarray(mesh.GetPointsAttr().Get()), prim.anchoring.mesh.vertices)
    for name in ("opacities", "radiance:sphericalHarmonicsCoefficients",
                 "radiance:sphericalHarmonicsDegree", "gsverse:anchor:faceIndices",
                 "gsverse:colorSpace"):
        assert gs.GetPrim().GetAttribute(name).GetNumTimeSamples() == 0, name
    static = UsdVol.ParticleField3DGaussianSplat(stage.GetPrimAtPath("/Asset/bg"))
    assert static.GetPositionsAttr().GetNumTimeSamples() == 0
    del stage
    _assert_assets_equal(read_usd(path), asset)


@pytest.mark.parametrize("form", ["npz", "json", "json-object"])
def test_cli_bake_poses(tmp_path, form):
    asset = _mixed_asset("local", "affine")
    write_gltf(asset, tmp_path / "in.glb")
    poses = _poses(asset.primitives[0].anchoring.mesh, count=3)
    if form == "npz":
        poses_path = tmp_path / "poses.npz"
        np.savez(poses_path, vertices=poses.vertices, times=poses.times,
                 time_codes_per_second=np.float64(30))
    else:
        items = [{"time": float(t), "vertices": v.tolist()}
                 for t, v in zip(poses.times, poses.vertices)]
        doc = items if form == "json" else {"timeCodesPerSecond": 30, "poses": items}
        poses_path = tmp_path / "poses.json"
        poses_path.write_text(json.dumps(doc))
    loaded = load_poses(poses_path)
    assert np.array_equal(loaded.vertices, poses.vertices)
    assert loaded.time_codes_per_second == (24 if form == "json" else 30)
    out = tmp_path / "baked.usda"
    assert main([str(tmp_path / "in.glb"), str(out), "--bake-poses", str(poses_path), "-q"]) == 0
    from pxr import Usd, UsdVol

    stage = Usd.Stage.Open(str(out))
    gs = UsdVol.ParticleField3DGaussianSplat(stage.GetPrimAtPath("/Asset/body"))
    assert list(gs.GetPositionsAttr().GetTimeSamples()) == [0.0, 1.0, 2.0]
    ref = remap(asset.primitives[0].anchoring, poses.vertices[2])
    assert np.array_equal(np.asarray(gs.GetPositionsAttr().Get(2)), ref.means.astype(np.float32))
    assert stage.GetTimeCodesPerSecond() == (24 if form == "json" else 30)
    del stage
    assert check_usd(out) == []


def test_cli_bake_poses_errors(tmp_path, example):
    asset = _mixed_asset("local", "affine")
    write_gltf(asset, tmp_path / "in.glb")
    mesh = asset.primitives[0].anchoring.mesh
    good = tmp_path / "poses.npz"
    np.savez(good, vertices=_poses(mesh).vertices, times=np.arange(3.0))
    wrong_v = tmp_path / "wrong.npz"
    np.savez(wrong_v, vertices=np.zeros((2, 5, 3), np.float32), times=np.arange(2.0))
    unsorted = tmp_path / "unsorted.json"
    unsorted.write_text(json.dumps([{"time": 1, "vertices": mesh.vertices.tolist()},
                                    {"time": 0, "vertices": mesh.vertices.tolist()}]))
    plain = tmp_path / "plain.glb"
    write_gltf(SplatAsset([SplatPrimitive(random_splats(4, 0), None, "p")]), plain)
    # Wrong flags or arguments exit 2; a poses file that holds the wrong data is bad input
    # (exit 1), named in the message.
    cases = [
        ([str(tmp_path / "in.glb"), str(tmp_path / "o.glb"), "--bake-poses", str(good)],
         "needs a USD output", 2, None),
        ([str(tmp_path / "in.glb"), str(tmp_path / "o.usda"), "--bake-poses", str(wrong_v)],
         "5 vertices", 1, wrong_v),
        ([str(tmp_path / "in.glb"), str(tmp_path / "o.usda"), "--bake-poses", str(unsorted)],
         "strictly increasing", 1, unsorted),
        ([str(tmp_path / "in.glb"), str(tmp_path / "o.usda"), "--bake-poses",
          str(tmp_path / "none.npz")], "file not found", 1, tmp_path / "none.npz"),
        ([str(plain), str(tmp_path / "o.usda"), "--bake-poses", str(good)],
         "exactly one mesh", 2, plain),
    ]
    for argv, message, code, named in cases:
        proc = subprocess.run([sys.executable, "-m", "gsverse_format.cli.convert", *argv, "-q"],
                              capture_output=True, text=True, timeout=300)
        assert proc.returncode == code, (argv, proc.stderr)
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and message in lines[0], (message, proc.stderr)
        if named is not None:
            assert f"error: {named}: " in lines[0], lines
    assert not [n for n in os.listdir(tmp_path) if n.startswith("o.")]


# ---------------------------------------------------------------------------- atomic output

def test_failed_write_leaves_existing_output_untouched(tmp_path):
    out = tmp_path / "out.usdz"
    out.write_bytes(b"previous contents")
    bad = _tiny_asset()
    bad.primitives[0].splats.means[0, 1] = np.nan
    with pytest.raises(UsageError, match="non-finite"):
        write_usd(bad, out)
    asset = _tiny_asset()
    with pytest.raises(UsageError, match="vertices"):
        write_usd(asset, out, bake_poses=BakedPoses([0.0], np.zeros((1, 3, 3), np.float32)))
    assert out.read_bytes() == b"previous contents"
    write_usd(asset, out)
    _assert_assets_equal(read_usd(out), asset)
    assert sorted(os.listdir(tmp_path)) == ["out.usdz"]  # no temporary files left
    with pytest.raises(UsageError, match="overwrite an input"):
        write_usd(asset, out, protect=[out])
    with pytest.raises(UsageError, match="USD output"):
        write_usd(asset, tmp_path / "out.usdx")


def test_rewritten_file_is_read_afresh(tmp_path):
    path = tmp_path / "again.usdc"
    first, second = _tiny_asset("local"), _tiny_asset("games")
    write_usd(first, path)
    from pxr import Usd

    held = Usd.Stage.Open(str(path))  # keeps the layer open in this process
    assert read_usd(path).primitives[0].anchoring.anchors.profile == "local"
    write_usd(second, path)
    assert read_usd(path).primitives[0].anchoring.anchors.profile == "games"
    del held


# ---------------------------------------------------------------------------- hardened reading

def test_unreadable_files(tmp_path):
    good = tmp_path / "good.usdc"
    write_usd(_tiny_asset(), good)
    data = good.read_bytes()
    cases = {"empty.usda": b"", "garbage.usda": b"#usda 1.0\n( blah \n def Xform {",
             "text.usdc": b"hello", "zeros.usdc": b"\0" * 100, "notzip.usdz": b"PK\3\4junk",
             "ply.usd": b"ply\nformat ascii 1.0\n"}
    for name, content in cases.items():
        (tmp_path / name).write_bytes(content)
        _expect_read_error(tmp_path / name, "not a readable USD file")
    for cut in range(0, len(data), 7):
        (tmp_path / "cut.usdc").write_bytes(data[:cut])
        _expect_read_error(tmp_path / "cut.usdc")
    _expect_read_error(tmp_path / "missing.usda", "file not found")
    (tmp_path / "folder.usda").mkdir()
    _expect_read_error(tmp_path / "folder.usda", "folder")


def test_truncated_usdz_and_usda(tmp_path):
    for suffix in (".usdz", ".usda"):
        good = tmp_path / f"good{suffix}"
        write_usd(_tiny_asset(), good)
        data = good.read_bytes()
        for cut in range(0, len(data) - 64, max(1, len(data) // 60)):
            path = tmp_path / f"cut{suffix}"
            path.write_bytes(data[:cut])
            try:
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", UsdReadWarning)
                    read_usd(path)
            except FormatError as err:
                assert "\n" not in str(err) and path.name in str(err)


def test_isolated_reading_survives_a_crashing_usd_library(tmp_path, monkeypatch):
    good = tmp_path / "good.usdc"
    asset = _mixed_asset("games", None)
    write_usd(asset, good)
    back = read_usd(good, isolate=True)
    _assert_assets_equal(back, asset)
    assert back.generator == f"gsverse-format {__version__}"
    (tmp_path / "bad.usda").write_text("#usda 1.0\n(")
    with pytest.raises(FormatError, match="not a readable USD file"):
        read_usd(tmp_path / "bad.usda", isolate=True)
    monkeypatch.setattr(isolation, "CHILD_CODE",
                        "import os, signal; os.kill(os.getpid(), signal.SIGSEGV)")
    with pytest.raises(FormatError, match="crashed reading it .SIGSEGV."):
        read_usd(good, isolate=True)
    with pytest.raises(FormatError, match="crashed"):
        check_usd(good)


def test_an_unexpected_exception_is_a_crash_not_bad_input(tmp_path, monkeypatch):
    """A bug in the reader (an injected KeyError) is never reported as a malformed file: in this
    process it propagates as it is; from the child it comes back as UsdInternalError naming
    its type."""
    good = tmp_path / "good.usda"
    write_usd(_tiny_asset(), good)

    def broken(self):
        raise KeyError("injected")

    with monkeypatch.context() as patch:
        patch.setattr(reader.StageReader, "read", broken)
        with pytest.raises(KeyError, match="injected"):
            read_usd(good)
        with pytest.raises(KeyError, match="injected"):
            check_usd(good, isolate=False)
    monkeypatch.setattr(isolation, "CHILD_CODE", BROKEN_READER + isolation.CHILD_CODE)
    for call in (lambda: read_usd(good, isolate=True), lambda: check_usd(good)):
        with pytest.raises(UsdInternalError, match="KeyError in the USD child process") as err:
            call()
        assert err.value.type_name == "KeyError" and "injected" in str(err.value)
        assert not isinstance(err.value, FormatError)


@pytest.mark.slow
def test_byte_flips_never_escape_isolated_reading(tmp_path):
    good = tmp_path / "good.usdc"
    write_usd(_tiny_asset(), good)
    data = good.read_bytes()
    rng = np.random.default_rng(0)
    path = tmp_path / "fuzz.usdc"
    for _ in range(12):
        mutated = bytearray(data)
        for pos in rng.integers(0, len(data), rng.integers(1, 4)):
            mutated[pos] = rng.integers(0, 256)
        path.write_bytes(bytes(mutated))
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", UsdReadWarning)
                read_usd(path, isolate=True)
        except FormatError as err:
            assert "fuzz.usdc" in str(err) and "\n" not in str(err)


@pytest.fixture
def tiny(tmp_path):
    """The tiny local-profile asset as .usda text to corrupt, plus the asset."""
    asset = _tiny_asset("local")
    return _usda(tmp_path, asset, "tiny.usda"), asset


def test_anchored_length_mismatches(tiny):
    path, _ = tiny
    bad = _edit(path, "uniform int[] gsverse:anchor:faceIndices = [",
                "uniform int[] gsverse:anchor:faceIndices = [0, ")
    _expect_read_error(bad, "/Asset/tiny.gsverse:anchor:faceIndices", "6 elements",
                       "5 particles")
    bad = _edit(path, "float[] opacities = [", "float[] opacities = [0.5, ")
    _expect_read_error(bad, "/Asset/tiny.opacities", "6 elements")
    bad = _edit(path, "uniform int radiance:sphericalHarmonicsDegree = 1",
                "uniform int radiance:sphericalHarmonicsDegree = 2")
    _expect_read_error(bad, "radiance:sphericalHarmonicsCoefficients", "needs 5 x 9")
    bad = _edit(path, "        uniform int radiance:sphericalHarmonicsDegree = 1\n", "")
    _expect_read_error(bad, "fallback is 3")


def test_nan_and_wrong_types(tiny):
    path, _ = tiny
    text = path.read_text(encoding="utf-8")
    first = re.search(r"point3f\[\] positions = \[\(([^,]+),", text).group(1)
    bad = _edit(path, f"point3f[] positions = [({first},", "point3f[] positions = [(nan,")
    _expect_read_error(bad, "/Asset/tiny.positions", "NaN")
    bad = _edit(path, "uniform int[] gsverse:anchor:faceIndices",
                "uniform float[] gsverse:anchor:faceIndices")
    _expect_read_error(bad, "/Asset/tiny.gsverse:anchor:faceIndices", "type float[]",
                       "expected int[]")
    bad = _edit(path, "(0, 0, 0), (1, 0, 0)", "(0, 0, 0), (inf, 0, 0)")
    _expect_read_error(bad, "/Asset/anchor_mesh.points", "NaN or infinite")


def test_face_and_vertex_indices_out_of_range(tiny):
    path, _ = tiny
    bad = _edit(path, "uniform int[] gsverse:anchor:faceIndices = [",
                "uniform int[] gsverse:anchor:faceIndices = [4, ")
    bad = _edit(bad, "float[] opacities = [", "float[] opacities = [1, ", name="bad2.usda")
    text = bad.read_text(encoding="utf-8")
    # keep the lengths consistent: drop the last face index instead of the first element
    text = re.sub(r"(gsverse:anchor:faceIndices = \[[^\]]*?), \d+\]", r"\1]", text)
    text = re.sub(r"(float\[\] opacities = \[[^\]]*?), [^,\]]+\]", r"\1]", text)
    bad.write_text(text, encoding="utf-8")
    _expect_read_error(bad, "/Asset/tiny.gsverse:anchor:faceIndices", "value 4 out of range",
                       "4 triangles")
    neg = _edit(path, "uniform int[] gsverse:anchor:faceIndices = [",
                "uniform int[] gsverse:anchor:faceIndices = [-1, ")
    text = re.sub(r"(gsverse:anchor:faceIndices = \[[^\]]*?), \d+\]", r"\1]",
                  neg.read_text(encoding="utf-8"))
    neg.write_text(text, encoding="utf-8")
    _expect_read_error(neg, "value -1 out of range")
    bad = _edit(path, "int[] faceVertexIndices = [0, ", "int[] faceVertexIndices = [9, ")
    _expect_read_error(bad, "/Asset/anchor_mesh.faceVertexIndices", "index 9 out of range")


def test_non_triangle_and_bad_anchor_meshes(tiny):
    path, _ = tiny
    bad = _edit(path, "int[] faceVertexCounts = [3, 3, 3, 3]",
                "int[] faceVertexCounts = [4, 3, 3, 2]")
    _expect_read_error(bad, "/Asset/anchor_mesh.faceVertexCounts", "4 vertices", "triangles")
    bad = _edit(path, "int[] faceVertexIndices = [0, 1, 2,", "int[] faceVertexIndices = [0, 1,")
    _expect_read_error(bad, "faceVertexIndices", "11 elements for 4 triangles")
    bad = _edit(path, "rel gsverse:anchor:mesh = </Asset/anchor_mesh>",
                "rel gsverse:anchor:mesh = </Asset/tiny>")
    _expect_read_error(bad, "gsverse:anchor:mesh", "not a Mesh")
    bad = _edit(path, "rel gsverse:anchor:mesh = </Asset/anchor_mesh>",
                "rel gsverse:anchor:mesh = [</Asset/anchor_mesh>, </Asset/anchor_mesh2>]")
    _expect_read_error(bad, "gsverse:anchor:mesh", "2 targets")
    bad = _edit(path, "        rel gsverse:anchor:mesh = </Asset/anchor_mesh>\n", "")
    _expect_read_error(bad, "gsverse:anchor:mesh", "0 targets")
    bad = _edit(path, '"local"', '"sugar"')
    _expect_read_error(bad, "gsverse:anchor:profile", "'sugar'")
    bad = _edit(path, '        uniform token gsverse:anchor:profile = "local"\n', "")
    _expect_read_error(bad, "gsverse:anchor:profile", "missing")
    bad = _edit(path, '        uniform float[] gsverse:anchor:normalOffsets', "        uniform float[] x")
    _expect_read_error(bad, "gsverse:anchor:normalOffsets", "missing")
    bad = _edit(path, '"affine"', '"elastic"')
    _expect_read_error(bad, "gsverse:anchor:deformation", "'elastic'")
    bad = _edit(path, "        int[] faceVertexCounts = [3, 3, 3, 3]\n",
                "        int[] faceVertexCounts = [3, 3, 3, 3]\n        int[] holeIndices = [1]\n")
    _expect_read_error(bad, "holeIndices")


def test_foreign_data_follows_the_usd_schema_rules(tmp_path):
    path = tmp_path / "foreign.usda"
    sh_deg4 = ", ".join(f"({k}, {k}, {k})" for k in range(25))
    path.write_text(textwrap.dedent(f'''\
        #usda 1.0
        (
            defaultPrim = "W"
            metersPerUnit = 1
            upAxis = "Y"
        )
        def Xform "W"
        {{
            def ParticleField3DGaussianSplat "a"
            {{
                point3h[] positionsh = [(1, 2, 3)]
                quatf[] orientations = [(0, 0, 0, 0), (1, 0, 0, 0)]
                float3[] scales = [(-1, 2, -3)]
                float[] opacities = [1.5]
                float3[] radiance:sphericalHarmonicsCoefficients = [{sh_deg4}]
                uniform int radiance:sphericalHarmonicsDegree = 4
            }}
            def ParticleField3DGaussianSplat "empty"
            {{
            }}
            def ParticleField "other"
            {{
                point3f[] positions = [(0, 0, 0)]
            }}
        }}
    '''), encoding="utf-8")
    asset, messages = _read_warned(path)
    assert len(asset.primitives) == 1
    c = asset.primitives[0].splats
    assert np.array_equal(c.means, [[1, 2, 3]])
    assert np.array_equal(c.rotations, [[0, 0, 0, 1]])     # zero quaternion -> identity
    assert np.array_equal(c.scales, [[1, 2, 3]])           # absolute values
    assert np.array_equal(c.opacities, [1])                # clamped
    assert c.sh_degree == 3 and np.array_equal(c.sh[0, :, 0], np.arange(16))
    joined = " | ".join(messages)
    for needle in ("orientations: has 2 elements for 1 particles: truncated", "truncated to 3",
                   "/W/empty: has no particles", "/W/other", "skipped"):
        assert needle in joined, joined


def test_up_axis_and_units_are_converted(tmp_path):
    asset = _mixed_asset("local", "affine")
    path = _usda(tmp_path, asset)
    bad = _edit(path, 'metersPerUnit = 1\n    upAxis = "Y"', 'metersPerUnit = 0.5\n    upAxis = "Z"')
    back, messages = _read_warned(bad)
    assert any("upAxis" in m for m in messages) and any("metersPerUnit" in m for m in messages)
    z_to_y = np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]])
    for got, want in zip(back.primitives, asset.primitives):
        w = rotate_splats(want.splats, z_to_y)
        assert np.allclose(got.splats.means, 0.5 * w.means, atol=1e-6)
        assert np.allclose(got.splats.scales, 0.5 * w.scales)
        assert max_rel_cov_error(got.splats.covariances(), 0.25 * w.covariances()) < 1e-5
        assert np.allclose(got.splats.sh, w.sh, atol=1e-5)
    anchoring = back.primitives[0].anchoring
    mesh = rotate_mesh(asset.primitives[0].anchoring.mesh, z_to_y)
    assert np.allclose(anchoring.mesh.vertices, 0.5 * mesh.vertices, atol=1e-6)
    # The converted anchors remap to the converted remap of the original anchors.
    original = remap(asset.primitives[0].anchoring)
    converted = remap(anchoring)
    assert np.allclose(converted.means, 0.5 * original.means @ z_to_y.T, atol=1e-6)
    assert max_rel_cov_error(converted.covariances,
                             0.25 * z_to_y @ original.covariances @ z_to_y.T) < 1e-5
    unauthored = _edit(path, 'metersPerUnit = 1\n', '', name="nometers.usda")
    asset2, messages = _read_warned(unauthored)
    assert np.array_equal(asset2.primitives[0].splats.means, asset.primitives[0].splats.means)
    assert any("metersPerUnit" in m for m in messages)
    weird = _edit(path, 'upAxis = "Y"', 'upAxis = "X"', name="x.usda")
    _expect_read_error(weird, "upAxis")


@pytest.mark.parametrize("arc", ["subLayers = [@../outside.usda@]",
                                 "subLayers = [@/etc/hosts@]",
                                 "subLayers = [@http://example.com/x.usda@]",
                                 "subLayers = [@./link/outside.usda@]"])
def test_composition_arcs_leaving_the_folder_are_refused(tmp_path, arc):
    """Sublayers/references outside the file's folder are refused before USD opens them."""
    outside = tmp_path / "outside.usda"
    write_usd(_tiny_asset(), outside)
    inner = tmp_path / "inner"
    inner.mkdir()
    (inner / "link").symlink_to(tmp_path, target_is_directory=True)
    base = _usda(inner, _tiny_asset(), "base.usda")
    bad = _edit(base, 'defaultPrim = "Asset"', f'defaultPrim = "Asset"\n    {arc}', "bad.usda")
    message = _expect_read_error(bad)
    assert "folder" in message or "URI schemes" in message or "absolute path" in message
    assert check_usd(bad)[0].code == Code.USD_LAYER_OUTSIDE_FOLDER
    with pytest.raises(FormatError):
        read_usd(bad, isolate=True)


def test_composition_arcs_inside_the_folder_are_followed(tmp_path):
    sub = tmp_path / "parts"
    sub.mkdir()
    write_usd(_tiny_asset(), sub / "part.usda")
    top = tmp_path / "top.usda"
    top.write_text('#usda 1.0\n(\n    defaultPrim = "Asset"\n    metersPerUnit = 1\n'
                   '    upAxis = "Y"\n    subLayers = [@./parts/part.usda@]\n)\n',
                   encoding="utf-8")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UsdReadWarning)
        asset = read_usd(top)
    _assert_assets_equal(asset, read_usd(sub / "part.usda"))


def test_zero_local_rotation_and_negative_scale_are_refused(tiny):
    """Spec v1.1: readers refuse a zero localRotation and a negative local scale."""
    path, _ = tiny
    text = path.read_text(encoding="utf-8")
    first = re.search(r"gsverse:anchor:localOrientations = \[(\([^)]*\))", text).group(1)
    bad = _edit(path, f"gsverse:anchor:localOrientations = [{first}",
                "gsverse:anchor:localOrientations = [(0, 0, 0, 0)")
    _expect_read_error(bad, "/Asset/tiny.gsverse:anchor:localOrientations", "zero quaternion")
    scale = re.search(r"float3\[\] scales = \[\(([^,]+),", text).group(1)
    bad = _edit(path, f"float3[] scales = [({scale},", "float3[] scales = [(-0.5,")
    _expect_read_error(bad, "negative")
