"""JSON Schema checking of the anchor extension object, without third-party packages.

Evaluates the subset of JSON Schema (draft 2020-12) that the extension's schema uses --
``type``, ``enum``, ``const``, ``minimum``, ``properties``, ``additionalProperties``,
``required``, ``allOf``,
``oneOf``, ``anyOf``, ``not`` and ``$ref`` to ``glTFProperty.schema.json`` -- on the schema
file shipped with the package, so the rules live in one place. A test checks that it agrees
with the ``jsonschema`` package. Integers are JSON integers: ``1.0`` is not accepted where an
index is expected (glTF loaders read indices as integers).
"""
from __future__ import annotations

import functools
import json
from importlib import resources
from typing import Any

__all__ = ["SCHEMA_NAME", "schema", "schema_errors"]

SCHEMA_NAME = ("primitive.KHR_gaussian_splatting.GSVERSE_gaussian_splatting_mesh_anchor"
               ".schema.json")

#: What ``glTFProperty.schema.json`` contributes: ``extensions`` is an object of objects
#: (``extension.schema.json``), ``extras`` anything.
_GLTF_PROPERTY = {"properties": {"extensions": {"type": "object",
                                                "additionalProperties": {"type": "object"}}}}


@functools.lru_cache(maxsize=1)
def schema() -> dict[str, Any]:
    """The extension's JSON Schema: package data of ``gsverse_format/schema`` (``spec/schema/``
    holds an identical copy for readers of the spec; a test keeps the two byte-identical)."""
    text = (resources.files("gsverse_format") / "schema" / SCHEMA_NAME).read_text(encoding="utf-8")
    result: dict[str, Any] = json.loads(text)
    return result


def _type_ok(value: Any, kind: str) -> bool:
    if kind == "integer":
        return isinstance(value, int) and not isinstance(value, bool)
    if kind == "number":
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if kind == "string":
        return isinstance(value, str)
    if kind == "object":
        return isinstance(value, dict)
    if kind == "array":
        return isinstance(value, list)
    if kind == "boolean":
        return isinstance(value, bool)
    if kind == "null":
        return value is None
    return True


def _token(key: str) -> str:
    return str(key).replace("~", "~0").replace("/", "~1")


def _errors(node: dict[str, Any], value: Any, pointer: str) -> list[tuple[str, str]]:
    """(pointer, message) for every violation of ``node`` by ``value``."""
    out: list[tuple[str, str]] = []
    if "$ref" in node:
        out += _errors(_GLTF_PROPERTY, value, pointer) if node["$ref"].startswith(
            "glTFProperty") else []
    kind = node.get("type")
    if kind is not None and not _type_ok(value, kind):
        return out + [(pointer, f"must be of type {kind}, got {json.dumps(value)[:40]}")]
    if "const" in node and value != node["const"]:
        out.append((pointer, f"must be {json.dumps(node['const'])}"))
    if "enum" in node and value not in node["enum"]:
        out.append((pointer, f"must be one of {', '.join(json.dumps(v) for v in node['enum'])}, "
                             f"got {json.dumps(value)[:40]}"))
    if "minimum" in node and _type_ok(value, "number") and value < node["minimum"]:
        out.append((pointer, f"must be >= {node['minimum']}, got {value}"))
    if isinstance(value, dict):
        for key in node.get("required", []):
            if key not in value:
                out.append((pointer, f"lacks required property {key!r}"))
        for key, sub in node.get("properties", {}).items():
            if key in value:
                out += _errors(sub, value[key], f"{pointer}/{_token(key)}")
        extra = node.get("additionalProperties")
        if isinstance(extra, dict):
            for key in value:
                if key not in node.get("properties", {}):
                    out += _errors(extra, value[key], f"{pointer}/{_token(key)}")
    for sub in node.get("allOf", []):
        out += _errors(sub, value, pointer)
    if "anyOf" in node and not any(not _errors(sub, value, pointer) for sub in node["anyOf"]):
        out.append((pointer, "matches none of the allowed alternatives"))
    if "not" in node and not _errors(node["not"], value, pointer):
        banned = node["not"].get("required") or [
            key for sub in node["not"].get("anyOf", []) for key in sub.get("required", [])
            if isinstance(value, dict) and key in value]
        out.append((pointer, f"must not have {', '.join(map(repr, banned))}" if banned
                    else "matches a forbidden form"))
    if "oneOf" in node:
        results: list[list[tuple[str, str]]] = [_errors(sub, value, pointer)
                                                 for sub in node["oneOf"]]
        passing = sum(1 for r in results if not r)
        if passing == 0:
            # Explain through the alternatives whose discriminating constants match (for
            # this schema: the branch of the object's profile); none match when the
            # discriminator itself is wrong, which the properties already report.
            matched = [r for sub, r in zip(node["oneOf"], results)
                       if isinstance(value, dict) and sub.get("properties") and all(
                           k in value and not _errors(p, value[k], pointer)
                           for k, p in sub["properties"].items())]
            for r in matched:
                out += r
            if not matched and not out:
                # no discriminator: explain through the alternative closest to passing (the
                # first of those with the fewest violations)
                closest = min(results, key=len)
                out += closest
        elif passing > 1:
            out.append((pointer, "matches more than one alternative"))
    return out


def schema_errors(obj: Any, pointer: str = "") -> list[tuple[str, str]]:
    """Violations of the extension's JSON Schema by ``obj``: (JSON pointer, message) pairs,
    without duplicates, in a stable order. Empty when ``obj`` is valid."""
    seen: dict[tuple[str, str], None] = {}
    for item in _errors(schema(), obj, pointer):
        seen.setdefault(item, None)
    return list(seen)
