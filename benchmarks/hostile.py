"""Hostile inputs against the readers' limits: ``python -m benchmarks.hostile [--quick]``.

Generates, in a temporary folder (nothing is committed), small files built to take huge
memory or time, and runs ``gsverse-convert`` and ``gsverse-validate`` on each in a separate
process. Prints one row per run: the input, its size, the limit it meets
(``gsverse_format/limits.py``, README §Limits), the outcome (exit status and the first words
of the message), the wall time and the peak resident memory of the process (``VmHWM``
polled every 20 ms; a USD child process is not included). The goal: every refusal within a
few seconds and a small multiple of the input's size (plus the interpreter's ~150 MiB).

Inputs: a glTF node graph where each node lists the next one 4 times (4⁶⁰ mesh instances);
a GLB with 400,000 accessors (``--quick``: 120,000) and one with 100,000 (the limit:
validated, every accessor checked); a ``.gltf`` with one 512 MiB base64
``data:`` URI (``--quick``: 16 MiB, validated with ``--max-data-uri-bytes 8M``); 3,000 splat
primitives sharing the accessors of one 3,000-splat primitive (``--quick``: 600 × 3,000);
JSON with a ``NaN`` literal; a ``.usda`` declaring 1.1 million prims and one nesting brackets
5,000 deep; an OBJ anchor mesh whose ``mtllib`` points outside its folder (converted: the
material file is never opened); ``.spz`` files of compressed zeros declaring millions of
splats (zstd v4, gzip v2); a ``.sog`` whose WebP header declares 8192² pixels; anchor meshes
far from a manifold (one OBJ polygon of 20,000 corners, 100,000 copies of one triangle);
an anchor mesh with 50,000 morph targets sharing one accessor, one at the end of a chain of
90,000 nodes, a truncated binary STL; for ``gsverse-pose``, a pose source whose key times run
to 4,166 s at ``--fps 24``, a 300-byte ``.npz`` vertex cache declaring 10¹¹ elements, one of
the wrong vertex count (48 MB declared), ``--vat-width 1e9``; ``gsverse-render --size 16384``.

Stop signals: the last rows send SIGTERM to a conversion busy in native code that holds the
interpreter (screened Poisson reconstructing an anchor mesh from 200,000 splats, pymeshlab
decimating a 1.3M-face mesh; ``--quick``: smaller) a fixed delay after it starts, and give the
time from the signal to the process's end (the goal: a second or two) and its exit status
(``-15``: ended by the signal's default action inside the native call, 143: by the command's
own handling). The delay is chosen to fall inside that step on this machine; the row says
how far the run got.
"""
from __future__ import annotations

import argparse
import base64
import json
import os
import signal
import subprocess
import sys
import tempfile
import time
from typing import Callable

import numpy as np

from benchmarks.processes import run_process
from gsverse_format import limits

TRIANGLE = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32).tobytes()


def _glb(path: str, doc: dict, binary: bytes) -> str:
    from gsverse_format.io.gltf import glb_bytes

    with open(path, "wb") as handle:
        handle.write(glb_bytes(json.dumps(doc).encode(), binary))
    return path


def _triangle_doc(nodes: list, accessors: list | None = None) -> dict:
    return {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": nodes,
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
            "accessors": accessors or [{"bufferView": 0, "componentType": 5126, "count": 3,
                                        "type": "VEC3"}],
            "bufferViews": [{"buffer": 0, "byteLength": len(TRIANGLE)}],
            "buffers": [{"byteLength": len(TRIANGLE)}]}


def dag_bomb(folder: str, quick: bool) -> str:
    nodes = [{"children": [i + 1] * 4} for i in range(60)] + [{"mesh": 0}]
    return _glb(os.path.join(folder, "dag_bomb.glb"), _triangle_doc(nodes), TRIANGLE)


def many_accessors(folder: str, quick: bool) -> str:
    n = 120_000 if quick else 400_000
    acc = {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}
    return _glb(os.path.join(folder, "many_accessors.glb"),
                _triangle_doc([{"mesh": 0}], [acc] * n), TRIANGLE)


def accessors_at_limit(folder: str, quick: bool) -> str:
    acc = {"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3"}
    return _glb(os.path.join(folder, "accessors_at_limit.glb"),
                _triangle_doc([{"mesh": 0}], [acc] * limits.MAX_GLTF_ARRAY_ITEMS), TRIANGLE)


def big_data_uri(folder: str, quick: bool) -> str:
    size = 2 ** 24 if quick else 2 ** 29
    path = os.path.join(folder, "data_uri.gltf")
    with open(path, "w", encoding="ascii") as handle:
        handle.write('{"asset": {"version": "2.0"}, "buffers": [{"byteLength": %d, "uri": '
                     '"data:application/octet-stream;base64,' % size)
        block = base64.b64encode(bytes(3 * 2 ** 20)).decode()
        for _ in range(size // (3 * 2 ** 20)):
            handle.write(block)
        handle.write(base64.b64encode(bytes(size % (3 * 2 ** 20))).decode())
        handle.write('"}]}')
    return path


def shared_primitives(folder: str, quick: bool) -> str:
    from gsverse_format import api
    from gsverse_format.examples import example_mesh, example_splats
    from gsverse_format.io.gltf import parse_glb
    from gsverse_format.model import SplatAsset, SplatPrimitive

    one = os.path.join(folder, "one_primitive.glb")
    cloud = example_splats(example_mesh(), 3000)
    api.write(SplatAsset([SplatPrimitive(cloud, None, "a")]), one)
    with open(one, "rb") as handle:
        json_chunk, binary = parse_glb(handle.read())
    doc = json.loads(json_chunk)
    doc["meshes"][0]["primitives"] *= 600 if quick else 3000
    return _glb(os.path.join(folder, "shared_primitives.glb"), doc, bytes(binary))


def nan_json(folder: str, quick: bool) -> str:
    path = os.path.join(folder, "nan.gltf")
    with open(path, "w", encoding="utf-8") as handle:
        handle.write('{"asset": {"version": "2.0"}, "nodes": [{"translation": [NaN, 0, 0]}]}')
    return path


def usda_prims(folder: str, quick: bool) -> str:
    path = os.path.join(folder, "prims.usda")
    with open(path, "w", encoding="ascii") as handle:
        handle.write("#usda 1.0\n")
        line = 'def "p" {}\n' * 1000
        for _ in range(1100):
            handle.write(line)
    return path


def usda_nesting(folder: str, quick: bool) -> str:
    path = os.path.join(folder, "nesting.usda")
    with open(path, "w", encoding="ascii") as handle:
        handle.write("#usda 1.0\n" + 'def "a" {' * 5000 + "}" * 5000 + "\n")
    return path


def obj_outside_material(folder: str, quick: bool) -> str:
    inner = os.path.join(folder, "obj")
    os.makedirs(inner, exist_ok=True)
    canary = os.path.join(folder, "canary.mtl")
    with open(canary, "w", encoding="ascii") as handle:
        handle.write("newmtl m\nKd 1 0 0\n")
    path = os.path.join(inner, "mesh.obj")
    with open(path, "w", encoding="ascii") as handle:
        handle.write(f"mtllib ../canary.mtl\nmtllib {canary}\n")
        with open(os.path.join(folder, "example", "mesh.obj"), encoding="ascii") as mesh:
            handle.write(mesh.read())
    return path


def spz_zstd_zeros(folder: str, quick: bool) -> str:
    """spz v4: ten million splats of zstd-compressed zeros (beyond the inflation ratio)."""
    import struct

    import zstandard

    n = 10_000_000
    sizes = [9 * n, n, 3 * n, 3 * n, 4 * n]
    packed = [zstandard.ZstdCompressor(level=19).compress(bytes(k)) for k in sizes]
    head = struct.pack("<4sIIBBBBI", b"NGSP", 4, n, 0, 12, 0, len(sizes), 32).ljust(32, b"\0")
    table = b"".join(struct.pack("<QQ", len(p), k) for p, k in zip(packed, sizes))
    path = os.path.join(folder, "zeros.spz")
    with open(path, "wb") as handle:
        handle.write(head + table + b"".join(packed))
    return path


def spz_gzip_zeros(folder: str, quick: bool) -> str:
    """spz v2: two million SH-3 splats of gzip-compressed zeros (beyond the ratio)."""
    import gzip
    import struct

    n = 2_000_000
    path = os.path.join(folder, "zeros_gzip.spz")
    with gzip.open(path, "wb", 9) as handle:
        handle.write(struct.pack("<IIIBBBB", 0x5053474E, 2, n, 3, 12, 0, 0))
        handle.write(bytes(65 * n))
    return path


def sog_pixels(folder: str, quick: bool) -> str:
    """A SOG archive whose 8×8 WebP says 8192² pixels in its header."""
    import io
    import zipfile

    from PIL import Image

    buf = io.BytesIO()
    Image.new("RGBA", (8, 8)).save(buf, "WEBP", lossless=True)
    data = buf.getvalue()
    at = data.index(b"VP8L") + 9
    bits = int.from_bytes(data[at:at + 4], "little") & ~((1 << 28) - 1)
    data = data[:at] + (bits | 8191 | (8191 << 14)).to_bytes(4, "little") + data[at + 4:]
    meta = {"version": 2, "count": 3, "means": {"mins": [0, 0, 0], "maxs": [1, 1, 1],
                                                "files": ["big.webp", "big.webp"]}}
    path = os.path.join(folder, "pixels.sog")
    with zipfile.ZipFile(path, "w") as z:
        z.writestr("meta.json", json.dumps(meta))
        z.writestr("big.webp", data)
    return path


def obj_long_polygon(folder: str, quick: bool) -> str:
    """One OBJ face of 20,000 corners (quick: 5,000)."""
    corners = 5_000 if quick else 20_000
    a = np.linspace(0, 2 * np.pi, corners, endpoint=False)
    path = os.path.join(folder, "polygon.obj")
    with open(path, "w", encoding="ascii") as handle:
        for t in a:
            handle.write(f"v {np.cos(t):.6f} {0.3 * np.sin(3 * t):.6f} {np.sin(t):.6f}\n")
        handle.write("f " + " ".join(str(i + 1) for i in range(corners)) + "\n")
    return path


def duplicate_triangles(folder: str, quick: bool) -> str:
    """A GLB mesh of 100,000 copies of one triangle (quick: 20,000)."""
    copies = 20_000 if quick else 100_000
    vertices = np.tile(np.frombuffer(TRIANGLE, np.float32), copies).tobytes()
    doc = _triangle_doc([{"mesh": 0}], [{"bufferView": 0, "componentType": 5126,
                                          "count": 3 * copies, "type": "VEC3",
                                          "min": [0, 0, 0], "max": [1, 1, 0]}])
    doc["bufferViews"][0]["byteLength"] = doc["buffers"][0]["byteLength"] = len(vertices)
    return _glb(os.path.join(folder, "duplicates.glb"), doc, vertices)


def shared_morph_targets(folder: str, quick: bool) -> str:
    """A GLB mesh of 600 triangles with 50,000 morph targets sharing one accessor (quick:
    10,000)."""
    targets = 10_000 if quick else 50_000
    vertices = np.random.default_rng(0).random((1800, 3)).astype(np.float32)
    blob = vertices.tobytes() + np.full_like(vertices, 0.01).tobytes()
    n = len(vertices)
    doc = _triangle_doc([{"mesh": 0}], [
        {"bufferView": 0, "componentType": 5126, "count": n, "type": "VEC3",
         "min": vertices.min(0).tolist(), "max": vertices.max(0).tolist()},
        {"bufferView": 1, "componentType": 5126, "count": n, "type": "VEC3"}])
    doc["bufferViews"] = [{"buffer": 0, "byteLength": 12 * n},
                          {"buffer": 0, "byteOffset": 12 * n, "byteLength": 12 * n}]
    doc["buffers"][0]["byteLength"] = len(blob)
    doc["meshes"][0]["primitives"][0]["targets"] = [{"POSITION": 1}] * targets
    doc["meshes"][0]["weights"] = [0] * targets
    return _glb(os.path.join(folder, "morphs.glb"), doc, blob)


def node_chain(folder: str, quick: bool) -> str:
    """A triangle at the end of a chain of 90,000 nodes (quick: 20,000)."""
    depth = 20_000 if quick else 90_000
    nodes = [{"children": [i + 1]} for i in range(depth - 1)] + [{"mesh": 0}]
    return _glb(os.path.join(folder, "chain.glb"), _triangle_doc(nodes), TRIANGLE)


def truncated_stl(folder: str, quick: bool) -> str:
    """A binary STL declaring 1,000 triangles holding 10."""
    path = os.path.join(folder, "cut.stl")
    with open(path, "wb") as handle:
        handle.write(b"\0" * 80 + (1000).to_bytes(4, "little") + b"\0" * 500)
    return path


def long_key_times(folder: str, quick: bool) -> str:
    """A pose source (one morph target on a quad) whose key times run to 4,166 s."""
    return _pose_source(os.path.join(folder, "long_keys.glb"), (0.0, 4166.0))


QUAD = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], np.float32)
QUAD_FACES = np.array([[0, 1, 2], [1, 3, 2]], np.uint16)


def quad_asset(folder: str) -> str:
    """An asset of 200 splats anchored to QUAD (the mesh of the pose sources)."""
    from gsverse_format import api
    from gsverse_format.examples import example_splats
    from gsverse_format.model import SplatAsset, SplatPrimitive, TriangleMesh

    mesh = TriangleMesh(QUAD, QUAD_FACES.astype(np.int64))
    cloud = example_splats(mesh, 200)
    path = os.path.join(folder, "quad.glb")
    api.write(SplatAsset([SplatPrimitive(cloud, api.bind(cloud, mesh), "quad")]), path)
    return path


def _pose_source(path: str, key_times: tuple[float, ...]) -> str:
    quad = QUAD
    times = np.asarray(key_times, np.float32)
    parts = [quad.tobytes(), QUAD_FACES.tobytes(),
             np.full((4, 3), 0.1, np.float32).tobytes(), times.tobytes(),
             np.linspace(0, 1, len(times), dtype=np.float32).tobytes()]
    views, offset = [], 0
    for part in parts:
        views.append({"buffer": 0, "byteOffset": offset, "byteLength": len(part)})
        offset += len(part)
    scalar = {"componentType": 5126, "count": len(times), "type": "SCALAR"}
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
           "nodes": [{"mesh": 0}], "bufferViews": views,
           "buffers": [{"byteLength": offset}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
                          "min": [0, 0, 0], "max": [1, 1, 0]},
                         {"bufferView": 1, "componentType": 5123, "count": 6, "type": "SCALAR"},
                         {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC3"},
                         {"bufferView": 3, **scalar}, {"bufferView": 4, **scalar}],
           "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1,
                                       "targets": [{"POSITION": 2}]}], "weights": [0]}],
           "animations": [{"samplers": [{"input": 3, "output": 4}],
                           "channels": [{"sampler": 0,
                                         "target": {"node": 0, "path": "weights"}}]}]}
    return _glb(path, doc, b"".join(parts))


def _npz_declaring(path: str, shape: tuple[int, ...], payload: bytes = b"") -> str:
    import io
    import zipfile

    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f4", "fortran_order": False,
                                                  "shape": shape})
    with zipfile.ZipFile(path, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("vertices.npy", header.getvalue() + payload)
    return path


def npz_declaring_1e11(folder: str, quick: bool) -> str:
    """A ``.npz`` vertex cache of 300 bytes whose header declares 10¹¹ float32 elements."""
    return _npz_declaring(os.path.join(folder, "bomb.npz"), (1, 33_333_333_334, 3))


def npz_wrong_vertices(folder: str, quick: bool) -> str:
    """A real ``.npz`` cache of 2,000 frames of 1,000 vertices (48 MB declared, within the
    ratio to its size) for an asset whose anchor mesh has another vertex count."""
    path = os.path.join(folder, "wrong.npz")
    np.savez_compressed(path, vertices=np.zeros((2000, 1000, 3), np.float64))
    return path


def the_asset(folder: str, quick: bool) -> str:
    """The example's anchored asset (the argument limits of gsverse-pose and -render)."""
    return os.path.join(folder, "asset.glb")


def big_capture(folder: str, quick: bool) -> str:
    """A 3DGS PLY of 200,000 splats on the example's surface (quick: 60,000), no mesh."""
    from gsverse_format.examples import example_mesh, example_splats
    from gsverse_format.io.ply import write_splat_ply

    path = os.path.join(folder, "capture.ply")
    write_splat_ply(example_splats(example_mesh(), 60_000 if quick else 200_000), path)
    return path


def dense_mesh(folder: str, quick: bool) -> str:
    """An OBJ icosphere of 1.3M faces (quick: 330k), to be decimated to 1,000."""
    import trimesh

    from gsverse_format.examples import write_obj
    from gsverse_format.model import TriangleMesh

    sphere = trimesh.creation.icosphere(subdivisions=7 if quick else 8)
    path = os.path.join(folder, "dense.obj")
    write_obj(TriangleMesh(sphere.vertices.astype(np.float32), sphere.faces), path)
    return path


#: (name, builder, the limit it meets, which tools run on it).
CASES: list[tuple[str, Callable[[str, bool], str], str, tuple[str, ...]]] = [
    ("node graph, 4⁶⁰ instances", dag_bomb,
     f"MAX_SCENE_INSTANCES = {limits.MAX_SCENE_INSTANCES:,}", ("mesh", "validate")),
    ("GLB with many accessors", many_accessors,
     f"MAX_GLTF_ARRAY_ITEMS = {limits.MAX_GLTF_ARRAY_ITEMS:,}", ("convert", "validate")),
    ("GLB with 100,000 accessors, at the limit", accessors_at_limit,
     f"MAX_GLTF_ARRAY_ITEMS = {limits.MAX_GLTF_ARRAY_ITEMS:,}", ("validate",)),
    ("one huge data: URI", big_data_uri,
     f"MAX_DATA_URI_BYTES = {limits.MAX_DATA_URI_BYTES:,}", ("convert", "validate")),
    ("primitives sharing accessors", shared_primitives,
     f"MAX_READ_AMPLIFICATION = {limits.MAX_READ_AMPLIFICATION}", ("convert", "validate")),
    ("NaN in glTF JSON", nan_json, "JSON only", ("convert", "validate")),
    ("USD text, 1.1M prims", usda_prims,
     f"MAX_USD_TEXT_PRIMS = {limits.MAX_USD_TEXT_PRIMS:,}", ("convert", "validate")),
    ("USD text, nesting 5,000", usda_nesting,
     f"MAX_USD_TEXT_NESTING = {limits.MAX_USD_TEXT_NESTING}", ("convert", "validate")),
    ("OBJ mtllib outside its folder", obj_outside_material, "no file outside is read",
     ("mesh",)),
    (".spz v4, zstd zeros", spz_zstd_zeros, "MAX_INFLATION_RATIO = 100", ("convert",)),
    (".spz v2, gzip zeros", spz_gzip_zeros, "MAX_INFLATION_RATIO = 100", ("convert",)),
    (".sog, WebP header of 8192² pixels", sog_pixels, "MAX_INFLATION_RATIO = 100",
     ("convert",)),
    ("OBJ, one polygon of many corners", obj_long_polygon,
     "the report is numpy (no manifold3d)", ("mesh",)),
    ("GLB mesh, one triangle many times", duplicate_triangles,
     "the report is numpy (no manifold3d)", ("mesh",)),
    ("GLB mesh, morph targets sharing one accessor", shared_morph_targets,
     f"MAX_MORPH_AMPLIFICATION = {limits.MAX_MORPH_AMPLIFICATION}", ("mesh",)),
    ("GLB mesh, node chain 90,000 deep", node_chain,
     f"MAX_NODE_DEPTH = {limits.MAX_NODE_DEPTH:,}", ("mesh",)),
    ("binary STL, truncated", truncated_stl, "declared triangles vs file size", ("mesh",)),
    ("pose source, key times to 4,166 s at 24 fps", long_key_times,
     f"MAX_POSES = {limits.MAX_POSES:,}", ("pose",)),
    (".npz vertex cache declaring 10¹¹ elements", npz_declaring_1e11,
     f"MAX_NPZ_RATIO = {limits.MAX_NPZ_RATIO}, from its header", ("pose",)),
    (".npz vertex cache, wrong vertex count", npz_wrong_vertices,
     "vertex count from its header", ("pose",)),
    ("anchored asset, --vat-width 1e9", the_asset, f"MAX_VAT_WIDTH = {limits.MAX_VAT_WIDTH:,}",
     ("vat-width",)),
    ("anchored asset, --size 16384x16384", the_asset,
     f"MAX_RENDER_PIXELS = {limits.MAX_RENDER_PIXELS:,}", ("render-size",)),
    ("SIGTERM in screened Poisson (no --mesh)", big_capture,
     "stop signals end native calls", ("sigterm-convert",)),
    ("SIGTERM in pymeshlab decimation (--faces 1000)", dense_mesh,
     "stop signals end native calls", ("sigterm-mesh",)),
]

#: seconds after the start at which the SIGTERM rows send the signal, quick and full sizes
#: (inside the step named on a 2-core machine: reading, normals or OBJ parsing take 3-10 s,
#: the step itself 10-40 s)
SIGTERM_AFTER_S = {True: 6.0, False: 14.0}


def _commands(tool: str, path: str, folder: str, quick: bool) -> list[str]:
    exe = os.path.dirname(sys.executable)
    out = os.path.join(folder, "out.glb")
    asset = os.path.join(folder, "asset.glb")
    poses = os.path.join(folder, "poses")
    if tool == "pose":     # the file as the pose source of an asset anchored to a quad
        return [os.path.join(exe, "gsverse-pose"), os.path.join(folder, "quad.glb"), "--source",
                path, "--fps", "24",
                "--output-dir", poses]
    if tool == "vat-width":
        return [os.path.join(exe, "gsverse-pose"), path, "--deform", "twist=30", "--vat",
                os.path.join(folder, "vat.exr"), "--vat-width", str(10 ** 9)]
    if tool == "render-size":
        return [os.path.join(exe, "gsverse-render"), path, os.path.join(folder, "r.png"),
                "--size", "16384x16384"]
    if tool == "sigterm-convert":
        return [os.path.join(exe, "gsverse-convert"), path, out, "--overwrite",
                "--reconstruct-faces", "200000"]
    if tool == "sigterm-mesh":
        splats = os.path.join(folder, "example", "splats.ply")
        return [os.path.join(exe, "gsverse-convert"), splats, out, "--mesh", path, "--faces",
                "1000", "--overwrite"]
    if tool == "validate":
        extra = ["--max-data-uri-bytes", "8M"] if quick and path.endswith("data_uri.gltf") else []
        return [os.path.join(exe, "gsverse-validate"), *extra, path]
    if tool == "mesh":  # the file as the anchor mesh of a conversion
        splats = os.path.join(folder, "example", "splats.ply")
        return [os.path.join(exe, "gsverse-convert"), splats, out, "--mesh", path, "--overwrite"]
    return [os.path.join(exe, "gsverse-convert"), path, out, "--overwrite"]


def _outcome(res: dict) -> str:
    lines = [ln for ln in res["output"].splitlines() if ln.strip()]
    if res["rc"] == 0:
        return "exit 0"
    finding = [ln.split(None, 1)[1] for ln in lines if ln.lstrip().startswith("error ")]
    if finding:  # the validator: the first error finding (code: message)
        words = finding[0]
    else:        # the converter: "gsverse-convert: error: FILE: cause"
        first = next((ln for ln in lines if "error" in ln), lines[-1] if lines else "")
        words = first.split(": ", 3)[-1]
    return f"exit {res['rc']}: {words[:80]}"


def _terminated(cmd: list[str], after_s: float) -> dict:
    """Run ``cmd``, send it SIGTERM ``after_s`` seconds after its start unless it has ended;
    the time from the signal to its end is ``signal_to_exit_s`` (0 when no signal was sent)."""
    with tempfile.TemporaryFile() as out:
        t0 = time.perf_counter()
        proc = subprocess.Popen(cmd, stdout=out, stderr=subprocess.STDOUT)
        sent = None
        while True:
            pid, status, usage = os.wait4(proc.pid, os.WNOHANG)
            if pid:
                break
            if sent is None and time.perf_counter() - t0 >= after_s:
                sent = time.perf_counter()
                os.kill(proc.pid, signal.SIGTERM)
            time.sleep(0.005)
        end = time.perf_counter()
        proc.returncode = os.waitstatus_to_exitcode(status)
        out.seek(0)
        text = out.read().decode("utf-8", "replace")
    return {"wall_s": end - t0, "rc": proc.returncode, "peak_rss_mb": usage.ru_maxrss / 1024.0,
            "output": text, "signal_to_exit_s": 0.0 if sent is None else end - sent,
            "signalled": sent is not None}


#: how each tool is named in the table
_TOOL_NAMES = {"mesh": "convert --mesh", "pose": "pose --source", "vat-width": "pose --vat",
               "render-size": "render", "sigterm-convert": "convert, SIGTERM",
               "sigterm-mesh": "convert --mesh, SIGTERM"}


def run(quick: bool, log: Callable[[str], None] = print) -> list[dict]:
    from gsverse_format.examples import make_example

    rows = []
    with tempfile.TemporaryDirectory(prefix="gsverse-hostile-") as folder:
        ply, obj = make_example(os.path.join(folder, "example"))
        subprocess.run([os.path.join(os.path.dirname(sys.executable), "gsverse-convert"), ply,
                        os.path.join(folder, "asset.glb"), "--mesh", obj, "--quiet"],
                       check=True)
        quad_asset(folder)
        for name, build, limit, tools in CASES:
            path = build(folder, quick)
            size = os.path.getsize(path)
            for tool in tools:
                cmd = _commands(tool, path, folder, quick)
                log(f"{name}: {os.path.basename(cmd[0])} {os.path.basename(path)}")
                if tool.startswith("sigterm"):
                    res = _terminated(cmd, SIGTERM_AFTER_S[quick])
                    outcome = (f"exit {res['rc']} {res['signal_to_exit_s']:.2f} s after the "
                               f"signal" if res["signalled"] else
                               f"finished before the signal: {_outcome(res)}")
                else:
                    res = run_process(cmd)
                    outcome = _outcome(res)
                rows.append({"case": name, "tool": _TOOL_NAMES.get(tool, tool), "bytes": size,
                             "limit": limit, "outcome": outcome, "wall_s": res["wall_s"],
                             "peak_rss_mb": res["peak_rss_mb"]})
            if path != the_asset(folder, quick):
                os.remove(path)
    return rows


def markdown(rows: list[dict], quick: bool) -> str:
    out = [f"# Hostile inputs ({'quick' if quick else 'full'} sizes)", "",
           "| input | tool | file size | limit | outcome | wall s | peak RSS MiB |",
           "|---|---|---|---|---|---|---|"]
    for r in rows:
        out.append(f"| {r['case']} | {r['tool']} | {r['bytes']:,} | {r['limit']} | "
                   f"{r['outcome']} | {r['wall_s']:.2f} | {r['peak_rss_mb']:.0f} |")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(prog="python -m benchmarks.hostile",
                                description=__doc__.split("\n")[0])
    p.add_argument("--quick", action="store_true", help="smaller inputs (about a minute)")
    args = p.parse_args(argv)
    rows = run(args.quick, lambda msg: print(msg, file=sys.stderr, flush=True))
    print(markdown(rows, args.quick))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
