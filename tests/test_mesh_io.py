"""Reading anchor meshes: formats, node transforms, order preservation, bad input."""
from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh

from gsverse_format.errors import FormatError
from gsverse_format.examples import example_mesh, write_obj
from gsverse_format.io.mesh import read_mesh


def test_obj_keeps_vertex_and_face_order(tmp_path):
    mesh = example_mesh(subdivisions=1)
    write_obj(mesh, str(tmp_path / "m.obj"))
    back = read_mesh(tmp_path / "m.obj")
    assert np.array_equal(back.faces, mesh.faces)
    assert np.allclose(back.vertices, mesh.vertices, atol=1e-6)


@pytest.mark.parametrize("name", ["trellis/AlexHe1234_TRELLIS_sample.glb", "meshes/Fox.glb",
                                  "meshes/SimpleSkin.gltf", "meshes/trimesh_bunny_stanford_res2.ply"])
def test_real_meshes_match_trimesh(shared_data, name):
    """Faces and vertices as trimesh reads them; a skinned glTF's vertices as glTF draws them at
    rest (skinned with the skeleton's own node values, the skinned node's transform ignored),
    which trimesh does not compute: there the reference is the tests' own numpy skinning."""
    ours = read_mesh(shared_data / name)
    ref = trimesh.load(shared_data / name, force="mesh", process=False)
    assert ours.face_count == len(ref.faces)
    want = np.asarray(ref.vertices)
    if name.endswith((".gltf", ".glb")):
        import pygltflib

        from helpers import numpy_skinning

        g = pygltflib.GLTF2().load(str(shared_data / name))
        if g.buffers[0].uri:            # a .gltf's data URIs: one blob, as in a GLB
            import base64

            parts, start = [], 0
            for k, buffer in enumerate(g.buffers):
                data = base64.b64decode(buffer.uri.split(",", 1)[1])
                for view in g.bufferViews:
                    if view.buffer == k:
                        view.buffer, view.byteOffset = 0, (view.byteOffset or 0) + start
                parts.append(data + bytes(-len(data) % 4))
                start += len(parts[-1])
            g.set_binary_blob(b"".join(parts))
        skinned = [i for i, n in enumerate(g.nodes) if n.mesh is not None and n.skin is not None]
        if skinned:
            assert len(skinned) == 1 and len(g.meshes[g.nodes[skinned[0]].mesh].primitives) == 1
            want = numpy_skinning(g, skinned[0], 0.0, animation=None)
    assert np.allclose(np.sort(ours.vertices, axis=0), np.sort(want, axis=0), atol=1e-5)


def _gltf_with_node(tmp_path, node: dict, uri: str | None = None):
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    data = v.tobytes()
    import base64
    doc = {
        "asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
        "nodes": [dict(node, mesh=0)],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "mode": 4}]}],
        "accessors": [{"bufferView": 0, "componentType": 5126, "count": 3, "type": "VEC3",
                       "min": [0, 0, 0], "max": [1, 1, 0]}],
        "bufferViews": [{"buffer": 0, "byteLength": len(data)}],
        "buffers": [{"byteLength": len(data),
                     "uri": uri or "data:application/octet-stream;base64," + base64.b64encode(data).decode()}],
    }
    path = tmp_path / "m.gltf"
    path.write_text(json.dumps(doc))
    return path


def test_gltf_node_transform_is_applied(tmp_path):
    path = _gltf_with_node(tmp_path, {"translation": [1, 2, 3], "scale": [2, 2, 2]})
    mesh = read_mesh(path)
    assert np.allclose(mesh.vertices, [[1, 2, 3], [3, 2, 3], [1, 4, 3]])


def test_gltf_mirroring_node_flips_winding(tmp_path):
    path = _gltf_with_node(tmp_path, {"scale": [-1, 1, 1]})
    mesh = read_mesh(path)
    assert list(mesh.faces[0]) == [2, 1, 0]


@pytest.mark.parametrize("uri", ["/etc/passwd", "../secret.bin", "http://example.com/x.bin",
                                 "file:///etc/passwd"])
def test_gltf_mesh_hostile_uris_are_refused(tmp_path, uri):
    path = _gltf_with_node(tmp_path, {}, uri=uri)
    with pytest.raises(FormatError) as err:
        read_mesh(path)
    assert "m.gltf" in str(err.value)


@pytest.mark.parametrize("text,cause", [
    ("v 0 0 0\nv 1 0 0\nf 1 2 9\n", ""),
    ("v 0 0 nan\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", "NaN"),
    ("v 0 0 0\n", ""),
])
def test_bad_obj(tmp_path, text, cause):
    path = tmp_path / "bad.obj"
    path.write_text(text)
    with pytest.raises(FormatError) as err:
        read_mesh(path)
    assert "bad.obj" in str(err.value) and cause in str(err.value)


def test_unknown_extension(tmp_path):
    path = tmp_path / "m.fbx"
    path.write_bytes(b"x")
    with pytest.raises(FormatError):
        read_mesh(path)


def _ply_mesh(path, fmt, faces_prop, *, extra_vertex=False):
    """A small PLY mesh (4 vertices, 2 triangles) with a chosen face list declaration."""
    verts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0.5]], np.float32)
    faces = np.array([[0, 1, 2], [1, 3, 2]])
    ctype, itype, name = faces_prop
    codes = {"uchar": "u1", "int": "i4", "uint": "u4", "ushort": "u2"}
    props = ["x", "y", "z"] + (["confidence"] if extra_vertex else [])
    head = [f"ply\nformat {fmt} 1.0\nelement vertex 4"]
    head += [f"property float {p}" for p in props]
    head += ["element face 2", f"property list {ctype} {itype} {name}", "property uchar flag",
             "end_header\n"]
    rows_v = np.concatenate([verts, np.full((4, 1), 0.25, np.float32)], 1) if extra_vertex else verts
    if fmt == "ascii":
        body = "".join(" ".join(repr(float(v)) for v in row) + "\n" for row in rows_v)
        body += "".join(f"3 {a} {b} {c} 7\n" for a, b, c in faces)
        data = body.encode()
    else:
        rows = np.zeros(2, [("n", codes[ctype]), ("v", codes[itype], (3,)), ("flag", "u1")])
        rows["n"], rows["v"], rows["flag"] = 3, faces, 7
        data = rows_v.astype("<f4").tobytes() + rows.tobytes()
    path.write_bytes("\n".join(head).encode() + data)
    return verts, faces


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian"])
@pytest.mark.parametrize("faces_prop", [("uchar", "int", "vertex_indices"),
                                        ("uchar", "uint", "vertex_index"),
                                        ("int", "int", "vertex_indices"),
                                        ("uchar", "ushort", "vertex_index")])
def test_ply_meshes_read_strictly_and_match_trimesh(tmp_path, monkeypatch, fmt, faces_prop):
    path = tmp_path / "m.ply"
    verts, faces = _ply_mesh(path, fmt, faces_prop, extra_vertex=True)
    ref = trimesh.load(path, force="mesh", process=False, maintain_order=True)

    def refuse(*args, **kwargs):
        raise AssertionError("PLY meshes must not go through trimesh")

    monkeypatch.setattr(trimesh, "load", refuse)
    mesh = read_mesh(path)
    assert np.array_equal(mesh.vertices, verts) and np.array_equal(mesh.faces, faces)
    assert np.array_equal(mesh.vertices, np.asarray(ref.vertices, np.float32))
    assert np.array_equal(mesh.faces, np.asarray(ref.faces))


def test_ply_mesh_polygons_and_bad_input(tmp_path):
    quads = (b"ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\n"
             b"property float z\nelement face 1\nproperty list uchar int vertex_indices\n"
             b"end_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n4 0 1 2 3\n")
    (tmp_path / "q.ply").write_bytes(quads)
    assert read_mesh(tmp_path / "q.ply").faces.tolist() == [[0, 1, 2], [0, 2, 3]]
    for name, data, cause in [
        ("far.ply", quads.replace(b"4 0 1 2 3", b"4 0 1 2 9"), "face indices"),
        ("nan.ply", quads.replace(b"1 1 0\n", b"1 nan 0\n"), "NaN"),
        ("cut.ply", quads[:-4], "ascii data ends early"),
        ("cloud.ply", quads.split(b"element face")[0] + b"end_header\n0 0 0\n1 0 0\n1 1 0\n0 1 0\n",
         "no 'face' element"),
    ]:
        (tmp_path / name).write_bytes(data)
        with pytest.raises(FormatError) as err:
            read_mesh(tmp_path / name)
        assert name in str(err.value) and cause in str(err.value) and "\n" not in str(err.value)
