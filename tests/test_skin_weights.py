"""Skin weights that do not sum to one (spec/README.md §Animated anchor meshes, *Skin
weights*): ``gsverse-convert --mesh character.glb`` normalizes them with a note (``--strict``
refuses), the pose path and the validator treat files of others as readers must (normalize;
warn), and the posed splats match an independent skinning with normalized weights."""
from __future__ import annotations

import numpy as np
import pygltflib
import pytest
from scipy.spatial.transform import Rotation

import gsverse_format as gv
from gsverse_format.cli.convert import main as convert_main
from gsverse_format.cli.pose import main as pose_main
from gsverse_format.codes import Code
from gsverse_format.conformance.skin import tube
from gsverse_format.model import SplatAsset, SplatPrimitive, TriangleMesh
from gsverse_format.poses.gltf_source import open_gltf_source
from gsverse_format.rig import normalized_weights
from gsverse_format.validators.issues import Severity
from gsverse_format.validators.validate import validate_file

from helpers import surface_splats

HEIGHT = 2.0
#: the tip joint turns by this much about +Z (about its pivot) at t = 1 s
TURN_DEG = 40.0
#: the weight sum of the vertices above the middle (unnormalized, as some exporters write)
SUM = 1.76


def _weights(rest: np.ndarray) -> np.ndarray:
    """Two influences by height (root below, tip above), summing to 1.76 above the middle."""
    up = np.clip(rest[:, 1] / HEIGHT, 0.0, 1.0)
    w = np.zeros((len(rest), 4))
    w[:, 0], w[:, 1] = 1.0 - up, up
    w[rest[:, 1] > HEIGHT / 2] *= SUM
    return w


def _character(path) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A skinned tube glTF (two joints: root at the origin, tip at half height whose rotation is
    animated) with unnormalized weights; returns rest vertices, faces, raw weights."""
    rest, faces = tube(9, 10, 0.3, HEIGHT)
    rest = rest.astype(np.float32)
    weights = _weights(rest.astype(np.float64)).astype(np.float32)
    joints = np.zeros((len(rest), 4), np.uint8)
    joints[:, 1] = 1
    ibm = np.stack([np.eye(4), np.eye(4)]).astype(np.float32)
    ibm[1, 1, 3] = -HEIGHT / 2
    times = np.array([0.0, 1.0], np.float32)
    quats = Rotation.from_euler("z", [[0.0], [TURN_DEG]], degrees=True).as_quat().astype(np.float32)
    arrays = [(rest, pygltflib.VEC3, pygltflib.FLOAT),
              (faces.astype(np.uint32).reshape(-1), pygltflib.SCALAR, pygltflib.UNSIGNED_INT),
              (joints, pygltflib.VEC4, pygltflib.UNSIGNED_BYTE),
              (weights, pygltflib.VEC4, pygltflib.FLOAT),
              (np.swapaxes(ibm, 1, 2).reshape(-1, 16), pygltflib.MAT4, pygltflib.FLOAT),
              (times, pygltflib.SCALAR, pygltflib.FLOAT),
              (quats, pygltflib.VEC4, pygltflib.FLOAT)]
    blob, views, accessors = b"", [], []
    for data, gtype, ctype in arrays:
        raw = np.ascontiguousarray(data).tobytes()
        views.append(pygltflib.BufferView(buffer=0, byteOffset=len(blob), byteLength=len(raw)))
        extra = {"min": rest.min(0).tolist(), "max": rest.max(0).tolist()} if data is rest \
            else {"min": [0.0], "max": [1.0]} if data is times else {}
        accessors.append(pygltflib.Accessor(bufferView=len(views) - 1, componentType=ctype,
                                            count=len(data), type=gtype, **extra))
        blob += raw + b"\0" * (-len(raw) % 4)
    g = pygltflib.GLTF2(
        scene=0, scenes=[pygltflib.Scene(nodes=[0, 1])],
        nodes=[pygltflib.Node(name="body", mesh=0, skin=0),
               pygltflib.Node(name="root", children=[2]),
               pygltflib.Node(name="tip", translation=[0.0, HEIGHT / 2, 0.0])],
        meshes=[pygltflib.Mesh(primitives=[pygltflib.Primitive(
            attributes=pygltflib.Attributes(POSITION=0, JOINTS_0=2, WEIGHTS_0=3), indices=1)])],
        skins=[pygltflib.Skin(joints=[1, 2], inverseBindMatrices=4)],
        animations=[pygltflib.Animation(
            name="bend", samplers=[pygltflib.AnimationSampler(input=5, output=6)],
            channels=[pygltflib.AnimationChannel(sampler=0, target=pygltflib.AnimationChannelTarget(
                node=2, path="rotation"))])],
        accessors=accessors, bufferViews=views, buffers=[pygltflib.Buffer(byteLength=len(blob))])
    g.set_binary_blob(blob)
    g.save_binary(str(path))
    return rest.astype(np.float64), faces, weights.astype(np.float64)


def _turned(rest: np.ndarray, t: float) -> np.ndarray:
    """The vertices moved by the tip joint alone: t·TURN_DEG about +Z around (0, HEIGHT/2, 0)."""
    pivot = np.array([0.0, HEIGHT / 2, 0.0])
    turn = Rotation.from_euler("z", t * TURN_DEG, degrees=True).as_matrix()
    return (rest - pivot) @ turn.T + pivot


def _skinned(rest: np.ndarray, weights: np.ndarray, t: float) -> np.ndarray:
    """Linear blend skinning of the character written out by hand (the root joint stays, the
    tip joint turns), with each vertex's weights normalized."""
    w = weights / weights.sum(axis=1, keepdims=True)
    return w[:, :1] * rest + w[:, 1:2] * _turned(rest, t)


@pytest.fixture
def character(tmp_path):
    """The character file, splats on its surface (a glTF file: no frame change), raw weights."""
    char = tmp_path / "character.glb"
    rest, faces, weights = _character(char)
    cloud = surface_splats(TriangleMesh(rest, faces), 300, 7, offset=0.0)
    splats = tmp_path / "splats.glb"
    gv.write(SplatAsset([SplatPrimitive(cloud, None, "body")]), splats)
    return char, splats, rest, weights


def _file_weights(path) -> np.ndarray:
    from helpers import gltf_accessor

    g = pygltflib.GLTF2().load(str(path))
    prim = next(p for m in g.meshes for p in m.primitives if p.attributes.WEIGHTS_0 is not None)
    return gltf_accessor(g, prim.attributes.WEIGHTS_0).astype(np.float64)


def test_normalized_weights_rule():
    fixed = normalized_weights(np.array([[0.5, 0.38, 0, 0], [0.25, 0.25, 0.5, 0],
                                         [0, 0, 0, 0], [1.0, 0.001, 0, 0]]))
    np.testing.assert_allclose(fixed.weights, [[0.5 / 0.88, 0.38 / 0.88, 0, 0],
                                               [0.25, 0.25, 0.5, 0], [1, 0, 0, 0],
                                               [1 / 1.001, 0.001 / 1.001, 0, 0]], rtol=1e-15)
    assert fixed.changed == 2 and fixed.all_zero.tolist() == [2]
    assert fixed.max_sum_error == pytest.approx(1.0)


def test_converter_normalizes_with_a_note(character, tmp_path, capsys):
    char, splats, rest, weights = character
    out = tmp_path / "anchored.glb"
    summary = gv.convert(splats, out, mesh=str(char))
    bad = int(np.count_nonzero(np.abs(weights.sum(axis=1) - 1) > 2e-3))
    assert bad > 0
    notes = [n for n in summary.notes if "skin weights" in n]
    assert len(notes) == 1 and f"{bad} of {len(rest)} vertices" in notes[0], summary.notes
    assert "character.glb" in notes[0] and "normalized" in notes[0]
    assert f"{SUM - 1:.3g}" in notes[0]
    written = _file_weights(out)
    np.testing.assert_allclose(written, weights / weights.sum(axis=1, keepdims=True), atol=1e-7)
    # the command line prints it
    assert convert_main([str(splats), str(tmp_path / "cli.glb"), "--mesh", str(char)]) == 0
    assert "skin weights (WEIGHTS_0)" in capsys.readouterr().out
    # the validator does not report the converter's output
    report = validate_file(out)
    assert Code.ANCHOR_SKIN_WEIGHTS_NOT_NORMALIZED not in report.codes()
    assert report.exit_status == 0, [f.message for f in report.findings]


def test_strict_refuses_in_one_line(character, tmp_path, capsys):
    char, splats, _, _ = character
    out = tmp_path / "strict.glb"
    assert convert_main([str(splats), str(out), "--mesh", str(char), "--strict", "-q"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(char) in err and "--strict" in err
    assert "Traceback" not in err and not out.exists()


def test_all_zero_weights_are_refused(character, tmp_path, capsys):
    char, splats, _, _ = character
    g = pygltflib.GLTF2().load(str(char))
    blob = bytearray(g.binary_blob())
    view = g.bufferViews[g.accessors[3].bufferView]
    blob[view.byteOffset:view.byteOffset + 16] = bytes(16)   # vertex 0: all zero
    g.set_binary_blob(bytes(blob))
    zero = tmp_path / "zero.glb"
    g.save_binary(str(zero))
    assert convert_main([str(splats), str(tmp_path / "z.glb"), "--mesh", str(zero), "-q"]) == 1
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and str(zero) in err and "all zero" in err


def test_posed_splats_match_independent_skinning(character, tmp_path):
    char, splats, rest, weights = character
    out = tmp_path / "anchored.glb"
    gv.convert(splats, out, mesh=str(char))
    asset = gv.read(out)
    anchoring = asset.anchored[0].anchoring
    np.testing.assert_allclose(anchoring.mesh.vertices, rest, atol=1e-6)
    t = 1.0
    posed = tmp_path / "posed.glb"
    assert pose_main([str(out), str(posed), "--times", str(t), "-q"]) == 0
    got = gv.read(posed).primitives[0].splats.means.astype(np.float64)
    want = gv.remap(anchoring, _skinned(rest, weights, t)).means
    np.testing.assert_allclose(got, want, atol=1e-5)
    # raw weights would put the upper vertices far away: the comparison tells them apart
    raw = weights[:, :1] * rest + weights[:, 1:2] * _turned(rest, t)
    assert np.abs(gv.remap(anchoring, raw).means - want).max() > 0.1


def test_readers_normalize_files_of_others(character, tmp_path):
    """An anchored file whose WEIGHTS_0 another tool left unnormalized: the pose path uses
    them normalized, the validator warns (not an error)."""
    char, splats, rest, weights = character
    out = tmp_path / "anchored.glb"
    gv.convert(splats, out, mesh=str(char))
    g = pygltflib.GLTF2().load(str(out))
    prim = next(p for m in g.meshes for p in m.primitives if p.attributes.WEIGHTS_0 is not None)
    acc = g.accessors[prim.attributes.WEIGHTS_0]
    view = g.bufferViews[acc.bufferView]
    blob = bytearray(g.binary_blob())
    start = (view.byteOffset or 0) + (acc.byteOffset or 0)
    w = np.ndarray((acc.count, 4), np.float32, buffer=blob, offset=start)
    w[:] = weights.astype(np.float32)           # back to the character's raw weights
    g.set_binary_blob(bytes(blob))
    other = tmp_path / "other.glb"
    g.save_binary(str(other))
    source = open_gltf_source(other, 0)
    source.match(rest)
    np.testing.assert_allclose(source.at(1.0), _skinned(rest, weights, 1.0), atol=1e-5)
    report = validate_file(other)
    found = [f for f in report.findings if f.code == Code.ANCHOR_SKIN_WEIGHTS_NOT_NORMALIZED]
    assert len(found) == 1 and found[0].severity == Severity.WARNING
    assert "readers normalize" in found[0].message
    assert report.exit_status == 0
