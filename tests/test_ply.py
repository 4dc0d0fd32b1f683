"""PLY reader/writer: generic parsing, the 3DGS layout, round-trip accuracy, hostile input."""
from __future__ import annotations

import copy
import os
import time
import tracemalloc
import warnings

import numpy as np
import pytest

from gsverse_format.errors import FormatError, UsageError
from gsverse_format.io.ply import (OPACITY_CLAMP, SH_C0, describe_ply, ply_triangles,
                                   read_ply_elements, read_ply_header, read_ply_mesh,
                                   read_splat_means, read_splat_ply, write_ply, write_splat_ply)
from gsverse_format.io.registry import FORMATS as FORMAT_TABLE
from gsverse_format.model import SplatAsset, SplatCloud, SplatPrimitive

# PLY type name -> numpy code, independent of the module under test.
TYPES = {"char": "i1", "uchar": "u1", "short": "i2", "ushort": "u2", "int": "i4", "uint": "u4",
         "float": "f4", "double": "f8", "int8": "i1", "uint8": "u1", "int16": "i2",
         "uint16": "u2", "int32": "i4", "uint32": "u4", "float32": "f4", "float64": "f8"}
FORMATS = {"ascii": None, "binary_little_endian": "<", "binary_big_endian": ">"}
ALL_FORMATS = list(FORMATS)


# --------------------------------------------------------------------------------------------
# A tiny independent PLY writer for fixtures.

def _fmt_value(value, code: str) -> str:
    if code[0] == "f":
        return repr(float(value))
    return str(int(value))


def raw_ply(fmt: str, elements, *, comments=(), obj_info=()) -> bytes:
    """``elements``: list of (name, count, props); a prop is (type, name, values) for a scalar
    or ("list <ctype> <itype>", name, list_of_sequences)."""
    lines = ["ply", f"format {fmt} 1.0", *(f"comment {c}" for c in comments),
             *(f"obj_info {c}" for c in obj_info)]
    body = []
    order = FORMATS[fmt]
    for name, count, props in elements:
        lines.append(f"element {name} {count}")
        for ptype, pname, _ in props:
            lines.append(f"property {ptype} {pname}")
        for row in range(count):
            parts_b, parts_a = [], []
            for ptype, _, values in props:
                if ptype.startswith("list"):
                    _, ctype, itype = ptype.split()
                    items = list(values[row])
                    if order:
                        parts_b.append(np.array([len(items)], order + TYPES[ctype]).tobytes())
                        parts_b.append(np.array(items, order + TYPES[itype]).tobytes())
                    parts_a += [str(len(items))] + [_fmt_value(v, TYPES[itype]) for v in items]
                else:
                    code = TYPES[ptype]
                    if order:
                        parts_b.append(np.array([values[row]], order + code).tobytes())
                    parts_a.append(_fmt_value(np.asarray(values[row], code), code))
            body.append(b"".join(parts_b) if order else (" ".join(parts_a) + "\n").encode())
    lines.append("end_header")
    return ("\n".join(lines) + "\n").encode() + b"".join(body)


def splat_props(n: int, degree: int = 0, *, normals: bool = False, extras=(), seed: int = 0,
                shuffle: bool = False) -> list:
    """Scalar properties of a random 3DGS vertex element (pre-activation float32 values)."""
    rng = np.random.default_rng(seed)
    f = lambda v: np.asarray(v, np.float32)  # noqa: E731
    props = [("float", a, f(rng.uniform(-3, 3, n))) for a in "xyz"]
    if normals:
        props += [("float", a, f(rng.normal(size=n))) for a in ("nx", "ny", "nz")]
    props += [("float", f"f_dc_{c}", f(rng.normal(0, 1, n))) for c in range(3)]
    props += [("float", f"f_rest_{i}", f(rng.normal(0, 0.3, n)))
              for i in range(3 * ((degree + 1) ** 2 - 1))]
    logits = rng.uniform(-10, 12, n)
    logits[:8] = [0.0, -2.0, 2.0, 16.0, 17.5, 30.0, -60.0, 5.0][:n]
    props.append(("float", "opacity", f(logits)))
    for i in range(3):
        log_scale = rng.uniform(-12, 3, n)
        log_scale[:6] = [0.0, -1.0, 1.0, -0.3, -80.0, 40.0][:n]
        props.append(("float", f"scale_{i}", f(log_scale)))
    q = rng.normal(size=(n, 4)) * rng.uniform(0.5, 2.0, (n, 1))
    props += [("float", f"rot_{i}", f(q[:, i])) for i in range(4)]
    for name, ptype in extras:
        code = TYPES[ptype]
        values = rng.integers(0, 100, n) if code[0] in "iu" else rng.normal(size=n)
        props.append((ptype, name, np.asarray(values).astype(code)))
    if shuffle:
        props = [props[i] for i in rng.permutation(len(props))]
    return props


def write(tmp_path, name: str, data: bytes):
    path = tmp_path / name
    path.write_bytes(data)
    return path


def splat_file(tmp_path, fmt="binary_little_endian", name="s.ply", n=50, **kw):
    return write(tmp_path, name, raw_ply(fmt, [("vertex", n, splat_props(n, **kw))]))


def expect_error(path, *, match: str | None = None, reader=read_splat_ply) -> FormatError:
    with pytest.raises(FormatError) as info:
        reader(path)
    text = str(info.value)
    assert os.path.basename(os.fspath(path)) in text
    assert "\n" not in text
    if match is not None:
        assert match in text, text
    return info.value


def ulp(values) -> np.ndarray:
    return np.spacing(np.abs(np.asarray(values, np.float32))).astype(np.float64)


def sigmoid(x) -> np.ndarray:
    return 1.0 / (1.0 + np.exp(-np.asarray(x, np.float64)))


# --------------------------------------------------------------------------------------------
# Round-trip accuracy (the bounds documented in the module docstring)


def check_round_trip(before: np.ndarray, after: np.ndarray) -> None:
    """``after`` is the vertex element re-written from ``read_splat_ply(before)``."""
    names = before.dtype.names
    for name in names:
        if name in ("nx", "ny", "nz") or name.startswith(("opacity", "scale_", "rot_")):
            continue
        assert np.array_equal(after[name], before[name].astype(np.float32)), name
    # log-scales: |L' - L| <= 2^-24 + ulp(L)/2 on the normal float32 range, exact for |L| > 1
    for i in range(3):
        a = before[f"scale_{i}"].astype(np.float64)
        b = after[f"scale_{i}"].astype(np.float64)
        normal = (a >= -87.3) & (a <= 88.7)
        assert np.all(np.abs(b - a)[normal] <= 2.0 ** -24 + ulp(a)[normal] / 2)
        assert np.all(np.abs(b - a)[normal] <= 2.0 ** -23)
        assert np.array_equal(a[normal & (np.abs(a) > 1)], b[normal & (np.abs(a) > 1)])
    # opacity logits: |L' - L| <= 2^-24 (1 + e^L) + ulp(L) where the opacity is resolvable,
    # and the decoded opacity within one float32 step everywhere
    a = before["opacity"].astype(np.float64)
    b = after["opacity"].astype(np.float64)
    ok = (a >= -87.3) & (a <= 16.6)
    bound = 2.0 ** -24 * (1.0 + np.exp(np.minimum(a, 16.6))) + ulp(a)
    assert np.all(np.abs(b - a)[ok] <= bound[ok])
    assert np.array_equal(a[ok & (a < -2)], b[ok & (a < -2)])
    assert np.max(np.abs(sigmoid(b) - sigmoid(a)), initial=0) <= 2.0 ** -24
    assert np.all(b[a > 17.4] == np.float32(np.log(OPACITY_CLAMP[1] / (1 - OPACITY_CLAMP[1]))))
    # quaternions: re-written normalized, within 2^-24 per component
    q = np.stack([before[f"rot_{i}"] for i in range(4)], axis=1).astype(np.float64)
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    q2 = np.stack([after[f"rot_{i}"] for i in range(4)], axis=1).astype(np.float64)
    assert np.max(np.abs(q2 - q), initial=0) <= 2.0 ** -24


@pytest.mark.parametrize("fmt", ALL_FORMATS)
@pytest.mark.parametrize("degree", [0, 1, 2, 3])
@pytest.mark.parametrize("normals", [False, True])
def test_round_trip_generated(tmp_path, fmt, degree, normals):
    extras = [("filter_3D", "float"), ("binding_0", "int")] if degree % 2 else []
    src = splat_file(tmp_path, fmt, n=80, degree=degree, normals=normals, extras=extras,
                     seed=degree, shuffle=normals)
    cloud = read_splat_ply(src)
    assert cloud.sh_degree == degree and len(cloud) == 80
    assert set(cloud.extra) == {e[0] for e in extras}
    out = tmp_path / "out.ply"
    order = ">" if fmt == "binary_big_endian" else "<"
    write_splat_ply(cloud, out, binary=fmt != "ascii", byte_order=order, normals=normals)
    assert read_ply_header(out).format == fmt
    before = read_ply_elements(src)["vertex"]
    after = read_ply_elements(out)["vertex"]
    assert set(after.dtype.names) == set(before.dtype.names)
    check_round_trip(before, after)
    # and reading the re-written file gives the same model up to the stated tolerances
    again = read_splat_ply(out)
    assert np.array_equal(again.means, cloud.means) and np.array_equal(again.sh, cloud.sh)
    for name in cloud.extra:
        assert np.array_equal(again.extra[name], cloud.extra[name])
    np.testing.assert_allclose(again.rotations, cloud.rotations, rtol=0, atol=2e-7)


REAL = ["donut_mipsplatting_sh0_fused.ply", "404gen_tmp_model_dreamgaussian_sh0.ply",
        "schwa_test-splat.3-points-from-train.ply"]


@pytest.mark.parametrize("name", REAL)
def test_round_trip_real_files(shared_data, tmp_path, name):
    src = shared_data / "3dgs" / name
    if not src.is_file():
        pytest.skip(f"{name} not present")
    info = describe_ply(src)
    cloud = read_splat_ply(src)
    assert len(cloud) == info["count"] and cloud.sh_degree == info["sh_degree"]
    assert np.allclose(np.linalg.norm(cloud.rotations, axis=1), 1, atol=1e-6)
    out = tmp_path / "out.ply"
    write_splat_ply(cloud, out, normals=info["has_normals"])
    before = read_ply_elements(src)["vertex"]
    after = read_ply_elements(out)["vertex"]
    assert after.dtype.names == before.dtype.names  # same layout and order as the source
    check_round_trip(before, after)


def test_real_file_facts(shared_data):
    folder = shared_data / "3dgs"
    if not (folder / REAL[2]).is_file():
        pytest.skip("sample files not present")
    small = describe_ply(folder / REAL[2])
    assert small == {"format": "binary_little_endian", "count": 3, "sh_degree": 3,
                     "has_normals": True, "color": "f_dc", "extra": [],
                     "elements": {"vertex": 3}, "comments": []}
    raw = read_ply_elements(folder / REAL[2])["vertex"]
    cloud = read_splat_ply(folder / REAL[2])
    # channel-major f_rest: coefficient j of channel c is f_rest_{c*15 + j-1}
    for c in range(3):
        for j in range(1, 16):
            assert np.array_equal(cloud.sh[:, j, c], raw[f"f_rest_{c * 15 + j - 1}"])
    dream = folder / REAL[1]
    if dream.is_file():
        raw = read_ply_elements(dream)["vertex"]
        norms = np.linalg.norm(np.stack([raw[f"rot_{i}"] for i in range(4)], 1), axis=1)
        assert norms.min() < 0.9 and norms.max() > 1.1  # the file's quaternions are not unit
        assert np.allclose(np.linalg.norm(read_splat_ply(dream).rotations, axis=1), 1, atol=1e-6)


def test_model_to_ply_to_model(tmp_path):
    rng = np.random.default_rng(3)
    n = 300
    q = rng.normal(size=(n, 4))
    cloud = SplatCloud(rng.normal(size=(n, 3)), q / np.linalg.norm(q, axis=1, keepdims=True),
                       np.exp(rng.uniform(-8, 1, (n, 3))), rng.uniform(0, 1, n),
                       rng.normal(size=(n, 16, 3)), extra={"w": rng.normal(size=n)})
    cloud.opacities[:4] = [0.0, 1.0, 0.5, np.float32(1 - 2 ** -24)]
    cloud.scales[0] = [0.0, 2.0 ** -149, 1.0]
    out = tmp_path / "m.ply"
    write_splat_ply(cloud, out)
    raw = read_ply_elements(out)["vertex"]
    assert all(np.all(np.isfinite(raw[n])) for n in raw.dtype.names)
    back = read_splat_ply(out)
    assert np.array_equal(back.means, cloud.means) and np.array_equal(back.sh, cloud.sh)
    assert np.array_equal(back.extra["w"], cloud.extra["w"])
    assert np.array_equal(back.opacities[:4], cloud.opacities[:4])   # 0 and 1 survive exactly
    assert np.array_equal(back.scales[0], cloud.scales[0])            # so do 0 and subnormals
    np.testing.assert_allclose(back.opacities, cloud.opacities, rtol=2e-6, atol=0)
    np.testing.assert_allclose(back.scales, cloud.scales, rtol=2e-6, atol=0)
    np.testing.assert_allclose(back.rotations, cloud.rotations, rtol=0, atol=1.5e-7)


# --------------------------------------------------------------------------------------------
# Layout details on hand-made files


def test_formats_read_identically(tmp_path):
    props = splat_props(40, degree=2, normals=True, extras=[("filter_3D", "float")], seed=9)
    clouds = [read_splat_ply(write(tmp_path, f"{fmt}.ply", raw_ply(fmt, [("vertex", 40, props)])))
              for fmt in ALL_FORMATS]
    for other in clouds[1:]:
        for attr in ("means", "rotations", "scales", "opacities", "sh"):
            assert np.array_equal(getattr(other, attr), getattr(clouds[0], attr)), attr
        assert np.array_equal(other.extra["filter_3D"], clouds[0].extra["filter_3D"])


@pytest.mark.parametrize("shuffle", [False, True])
def test_means_alone_are_the_means_of_the_full_read(tmp_path, shuffle):
    """``read_splat_means`` (source detection's read) gives ``read_splat_ply``'s means in every
    format and property order (x, y, z scattered among the others: the copying path), NaN
    included, and refuses what is not a splat PLY as the full read does."""
    props = splat_props(60, degree=3, shuffle=shuffle, seed=4)
    for fmt in ALL_FORMATS:
        path = write(tmp_path, f"{fmt}.ply", raw_ply(fmt, [("vertex", 60, props)]))
        means = read_splat_means(path)
        assert means.dtype == np.float32 and means.shape == (60, 3)
        assert np.array_equal(means, read_splat_ply(path).means), fmt
    nan_props = [(t, name, np.where(np.arange(60) == 7, np.nan, v) if name == "y" else v)
                 for t, name, v in props]
    nan_path = write(tmp_path, "nan.ply", raw_ply("binary_little_endian",
                                                   [("vertex", 60, nan_props)]))
    assert np.isnan(read_splat_means(nan_path)[7, 1])
    no_rot = [p for p in props if not p[1].startswith("rot_")]
    bad = write(tmp_path, "bad.ply", raw_ply("binary_little_endian", [("vertex", 60, no_rot)]))
    full = expect_error(bad)
    alone = expect_error(bad, reader=read_splat_means)
    assert str(alone) == str(full)


def test_f_rest_channel_major(tmp_path):
    n, k = 2, 9                                 # degree 2: 24 f_rest values
    rest = [(("float", f"f_rest_{i}", np.array([100 + i, 200 + i], np.float32))) for i in range(24)]
    rest = rest[::-1]                           # declared out of order: f_rest_23 … f_rest_0
    base = [p for p in splat_props(n) if not p[1].startswith("f_rest")]
    path = write(tmp_path, "rest.ply", raw_ply("binary_little_endian",
                                               [("vertex", n, base[:6] + rest + base[6:])]))
    cloud = read_splat_ply(path)
    assert cloud.sh.shape == (2, 9, 3)
    for c in range(3):
        for j in range(1, k):
            assert cloud.sh[0, j, c] == 100 + c * (k - 1) + (j - 1)
            assert cloud.sh[1, j, c] == 200 + c * (k - 1) + (j - 1)
    # the writer uses the same mapping
    out = tmp_path / "out.ply"
    write_splat_ply(cloud, out)
    raw = read_ply_elements(out)["vertex"]
    assert [n for n in raw.dtype.names if n.startswith("f_rest")] == [f"f_rest_{i}" for i in range(24)]
    for i in range(24):
        assert raw[f"f_rest_{i}"][0] == 100 + i


def test_quaternion_reorder_and_normalization(tmp_path):
    rot = [np.array(v, np.float32) for v in ([2.0, 1.0, -0.5], [0.0, 2.0, 0.5],
                                             [0.0, 3.0, 0.5], [0.0, 4.0, 0.5])]
    base = [p for p in splat_props(3) if not p[1].startswith("rot_")]
    props = base + [("float", f"rot_{i}", rot[i]) for i in range(4)]
    cloud = read_splat_ply(write(tmp_path, "q.ply", raw_ply("binary_little_endian",
                                                            [("vertex", 3, props)])))
    expected = np.array([[0, 0, 0, 1], np.array([2, 3, 4, 1]) / np.sqrt(30),
                         np.array([0.5, 0.5, 0.5, -0.5])], np.float32)
    np.testing.assert_allclose(cloud.rotations, expected, atol=1e-7)
    out = tmp_path / "out.ply"
    write_splat_ply(cloud, out)
    raw = read_ply_elements(out)["vertex"]
    np.testing.assert_array_equal(np.stack([raw[f"rot_{i}"] for i in range(4)], 1),
                                  cloud.rotations[:, [3, 0, 1, 2]])


def test_activations(tmp_path):
    base = [p for p in splat_props(5) if p[1] not in ("opacity", "scale_0", "scale_1", "scale_2")]
    logits = np.array([0.0, 1000.0, -1000.0, np.log(3.0), -50.0], np.float32)
    log_scales = np.array([0.0, np.log(0.5), -200.0, 2.0, -10.0], np.float32)
    props = base + [("float", "opacity", logits)] + \
        [("float", f"scale_{i}", log_scales) for i in range(3)]
    path = write(tmp_path, "a.ply", raw_ply("binary_little_endian", [("vertex", 5, props)]))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        cloud = read_splat_ply(path)
    np.testing.assert_allclose(cloud.opacities, [0.5, 1.0, 0.0, 0.75, np.exp(-50.0)], rtol=1e-6)
    np.testing.assert_array_equal(cloud.scales[:, 0],
                                  np.exp(log_scales.astype(np.float64)).astype(np.float32))
    assert cloud.scales[2, 0] == 0.0


def test_rgb_fallback_extras_normals(tmp_path):
    n = 4
    base = [p for p in splat_props(n, normals=True) if not p[1].startswith("f_dc")]
    rgb = [("uchar", c, np.array([0, 255, 128, 64], np.uint8)) for c in ("red", "green", "blue")]
    extras = [("float", "filter_3D", np.arange(n, dtype=np.float32) / 7),
              ("int", "binding_0", np.array([-1, 0, 5, 70000], np.int32)),
              ("uchar", "flag", np.array([1, 2, 3, 4], np.uint8))]
    path = write(tmp_path, "rgb.ply", raw_ply("binary_big_endian", [("vertex", n, base + rgb + extras)]))
    cloud = read_splat_ply(path)
    expected = (np.array([0, 255, 128, 64]) / 255 - 0.5) / SH_C0
    np.testing.assert_allclose(cloud.sh[:, 0, 1], expected, rtol=1e-6)
    assert list(cloud.extra) == ["filter_3D", "binding_0", "flag"]
    assert all(v.dtype == np.float32 for v in cloud.extra.values())
    assert np.array_equal(cloud.extra["binding_0"], [-1, 0, 5, 70000])
    info = describe_ply(path)
    assert info["color"] == "rgb" and info["has_normals"] and info["extra"] == list(cloud.extra)
    assert info["format"] == "binary_big_endian" and info["sh_degree"] == 0


def test_comments_obj_info_all_scalar_types(tmp_path):
    rng = np.random.default_rng(0)
    names = ["char", "uchar", "short", "ushort", "int", "uint", "float", "double",
             "int8", "uint8", "int16", "uint16", "int32", "uint32", "float32", "float64"]
    props = []
    for i, t in enumerate(names):
        code = TYPES[t]
        if code[0] == "f":
            values = rng.normal(size=5).astype(code)
        else:
            info = np.iinfo(code)
            values = np.array([info.min, info.max, 0, 1, info.max // 3], code)
        props.append((t, f"p{i}", values))
    for fmt in ALL_FORMATS:
        path = write(tmp_path, f"{fmt}.ply", raw_ply(fmt, [("thing", 5, props), ("empty", 0, props)],
                                                     comments=["hello world", ""],
                                                     obj_info=["made by hand"]))
        data = read_ply_elements(path)
        assert data.format == fmt and data.comments == ["hello world", ""]
        assert data.header.obj_info == ["made by hand"]
        thing = data["thing"]
        for t, name, values in props:
            assert thing.dtype[name] == np.dtype(TYPES[t]) and thing.dtype[name].isnative
            assert np.array_equal(thing[name], values), (fmt, t)
        assert len(data["empty"]) == 0


@pytest.mark.parametrize("fmt", ALL_FORMATS)
def test_mesh_with_faces(tmp_path, fmt):
    verts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [1, 1, 0]], np.float32)
    faces = [[0, 1, 2], [1, 3, 2]]
    vprops = [("float", a, verts[:, i]) for i, a in enumerate("xyz")]
    fprops = [("list uchar int", "vertex_indices", faces), ("uchar", "material", [7, 8])]
    path = write(tmp_path, "m.ply", raw_ply(fmt, [("vertex", 4, vprops), ("face", 2, fprops)]))
    data = read_ply_elements(path)
    assert data["face"].dtype["vertex_indices"].shape == (3,)
    assert np.array_equal(ply_triangles(data), faces)
    assert np.array_equal(data["face"]["material"], [7, 8])
    mesh = read_ply_mesh(path)
    assert np.array_equal(mesh.faces, faces) and np.array_equal(mesh.vertices, verts)
    # a splat read of a mesh file explains itself
    expect_error(path, match="not a Gaussian splat PLY")
    # polygons of mixed sizes are parsed (object field) but are not triangles
    mixed = [("list uchar uint", "vertex_index", [[0, 1, 2], [0, 1, 3, 2], []])]
    path = write(tmp_path, "poly.ply", raw_ply(fmt, [("vertex", 4, vprops), ("face", 3, mixed),
                                                     ("tail", 1, [("short", "v", [-3])])]))
    data = read_ply_elements(path)
    assert data["face"].dtype["vertex_index"] == object
    assert [list(v) for v in data["face"]["vertex_index"]] == [[0, 1, 2], [0, 1, 3, 2], []]
    assert data["tail"]["v"][0] == -3
    expect_error(path, match="not all triangles", reader=read_ply_mesh)


@pytest.mark.parametrize("fmt", ALL_FORMATS)
def test_mesh_polygons_triangulated_on_request(tmp_path, fmt):
    verts = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0], [2, 0, 0], [2, 1, 0]], np.float32)
    vprops = [("float", a, verts[:, i]) for i, a in enumerate("xyz")]
    quads = [("list uchar uint", "vertex_index", [[0, 1, 2, 3], [1, 4, 5, 2]])]
    path = write(tmp_path, "quads.ply", raw_ply(fmt, [("vertex", 6, vprops), ("face", 2, quads)]))
    expect_error(path, match="4 vertices each", reader=read_ply_mesh)
    mesh = read_ply_mesh(path, triangulate=True)      # fan per polygon, in file order
    assert mesh.faces.tolist() == [[0, 1, 2], [0, 2, 3], [1, 4, 5], [1, 5, 2]]
    mixed = [("list uchar int", "vertex_indices", [[0, 1, 2], [0, 1, 4, 5, 2], [2, 5, 3]])]
    path = write(tmp_path, "mixed.ply", raw_ply(fmt, [("vertex", 6, vprops), ("face", 3, mixed)]))
    mesh = read_ply_mesh(path, triangulate=True)
    assert mesh.faces.tolist() == [[0, 1, 2], [0, 1, 4], [0, 4, 5], [0, 5, 2], [2, 5, 3]]
    short = [("list uchar int", "vertex_indices", [[0, 1, 2], [0, 1]])]
    path = write(tmp_path, "short.ply", raw_ply(fmt, [("vertex", 6, vprops), ("face", 2, short)]))
    expect_error(path, match="face 1 has 2 vertices",
                 reader=lambda p: read_ply_mesh(p, triangulate=True))


def test_mesh_refusals(tmp_path):
    verts = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    vprops = [("float", a, verts[:, i]) for i, a in enumerate("xyz")]

    def mesh_file(name, faces, vertex=vprops, count=3):
        elements = [("vertex", count, vertex)] + ([("face", len(faces[0][2]), faces)] if faces else [])
        return write(tmp_path, name, raw_ply("ascii", elements))

    tri = [("list uchar int", "vertex_indices", [[0, 1, 2]])]
    expect_error(mesh_file("far.ply", [("list uchar int", "vertex_indices", [[0, 1, 3]])]),
                 match="face indices", reader=read_ply_mesh)
    expect_error(mesh_file("neg.ply", [("list uchar int", "vertex_indices", [[0, 1, -1]])]),
                 match="face indices", reader=read_ply_mesh)
    expect_error(mesh_file("float.ply", [("list uchar float", "vertex_indices", [[0, 1, 2]])]),
                 match="list of integers", reader=read_ply_mesh)
    expect_error(mesh_file("cloud.ply", None), match="no 'face' element", reader=read_ply_mesh)
    expect_error(mesh_file("noxyz.ply", tri, vertex=vprops[:2]), match="x, y, z", reader=read_ply_mesh)
    nan = [("float", "x", [0, 1, np.nan])] + vprops[1:]
    expect_error(mesh_file("nan.ply", tri, vertex=nan), match="1 vertices with NaN",
                 reader=read_ply_mesh)
    huge = [("double", "x", [0, 1, 1e300])] + vprops[1:]
    expect_error(mesh_file("huge.ply", tri, vertex=huge), match="float32 range", reader=read_ply_mesh)
    expect_error(mesh_file("none.ply", [("list uchar int", "vertex_indices", [])]),
                 match="no faces", reader=read_ply_mesh)


def test_bunny_mesh(shared_data):
    path = shared_data / "meshes" / "trimesh_bunny_stanford_res2.ply"
    if not path.is_file():
        pytest.skip("bunny not present")
    data = read_ply_elements(path)
    assert data.format == "ascii" and data.comments == ["zipper output"]
    mesh = read_ply_mesh(path)
    assert mesh.vertices.shape == (8171, 3) and mesh.faces.shape == (16301, 3)


# --------------------------------------------------------------------------------------------
# Writer options and refusals


def test_writer_ascii_and_big_endian_equal_little(tmp_path):
    cloud = read_splat_ply(splat_file(tmp_path, n=30, degree=1, extras=[("filter_3D", "float")]))
    outputs = {}
    for label, kw in {"le": {}, "be": {"byte_order": ">"}, "ascii": {"binary": False}}.items():
        outputs[label] = tmp_path / f"{label}.ply"
        write_splat_ply(cloud, outputs[label], **kw)
    header = outputs["le"].read_bytes().split(b"end_header\n")[0].decode()
    assert "format binary_big_endian 1.0" in outputs["be"].read_text(errors="replace")
    assert "format binary_little_endian 1.0" in header and "property float filter_3D" in header
    assert header.splitlines()[-1] == "property float filter_3D"   # extras follow rot_3
    assert header.splitlines()[-2] == "property float rot_3"
    raw = {k: read_ply_elements(v)["vertex"] for k, v in outputs.items()}
    assert np.array_equal(raw["le"], raw["be"]) and np.array_equal(raw["le"], raw["ascii"])
    assert len(outputs["le"].read_bytes()) == \
        len(header) + len("end_header\n") + 30 * 4 * header.count("property float")


def test_writer_refusals(tmp_path):
    cloud = read_splat_ply(splat_file(tmp_path, n=5))
    out = tmp_path / "o.ply"
    with pytest.raises(UsageError):
        write_splat_ply(cloud, out, byte_order="big")
    bad = copy.deepcopy(cloud)
    bad.means[0, 0] = np.nan
    with pytest.raises(UsageError, match="NaN"):
        write_splat_ply(bad, out)
    bad = copy.deepcopy(cloud)
    bad.rotations[1] = 0
    with pytest.raises(UsageError, match="zero rotation"):
        write_splat_ply(bad, out)
    for name in ("x", "has space", "f_rest_3", ""):
        bad = copy.deepcopy(cloud)
        bad.extra = {name: np.zeros(5, np.float32)}
        with pytest.raises(UsageError):
            write_splat_ply(bad, out)
    assert not out.exists() and not [p for p in os.listdir(tmp_path) if p.startswith(".tmp")]
    src = tmp_path / "s.ply"
    before = src.read_bytes()
    with pytest.raises(UsageError):
        write_splat_ply(cloud, src, protect=(src,))
    assert src.read_bytes() == before


def test_empty_cloud(tmp_path):
    cloud = SplatCloud(np.zeros((0, 3)), np.zeros((0, 4)), np.zeros((0, 3)), np.zeros(0),
                       np.zeros((0, 4, 3)))
    for kw in ({}, {"binary": False}):
        out = tmp_path / "e.ply"
        write_splat_ply(cloud, out, **kw)
        back = read_splat_ply(out)
        assert len(back) == 0 and back.sh_degree == 1


# --------------------------------------------------------------------------------------------
# Malformed input: always a one-line FormatError naming the file


def _good(fmt="binary_little_endian", n=3, degree=0) -> bytes:
    return raw_ply(fmt, [("vertex", n, splat_props(n, degree))])


def test_truncated_binary(tmp_path):
    good = _good()
    expect_error(write(tmp_path, "cut.ply", good[:-5]), match="truncated")
    head = good.index(b"end_header") + 11
    expect_error(write(tmp_path, "nodata.ply", good[:head]), match="truncated")


def test_every_truncation_and_byte_flip(tmp_path):
    rng = np.random.default_rng(7)
    for fmt in ("binary_little_endian", "ascii"):
        good = raw_ply(fmt, [("vertex", 2, splat_props(2, 1)),
                             ("face", 2, [("list uchar int", "vertex_indices", [[0, 1, 1], [1, 0, 0]])])])
        path = tmp_path / "fuzz.ply"
        cuts = range(len(good)) if fmt != "ascii" else rng.integers(0, len(good), 150)
        for cut in cuts:
            path.write_bytes(good[:cut])
            expect_error(path)
        for _ in range(200):
            data = bytearray(good)
            for pos in rng.integers(0, len(data), rng.integers(1, 4)):
                data[pos] = int(rng.integers(0, 256))
            path.write_bytes(bytes(data))
            try:
                read_splat_ply(path)
                read_ply_elements(path)
            except FormatError as exc:
                assert "fuzz.ply" in str(exc) and "\n" not in str(exc)


def test_header_without_end_header(tmp_path):
    expect_error(write(tmp_path, "h.ply", b"ply\nformat ascii 1.0\nelement vertex 0\n"),
                 match="end_header")
    expect_error(write(tmp_path, "h2.ply", b"ply\nformat binary_little_endian 1.0\n" + bytes(64)),
                 match="end_header")


def test_count_larger_than_data(tmp_path):
    good = _good(n=3)
    bigger = good.replace(b"element vertex 3", b"element vertex 4")
    expect_error(write(tmp_path, "more.ply", bigger), match="vertex")
    ascii_bigger = _good("ascii", n=3).replace(b"element vertex 3", b"element vertex 4")
    expect_error(write(tmp_path, "more_ascii.ply", ascii_bigger), match="ascii")
    smaller = good.replace(b"element vertex 3", b"element vertex 2")
    expect_error(write(tmp_path, "less.ply", smaller), match="after the last element")
    ascii_smaller = _good("ascii", n=3).replace(b"element vertex 3", b"element vertex 2")
    expect_error(write(tmp_path, "less_ascii.ply", ascii_smaller), match="after the last element")


@pytest.mark.parametrize("fmt", ALL_FORMATS)
def test_huge_count_does_not_allocate(tmp_path, fmt):
    data = _good(fmt, n=3).replace(b"element vertex 3", b"element vertex 1000000000000")
    path = write(tmp_path, "huge.ply", data)
    tracemalloc.start()
    start = time.perf_counter()
    try:
        expect_error(path, match="1000000000000")
        expect_error(path, reader=read_ply_elements)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    assert peak < 8 << 20 and time.perf_counter() - start < 1.0
    faces = raw_ply(fmt, [("face", 0, [("list uchar int", "vertex_indices", [])])])
    path = write(tmp_path, "hugefaces.ply", faces.replace(b"face 0", b"face 99999999999"))
    expect_error(path, reader=read_ply_elements)
    path = write(tmp_path, "absurd.ply", data.replace(b"1000000000000", b"9" * 5000))
    expect_error(path, reader=read_ply_elements, match="large")


def test_list_property_in_vertex(tmp_path):
    props = splat_props(2) + [("list uchar float", "weights", [[1.0], [2.0, 3.0]])]
    path = write(tmp_path, "list.ply", raw_ply("binary_little_endian", [("vertex", 2, props)]))
    expect_error(path, match="'weights' is a list")
    assert len(read_ply_elements(path)["vertex"]) == 2   # the generic reader copes


@pytest.mark.parametrize("fmt", ALL_FORMATS)
def test_nan_and_inf_values(tmp_path, fmt):
    props = splat_props(6, 1)
    values = dict((p[1], p[2]) for p in props)
    values["opacity"][[1, 4]] = np.nan
    values["f_rest_3"][2] = np.inf
    values["x"][0] = -np.inf
    path = write(tmp_path, "nan.ply", raw_ply(fmt, [("vertex", 6, props)]))
    err = expect_error(path, match="4 NaN or Inf values")
    assert "opacity (2 rows)" in str(err) and "f_rest_3 (1 row)" in str(err) and "x (1 row)" in str(err)


def test_garbage_and_non_ply(tmp_path):
    rng = np.random.default_rng(1)
    expect_error(write(tmp_path, "garbage.ply", rng.bytes(4096)), match="not a PLY file")
    expect_error(write(tmp_path, "garbage2.ply", b"ply\n" + rng.bytes(4096)))
    expect_error(write(tmp_path, "empty.ply", b""), match="empty")
    expect_error(tmp_path / "missing.ply", match="not found")
    (tmp_path / "dir.ply").mkdir()
    expect_error(tmp_path / "dir.ply")


@pytest.mark.parametrize("header, match", [
    (b"ply\nformat ascii 1.0\ncomment caf\xc3\xa9\nend_header\n", "non-ASCII"),
    (b"ply\nformat binary_middle_endian 1.0\nend_header\n", "unknown PLY format"),
    (b"ply\nformat ascii 2.0\nend_header\n", "version"),
    (b"ply\nelement vertex 0\nproperty float x\nend_header\n", "no format line"),
    (b"ply\nformat ascii 1.0\nformat ascii 1.0\nend_header\n", "second format"),
    (b"ply\nformat ascii 1.0\nproperty float x\nend_header\n", "before any element"),
    (b"ply\nformat ascii 1.0\nelement vertex -1\nend_header\n", "non-negative"),
    (b"ply\nformat ascii 1.0\nelement vertex 1\nproperty int64 x\nend_header\n1\n",
     "unsupported property type 'int64'"),
    (b"ply\nformat ascii 1.0\nelement v 1\nproperty list float int i\nend_header\n1 1\n",
     "non-integer length type"),
    (b"ply\nformat ascii 1.0\nelement v 1\nproperty float a\nproperty float a\nend_header\n1 1\n",
     "twice"),
    (b"ply\nformat ascii 1.0\nelement v 1\nelement v 1\nend_header\n", "twice"),
    (b"ply\nformat ascii 1.0\nelement v 1\nend_header\n", "no properties"),
    (b"ply\nformat ascii 1.0\nelement v 1\nproperty float\nend_header\n1\n", "malformed property"),
    (b"ply\nformat ascii 1.0\nfoo bar\nend_header\n", "unknown keyword"),
    (b"ply\nformat ascii 1.0\nelement v 1\nproperty uchar a\nend_header\n300\n", "outside the range"),
    (b"ply\nformat ascii 1.0\nelement v 1\nproperty int a\nend_header\n1.5\n", "not a valid integer"),
    (b"ply\nformat ascii 1.0\nelement v 1\nproperty float a\nend_header\nabc\n", "not a valid number"),
    (b"ply\nformat ascii 1.0\nelement v 1\nproperty list uchar int a\nend_header\n-1\n",
     "negative list length"),
])
def test_bad_headers_and_ascii(tmp_path, header, match):
    expect_error(write(tmp_path, "bad.ply", header), match=match, reader=read_ply_elements)


def test_ascii_whitespace_and_odd_bytes(tmp_path):
    head = b"ply\nformat ascii 1.0\nelement v 2\nproperty float a\nproperty uchar b\nend_header\n"
    data = read_ply_elements(write(tmp_path, "ws.ply", head + b"\t1.5\r\n  2 \x0b\n-0.25\f7  \n"))
    assert data["v"]["a"].tolist() == [1.5, -0.25] and data["v"]["b"].tolist() == [2, 7]
    empty = b"ply\nformat ascii 1.0\nelement v 0\nproperty float a\nend_header\n  \n\n"
    assert len(read_ply_elements(write(tmp_path, "blank.ply", empty))["v"]) == 0
    expect_error(write(tmp_path, "nul.ply", head + b"1 2\x003 4\n"), reader=read_ply_elements)
    expect_error(write(tmp_path, "hex.ply", head + b"0x1 2 3 4\n"), reader=read_ply_elements,
                 match="not a valid number")
    expect_error(write(tmp_path, "extra.ply", head + b"1 2 3 4 5\n"), reader=read_ply_elements,
                 match="1 values of ascii data after the last element")
    expect_error(write(tmp_path, "short.ply", head + b"1.000 2 3\n"), reader=read_ply_elements,
                 match="ends early")


def test_crlf_header_and_blank_lines(tmp_path):
    good = _good(n=2)
    head, body = good.split(b"end_header\n", 1)
    path = write(tmp_path, "crlf.ply", head.replace(b"\n", b"\r\n") + b"\r\n" + b"end_header\r\n" + body)
    assert len(read_splat_ply(path)) == 2


def test_missing_and_unsupported_layouts(tmp_path):
    def make(name, keep, add=()):
        props = [p for p in splat_props(2, 1) if keep(p[1])] + list(add)
        return write(tmp_path, name, raw_ply("binary_little_endian", [("vertex", 2, props)]))

    err = expect_error(make("m.ply", lambda n: n not in ("f_dc_0", "rot_3", "opacity")),
                       match="missing required vertex properties")
    assert "rot_3" in str(err) and "opacity" in str(err) and "f_dc_0" in str(err)
    expect_error(make("dc.ply", lambda n: n != "f_dc_1"), match="f_dc_1")
    expect_error(make("2dgs.ply", lambda n: n != "scale_2"), match="2D Gaussian splats")
    expect_error(make("rest.ply", lambda n: n != "f_rest_8"), match="f_rest")
    expect_error(make("rest10.ply", lambda n: True, [("float", "f_rest_9", np.zeros(2))]),
                 match="10 f_rest")
    expect_error(make("gap.ply", lambda n: n != "f_rest_4", [("float", "f_rest_9", np.zeros(2))]),
                 match="missing f_rest_4")
    expect_error(write(tmp_path, "novertex.ply", raw_ply("ascii", [("point", 1, [("float", "x", [1])])])),
                 match="no 'vertex' element")


def test_zero_quaternion_and_overflow(tmp_path):
    props = splat_props(5)
    values = dict((p[1], p[2]) for p in props)
    for i in range(4):
        values[f"rot_{i}"][[1, 3]] = 0
    expect_error(write(tmp_path, "zq.ply", raw_ply("ascii", [("vertex", 5, props)])),
                 match="2 rows (first: row 1) have a zero rotation quaternion")
    props = splat_props(5)
    dict((p[1], p[2]) for p in props)["scale_1"][2] = 100.0
    expect_error(write(tmp_path, "big.ply", raw_ply("binary_little_endian", [("vertex", 5, props)])),
                 match="exceed the float32 range")
    props = [(("double" if p[1] == "y" else p[0]), p[1], p[2]) for p in splat_props(5)]
    props[1] = ("double", "y", np.array([0, 0, 1e300, 0, 0]))
    expect_error(write(tmp_path, "dbl.ply", raw_ply("binary_little_endian", [("vertex", 5, props)])),
                 match="x, y, z exceed the float32 range")


def test_compressed_playcanvas(tmp_path):
    chunk = [("float", f"min_{a}", [0.0]) for a in "xyz"]
    packed = [("uint", n, [0]) for n in ("packed_position", "packed_rotation", "packed_scale",
                                         "packed_color")]
    path = write(tmp_path, "c.compressed.ply",
                 raw_ply("binary_little_endian", [("chunk", 1, chunk), ("vertex", 1, packed)]))
    message = ("compressed PLY (SuperSplat/PlayCanvas) is not the 3DGS PLY layout; "
               "read it as compressed-ply (gsverse-convert --from compressed-ply)")
    assert str(expect_error(path)).endswith(message)
    assert str(expect_error(path, reader=describe_ply)).endswith(message)


# --------------------------------------------------------------------------------------------
# The container writer: any structured arrays, read back unchanged


@pytest.mark.parametrize("fmt", ALL_FORMATS)
def test_write_ply_round_trip(tmp_path, fmt):
    rng = np.random.default_rng(5)
    codes = ["i1", "u1", "i2", "u2", "i4", "u4", "f4", "f8"]
    thing = np.empty(6, [(f"p{i}", c) for i, c in enumerate(codes)] + [("tri", "<i4", (3,))])
    for i, c in enumerate(codes):
        if c[0] == "f":
            thing[f"p{i}"] = rng.normal(size=6) * 10.0 ** rng.integers(-30, 30, 6)
        else:
            info = np.iinfo(c)
            thing[f"p{i}"] = [info.min, info.max, 0, 1, info.max // 3, -1 if info.min else 2]
    thing["tri"] = rng.integers(-5, 1000, (6, 3))
    ragged = np.empty(3, [("idx", object), ("w", "f4")])
    ragged["idx"] = [np.array([1, 2, 3], np.uint16), np.zeros(0, np.uint16), np.arange(300, dtype=np.uint16)]
    ragged["w"] = [0.5, -1.0, 3.25]
    wide = np.zeros(2, [("v", "u1", (300,))])
    wide["v"] = rng.integers(0, 255, (2, 300))
    empty = np.zeros(0, [("a", "f4")])
    out = tmp_path / "w.ply"
    write_ply(out, {"thing": thing, "ragged": ragged, "wide": wide, "empty": empty}, format=fmt,
              comments=["made here", ""], obj_info=["x"])
    data = read_ply_elements(out)
    assert data.format == fmt and data.comments == ["made here", ""] and data.header.obj_info == ["x"]
    assert list(data.elements) == ["thing", "ragged", "wide", "empty"]
    assert data["thing"].dtype == thing.dtype.newbyteorder("=") and np.array_equal(data["thing"], thing)
    assert data["ragged"]["w"].tolist() == [0.5, -1.0, 3.25]
    for got, want in zip(data["ragged"]["idx"], ragged["idx"]):
        assert got.dtype == np.uint16 and np.array_equal(got, want)
    assert np.array_equal(data["wide"]["v"], wide["v"]) and len(data["empty"]) == 0
    header = read_ply_header(out)
    assert header.element("wide").property("v").count_type == "u4"
    assert header.element("thing").property("tri").count_type == "u1"


def test_write_ply_refusals(tmp_path):
    out = tmp_path / "r.ply"
    good = np.zeros(2, [("a", "f4")])
    for elements, kw, match in [
        ({"v": np.zeros(2, [("a", "i8")])}, {}, "cannot store"),
        ({"v": np.zeros(2, [("has space", "f4")])}, {}, "property name"),
        ({"bad name": good}, {}, "element name"),
        ({"v": np.zeros(2, [("m", "f4", (2, 2))])}, {}, "one-dimensional"),
        ({"v": np.zeros((2, 2), [("a", "f4")])}, {}, "1-D structured"),
        ({"v": np.zeros(2, "f4")}, {}, "1-D structured"),
        ({"v": good}, {"format": "binary"}, "unknown PLY format"),
        ({"v": good}, {"comments": ["two\nlines"]}, "one line"),
    ]:
        with pytest.raises(UsageError, match=match) as info:
            write_ply(out, elements, **kw)
        assert str(info.value).startswith(str(out)) and "\n" not in str(info.value)
    assert not out.exists() and not [p for p in os.listdir(tmp_path) if p.startswith(".tmp")]


# --------------------------------------------------------------------------------------------
# The format table entry: a splat asset in the file's own (3DGS) frame


def test_registered_format(tmp_path):
    fmt = FORMAT_TABLE[".ply"]
    assert fmt.name == "ply" and fmt.frame == "3dgs"
    src = splat_file(tmp_path, n=20, degree=1, name="scene.ply")
    asset = fmt.read(src)
    cloud = read_splat_ply(src)
    assert len(asset.primitives) == 1 and asset.primitives[0].name == "scene"
    assert asset.primitives[0].anchoring is None
    assert np.array_equal(asset.primitives[0].splats.means, cloud.means)        # no rotation
    assert np.array_equal(asset.primitives[0].splats.rotations, cloud.rotations)
    other = read_splat_ply(splat_file(tmp_path, n=7, degree=0, name="other.ply", seed=4))
    out = tmp_path / "both.ply"
    fmt.write(SplatAsset([SplatPrimitive(cloud), SplatPrimitive(other)]), out)
    back = read_splat_ply(out)
    assert len(back) == 27 and back.sh_degree == 1
    assert np.array_equal(back.means, np.concatenate([cloud.means, other.means]))
    with pytest.raises(UsageError, match="no splats"):
        fmt.write(SplatAsset([]), tmp_path / "none.ply")
    with pytest.raises(UsageError):
        fmt.write(asset, src, protect=(src,))
