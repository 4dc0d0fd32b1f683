"""The extension's vocabulary is written once (gsverse_format/vocabulary.py); the independent
implementations that keep their own copies on purpose (the minimal reader, the C header) and
the JSON Schema agree with it."""
from __future__ import annotations

import json
from importlib import resources

import pytest

from gsverse_format import vocabulary as V
from gsverse_format.conformance import minimal_reader

GTYPES = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4"}
CTYPES = tuple(V.COMPONENT_TYPE_NAMES)


def _combinations():
    for field in V.ANCHOR_FIELDS + (V.FACE_COUNTS,):
        for ncomp, gtype in GTYPES.items():
            for ctype in CTYPES:
                for normalized in (False, True):
                    yield field, ncomp, gtype, ctype, normalized


def test_minimal_reader_allows_exactly_the_vocabulary_formats():
    for field, _, gtype, ctype, normalized in _combinations():
        assert minimal_reader.accessor_allowed(field.key, gtype, ctype, normalized) == \
            field.allows(gtype, ctype, normalized), (field.key, gtype, ctype, normalized)
    assert minimal_reader.KHR == V.KHR and minimal_reader.ANCHOR == V.EXTENSION
    assert minimal_reader.SPZ == V.SPZ_EXTENSION


def test_c_header_allows_exactly_the_vocabulary_formats(tmp_path):
    from test_conformance_native import PROPS, build, compiler

    if compiler() is None:
        pytest.skip("no C compiler")
    lib = build(tmp_path, real="double")
    assert set(PROPS) == {f.key for f in V.ANCHOR_FIELDS + (V.FACE_COUNTS,)}
    for field, ncomp, gtype, ctype, normalized in _combinations():
        got = bool(lib.gsv_anchor_accessor_allowed(PROPS[field.key], ncomp, ctype,
                                                   int(normalized)))
        assert got == field.allows(gtype, ctype, normalized), (field.key, gtype, ctype)


def test_json_schema_names_and_requires_the_vocabulary_fields():
    from gsverse_format.validators.schema import schema_errors

    name = f"primitive.{V.KHR}.{V.EXTENSION}.schema.json"
    schema = json.loads((resources.files("gsverse_format") / "schema" / name).read_text("utf-8"))
    keys = {f.key for f in V.ANCHOR_FIELDS} | {V.FACE_COUNTS.key}
    assert keys <= set(schema["properties"])
    assert {branch["properties"]["profile"]["const"] for branch in schema["oneOf"]} == \
        set(V.PROFILES)
    # the schema requires exactly what gltf_required_keys says, for every encoding
    for profile in V.PROFILES:
        for counts in (False, True):
            for derived in ((False, True) if profile == "local" else (False,)):
                required = V.gltf_required_keys(profile, counts=counts, derived=derived)
                obj = {"mesh": 0, "profile": profile, **{k: 1 for k in required}}
                assert schema_errors(obj, "") == [], (profile, counts, derived)
                for key in required:
                    partial = {k: v for k, v in obj.items() if k != key}
                    assert schema_errors(partial, ""), (profile, counts, derived, key)
                other = "faceIndex" if counts else V.FACE_COUNTS.key
                assert schema_errors(dict(obj, **{other: 1}), ""), "both face encodings"
    derived = {"mesh": 0, "profile": "local", "faceCounts": 1}
    for key in V.DERIVED_KEYS[1:]:
        assert schema_errors(dict(derived, **{key: 1}), ""), key
    assert V.gltf_required_keys("local", counts=False, derived=False) == tuple(
        f.key for f in V.required_fields("local"))
    assert schema["properties"]["deformation"]["enum"] == list(V.DEFORMATIONS)
