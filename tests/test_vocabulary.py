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
    for field in V.ANCHOR_FIELDS:
        for ncomp, gtype in GTYPES.items():
            for ctype in CTYPES:
                for normalized in (False, True):
                    yield field, ncomp, gtype, ctype, normalized


def test_minimal_reader_allows_exactly_the_vocabulary_formats():
    for field, _, gtype, ctype, normalized in _combinations():
        assert minimal_reader.accessor_allowed(field.key, gtype, ctype, normalized) == \
            field.allows(gtype, ctype, normalized), (field.key, gtype, ctype, normalized)
    assert minimal_reader.KHR == V.KHR and minimal_reader.ANCHOR == V.EXTENSION


def test_c_header_allows_exactly_the_vocabulary_formats(tmp_path):
    from test_conformance_native import PROPS, build, compiler

    if compiler() is None:
        pytest.skip("no C compiler")
    lib = build(tmp_path, real="double")
    assert set(PROPS) == {f.key for f in V.ANCHOR_FIELDS}
    for field, ncomp, gtype, ctype, normalized in _combinations():
        got = bool(lib.gsv_anchor_accessor_allowed(PROPS[field.key], ncomp, ctype,
                                                   int(normalized)))
        assert got == field.allows(gtype, ctype, normalized), (field.key, gtype, ctype)


def test_json_schema_names_and_requires_the_vocabulary_fields():
    name = f"primitive.{V.KHR}.{V.EXTENSION}.schema.json"
    schema = json.loads((resources.files("gsverse_format") / "schema" / name).read_text("utf-8"))
    keys = {f.key for f in V.ANCHOR_FIELDS}
    assert keys <= set(schema["properties"])
    base = set(schema["required"]) & keys
    by_profile = {branch["properties"]["profile"]["const"]: set(branch["required"]) | base
                  for branch in schema["oneOf"]}
    assert set(by_profile) == set(V.PROFILES)
    for profile in V.PROFILES:
        assert by_profile[profile] == {f.key for f in V.required_fields(profile)}, profile
    assert schema["properties"]["deformation"]["enum"] == list(V.DEFORMATIONS)
