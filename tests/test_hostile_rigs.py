"""Bad input that used to surface as an internal error or to be carried silently into the
output: a compressed PLY whose chunk bound is a list property, and ``--mesh`` rigs with NaN
or decreasing key times, NaN morph deltas or inverse bind matrices, channels aimed at missing
nodes, out-of-range JOINTS_0 and morph weights that do not match the targets. Each is refused
when read, in one line naming the file and what is wrong, exit 1, nothing written; the
validator reports the same things in an output file by the same checks
(:mod:`gsverse_format.rig_checks`). Every input is built here."""
from __future__ import annotations

import struct

import numpy as np
import pytest

from test_hostile_web_formats import CHILD_CPU_S, CHILD_PEAK_MIB, convert_measured


def assert_refused(source, tmp_path, *words: str, extra: tuple = ("--plain",), named=None) -> str:
    """``gsverse-convert SOURCE out.glb EXTRA``: exit 1, one line naming ``named`` (the
    source by default) and ``words``, no traceback, bounded CPU and memory, nothing written."""
    out = tmp_path / "out.glb"
    before = sorted(p.name for p in tmp_path.iterdir())
    code, err, cpu, peak = convert_measured(source, out, *extra)
    assert code == 1, err
    assert len(err.splitlines()) == 1 and "Traceback" not in err, err
    assert str(named or source) in err, err
    for word in words:
        assert word in err, err
    assert cpu < CHILD_CPU_S and peak < CHILD_PEAK_MIB, (cpu, peak)
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    return err

_CHUNK = ("min_x", "min_y", "min_z", "max_x", "max_y", "max_z", "min_scale_x", "min_scale_y",
          "min_scale_z", "max_scale_x", "max_scale_y", "max_scale_z")


def compressed_ply_with_a_list_bound(path, count: int, n: int = 4) -> None:
    """A compressed PLY of ``n`` splats whose ``chunk.min_x`` is a list of ``count`` floats."""
    header = ["ply", "format binary_little_endian 1.0", "element chunk 1"]
    body = b""
    for name in _CHUNK:
        if name == "min_x":
            header.append(f"property list uchar float {name}")
            body += struct.pack(f"<B{count}f", count, *([0.5] * count))
        else:
            header.append(f"property float {name}")
            body += struct.pack("<f", 0.0 if name.startswith("min") else 1.0)
    header.append(f"element vertex {n}")
    header += [f"property uint {p}" for p in ("packed_position", "packed_rotation",
                                               "packed_scale", "packed_color")]
    header.append("end_header")
    packed = np.random.default_rng(0).integers(0, 2 ** 32, (n, 4), dtype=np.uint32)
    path.write_bytes(("\n".join(header) + "\n").encode() + body + packed.astype("<u4").tobytes())


@pytest.mark.parametrize("count", [0, 1, 2])
def test_compressed_ply_chunk_bound_that_is_a_list(tmp_path, count):
    src = tmp_path / "bounds.compressed.ply"
    compressed_ply_with_a_list_bound(src, count)
    assert_refused(src, tmp_path, "chunk.min_x is a list")


# ------------------------------------------------------------------------------- --mesh rigs
def character(path, fault: str | None = None) -> None:
    """A tube skinned to two joints (root → tip), with one morph target on its node, and an
    animation that moves the tip and the morph weight; ``fault`` breaks one rule."""
    from gsverse_format.conformance.glb import (FLOAT, UNSIGNED_BYTE, UNSIGNED_SHORT,
                                                BufferBuilder, pack_glb)
    from gsverse_format.conformance.skin import tube

    v, f = tube(5, 8, 0.2, 1.0)
    joints = np.zeros((len(v), 4), np.uint8)
    joints[:, 1] = 1
    weights = np.zeros((len(v), 4), np.float32)
    weights[:, 1] = np.clip(v[:, 1], 0.0, 1.0)
    weights[:, 0] = 1.0 - weights[:, 1]
    if fault == "joints":
        joints[7, 1] = 9
    ibm = np.stack([np.eye(4), np.eye(4)])
    ibm[1, 3, 1] = -0.5                   # column-major: the tip sits at y = 0.5
    if fault == "ibm":
        ibm[1, 0, 0] = np.nan
    delta = np.full((len(v), 3), 0.05, np.float32)
    if fault == "morph":
        delta[3, 1] = np.nan
    times = np.array([0.0, 0.5, 1.0], np.float32)
    if fault == "times-nan":
        times[1] = np.nan
    elif fault == "times-decreasing":
        times[:] = [0.0, 1.0, 0.5]
    move = np.array([[0, 0.5, 0], [0.1, 0.5, 0], [0, 0.6, 0]], np.float32)
    if fault == "values-nan":
        move[2, 0] = np.nan

    b = BufferBuilder()
    prim = {"attributes": {
        "POSITION": b.add(v.astype(np.float32), FLOAT, "VEC3", target=34962, minmax=True),
        "JOINTS_0": b.add(joints, UNSIGNED_BYTE, "VEC4", target=34962),
        "WEIGHTS_0": b.add(weights, FLOAT, "VEC4", target=34962)},
        "indices": b.add(f.reshape(-1).astype(np.uint16), UNSIGNED_SHORT, "SCALAR",
                         target=34963),
        "targets": [{"POSITION": b.add(delta, FLOAT, "VEC3")}], "mode": 4}
    t = b.add(times, FLOAT, "SCALAR")
    animation = {"name": "wave", "samplers": [
        {"input": t, "output": b.add(move, FLOAT, "VEC3")},
        {"input": t, "output": b.add(np.float32([0, 1, 0]), FLOAT, "SCALAR")}],
        "channels": [{"sampler": 0, "target": {"node": 2, "path": "translation"}},
                     {"sampler": 1, "target": {"node": 0, "path": "weights"}}]}
    if fault == "missing-node":
        animation["channels"][0]["target"]["node"] = 7
    mesh = {"primitives": [prim], "weights": [0.0]}
    if fault == "morph-weights":
        mesh["weights"] = [0.0, 0.0]
    doc = {"scenes": [{"nodes": [0, 1]}], "scene": 0,
           "nodes": [{"name": "body", "mesh": 0, "skin": 0},
                     {"name": "root", "children": [2]},
                     {"name": "tip", "translation": [0.0, 0.5, 0.0]}],
           "meshes": [mesh],
           "skins": [{"joints": [1, 2], "inverseBindMatrices": b.add(
               ibm.reshape(2, 16).astype(np.float32), FLOAT, "MAT4")}],
           "animations": [animation]}
    blob = b.finish()
    doc.update({"asset": {"version": "2.0"}, "accessors": b.accessors,
                "bufferViews": b.views, "buffers": [{"byteLength": len(blob)}]})
    path.write_bytes(pack_glb(doc, blob))


@pytest.fixture
def splats(tmp_path):
    import gsverse_format as gv
    from gsverse_format.model import SplatAsset, SplatPrimitive

    from helpers import random_splats

    path = tmp_path / "splats.glb"
    gv.write(SplatAsset([SplatPrimitive(random_splats(200, spread=0.2, center=(0, 0.5, 0)),
                                        None, "body")]), path)
    return path


def test_the_character_without_a_fault_converts(tmp_path, splats):
    """The base of the cases below is a valid rig: each refusal is its fault's."""
    from gsverse_format.io.mesh import read_mesh

    src = tmp_path / "character.glb"
    character(src)
    mesh = read_mesh(src)
    assert mesh.rig is not None and len(mesh.rig.targets) == 1 and mesh.rig.animations


@pytest.mark.parametrize("fault, words", [
    ("times-nan", ("animation 0 channel 0", "key times", "NaN")),
    ("times-decreasing", ("animation 0 channel 0", "key times", "decrease")),
    ("values-nan", ("animation 0 channel 0", "values", "NaN")),
    ("missing-node", ("animation 0 channel 0 targets node 7", "does not exist")),
    ("joints", ("JOINTS_0", "not below the skin's 2 joints")),
    ("ibm", ("inverse bind matrices of skin 0", "NaN")),
    ("morph", ("morph target 0", "POSITION deltas", "NaN")),
    ("morph-weights", ("default morph weights of mesh 0", "2 for 1 morph targets")),
])
def test_invalid_rig_data_is_refused_when_the_mesh_is_read(tmp_path, splats, fault, words):
    src = tmp_path / f"{fault}.glb"
    character(src, fault)
    assert_refused(splats, tmp_path, *words, extra=("--mesh", str(src), "-q"), named=src)


# -------------------------------------------- the same faults in an output file: the validator
def _sampler(d, key: str) -> np.ndarray:
    return d.values(d.doc["animations"][0]["samplers"][0][key])


def _skin_values(d, key: str) -> np.ndarray:
    return d.values(d.doc["skins"][0][key]) if key == "inverseBindMatrices" else \
        d.values(d.anchor_prim()["attributes"][key])


_OUTPUT_FAULTS = {
    "times-nan": ("NON_FINITE_VALUE",
                  lambda d: _sampler(d, "input").__setitem__(0, np.nan)),
    "times-decreasing": ("ANCHOR_ANIMATION_SAMPLER_INVALID",
                         lambda d: _sampler(d, "input").__setitem__(-1, -1.0)),
    "values-nan": ("NON_FINITE_VALUE",
                   lambda d: _sampler(d, "output").__setitem__(0, np.nan)),
    "missing-node": ("ANCHOR_ANIMATION_TARGET_INVALID",
                     lambda d: d.doc["animations"][0]["channels"][0]["target"].update(node=99)),
    "joints": ("ANCHOR_SKIN_ATTRIBUTES_INVALID",
               lambda d: _skin_values(d, "JOINTS_0").__setitem__(0, 200)),
    "ibm": ("NON_FINITE_VALUE",
            lambda d: _skin_values(d, "inverseBindMatrices").__setitem__((0, 0), np.nan)),
    "morph": ("NON_FINITE_VALUE",
              lambda d: d.values(d.anchor_prim()["targets"][0]["POSITION"]).__setitem__(
                  (1, 1), np.nan)),
    "morph-weights": ("ANCHOR_MORPH_TARGETS_INVALID",
                      lambda d: d.doc["meshes"][d.ext()["mesh"]]["weights"].append(0.0)),
}


@pytest.mark.parametrize("fault", sorted(_OUTPUT_FAULTS))
def test_the_validator_reports_the_same_faults_in_an_output_file(tmp_path, fault):
    """The rules the converter refuses a ``--mesh`` rig by (above) are those the validator
    reports in an output file: one code each, an error."""
    import validation_assets as va

    from gsverse_format.validators.validate import Severity, validate_file

    code, edit = _OUTPUT_FAULTS[fault]
    clean = validate_file(va._rigged().write(tmp_path, "clean.glb"))
    assert not [f for f in clean.findings if f.severity == Severity.ERROR], clean.findings
    d = va._rigged()
    edit(d)
    report = validate_file(d.write(tmp_path, f"{fault}.glb"))
    found = [f for f in report.findings if f.code == code]
    assert found and all(f.severity == Severity.ERROR for f in found), report.findings

