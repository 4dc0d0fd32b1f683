"""The validator's JSON Schema evaluation agrees with the jsonschema package, and the glTF
reader's errors carry the codes and locations the validator reports."""
from __future__ import annotations

import json
import pathlib
import random
import struct
from importlib import resources

import pytest

from helpers import extension_schema_validator

from gsverse_format.errors import FormatError
from gsverse_format.io import gltf as G
from gsverse_format.validators.issues import CATALOGUE
from gsverse_format.validators.schema import SCHEMA_NAME, schema, schema_errors

import validation_assets as va

ROOT = pathlib.Path(__file__).resolve().parents[1]


def _jsonschema_validator():
    return extension_schema_validator()


def test_schema_is_the_shipped_one():
    """spec/schema/ holds the extension's schema as a real file (the spec folder stands alone);
    the package ships the same bytes as package data, which the validator reads. Edit
    spec/schema/ and copy it to gsverse_format/schema/."""
    spec = ROOT / "spec" / "schema"
    shipped = resources.files("gsverse_format") / "schema"
    assert not (spec / SCHEMA_NAME).is_symlink()
    assert sorted(p.name for p in spec.iterdir()) == \
        sorted(p.name for p in shipped.iterdir() if p.name.endswith(".json")) == [SCHEMA_NAME]
    assert (shipped / SCHEMA_NAME).read_bytes() == (spec / SCHEMA_NAME).read_bytes()
    assert schema() == json.loads((spec / SCHEMA_NAME).read_text(encoding="utf-8"))


_VALUES = [0, 1, 7, -1, 2.5, "1", None, True, [], {}, "local", "games", "affine", "rigid",
           "elastic", {"VENDOR_x": {}}, {"VENDOR_x": 3}]
_KEYS = ["mesh", "primitive", "profile", "deformation", "faceIndex", "barycentrics",
         "normalOffset", "localRotation", "localScale", "rho", "extensions", "extras", "other"]


def _random_object(rng: random.Random) -> object:
    if rng.random() < 0.03:
        return rng.choice([[], "x", 3, None])
    base = dict(rng.choice([
        {"mesh": 1, "profile": "local", "deformation": "rigid", "faceIndex": 2,
         "barycentrics": 3, "normalOffset": 4, "localRotation": 5, "localScale": 6},
        {"mesh": 1, "primitive": 0, "profile": "games", "faceIndex": 2, "barycentrics": 3,
         "rho": 4}]))
    for _ in range(rng.choice([0, 1, 1, 2, 3])):
        key = rng.choice(_KEYS)
        if rng.random() < 0.4:
            base.pop(key, None)
        else:
            base[key] = rng.choice(_VALUES)
    return base


def test_schema_agrees_with_jsonschema():
    validator = _jsonschema_validator()
    rng = random.Random(0)
    valid = invalid = 0
    for _ in range(3000):
        obj = _random_object(rng)
        ours = not schema_errors(obj)
        theirs = validator.is_valid(obj)
        assert ours == theirs, (obj, schema_errors(obj))
        valid += ours
        invalid += not ours
    assert valid > 300 and invalid > 300


def test_schema_messages_point_at_the_property():
    local = {"mesh": 1, "profile": "local", "faceIndex": 2, "barycentrics": 3,
             "normalOffset": 4, "localRotation": 5, "localScale": 6}
    assert schema_errors(local) == []
    assert schema_errors(dict(local, mesh=-1), "/x") == [("/x/mesh", "must be >= 0, got -1")]
    assert schema_errors(dict(local, faceIndex=2.0))[0][0] == "/faceIndex"  # integers only
    missing = schema_errors({k: v for k, v in local.items() if k != "localScale"})
    assert missing == [("", "lacks required property 'localScale'")]
    games = {"mesh": 1, "profile": "games", "faceIndex": 2, "barycentrics": 3, "rho": 4}
    assert schema_errors(dict(games, deformation="rigid")) == [("", "must not have 'deformation'")]
    # Without a valid profile only the profile is reported, not both branches' requirements.
    assert [m for _, m in schema_errors(dict(local, profile="x"))] == [
        'must be one of "local", "games", got "x"']


# ---------------------------------------------------------------------------- reader codes

def _good() -> bytes:
    return va.Doc.of(va.local_asset(12)).glb()


def test_parse_glb_codes_and_offsets():
    data = _good()
    for cut, code in ((5, "GLB_TRUNCATED"), (len(data) - 4, "GLB_TRUNCATED")):
        with pytest.raises(G.GltfFormatError) as info:
            G.parse_glb(data[:cut])
        assert info.value.code == code
    with pytest.raises(G.GltfFormatError) as info:
        G.parse_glb(data + b"\0" * 4)
    assert (info.value.code, info.value.offset) == ("GLB_LENGTH_MISMATCH", 8)
    issues: list = []
    extra = bytearray(data) + struct.pack("<II", 4, 0x12345678) + b"abcd"
    struct.pack_into("<I", extra, 8, len(extra))
    text, binary = G.parse_glb(bytes(extra), issues)
    assert json.loads(text) and binary is not None
    assert [(c, o) for c, _, o in issues] == [("GLB_UNKNOWN_CHUNK", len(data) + 4)]
    assert G.parse_glb(bytes(extra))[0] == text  # the reader ignores it


def test_reader_errors_carry_catalogue_codes(tmp_path):
    folder = tmp_path / "assets"
    folder.mkdir()
    for code in ("GLB_BAD_MAGIC", "JSON_NOT_UTF8", "URI_OUTSIDE_FOLDER", "URI_SCHEME_REJECTED",
                 "ACCESSOR_OUT_OF_BOUNDS", "BUFFER_VIEW_OUT_OF_BOUNDS", "GLTF_SCHEMA_VIOLATION"):
        path = va.TRIGGERS[code](folder).path
        with pytest.raises(FormatError) as info:
            G.read_gltf(path)
        # read_gltf re-raises as a one-line FormatError naming the file ...
        assert str(info.value).startswith(str(path)) and "\n" not in str(info.value)
        # ... while the internal error carries the code the validator reports.
        with pytest.raises(G.GltfFormatError) as inner:
            document = G.load_document(str(path))
            reader = document.reader
            for b in range(len(reader.buffers_json)):
                reader.buffer(b)
            for i in range(len(reader.accessors)):
                reader.layout(i)
        assert inner.value.code == code
        assert inner.value.code in CATALOGUE


def test_gltf_error_with_path_keeps_code():
    err = G.GltfFormatError("bad", code="URI_INVALID", pointer="/buffers/0/uri")
    named = err.with_path("a.gltf")
    assert (named.code, named.pointer, str(named)) == ("URI_INVALID", "/buffers/0/uri",
                                                       "a.gltf: bad")


def test_reading_does_not_reserve_the_size_cap(tmp_path):
    path = tmp_path / "a.glb"
    path.write_bytes(_good())
    assert G.read_gltf(path, max_bytes=2 ** 62).primitives


def test_reader_rejects_non_finite_values(tmp_path):
    folder = tmp_path / "assets"
    folder.mkdir()
    path = va.TRIGGERS["NON_FINITE_VALUE"](folder).path
    with pytest.raises(FormatError, match=r"POSITION \(accessor \d+\): 1 of 60 elements hold "
                                          r"NaN or infinity"):
        G.read_gltf(path)
