"""Mutations of the fuzz harness (:mod:`fuzz.fuzz_readers`): generic byte edits, and edits
that know the structure of glTF JSON, GLB containers, PLY headers and USD text layers."""
from __future__ import annotations

import json
import random
import re
import struct

__all__ = ["INTERESTING_U32", "INTERESTING_NUMBERS", "mutate", "glb_parts"]

INTERESTING_U32 = (0, 1, 2, 3, 4, 7, 8, 12, 16, 255, 256, 0x7FFF, 0x8000, 0xFFFF, 0x10000,
                   0x7FFFFFFF, 0x80000000, 0xFFFFFFFE, 0xFFFFFFFF)
INTERESTING_NUMBERS = ("0", "-1", "1", "2", "3", "4", "5120", "5121", "5123", "5125", "5126",
                       "65535", "65536", "2147483647", "4294967296", "1000000000000", "1e308",
                       "-1e308", "0.5", "1.5", "NaN", "Infinity", "true", "null", '"x"', "[]",
                       "{}")
_NUMBER = re.compile(rb"-?\d+(?:\.\d+)?(?:[eE][+-]?\d+)?")
_KEY = re.compile(rb'"([A-Za-z_:0-9]+)"\s*:')


def glb_parts(data: bytes):
    """(json bytes, bin bytes or None) of a well-formed GLB, else None."""
    if len(data) < 20 or data[:4] != b"glTF":
        return None
    size, kind = struct.unpack_from("<II", data, 12)
    if kind != 0x4E4F534A or 20 + size > len(data):
        return None
    text = data[20:20 + size]
    rest = data[20 + size:]
    binary = None
    if len(rest) >= 8:
        bsize, bkind = struct.unpack_from("<II", rest, 0)
        binary = rest[8:8 + bsize] if bkind == 0x004E4942 else None
    return text, binary


def _glb(text: bytes, binary: bytes | None) -> bytes:
    from gsverse_format.io.gltf import glb_bytes

    return glb_bytes(text, binary)


#: Members whose value is an index into a top-level array of the document.
REFERENCE_KEYS = ("bufferView", "buffer", "indices", "mesh", "skin", "camera", "material",
                  "scene", "accessor", "input", "output", "node", "inverseBindMatrices",
                  "skeleton", "source", "sampler")
#: Members holding byte offsets, lengths and strides.
OFFSET_KEYS = ("byteOffset", "byteLength", "byteStride")
ENUMS = {"componentType": (5120, 5121, 5122, 5123, 5125, 5126, 5124, 5130, 0),
         "type": ("SCALAR", "VEC2", "VEC3", "VEC4", "MAT2", "MAT3", "MAT4", "VEC5", ""),
         "mode": (0, 1, 2, 3, 4, 5, 6, 7, -1),
         "kernel": ("ellipse", "x", ""), "profile": ("local", "games", "rigid", ""),
         "deformation": ("affine", "rigid", "similarity", "x")}
OTHER_TYPE = (None, True, -1, 0, 1, 2 ** 31, 2 ** 64, -0.5, 1e309, "", "x", [], [0], {},
              {"a": 1})


def _nodes(value, path=()):
    """Every (container, key, value) below ``value`` (dict members and list items)."""
    if isinstance(value, dict):
        for k, v in value.items():
            yield value, k, v
            yield from _nodes(v, path + (k,))
    elif isinstance(value, list):
        for i, v in enumerate(value):
            yield value, i, v
            yield from _nodes(v, path + (i,))


def _mutate_gltf_doc(rng: random.Random, doc) -> None:
    """One structure-aware edit of a parsed glTF document, in place."""
    members = list(_nodes(doc))
    if not members:
        return
    op = rng.randrange(9)
    if op == 0:  # a value of another type
        parent, key, _ = rng.choice(members)
        parent[key] = rng.choice(OTHER_TYPE)
        return
    if op == 1:  # accessor counts
        accessors = [a for a in doc.get("accessors", []) if isinstance(a, dict)] \
            if isinstance(doc, dict) and isinstance(doc.get("accessors"), list) else []
        if accessors:
            acc = rng.choice(accessors)
            count = acc.get("count") if isinstance(acc.get("count"), int) else 1
            acc["count"] = rng.choice((0, 1, count - 1, count + 1, 2 * count, count * 1000,
                                       2 ** 31, 2 ** 32 + count, -1))
            return
    if op == 2:  # references: out of range, negative, or to another element
        refs = [(p, k, v) for p, k, v in members
                if isinstance(v, int) and not isinstance(v, bool) and (
                    isinstance(k, int) or k in REFERENCE_KEYS or k.upper() == k or ":" in k)]
        if refs:
            parent, key, value = rng.choice(refs)
            parent[key] = rng.choice((-1, 0, 1, value + 1, value - 1, value + 1000, 2 ** 31))
            return
    if op == 3:  # byte offsets, lengths and strides
        offsets = [(p, k, v) for p, k, v in members if k in OFFSET_KEYS]
        if offsets:
            parent, key, value = rng.choice(offsets)
            value = value if isinstance(value, int) else 0
            parent[key] = rng.choice((0, 1, 2, 3, 4, 5, 252, 256, value - 1, value + 1,
                                      value + 4, 2 * value, -4, 2 ** 32, 2 ** 63))
            return
        if isinstance(doc, dict) and isinstance(doc.get("bufferViews"), list) \
                and doc["bufferViews"] and isinstance(doc["bufferViews"][0], dict):
            rng.choice(doc["bufferViews"])["byteStride"] = rng.choice((0, 2, 4, 12, 252, 256))
            return
    if op == 4:  # enumerations
        enums = [(p, k, v) for p, k, v in members if k in ENUMS]
        if enums:
            parent, key, _ = rng.choice(enums)
            parent[key] = rng.choice(ENUMS[key])
            return
    if op == 5:  # extension objects
        exts = [(p, k, v) for p, k, v in members if k == "extensions" and isinstance(v, dict)]
        if exts:
            parent, key, ext = rng.choice(exts)
            if ext:
                name = rng.choice(list(ext))
                obj = ext[name]
                r = rng.random()
                if r < 0.25 and isinstance(obj, dict) and obj:
                    del obj[rng.choice(list(obj))]
                elif r < 0.4 and isinstance(obj, dict):
                    obj[rng.choice(("unknown", "extras", "extensions"))] = rng.choice(OTHER_TYPE)
                elif r < 0.55:
                    ext[name] = rng.choice(OTHER_TYPE)
                elif r < 0.7:  # move it to another object that has extensions, or up one level
                    other = rng.choice(exts)[2]
                    other[name] = json.loads(json.dumps(obj))
                elif r < 0.85 and isinstance(obj, dict) and isinstance(obj.get("extensions"),
                                                                       dict):
                    ext.update(json.loads(json.dumps(obj["extensions"])))  # nested -> outer
                else:
                    del ext[name]
                return
    if op == 6:  # lists: duplicate, delete or swap elements (indices shift)
        lists = [(p, k, v) for p, k, v in members if isinstance(v, list) and v]
        if lists:
            _, _, items = rng.choice(lists)
            i = rng.randrange(len(items))
            r = rng.random()
            if r < 0.4:
                items.insert(rng.randrange(len(items) + 1), json.loads(json.dumps(items[i])))
            elif r < 0.7:
                del items[i]
            else:
                j = rng.randrange(len(items))
                items[i], items[j] = items[j], items[i]
            return
    if op == 7:  # delete a member
        dicts = [(p, k) for p, k, _ in members if isinstance(p, dict)]
        if dicts:
            parent, key = rng.choice(dicts)
            parent.pop(key, None)
            return
    _mutate_tree(rng, doc, 0)


def _duplicate_key(rng: random.Random, text: bytes) -> bytes:
    """Write one member of ``text`` (JSON) twice, the second time with another value."""
    keys = list(_KEY.finditer(text))
    if not keys:
        return text
    m = rng.choice(keys)
    value = rng.choice(INTERESTING_NUMBERS).encode()
    return text[:m.start()] + m.group() + b" " + value + b", " + text[m.start():]


def _mutate_json(rng: random.Random, text: bytes) -> bytes:
    choice = rng.randrange(8)
    if choice >= 5:
        try:
            doc = json.loads(text)
        except ValueError:
            return text
        _mutate_gltf_doc(rng, doc)
        out = json.dumps(doc).encode()
        return _duplicate_key(rng, out) if choice == 7 and rng.random() < 0.3 else out
    if choice == 4 and rng.random() < 0.5:
        return _duplicate_key(rng, text)
    if choice <= 1:
        numbers = list(_NUMBER.finditer(text))
        if numbers:
            m = rng.choice(numbers)
            value = rng.choice(INTERESTING_NUMBERS).encode()
            if rng.random() < 0.3 and m.group().lstrip(b"-").isdigit():  # off by one
                value = str(int(m.group()) + rng.choice((-1, 1))).encode()
            return text[:m.start()] + value + text[m.end():]
    if choice == 2:
        keys = list(_KEY.finditer(text))
        if keys:  # rename a key (drops the property)
            m = rng.choice(keys)
            return text[:m.start(1)] + b"_" + text[m.start(1):]
    if choice == 3:
        try:
            doc = json.loads(text)
        except ValueError:
            return text
        _mutate_tree(rng, doc, 0)
        return json.dumps(doc).encode()
    # string edits: an interesting string in place of a random string value
    strings = list(re.finditer(rb':\s*"([^"\\]*)"', text))
    if strings:
        m = rng.choice(strings)
        value = rng.choice((b"", b"../x.bin", b"/etc/passwd", b"http://x", b"data:,", b"\xff",
                            b"rigid", b"games", b"local", b"POINTS", b"\\u0000"))
        return text[:m.start(1)] + value + text[m.end(1):]
    return text


def _mutate_tree(rng: random.Random, node, depth: int) -> None:
    """Structural JSON edits: drop, duplicate or retype members, append array elements."""
    if depth > 12:
        return
    if isinstance(node, dict) and node:
        key = rng.choice(list(node))
        r = rng.random()
        if r < 0.25:
            del node[key]
        elif r < 0.4:
            node[key] = rng.choice((None, -1, 0, 2 ** 40, 1.5, "x", [], {}, [0, 0]))
        else:
            _mutate_tree(rng, node[key], depth + 1)
    elif isinstance(node, list) and node:
        i = rng.randrange(len(node))
        r = rng.random()
        if r < 0.2:
            node.append(node[i])
        elif r < 0.3:
            del node[i]
        else:
            _mutate_tree(rng, node[i], depth + 1)


def _mutate_ply_header(rng: random.Random, data: bytes) -> bytes:
    end = data.find(b"end_header")
    if end < 0:
        return data
    header, body = data[:end], data[end:]
    lines = header.split(b"\n")
    i = rng.randrange(len(lines))
    line = lines[i]
    if line.startswith(b"element"):
        parts = line.split()
        if len(parts) == 3:
            parts[2] = rng.choice((b"0", b"1", b"-1", b"1000000000000", b"4294967296", b"x",
                                   str(int(parts[2]) + rng.choice((-1, 1)) if parts[2].isdigit()
                                       else 0).encode()))
            lines[i] = b" ".join(parts)
    elif line.startswith(b"property"):
        types = (b"char", b"uchar", b"short", b"ushort", b"int", b"uint", b"float", b"double",
                 b"float16", b"list uchar int", b"list int float")
        parts = line.split()
        lines[i] = b"property " + rng.choice(types) + b" " + parts[-1]
    elif line.startswith(b"format"):
        lines[i] = b"format " + rng.choice((b"ascii", b"binary_little_endian",
                                             b"binary_big_endian", b"binary")) + b" 1.0"
    else:
        if rng.random() < 0.5:
            del lines[i]
        else:
            lines.insert(i, rng.choice((b"comment x", b"obj_info y", b"element face 3",
                                        b"property float x", b"end_header")))
    return b"\n".join(lines) + (body if rng.random() > 0.05 else body[10:])


USD_TOKENS = (b"float3[]", b"float[]", b"int[]", b"quatf[]", b"half3[]", b"point3f[]",
              b"double3[]", b"token", b"uniform", b"custom", b"def", b"over", b"class", b"Mesh",
              b"Xform", b"ParticleField3DGaussianSplat", b"local", b"games", b"affine",
              b"rigid", b"GsVerseMeshAnchorAPI", b"GsVerseColorSpaceAPI", b"</Asset>",
              b"</Asset/anchor_mesh>", b"</Nope>", b"</Asset/body>", b'"Y"', b'"Z"', b'"X"',
              b"rel", b"prepend", b"delete", b"[]", b"()", b"None", b"nan", b"inf", b"-inf")
USD_LINES = (b"    subLayers = [@./input.usda@]", b"    subLayers = [@../outside.usda@]",
             b"    subLayers = [@missing.usda@]", b"    subLayers = [@/etc/passwd@]",
             b'def Xform "R" (references = @./input.usda@</Asset>) {}',
             b'def Xform "P" (payload = @./input.usda@</Asset>) {}',
             b'def Xform "C" (references = </Asset>) {}',
             b'def Xform "V" (clips = { dictionary d = { asset[] assetPaths = '
             b'[@../x.usda@] string primPath = "/Asset" } }) {}',
             b'def Xform "T" (clips = { dictionary d = { string templateAssetPath = '
             b'"./input.#.usda" double templateStartTime = 0 double templateEndTime = 3 '
             b'double templateStride = 1 string primPath = "/Asset" } }) {}',
             b"    float[] opacities.timeSamples = { 0: [1], 1: [] }",
             b"    uniform int gsverse:anchor:faceIndices = 3",
             b'    uniform token gsverse:anchor:profile = "games"')
_USD_NUMBER = re.compile(rb"-?\d+(?:\.\d+)?(?:[eE][+-]?\d+)?")
_USD_ITEM = re.compile(rb"\([^()\[\]]*\), |-?[\d.e+-]+, ")


def _mutate_usda(rng: random.Random, text: bytes) -> bytes:
    """One edit of a ``.usda`` layer that keeps most of it parseable."""
    choice = rng.randrange(7)
    lines = text.split(b"\n")
    if choice == 0:
        numbers = list(_USD_NUMBER.finditer(text))
        if numbers:
            m = rng.choice(numbers)
            value = rng.choice(INTERESTING_NUMBERS[:17] + ("nan", "inf", "-inf", "0.0",
                                                          "1e39", "-2", "99999999"))
            return text[:m.start()] + value.encode() + text[m.end():]
    if choice == 1:
        present = [t for t in USD_TOKENS if t in text]
        if present:
            old = rng.choice(present)
            starts = [m.start() for m in re.finditer(re.escape(old), text)]
            at = rng.choice(starts)
            return text[:at] + rng.choice(USD_TOKENS) + text[at + len(old):]
    if choice == 2 and len(lines) > 2:
        del lines[rng.randrange(1, len(lines))]
        return b"\n".join(lines)
    if choice == 3 and len(lines) > 2:
        i = rng.randrange(1, len(lines))
        lines.insert(i, lines[rng.randrange(1, len(lines))])
        return b"\n".join(lines)
    if choice == 4:  # drop one array element: lengths no longer match
        items = list(_USD_ITEM.finditer(text))
        if items:
            m = rng.choice(items)
            return text[:m.start()] + text[m.end():]
    if choice == 5:  # composition arcs, value clips, time samples
        line = rng.choice(USD_LINES)
        if line.startswith(b"    subLayers"):
            at = text.find(b"defaultPrim")
            if at >= 0:
                return text[:at] + line.strip() + b"\n    " + text[at:]
        return text + b"\n" + line + b"\n"
    # a prim nested deeply, or a reference to itself
    depth = rng.choice((2, 50, 200))
    nested = b"".join(b'def Xform "n%d" {' % i for i in range(depth)) + b"}" * depth
    return text + b"\n" + nested + b"\n"


def mutate(rng: random.Random, suffix: str, data: bytes, pool: list[tuple[str, bytes]]) -> bytes:
    """One random mutation of ``data`` (a file of kind ``suffix``)."""
    kind = rng.randrange(12)
    n = len(data)
    if suffix == ".usda" and kind < 6:
        return _mutate_usda(rng, data)
    if kind == 0 and suffix == ".glb":
        parts = glb_parts(data)
        if parts:
            return _glb(_mutate_json(rng, parts[0]), parts[1])
    if kind == 1 and suffix == ".gltf":
        return _mutate_json(rng, data)
    if kind == 2 and suffix == ".ply":
        return _mutate_ply_header(rng, data)
    if n == 0:
        return bytes([rng.randrange(256)])
    buf = bytearray(data)
    if kind in (0, 1, 2, 3):  # flip bits
        for _ in range(rng.randint(1, 8)):
            buf[rng.randrange(n)] ^= 1 << rng.randrange(8)
    elif kind == 4:  # interesting bytes
        for _ in range(rng.randint(1, 4)):
            buf[rng.randrange(n)] = rng.choice((0, 1, 0x7F, 0x80, 0xFF, 0x20, 0x0A, 0x22))
    elif kind == 5 and n >= 4:  # interesting 32-bit words (GLB header, chunk lengths, data)
        pos = rng.randrange(0, n - 3) & ~3 if rng.random() < 0.7 else rng.randrange(n - 3)
        if rng.random() < 0.3 and suffix == ".glb":
            pos = rng.choice((4, 8, 12, 16)) if n >= 20 else pos
        value = rng.choice(INTERESTING_U32 + (n, n - 4, n + 4, n // 2))
        if suffix == ".usdc" and n >= 8 and rng.random() < 0.5:  # crate offsets are 64-bit
            pos = min(pos & ~7, n - 8)
            struct.pack_into("<Q", buf, pos, rng.choice((0, 1, 8, n, n - 8, n + 8, 2 ** 31,
                                                         2 ** 32, 2 ** 63, 2 ** 64 - 1)))
        else:
            struct.pack_into("<I", buf, pos, value & 0xFFFFFFFF)
    elif kind == 6:  # truncate
        return bytes(buf[:rng.randrange(n)])
    elif kind == 7:  # insert
        pos = rng.randrange(n + 1)
        buf[pos:pos] = bytes(rng.randrange(256) for _ in range(rng.randint(1, 16)))
    elif kind == 8:  # delete a range
        a = rng.randrange(n)
        del buf[a:a + rng.randint(1, 64)]
    elif kind == 9:  # duplicate a range
        a = rng.randrange(n)
        piece = buf[a:a + rng.randint(1, 256)]
        pos = rng.randrange(n)
        buf[pos:pos] = piece
    elif kind == 10:  # splice with another input
        other = rng.choice(pool)[1]
        if other:
            a = rng.randrange(n)
            b = rng.randrange(len(other))
            return bytes(buf[:a]) + other[b:b + rng.randint(1, 512)] + bytes(buf[a:])
    else:  # NaN / Inf floats into the data
        if n >= 4:
            pos = rng.randrange(n - 3)
            buf[pos:pos + 4] = struct.pack("<f", rng.choice((float("nan"), float("inf"),
                                                             -float("inf"), 1e38, -0.0)))
    return bytes(buf)


