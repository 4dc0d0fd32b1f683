"""Compact anchor encodings (extension 1.2): ``faceCounts``, derived ``local`` anchors, the
writer's ``anchors=``/``quantize=`` options, ``gsverse-convert --anchors/--quantize``, and the
rest-pose tolerance of spec §Outputs for every compact or quantized file (read back, remap at
the rest mesh, compare means and covariances)."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from gsverse_format.anchors_derive import derive_local
from gsverse_format.binding import bind_local
from gsverse_format.cli.convert import main as convert_main
from gsverse_format.codes import Code
from gsverse_format.conformance import minimal_reader
from gsverse_format.errors import FormatError, UsageError
from gsverse_format.examples import example_mesh, example_splats
from gsverse_format.frames import local_frames
from gsverse_format.io.gltf import asset_to_gltf, read_gltf, write_gltf
from gsverse_format.io.gltf.writer import QUANTIZE_BITS, compact_problem, quantize_notes
from gsverse_format.model import (Anchoring, LocalAnchors, SplatAsset, SplatCloud,
                                  SplatPrimitive, TriangleMesh)
from gsverse_format.remapping.reference import remap
from gsverse_format.tolerances import (REST_COVARIANCE_FLOOR, REST_COVARIANCE_RELATIVE,
                                       mesh_extent, rest_mean_tolerance)
from gsverse_format.validators import validate_file

from validation_assets import games_asset, local_asset

ROOT = Path(__file__).resolve().parents[1]
CAPSULE = ROOT / "examples" / "capsule"
ANCHOR = "GSVERSE_gaussian_splatting_mesh_anchor"


def _anchor_json(path: Path) -> dict:
    from gsverse_format.conformance.glb import anchor_extension, unpack_glb

    doc, _ = unpack_glb(path.read_bytes())
    return anchor_extension(doc)


def _rest_errors(prim: SplatPrimitive) -> tuple[float, float]:
    """The worst rest-pose errors of ``prim`` in units of the spec's tolerances (≤ 1 holds):
    |Δμ| / (1e-5 D + 8 ε₃₂ L) and ‖ΔΣ‖_F / (1e-4 ‖Σ‖_F + (1e-7 D)²)."""
    anchoring = prim.anchoring
    assert anchoring is not None
    diagonal, largest = mesh_extent(anchoring.mesh)
    r = remap(anchoring)
    mean = np.linalg.norm(r.means - prim.splats.means.astype(np.float64), axis=1).max()
    stored = prim.splats.covariances()
    diff = np.linalg.norm(r.covariances - stored, axis=(1, 2))
    bound = REST_COVARIANCE_RELATIVE * np.linalg.norm(stored, axis=(1, 2)) + \
        (REST_COVARIANCE_FLOOR * diagonal) ** 2
    return float(mean / rest_mean_tolerance(diagonal, largest)), float((diff / bound).max())


# --------------------------------------------------------------------------- the derivation rule

def test_derivation_inverts_the_remap_at_rest_and_is_the_binding_rule():
    mesh = example_mesh(subdivisions=1)
    cloud = example_splats(mesh, 200, seed=3)
    bound = bind_local(cloud, mesh).anchors
    d = derive_local(mesh, bound.face_index, cloud.means, cloud.rotations)
    np.testing.assert_array_equal(d.barycentrics.astype(np.float32), bound.barycentrics)
    np.testing.assert_array_equal(d.normal_offset.astype(np.float32), bound.normal_offset)
    np.testing.assert_array_equal(d.local_rotation.astype(np.float32), bound.local_rotation)
    # remap at rest of the derived anchors (float64) gives the splats back to rounding
    anchors = LocalAnchors(bound.face_index, d.barycentrics, d.normal_offset, d.local_rotation,
                           cloud.scales)
    r = remap(Anchoring(mesh, anchors))
    np.testing.assert_allclose(r.means, cloud.means, atol=1e-6)
    np.testing.assert_allclose(r.covariances, cloud.covariances(), atol=1e-7)


def test_minimal_reader_derives_the_same_anchors_independently(tmp_path):
    path = tmp_path / "c.glb"
    write_gltf(local_asset(lift=0.05), path, anchors="compact")
    raw = minimal_reader.read_anchored_glb(path)
    assert raw.derived and raw.face_counts is not None and "faceIndex" not in raw.anchors
    ours = read_gltf(path).primitives[0].anchoring.anchors
    theirs = minimal_reader.derive_local(raw)
    np.testing.assert_array_equal(minimal_reader.face_index(raw), ours.face_index)
    np.testing.assert_allclose(theirs["barycentrics"], ours.barycentrics, atol=1e-6)
    np.testing.assert_allclose(theirs["normalOffset"], ours.normal_offset, atol=1e-7)
    np.testing.assert_allclose(np.abs(np.sum(theirs["localRotation"] * ours.local_rotation, 1)),
                               1.0, atol=1e-6)


def test_c_header_derives_the_same_anchors_and_refuses_degenerate_faces(tmp_path):
    from test_conformance_native import _ptr, build, compiler

    if compiler() is None:
        pytest.skip("no C compiler")
    lib = build(tmp_path, real="float")     # the derivation is double in every build
    mesh = example_mesh(subdivisions=1)
    cloud = example_splats(mesh, 120, seed=5)
    face = bind_local(cloud, mesh).anchors.face_index
    d = derive_local(mesh, face, cloud.means, cloud.rotations)
    verts = np.ascontiguousarray(mesh.vertices, np.float32)
    idx = np.ascontiguousarray(mesh.faces.reshape(-1), np.uint32)
    face32 = np.ascontiguousarray(face, np.uint32)
    bary, off, rot = np.zeros((120, 2), np.float32), np.zeros(120, np.float32), \
        np.zeros((120, 4), np.float32)
    means, rots = np.ascontiguousarray(cloud.means), np.ascontiguousarray(cloud.rotations)
    assert lib.gsv_derive_local(_ptr(verts), _ptr(idx), 120, _ptr(face32), _ptr(means),
                                _ptr(rots), _ptr(bary), _ptr(off), _ptr(rot)) == 1
    np.testing.assert_allclose(bary, d.barycentrics, atol=1e-6)
    np.testing.assert_allclose(off, d.normal_offset, atol=1e-7)
    np.testing.assert_allclose(rot, d.local_rotation, atol=1e-6)
    flat = verts.copy()
    flat[idx[3 * face[0] + 2]] = flat[idx[3 * face[0]]]     # splat 0's face degenerate at rest
    assert lib.gsv_derive_local(_ptr(flat), _ptr(idx), 120, _ptr(face32), _ptr(means),
                                _ptr(rots), _ptr(bary), _ptr(off), _ptr(rot)) == 0
    counts = np.ascontiguousarray(np.bincount(face, minlength=mesh.face_count), np.uint32)
    out = np.zeros(120, np.uint32)
    assert lib.gsv_faces_from_counts(_ptr(counts), len(counts), mesh.face_count, 120, _ptr(out))
    np.testing.assert_array_equal(out, np.sort(face))
    assert not lib.gsv_faces_from_counts(_ptr(counts), len(counts) - 1, mesh.face_count, 120,
                                         _ptr(out))
    assert not lib.gsv_faces_from_counts(_ptr(counts), len(counts), mesh.face_count, 119,
                                         _ptr(out))


# --------------------------------------------------------------------------- writer and reader

def test_explicit_is_the_default_and_the_version_1_1_layout(tmp_path):
    asset = local_asset()
    default = asset_to_gltf(asset)
    explicit = asset_to_gltf(asset, anchors="explicit")
    assert default.binary_blob() == explicit.binary_blob()
    assert default.to_json() == explicit.to_json()
    write_gltf(asset, tmp_path / "e.glb")
    ext = _anchor_json(tmp_path / "e.glb")
    assert {"faceIndex", "barycentrics", "normalOffset", "localRotation", "localScale"} <= set(ext)
    assert "faceCounts" not in ext


@pytest.mark.parametrize("deformation", ["affine", "rigid"])
def test_compact_local_stores_only_face_counts_and_reads_back_the_same_splats(tmp_path,
                                                                              deformation):
    asset = local_asset(deformation=deformation, shuffle=True, lift=0.05)
    path = tmp_path / "c.glb"
    write_gltf(asset, path, anchors="compact")
    ext = _anchor_json(path)
    assert set(ext) == {"mesh", "primitive", "profile", "deformation", "faceCounts"}
    prim = read_gltf(path).primitives[0]
    src = asset.primitives[0]
    mesh = src.anchoring.mesh
    counts = np.bincount(src.anchoring.anchors.face_index.astype(np.int64),
                         minlength=mesh.face_count)
    face = prim.anchoring.anchors.face_index
    np.testing.assert_array_equal(face, np.repeat(np.arange(mesh.face_count), counts))
    # the splats were grouped by face (stable): same splats, new order
    order = np.argsort(src.anchoring.anchors.face_index, kind="stable")
    np.testing.assert_array_equal(prim.splats.means, src.splats.means[order])
    np.testing.assert_array_equal(prim.splats.sh, src.splats.sh[order])
    assert prim.anchoring.anchors.deformation == deformation
    mean, cov = _rest_errors(prim)
    assert mean < 0.01 and cov < 0.01          # binary64 rounding only
    assert not validate_file(path).findings or all(
        f.severity.name in ("INFO", "HINT") for f in validate_file(path).findings)


def test_compact_games_keeps_barycentrics_and_rho(tmp_path):
    path = tmp_path / "g.glb"
    write_gltf(games_asset(), path, anchors="compact")
    ext = _anchor_json(path)
    assert "faceCounts" in ext and "faceIndex" not in ext
    assert {"barycentrics", "rho"} <= set(ext)
    prim = read_gltf(path).primitives[0]
    assert max(_rest_errors(prim)) <= 1.0


def test_face_counts_take_the_smallest_type(tmp_path):
    mesh = example_mesh(subdivisions=1)
    cloud = example_splats(mesh, 400, seed=9)
    anchors = bind_local(cloud, mesh).anchors
    crowded = LocalAnchors(np.zeros(400, np.uint32), anchors.barycentrics, anchors.normal_offset,
                           anchors.local_rotation, anchors.local_scale)
    rest = remap(Anchoring(mesh, crowded))
    cloud = SplatCloud(rest.means, rest.rotations, rest.scales, cloud.opacities, cloud.sh)
    gltf = asset_to_gltf(SplatAsset([SplatPrimitive(cloud, Anchoring(mesh, crowded))]),
                         anchors="compact")
    doc = json.loads(gltf.to_json())
    ext = doc["meshes"][0]["primitives"][0]["extensions"]["KHR_gaussian_splatting"][
        "extensions"][ANCHOR]
    assert doc["accessors"][ext["faceCounts"]]["componentType"] == 5123   # 400 > 255
    gltf = asset_to_gltf(local_asset(), anchors="compact")
    doc = json.loads(gltf.to_json())
    ext = doc["meshes"][0]["primitives"][0]["extensions"]["KHR_gaussian_splatting"][
        "extensions"][ANCHOR]
    assert doc["accessors"][ext["faceCounts"]]["componentType"] == 5121


def test_compact_refuses_splats_on_faces_degenerate_at_rest(tmp_path, capsys):
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [2, 0, 0]], np.float32)
    mesh = TriangleMesh(v, np.array([[0, 1, 2], [0, 1, 3]]))   # face 1 is a segment
    anchors = LocalAnchors([0, 1], [[0.2, 0.2], [0.3, 0.0]], [0.0, 0.0],
                           [[0, 0, 0, 1], [0, 0, 0, 1]], [[0.1, 0.1, 0.1]] * 2)
    rest = remap(Anchoring(mesh, anchors))
    cloud = SplatCloud(rest.means, rest.rotations, rest.scales, np.ones(2), np.zeros((2, 1, 3)))
    asset = SplatAsset([SplatPrimitive(cloud, Anchoring(mesh, anchors))])
    asset_to_gltf(asset)                                       # explicit: allowed (remapped)
    assert "primitive 0: 1 splat(s) are bound to triangles degenerate" in compact_problem(asset)
    with pytest.raises(UsageError, match="degenerate at rest"):
        asset_to_gltf(asset, anchors="compact")
    with pytest.raises(UsageError, match="anchors must be one of"):
        asset_to_gltf(asset, anchors="tiny")
    assert compact_problem(SplatAsset([SplatPrimitive(cloud, Anchoring(mesh, LocalAnchors(
        [0, 0], anchors.barycentrics, anchors.normal_offset, anchors.local_rotation,
        anchors.local_scale)))])) is None
    # gsverse-convert keeps these anchors: its default layout falls back to explicit and says so
    write_gltf(asset, tmp_path / "in.glb")
    base = [str(tmp_path / "in.glb"), str(tmp_path / "out.glb"), "-w"]
    assert convert_main(base) == 0
    out = capsys.readouterr().out
    assert "explicit anchors (extension 1.1 layout)" in out and "degenerate at rest" in out
    assert "faceIndex" in _anchor_json(tmp_path / "out.glb")
    assert convert_main(base + ["--anchors", "compact"]) == 2          # asked for: refused
    err = capsys.readouterr().err
    assert "degenerate at rest" in err and err.count("\n") == 1


@pytest.mark.parametrize("bits", [16, 8])
@pytest.mark.parametrize("encoding", ["explicit", "compact"])
@pytest.mark.parametrize("kind", ["affine", "rigid", "games"])
def test_every_compact_and_quantized_file_holds_the_rest_pose_tolerance(tmp_path, bits,
                                                                        encoding, kind):
    asset = games_asset() if kind == "games" else local_asset(deformation=kind, lift=0.05)
    path = tmp_path / f"{kind}-{encoding}-{bits}.glb"
    write_gltf(asset, path, anchors=encoding, quantize=QUANTIZE_BITS[bits])
    prim = read_gltf(path).primitives[0]
    mean, cov = _rest_errors(prim)
    assert mean <= 1.0 and cov <= 1.0, (mean, cov)
    assert not [f for f in validate_file(path).findings if f.severity.name == "ERROR"]
    doc_ext = _anchor_json(path)
    if encoding == "compact" and kind != "games":
        # derived anchors: nothing quantized but the rest ROTATION; the means are the input's
        src = asset.primitives[0]
        order = np.argsort(src.anchoring.anchors.face_index, kind="stable")
        np.testing.assert_array_equal(prim.splats.means, src.splats.means[order])
        assert set(doc_ext) == {"mesh", "primitive", "profile", "deformation", "faceCounts"}


def test_quantized_rest_rotation_only_where_no_anchor_depends_on_it(tmp_path):
    from gsverse_format.conformance.glb import unpack_glb

    for encoding, expected in (("explicit", 5126), ("compact", 5120)):
        path = tmp_path / f"{encoding}.glb"
        write_gltf(local_asset(), path, anchors=encoding, quantize=QUANTIZE_BITS[8])
        doc, _ = unpack_glb(path.read_bytes())
        for prim in (p for m in doc["meshes"] for p in m["primitives"]
                     if "KHR_gaussian_splatting" in p.get("extensions", {})):
            rot = doc["accessors"][prim["attributes"]["KHR_gaussian_splatting:ROTATION"]]
            anchored = ANCHOR in prim["extensions"]["KHR_gaussian_splatting"].get("extensions",
                                                                                  {})
            # the static primitive has no anchors: quantized in both encodings
            assert rot["componentType"] == (expected if anchored else 5120)


def test_barycentrics_outside_the_unit_range_stay_float_and_say_so(tmp_path):
    asset = local_asset(lift=0.3)
    bary = asset.primitives[0].anchoring.anchors.barycentrics
    assert np.any((bary < 0) | (bary > 1))
    notes = quantize_notes(asset, QUANTIZE_BITS[8])
    assert len(notes) == 1 and "barycentrics stay FLOAT" in notes[0] and "primitive 0" in notes[0]
    assert quantize_notes(asset, QUANTIZE_BITS[8], "compact") == []     # derived: none stored
    assert quantize_notes(asset, None) == []


# --------------------------------------------------------------------------- reader refusals

def _edited(tmp_path: Path, edit) -> Path:
    from gsverse_format.conformance.glb import anchor_extension, pack_glb, unpack_glb

    src = tmp_path / "src.glb"
    write_gltf(local_asset(), src, anchors="compact")
    doc, blob = unpack_glb(src.read_bytes())
    doc, blob = edit(doc, blob, anchor_extension(doc))
    out = tmp_path / "edited.glb"
    out.write_bytes(pack_glb(doc, blob))
    return out


def _both(doc, blob, ext):
    ext["faceIndex"] = ext["faceCounts"]
    return doc, blob


def _neither(doc, blob, ext):
    del ext["faceCounts"]
    return doc, blob


def _partial(doc, blob, ext):
    ext["localScale"] = 2
    return doc, blob


def _short(doc, blob, ext):
    doc["accessors"][ext["faceCounts"]]["count"] -= 1
    return doc, blob


def _sum(doc, blob, ext):
    from gsverse_format.conformance.glb import accessor_bytes, patch_accessor

    counts = accessor_bytes(doc, blob, ext["faceCounts"]).copy()
    counts[int(np.argmax(counts[:, 0]))] -= 1
    return doc, patch_accessor(doc, blob, ext["faceCounts"], counts)


def _rest(attribute: str, value):
    def edit(doc, blob, ext):
        from gsverse_format.conformance.glb import (accessor_bytes, anchored_primitive,
                                                    patch_accessor)

        index = anchored_primitive(doc)["attributes"][f"KHR_gaussian_splatting:{attribute}"]
        v = accessor_bytes(doc, blob, index).copy()
        v[3] = value(v[3])
        return doc, patch_accessor(doc, blob, index, v)
    return edit


@pytest.mark.parametrize("edit,code,message", [
    (_rest("ROTATION", lambda q: 0 * q), Code.ROTATION_NOT_UNIT, "derived localRotation"),
    (_rest("SCALE", lambda s: -s), Code.SCALE_NEGATIVE, "derived local scales"),
    (_both, Code.ANCHOR_SCHEMA_VIOLATION, "exactly one of faceIndex and faceCounts, not both"),
    (_neither, Code.ANCHOR_SCHEMA_VIOLATION, "not neither"),
    (_partial, Code.ANCHOR_SCHEMA_VIOLATION, "localScale must be absent"),
    (_short, Code.ANCHOR_FACE_COUNTS_COUNT, "one count per triangle"),
    (_sum, Code.ANCHOR_FACE_COUNTS_SUM, "sums to"),
])
def test_reader_and_validator_refuse_broken_compact_anchors(tmp_path, edit, code, message):
    path = _edited(tmp_path, edit)
    with pytest.raises(FormatError, match=message) as info:
        read_gltf(path)
    assert getattr(info.value, "code", code) == code
    assert code in {f.code for f in validate_file(path).findings}
    with pytest.raises(minimal_reader.Refused):
        minimal_reader.read_anchored_glb(path)


# --------------------------------------------------------------------------- command line

def _convert(tmp_path: Path, name: str, *args: str) -> dict:
    out = tmp_path / name
    json_path = tmp_path / f"{name}.json"
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf):
        rc = convert_main([str(CAPSULE / "splats.ply"), str(out), "--mesh",
                           str(CAPSULE / "mesh.obj"), "-q", "--json", *args])
    assert rc == 0
    json_path.write_text(buf.getvalue())
    return json.loads(buf.getvalue())


def test_cli_anchors_and_quantize_shrink_the_file_and_keep_the_rest_pose(tmp_path):
    sizes = {}
    layouts = {}
    for name, args in (("explicit.glb", ("--anchors", "explicit")), ("default.glb", ()),
                       ("compact.glb", ("--anchors", "compact")),
                       ("q16.glb", ("--anchors", "explicit", "--quantize", "16")),
                       ("compact8.glb", ("--anchors", "compact", "--quantize", "8"))):
        summary = _convert(tmp_path, name, *args)
        sizes[name], layouts[name] = summary["output_bytes"], summary["anchors"]
        prim = read_gltf(tmp_path / name).primitives[0]
        assert max(_rest_errors(prim)) <= 1.0, name
    assert sizes["compact8.glb"] < sizes["compact.glb"] < sizes["q16.glb"] < sizes["explicit.glb"]
    assert "faceCounts" in _anchor_json(tmp_path / "compact8.glb")
    # the default is compact (extension 1.2), byte for byte what --anchors compact writes
    assert (tmp_path / "default.glb").read_bytes() == (tmp_path / "compact.glb").read_bytes()
    assert layouts == {"explicit.glb": "explicit", "default.glb": "compact",
                       "compact.glb": "compact", "q16.glb": "explicit", "compact8.glb": "compact"}
    assert "faceIndex" in _anchor_json(tmp_path / "explicit.glb")


def test_cli_default_layout_is_explicit_with_keep_order_and_says_so(tmp_path, capsys):
    base = [str(CAPSULE / "splats.ply"), str(tmp_path / "o.glb"), "--mesh",
            str(CAPSULE / "mesh.obj"), "-w"]
    assert convert_main(base) == 0
    out = capsys.readouterr().out
    assert "; compact anchors (extension 1.2)" in out and "not the default" not in out
    assert convert_main(base + ["--keep-order"]) == 0
    out = capsys.readouterr().out
    assert "; explicit anchors (extension 1.1 layout)" in out
    assert "not the default compact ones: --keep-order" in out
    assert "faceIndex" in _anchor_json(tmp_path / "o.glb")
    assert convert_main(base + ["--keep-order", "--anchors", "explicit"]) == 0
    assert "not the default" not in capsys.readouterr().out       # asked for: no note
    # outputs without glTF anchors say no layout
    assert convert_main([str(CAPSULE / "splats.ply"), str(tmp_path / "p.glb"), "--plain",
                         "-w", "--json", "-q"]) == 0
    assert json.loads(capsys.readouterr().out)["anchors"] is None


def test_cli_refuses_compact_with_keep_order_and_other_bit_depths(tmp_path, capsys):
    base = [str(CAPSULE / "splats.ply"), str(tmp_path / "o.glb"), "--mesh",
            str(CAPSULE / "mesh.obj"), "-q"]
    assert convert_main(base + ["--anchors", "compact", "--keep-order"]) != 0
    err = capsys.readouterr().err
    assert "grouped by face" in err and err.count("\n") == 1
    with pytest.raises(SystemExit):
        convert_main(base + ["--quantize", "12"])
    assert "invalid choice" in capsys.readouterr().err
    assert not (tmp_path / "o.glb").exists()


def test_cli_compact_is_for_gltf_output_only(tmp_path, capsys):
    rc = convert_main([str(CAPSULE / "splats.ply"), str(tmp_path / "o.usda"), "--mesh",
                       str(CAPSULE / "mesh.obj"), "-q", "--anchors", "compact"])
    err = capsys.readouterr().err
    assert rc != 0 and "glTF output" in err and err.count("\n") == 1
    assert not (tmp_path / "o.usda").exists()


def test_real_splats_compact_and_quantized_hold_the_rest_pose(shared_data, tmp_path):
    """A real 3DGS capture bound to an unrelated mesh (many feet outside their triangles)."""
    import contextlib
    import io

    src = shared_data / "3dgs" / "donut_mipsplatting_sh0_fused.ply"
    mesh = shared_data / "meshes" / "trimesh_bunny_stanford_res2.ply"
    for args in (("--anchors", "compact", "--quantize", "8"),
                 ("--anchors", "explicit", "--quantize", "8")):
        out = tmp_path / "real.glb"
        buf = io.StringIO()
        with contextlib.redirect_stdout(buf):
            rc = convert_main([str(src), str(out), "--mesh", str(mesh), "-q", "-w", "--json",
                               *args])
        assert rc == 0
        summary = json.loads(buf.getvalue())
        prim = read_gltf(out).primitives[0]
        assert max(_rest_errors(prim)) <= 1.0, args
        if "compact" not in args:   # explicit 8-bit: feet outside [0, 1] keep FLOAT, said so
            assert any("barycentrics stay FLOAT" in n for n in summary["notes"])


def test_usd_keeps_explicit_arrays_for_a_compact_gltf(tmp_path):
    from gsverse_format import api

    write_gltf(local_asset(), tmp_path / "c.glb", anchors="compact")
    asset = api.read(tmp_path / "c.glb")
    api.write(asset, tmp_path / "c.usda")
    text = (tmp_path / "c.usda").read_text()
    assert "gsverse:anchor:barycentrics" in text and "gsverse:anchor:localOrientations" in text
    back = api.read(tmp_path / "c.usda").primitives[0].anchoring.anchors
    ours = asset.primitives[0].anchoring.anchors
    np.testing.assert_array_equal(back.face_index, ours.face_index)
    np.testing.assert_array_equal(back.barycentrics, ours.barycentrics)
