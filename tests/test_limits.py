"""Small hostile inputs that would take huge memory or time: each is generated here and must be
refused before anything is expanded, with one line naming the file (README §Limits)."""
from __future__ import annotations

import base64
import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest

from gsverse_format import api, limits
from gsverse_format.codes import Code
from gsverse_format.errors import FormatError
from gsverse_format.examples import example_mesh, example_splats
from gsverse_format.io.gltf import glb_bytes, load_document, open_document, parse_glb
from gsverse_format.io.gltf.container import GltfFormatError, check_data_uri_sizes
from gsverse_format.io.gltf.scene import instance_counts, node_instances
from gsverse_format.io.mesh import read_mesh, strip_material_libraries
from gsverse_format.io.usd.stage import check_path
from gsverse_format.model import SplatAsset, SplatPrimitive
from gsverse_format.validators.context import Options
from gsverse_format.validators.validate import validate_file

TRIANGLE = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32).tobytes()


def _mesh_glb(path, nodes, roots=(0,), extra: dict | None = None) -> str:
    """A GLB with one one-triangle mesh and the given node graph."""
    doc = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": list(roots)}],
           "nodes": nodes, "meshes": [{"primitives": [{"attributes": {"POSITION": 0}}]}],
           "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                          "min": [0, 0, 0], "max": [1, 1, 0]}],
           "bufferViews": [{"buffer": 0, "byteLength": len(TRIANGLE)}],
           "buffers": [{"byteLength": len(TRIANGLE)}]}
    doc.update(extra or {})
    path.write_bytes(glb_bytes(json.dumps(doc).encode(), TRIANGLE))
    return str(path)


def _bomb(path, depth: int = 60, fan: int = 4) -> str:
    """Each node lists the next one ``fan`` times: fan**depth paths to the mesh node."""
    nodes = [{"children": [i + 1] * fan} for i in range(depth)] + [{"mesh": 0}]
    return _mesh_glb(path, nodes)


# ---------------------------------------------------------------------------- node graphs

def test_instances_are_counted_by_paths_without_expanding(tmp_path):
    doc = json.loads(parse_glb(open(_bomb(tmp_path / "small.glb", depth=3, fan=3), "rb")
                               .read())[0])
    counts = instance_counts(doc)
    assert counts == {0: 1, 1: 3, 2: 9, 3: 27}
    assert len(node_instances(doc)) == 27  # what the expansion makes, counted beforehand


def test_node_dag_bomb_is_refused_by_reader_and_validator(tmp_path):
    path = _bomb(tmp_path / "bomb.glb")
    with pytest.raises(FormatError) as err:
        read_mesh(path)
    message = str(err.value)
    assert message.startswith(path) and "\n" not in message
    assert f"more than {limits.MAX_SCENE_INSTANCES} node instances" in message
    report = validate_file(path)
    assert Code.SIZE_LIMIT_EXCEEDED in report.codes()
    assert report.exit_status == 1


def test_node_dag_bomb_without_meshes_is_refused(tmp_path):
    nodes = [{"children": [i + 1] * 4} for i in range(60)] + [{}, {"mesh": 0}]
    path = _mesh_glb(tmp_path / "empty_bomb.glb", nodes, roots=(0, 61))
    with pytest.raises(FormatError, match="node instances"):
        read_mesh(path)


def test_scene_vertices_after_instancing_are_bounded(tmp_path):
    # 1000 instances of a mesh declaring 2**16 vertices: within the instance limit, past
    # the vertex limit; refused on the declared counts, nothing is read.
    nodes = [{"children": list(range(1, 1001))}] + [{"mesh": 0}] * 1000
    big = {"accessors": [{"bufferView": 0, "componentType": 5126, "count": 2 ** 16,
                          "type": "VEC3"}]}
    path = _mesh_glb(tmp_path / "wide.glb", nodes, extra=big)
    with pytest.raises(FormatError, match="vertices or"):
        read_mesh(path)


def test_node_cycle_is_reported(tmp_path):
    path = _mesh_glb(tmp_path / "cycle.glb", [{"children": [1]}, {"children": [0], "mesh": 0}])
    with pytest.raises(FormatError, match="cycle"):
        read_mesh(path)
    report = validate_file(path)
    assert Code.GLTF_SCHEMA_VIOLATION in report.codes() and report.exit_status == 1


def test_shared_instances_within_limits_still_read(tmp_path):
    path = _mesh_glb(tmp_path / "two.glb", [{"children": [1, 1]}, {"mesh": 0}])
    assert read_mesh(path).face_count == 2


# ---------------------------------------------------------------------------- JSON

def test_too_many_accessors_refused_before_decoding(tmp_path):
    n = limits.MAX_GLTF_ARRAY_ITEMS + 1
    doc = {"asset": {"version": "2.0"}, "accessors": [{"count": 1}] * n}
    path = tmp_path / "many.gltf"
    path.write_text(json.dumps(doc))
    with pytest.raises(GltfFormatError) as err:
        load_document(str(path))
    assert err.value.code == Code.SIZE_LIMIT_EXCEEDED and err.value.pointer == "/accessors"
    assert Code.SIZE_LIMIT_EXCEEDED in validate_file(str(path)).codes()


@pytest.mark.parametrize("literal", ["NaN", "Infinity", "-Infinity"])
def test_non_json_constants_are_refused(tmp_path, literal):
    path = tmp_path / "nan.gltf"
    path.write_text('{"asset": {"version": "2.0"}, "nodes": [{"translation": [%s, 0, 0]}]}'
                    % literal)
    with pytest.raises(FormatError) as err:
        api.read(path)
    assert str(err.value).startswith(str(path)) and literal.lstrip("-") in str(err.value)
    assert Code.JSON_INVALID in validate_file(str(path)).codes()


# ---------------------------------------------------------------------------- data: URIs

@pytest.mark.parametrize("size", [0, 1, 2, 3, 5 * 2 ** 20 + 1])
def test_data_uri_decoded_in_slices_is_exact(tmp_path, size):
    blob = np.random.default_rng(size).integers(0, 256, size, np.uint8).tobytes()
    uri = "data:application/octet-stream;base64," + base64.b64encode(blob).decode()
    doc = {"asset": {"version": "2.0"}, "buffers": [{"byteLength": size, "uri": uri}]}
    path = tmp_path / "uri.gltf"
    path.write_text(json.dumps(doc))
    assert bytes(open_document(str(path)).reader.buffer(0)) == blob


@pytest.mark.parametrize("payload", ["AAA", "AA=A", "AAAA====", "AA\u00e9A"])
def test_bad_base64_is_refused(tmp_path, payload):
    doc = {"asset": {"version": "2.0"},
           "buffers": [{"byteLength": 1, "uri": "data:;base64," + payload}]}
    path = tmp_path / "bad.gltf"
    path.write_text(json.dumps(doc))
    with pytest.raises(GltfFormatError) as err:
        open_document(str(path)).reader.buffer(0)
    assert err.value.code == Code.URI_INVALID


def test_data_uri_over_the_limit_is_refused_before_the_json_is_parsed(tmp_path):
    uri = "data:application/octet-stream;base64," + "A" * 4000
    raw = json.dumps({"asset": {"version": "2.0"},
                      "buffers": [{"byteLength": 3000, "uri": uri}]}).encode()
    with pytest.raises(GltfFormatError) as err:
        check_data_uri_sizes(raw, 1000)
    assert err.value.code == Code.DATA_URI_TOO_LARGE
    check_data_uri_sizes(raw, 3000)
    path = tmp_path / "big.gltf"
    path.write_bytes(raw)
    with pytest.raises(GltfFormatError) as err:
        load_document(str(path), max_data_uri=1000)
    assert err.value.code == Code.DATA_URI_TOO_LARGE
    report = validate_file(str(path), Options(max_data_uri_bytes=1000))
    assert Code.DATA_URI_TOO_LARGE in report.codes()


# ---------------------------------------------------------------------------- shared accessors

def _shared_primitives(tmp_path, copies: int) -> str:
    mesh = example_mesh(subdivisions=1)
    one = tmp_path / "one.glb"
    api.write(SplatAsset([SplatPrimitive(example_splats(mesh, 3000), None, "a")]), one)
    json_chunk, binary = parse_glb(one.read_bytes())
    doc = json.loads(json_chunk)
    doc["meshes"][0]["primitives"] = doc["meshes"][0]["primitives"] * copies
    path = tmp_path / f"shared{copies}.glb"
    path.write_bytes(glb_bytes(json.dumps(doc).encode(), bytes(binary)))
    return str(path)


def test_primitives_sharing_accessors_cannot_amplify_reads(tmp_path):
    path = _shared_primitives(tmp_path, 400)  # 400 x 3000 splats from a 0.2 MB file
    with pytest.raises(FormatError) as err:
        api.read(path)
    assert str(err.value).startswith(path) and "times the" in str(err.value)
    assert len(api.read(_shared_primitives(tmp_path, 2)).primitives) == 2


# ---------------------------------------------------------------------------- OBJ materials

def _obj_with_outside_materials(tmp_path) -> tuple[str, str]:
    inner = tmp_path / "in"
    inner.mkdir()
    canary = tmp_path / "canary.mtl"
    canary.write_text("newmtl m\nKd 1 0 0\nmap_Kd ../canary.png\n")
    obj = inner / "m.obj"
    obj.write_text(f"mtllib ../canary.mtl\n  mtllib {canary}\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                   f"v 1 1 0\nusemtl m\nf 1 2 3\nf 2 4 3\n")
    return str(obj), str(canary)


def test_obj_material_libraries_are_stripped(tmp_path):
    obj, _ = _obj_with_outside_materials(tmp_path)
    data = open(obj, "rb").read()
    stripped = strip_material_libraries(data)
    assert b"mtllib" not in stripped and b"usemtl m" in stripped
    plain = tmp_path / "plain.obj"
    plain.write_bytes(stripped)
    ours, reference = read_mesh(obj), read_mesh(plain)
    assert np.array_equal(ours.faces, reference.faces)
    assert np.array_equal(ours.vertices, reference.vertices)


@pytest.mark.skipif(shutil.which("strace") is None, reason="strace not installed")
def test_obj_reader_opens_no_file_outside_the_folder(tmp_path):
    obj, canary = _obj_with_outside_materials(tmp_path)
    trace = tmp_path / "trace.txt"
    code = f"from gsverse_format.io.mesh import read_mesh; read_mesh({obj!r})"
    subprocess.run(["strace", "-f", "-e", "trace=open,openat,stat,newfstatat,statx,access",
                    "-o", str(trace), sys.executable, "-c", code], check=True)
    opened = trace.read_text()
    assert obj in opened  # the trace sees the reader's own file
    assert "canary" not in opened


# ---------------------------------------------------------------------------- USD text layers

def test_usd_text_nesting_refused_before_parsing(tmp_path):
    path = tmp_path / "deep.usda"
    path.write_text("#usda 1.0\n" + 'def "a" {' * 5000 + "}" * 5000 + "\n")
    with pytest.raises(FormatError) as err:
        check_path(str(path))
    assert str(err.value).startswith(str(path)) and "nests brackets" in str(err.value)


def test_usd_text_sublayer_is_checked_before_parsing(tmp_path):
    (tmp_path / "deep.usda").write_text("#usda 1.0\n" + "(" * 3000 + "\n")
    root = tmp_path / "root.usda"
    root.write_text('#usda 1.0\n(\n    subLayers = [@./deep.usda@]\n)\n')
    with pytest.raises(FormatError) as err:
        api.read(root)
    assert str(err.value).startswith(str(root)) and "layer deep.usda: " in str(err.value)


def test_usd_text_prim_count_refused_before_parsing(tmp_path):
    path = tmp_path / "prims.usda"
    body = 'def "p" {}\n' * (limits.MAX_USD_TEXT_PRIMS // 2 + 1)
    path.write_text("#usda 1.0\n" + 'over "q" {}\n' * (limits.MAX_USD_TEXT_PRIMS // 2) + body)
    with pytest.raises(FormatError, match="prims"):
        api.read(path)


def test_usd_text_size_limit(tmp_path, monkeypatch):
    from gsverse_format.io.usd import stage

    path = tmp_path / "big.usda"
    path.write_text("#usda 1.0\n" + " " * 5000)
    check_path(str(path))
    monkeypatch.setattr(stage, "MAX_USD_TEXT_BYTES", 4096)
    with pytest.raises(FormatError, match="larger than the limit of 4096"):
        check_path(str(path))
    binary = tmp_path / "big.usdc"
    binary.write_bytes(b"PXR-USDC" + bytes(5000))
    check_path(str(binary))  # only text layers are limited by this rule


def test_limits_are_documented():
    readme = open(os.path.join(os.path.dirname(__file__), "..", "README.md"),
                  encoding="utf-8").read()
    for name in limits.__all__:
        assert f"`{name}`" in readme, name


@pytest.mark.slow
def test_hostile_benchmark_refuses_every_input():
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [root, env.get("PYTHONPATH")]))
    out = subprocess.run([sys.executable, "-m", "benchmarks.hostile", "--quick"], cwd=root,
                         env=env, capture_output=True, text=True, timeout=900)
    assert out.returncode == 0, out.stderr[-2000:]
    rows = {tuple(cell.strip() for cell in line.split("|")[1:3]): line.split("|")[5].strip()
            for line in out.stdout.splitlines() if line.startswith("| ") and "---" not in line}
    expected = {("node graph, 4⁶⁰ instances", "convert --mesh"): "node instances",
                ("node graph, 4⁶⁰ instances", "validate"): "exit 1: ",
                ("GLB with many accessors", "convert"): "accessors, more than the limit",
                ("GLB with many accessors", "validate"): "SIZE_LIMIT_EXCEEDED",
                ("one huge data: URI", "validate"): "DATA_URI_TOO_LARGE",
                ("primitives sharing accessors", "convert"): "would read",
                ("NaN in glTF JSON", "convert"): "NaN is not a JSON value",
                ("NaN in glTF JSON", "validate"): "JSON_INVALID",
                ("USD text, 1.1M prims", "convert"): "prims",
                ("USD text, nesting 5,000", "validate"): "nests brackets",
                ("OBJ mtllib outside its folder", "convert --mesh"): "exit 0",
                ("GLB mesh, morph targets sharing one accessor", "convert --mesh"):
                    "morph targets would read",
                ("GLB mesh, node chain 90,000 deep", "convert --mesh"): "levels deep",
                ("binary STL, truncated", "convert --mesh"): "truncated binary STL",
                ("pose source, key times to 4,166 s at 24 fps", "pose --source"): "exit 2: lower --fps",
                (".npz vertex cache declaring 10¹¹ elements", "pose --source"):
                    "declares 100000000002 elements",
                (".npz vertex cache, wrong vertex count", "pose --source"):
                    "holds 1000 vertices per frame",
                ("anchored asset, --vat-width 1e9", "pose --vat"): "exit 2: --vat-width",
                ("anchored asset, --size 16384x16384", "render"): "pixels"}
    for key, phrase in expected.items():
        assert phrase in rows[key], (key, rows[key])
    # stop signals: ended by the signal (-15 in the native call, 143 by the command's
    # handling), or done before the signal came (a fast machine); never an internal error
    for key in (("SIGTERM in screened Poisson (no --mesh)", "convert, SIGTERM"),
                ("SIGTERM in pymeshlab decimation (--faces 1000)", "convert --mesh, SIGTERM")):
        assert rows[key].startswith(("exit -15 ", "exit 143 ", "finished before the signal: "
                                     "exit 0")), (key, rows[key])


#: A 4 KB ``.usdc`` (one of our own USD files with bytes changed by the fuzz harness) on which
#: usd-core 26.x loops for minutes and allocates gigabytes; zlib-compressed, base64.
_USD_HANG = (
    "eNrNV3lUU8can6yERU0UEEXZpaAgmyvJvZPI4vIUoxB3tCHcwMWQhCRY10Jxw2NVtOBSaaVuFbe64FLJvdFqq7VSsVoUinvr"
    "dqwiPhQEkjc3JkrPeX+8vvP+eHPO785v5lvmu3NnvnM/+bTJkYrUxAQgAPbmJQT/k8Zy9NwunGmCv8jdpBzHmFlWhNATge+Y"
    "82TiQfBG6I3gg9AHIcDpsJ/DiGl+CP6MECEQIQghGCEEYYDDMBThA4QwhHCEgQiDECIQIrs6HszE9jcdv21sRz/g5HV6unCk"
    "ZejWRtpzTgNeM3AErFvTgDvlxPrjtGGau6Uh4iIt7NyFF4iD4bq4Xe/kQzOq6MK1NfTn7PuSpYQcc8o9HXIP54IV73aTI3FM"
    "jXPKSph5hZciScEDTRFpijSFIg24v2nnddj4bS6cV26vuNwOxGytgk7bG5d2frvNauN2ctjtPKTTyXZp7xBYrWxb2/v1Zuf2"
    "xkMs7jDoYg6uFezD15cPhN1XhuKp/T3gtlnbcS8XPkwftAl/vtUVnjixCN+4uxmfFL4Cl9e5wdUzi7CrhxLggX4h2J1FPDho"
    "2kf4jn4vscu1zfg/P6XwPv49cY8u54PrOBfujn1lzo4r86IIPRxzLo4v5bS7vyYv9tbvotjSLE+Yt1kOvVOmH15IFMVoIjsk"
    "L+4UQNOVUYeHRnKOJJklcHNLBNy9UB+jKtl+eP+w7fi9ywbouv+nmPaJnYcTBsyFMvIi3npyZwy9JuQI/X1PmGCZBDc0r4oN"
    "2P06us1DCMMrUuH2J6ti1fmmw7KcJfB0qAi/sHHZ4a/KNIflkZ6w/owcfikIODJloyi2PJ0HU5bNgHGle2KeXu1/dLEnD94+"
    "NANOCRkfPRXcinrwURSsyoqHHNZfD5LzvdilR8VDcizVDxT9qtdr9pxaUzw3vv9Vb/G5kzuq1565Vx0WXnoiT7hNvCQ/WZwQ"
    "mBHvtHsNU6Ff/Bx45uB4mB8thp+0JsJrR/KhIjUCemaHweG1feGuA1pYkLIYzh8aAzn/xq5rHN77Wmnw8jT29XM/7JF0NrSt"
    "4sHk+hZ6hrWP5VuTGfddsZgOSaygq7bPgL5D9uGG5yH4l32f0i3LZ8ItswbgotD1dFX9JEjy7+GssXPxx9NNliEV2fhnlVL8"
    "3O04qkiWbhnvk4fPyNlEf/2oEr/YexxelpkJzfIWbOJPP9CyyP544KQfsYzpk+Fr3A32KR5ieZbMgj9ez8Y99tzDr00Lhiul"
    "X9KbjELLoNIbePPxc3iRfir9US4B29rXYZz/8j2c7/8oeS3N3GX7npxfgq+DIXaOt66133eGp+d8jI+qDLE4r+HWqDq6YssN"
    "nOGY3w2cyQMM/25AA83kB7uSsh6XXPvNnivs41cr6OYB9Xa+cMgKfGdSnV0vJ3cZzeQWhqsnL38XlzNHfMdaiTG5QzWqAmdy"
    "B8v6hGLyCJM7UkglxeSc1aQGV9Vtx/J294Zjktn0lfnVVNXDDozJRXnjs3Db66t46cnhdO4vfDqlkQ1L1iy05yiP28uoT7/Z"
    "gu9gL8VU5f3gL2Q9xeSx4de+oXVhn2O/71yL7w230C9PBeKcvxEXoxft0K8tGGpp9C+GDHLbFpiPpH1rvrTsB8mGvT2oPWU4"
    "NS7we8nKkR3Yy6/Gmk8fvG/eWWGjyit6wbasFnx6g45aWlVMLRJcl5Thg7GioqaR/iOLJU1PKHGPiPviaaPLqRebS6EqtZN+"
    "k5diidpVba7ddVxckBlAjRlw1rzkzAdU5ZZic96JwZjbqt1mt74d1bUFx6AjJsvo3aHYSg8uVr/xAFYrrKO8F0dhH6z+3nzj"
    "QKN4W8kgbG99OtZvT4Blwt2PITd7EXz8Wxo2L8AqnnptJ2a7nGXu2/Ggmn8sGNt4/a65Mfkmdr5ajrWQ6XgSXYbvL+uGZ52/"
    "hclkB09ZHpebP7khkLzWe2OjypvMX6zYKvlZNutUoGEXVtFSTo9Qx8OT8eGw8qQLxZZNwayNHOqBOZEKnS+iuKeN1MXzz8Xn"
    "4lKxtK18yaolr+ioqjlwv1UBJd/aJPODvsZ2D0mXLL3jL9mQpjT7frOTitvsi61rPEq57+Nh6sDu0HQgWNK6fALd66j4VM1Z"
    "NXZFNLua2BRGfbFlg4S74A+zGvM0n41zFWOGxuqcsnBLY9hSWDmwCB7b29fss3ggJW7qa570uoF6fg+Yd8zKp7y0BDbbrQhr"
    "vXCeGjpyJXxB19JFR+IsRdo/xbcLL1e7z55C3T5bL9njS5nXgGNU6LwZ5pt/NFdnf3hQHOe/Fn5GPaSXfCyz9AxbTF0d3CEJ"
    "2uaNTd+bQ7Gf86nH25ZWb6h5aF607ghWc2SgxOP/9Bw547L5H5Vs65wp0fXkiMfN7ZQ8O5li57Ks/thVqtDOGwQAC3k61c6N"
    "jd2xQ1uW2XlhkT928KtP7PzVQ2+s4cUQO//oVncsI1Vj5zXFnhh1XGXnXr5emM/l1XaeklMj2TI61s5df26WVC6Hds75T+IK"
    "eBuXzKGb7jDa5fxZeVMljgwH00G+XjafNIJcwkQYjHLCoNCSJiAzGgkT0BvI3IRsUpNpILQgk1Ar8zUmOZoDWYSWMChNOgPI"
    "Ms5DZkSkWmfIVZoCogfHDI4GqnyjSZc7XrmAMCQqTUoAjHpCRapJwgCmMYrAtEBPpChzAVDpcvU6LaE1gbmkNhMotapsnWFO"
    "LmHMBhm6zAXAaFKaSBWYwEzodaTWZARqpYqYQhhMxPwEXb4INPmM1WaSKsIIjPkZmeQ80kjqtKmqbCKXAPp8g15nJAAx30Ro"
    "60GTn06PDEmkK1eiXqUhkklCkxmXOFqZbzSSSm2qXqM0gdHGKcw7FQCRbCvIk8nHAqWenAKaOEojCsJImtAKRqAzkIT2AADd"
    "wBmjSqlBTnV6pYokgK2nQZmJnKmIeKM+mzCQSDpGacjVaUmVMZHIMhBEEHDVJ+gItZpUfQgKkVeDLodQZYEW1gRdJjEGvScw"
    "6lCE2iwh4HzGOhav0ml0hlTkn+gF2B+ylsQjCzWp6Q2CMokfWBIUUCwA+SzubJb7BEBlKA0LVGhT0dL9QI2W+TSaiWo1+qT9"
    "QbZGh+KZOILlPgOwXNicpSyvhBqU8lnL1Bqd0hQ3M72MnQFQBDPTe4PmwNiZ6WCe0kAqM0gNaVoATLq56CwoUeRaAuTlK01q"
    "pGBSGrIIk1xpyjYOAzFoogQ084DRkJUxx0CohkePnJNJGtHWLljIFsaNANHoK1xiV5jIeQTIyicziYWgiQ9Uylx0phJJ9MnR"
    "1gEtOhbvfsxdHD+SwxxjZw/uMA8FarwkRRoP6Tf1YrPYLA6bzX4l6PZS2MnpfBl8M/hmaCd6BLvUMTw4xvm7hkoHFjjkLgWg"
    "EP0PuEqn9QAyVGNwBSDGXZopACJ/PpCjikPq4QISgLu0O5oqRMJw0MuuUmrnvnZehZ4B4Ix9plsew/vaeZQPI5ULQZxPoV4A"
    "epUgIKHoEJrhVFxCo1gfwOqB1omQhrFFINqzcMjb1Yai1Up8kFbhMCEQXRACqaiwhIM0gsAIFxSou7QC+RAUjhSCXvHIzw0f"
    "IBKKWDGCwjABiBMVNqE5cRgICOO5MoufFoCgaXwhEEreuseQuNgHBNQKkEufQtwF8C4AKUea7SoCo3wKgZsACKELOIRUpfbd"
    "cpcuduzbSuf2t7CYrWR5yifJvJJQzSJTsIBXmhtoSgft/Nd8bguf38znc5pEz0TsP0Wcp15PvNiPfR74Wjm/e3G59/3a+Xf7"
    "uNwJbHW95Wt1u+lrdW8M5P4WyGvwc633c7sRXhfO/jWcc83X6nnV1+r1i8jvisi/NuZRn59FQTWi4Eu+1n4/+Vr7X3QWcs4+"
    "zBleswfbcTy8EqU8VHSyWBwOqzvP9RaHiyLXczh3Oe4cTpRTv6m/vfZCJVeSKE3B5bm98bjOtbE7wuqes22dNjaXx37Dbh/+"
    "60t77/vOjKlvwCR72StnAa5N0GbzfGZlsazOiHq+U7XXSF1q6xAnecFnErSCJ/VSACmPxwN8HpfH47LQXeICLpd5eL/zwhRZ"
    "gMdlDqf9etjaXdqcBXjaxH8kpaS+XyHCURNTjsuUmjZ5bMro9wqPPd4X80xLHps0PrGLfZtDXsDqKk9Kc6rM7/623+QYy2Vp"
    "Y7qYgx493vafO8ap8qSErvJKh1zjGP8L8ckz9Q=="
)


def test_usd_child_is_stopped_by_its_time_limit(tmp_path):
    """The USD child process has a time limit (by default :func:`limits.usd_child_seconds`),
    so a corrupt file on which the USD library loops becomes a one-line refusal."""
    import time
    import zlib

    from gsverse_format.io.usd import read_usd

    path = tmp_path / "hang.usdc"
    path.write_bytes(zlib.decompress(base64.b64decode("".join(_USD_HANG))))
    assert limits.usd_child_seconds(path.stat().st_size) == pytest.approx(
        limits.USD_CHILD_SECONDS_BASE + path.stat().st_size / 2 ** 20)
    start = time.monotonic()
    with pytest.raises(FormatError) as err:
        read_usd(path, isolate=True, timeout=3)
    assert time.monotonic() - start < 60
    message = str(err.value)
    assert message.startswith(str(path)) and "\n" not in message
