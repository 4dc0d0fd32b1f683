"""Build native/gsverse_remap.h into a shared library and drive it as an engine plugin would.

Used by tests/test_conformance.py. :func:`build` compiles the header with the system C
compiler (``cc``, or ``$CC``) into a shared library; :class:`CPlugin` is a harness in the
sense of spec/conformance.md: it imports the asset with the minimal reader (no glTF library),
dequantizes and checks the anchors with the header's helpers, and remaps with the header.
"""
from __future__ import annotations

import ctypes
import os
import shutil
import subprocess
from pathlib import Path

import numpy as np

from gsverse_format.conformance.minimal_reader import Raw, Refused, read_anchored_glb

HEADER_DIR = Path(__file__).resolve().parents[1] / "native"

_WRAPPER = """
#define GSV_REMAP_IMPLEMENTATION
#include "gsverse_remap.h"
#ifdef __cplusplus
extern "C" {
#endif
size_t gsv_sizeof_rest_face(void) { return sizeof(gsv_rest_face); }
size_t gsv_sizeof_local_face(void) { return sizeof(gsv_local_face); }
size_t gsv_sizeof_games_face(void) { return sizeof(gsv_games_face); }
#ifdef __cplusplus
}
#endif
"""

PROPS = {"faceIndex": 0, "barycentrics": 1, "normalOffset": 2, "localRotation": 3,
         "localScale": 4, "rho": 5}


def compiler() -> str | None:
    cc = os.environ.get("CC") or "cc"
    return shutil.which(cc)


def build(out_dir: Path, *, real: str = "double", cplusplus: bool = False) -> ctypes.CDLL:
    """Compile the header (strict warnings as errors) into ``out_dir`` and load it."""
    cc = compiler()
    src = out_dir / "gsv_wrapper.c"
    src.write_text(_WRAPPER)
    lib = out_dir / f"libgsv_{real}{'_cpp' if cplusplus else ''}.so"
    cmd = [cc]
    if cplusplus:
        cmd = [shutil.which("c++") or "c++", "-x", "c++", "-std=c++11"]
    else:
        cmd += ["-std=c99"]
    cmd += ["-O2", "-Wall", "-Wextra", "-pedantic", "-Werror", "-fPIC", "-shared",
            f"-I{HEADER_DIR}", f"-DGSV_REAL={real}", str(src), "-o", str(lib), "-lm"]
    subprocess.run(cmd, check=True, capture_output=True, text=True, timeout=120)
    return _declare(ctypes.CDLL(str(lib)))


def _declare(lib: ctypes.CDLL) -> ctypes.CDLL:
    P, S, I = ctypes.c_void_p, ctypes.c_size_t, ctypes.c_int
    sigs = {
        "gsv_prepare_rest": ([P, P, S, P], None),
        "gsv_local_faces": ([P, P, S, P, P], None),
        "gsv_local_splats": ([P, S, P, P, P, P, P, I, P, P, P, P], None),
        "gsv_games_faces": ([P, P, S, P], None),
        "gsv_games_splats": ([P, S, P, P, P, P, P, P, P], None),
        "gsv_rot_scale_to_cov": ([P, P, P], None),
        "gsv_cov_to_rot_scale": ([P, P, P], None),
        "gsv_read_floats": ([P, S, S, I, I, I, P], I),
        "gsv_read_uints": ([P, S, S, I, P], I),
        "gsv_normalize_quaternions": ([P, S], None),
        "gsv_anchor_accessor_allowed": ([I, I, I, I], I),
        "gsv_check_face_indices": ([P, S, S], I),
        "gsv_all_finite": ([P, S], I),
        "gsv_dequantize": ([ctypes.c_int32, I, I], ctypes.c_double),
        "gsv_sizeof_rest_face": ([], S),
        "gsv_sizeof_local_face": ([], S),
        "gsv_sizeof_games_face": ([], S),
    }
    for name, (args, res) in sigs.items():
        fn = getattr(lib, name)
        fn.argtypes = args
        fn.restype = res
    return lib


def _ptr(a: np.ndarray | None):
    return None if a is None else a.ctypes.data_as(ctypes.c_void_p)


class CPlugin:
    """The C header as an engine plugin: minimal reader + C dequantization, checks and remap.

    ``form`` is ``"cov"`` (dump covariances) or ``"rotscale"`` (dump the rotation/scale pairs
    the header derives: directly for rigid and games, by eigen-decomposition for affine).
    """

    def __init__(self, lib: ctypes.CDLL, form: str = "cov") -> None:
        self.lib = lib
        self.form = form

    def _floats(self, raw: Raw) -> np.ndarray:
        values = np.ascontiguousarray(raw.values)
        out = np.zeros(values.shape, np.float32)
        rc = self.lib.gsv_read_floats(_ptr(values), 0, values.shape[0], values.shape[1],
                                      raw.component_type, int(raw.normalized), _ptr(out))
        if rc != 0:
            raise Refused(f"component type {raw.component_type} not readable")
        return out

    def _uints(self, raw: Raw) -> np.ndarray:
        values = np.ascontiguousarray(raw.values)
        out = np.zeros(values.shape[0], np.uint32)
        if self.lib.gsv_read_uints(_ptr(values), 0, values.shape[0], raw.component_type,
                                   _ptr(out)) != 0:
            raise Refused("faceIndex must be an unsigned integer accessor")
        return out

    def load(self, asset_path: str) -> None:
        a = read_anchored_glb(asset_path)
        for prop, raw in a.anchors.items():
            if not self.lib.gsv_anchor_accessor_allowed(PROPS[prop], raw.values.shape[1],
                                                        raw.component_type, int(raw.normalized)):
                raise Refused(f"{prop}: accessor layout not allowed")
        self.raw = a
        self.vertices_rest = np.ascontiguousarray(a.anchor_vertices, dtype=np.float32)
        self.indices = np.ascontiguousarray(a.anchor_faces.reshape(-1), dtype=np.uint32)
        self.faces = len(a.anchor_faces)
        self.n = a.count
        self.face = self._uints(a.anchors["faceIndex"])
        if not self.lib.gsv_check_face_indices(_ptr(self.face), self.n, self.faces):
            raise Refused("faceIndex out of range")
        vertices_ok = self.lib.gsv_all_finite(_ptr(self.vertices_rest), self.vertices_rest.size)
        self.bary = self._floats(a.anchors["barycentrics"])
        self.profile = a.profile
        if a.profile == "games":
            self.rho = self._floats(a.anchors["rho"])[:, 0].copy()
            if not vertices_ok or not all(self.lib.gsv_all_finite(_ptr(x), x.size)
                                          for x in (self.bary, self.rho)):
                raise Refused("non-finite anchor data")
            self.cur = np.zeros(self.faces * self.lib.gsv_sizeof_games_face(), np.uint8)
        else:
            self.law = 1 if a.deformation == "rigid" else 0
            self.offset = self._floats(a.anchors["normalOffset"])[:, 0].copy()
            self.rotation = self._floats(a.anchors["localRotation"])
            if a.anchors["localRotation"].component_type != 5126:
                self.lib.gsv_normalize_quaternions(_ptr(self.rotation), self.n)
            self.scale = self._floats(a.anchors["localScale"])
            self.rest_faces = np.zeros(self.faces * self.lib.gsv_sizeof_rest_face(), np.uint8)
            self.cur = np.zeros(self.faces * self.lib.gsv_sizeof_local_face(), np.uint8)
            anchors = (self.bary, self.offset, self.rotation, self.scale)
            if not vertices_ok or not all(self.lib.gsv_all_finite(_ptr(x), x.size) for x in anchors):
                raise Refused("non-finite anchor data")
            self.lib.gsv_prepare_rest(_ptr(self.vertices_rest), _ptr(self.indices), self.faces,
                                      _ptr(self.rest_faces))

    def rest(self) -> dict[str, np.ndarray]:
        a = self.raw
        rot = self._floats(a.rotations)
        if a.rotations.component_type != 5126:
            self.lib.gsv_normalize_quaternions(_ptr(rot), self.n)
        scale = self._floats(a.scales)
        cov = np.zeros((self.n, 6), np.float32)
        for i in range(self.n):
            self.lib.gsv_rot_scale_to_cov(_ptr(rot[i]), _ptr(scale[i]), _ptr(cov[i]))
        out = {"means": self._floats(a.positions), "cov": cov}
        out.update(self.splat_data())
        return out

    def apply_pose(self, vertices: np.ndarray) -> dict[str, np.ndarray]:
        v = np.ascontiguousarray(vertices, dtype=np.float32)
        means = np.zeros((self.n, 3), np.float32)
        cov = np.zeros((self.n, 6), np.float32)
        rot = np.zeros((self.n, 4), np.float32) if self.form == "rotscale" else None
        scl = np.zeros((self.n, 3), np.float32) if self.form == "rotscale" else None
        if self.profile == "games":
            self.lib.gsv_games_faces(_ptr(v), _ptr(self.indices), self.faces, _ptr(self.cur))
            self.lib.gsv_games_splats(_ptr(self.cur), self.n, _ptr(self.face), _ptr(self.bary),
                                      _ptr(self.rho), _ptr(means), _ptr(cov), _ptr(rot),
                                      _ptr(scl))
        else:
            self.lib.gsv_local_faces(_ptr(v), _ptr(self.indices), self.faces,
                                     _ptr(self.rest_faces), _ptr(self.cur))
            self.lib.gsv_local_splats(_ptr(self.cur), self.n, _ptr(self.face), _ptr(self.bary),
                                      _ptr(self.offset), _ptr(self.rotation), _ptr(self.scale),
                                      self.law, _ptr(means), _ptr(cov), _ptr(rot), _ptr(scl))
        if self.form == "rotscale":
            return {"means": means, "rotation": rot, "scale": scl}
        return {"means": means, "cov": cov}

    def splat_data(self) -> dict[str, np.ndarray]:
        a = self.raw
        sh = np.stack([self._floats(s) for s in a.sh], axis=1)
        return {"opacity": self._floats(a.opacities)[:, 0].copy(), "sh": sh}


# --------------------------------------------------------------------------- tests of the header

import re  # noqa: E402

import pytest  # noqa: E402

from gsverse_format import frames as F  # noqa: E402
from gsverse_format.conformance.minimal_reader import accessor_allowed, dequantize  # noqa: E402
from gsverse_format.model import Anchoring, GamesAnchors, LocalAnchors, TriangleMesh  # noqa: E402
from gsverse_format.remap import remap  # noqa: E402

_CTYPES = (5120, 5121, 5122, 5123, 5125, 5126)


class _Frame(ctypes.Structure):
    _fields_ = [("r", ctypes.c_double * 9), ("c", ctypes.c_double * 4),
                ("area2", ctypes.c_double), ("regular", ctypes.c_int)]


@pytest.fixture(scope="module")
def lib(tmp_path_factory):
    if compiler() is None:
        pytest.skip("no C compiler (cc) on this machine")
    return build(tmp_path_factory.mktemp("native-unit"), real="double")


def test_header_is_standalone_c99():
    text = (HEADER_DIR / "gsverse_remap.h").read_text()
    includes = set(re.findall(r"^\s*#\s*include\s*(<[^>]+>|\"[^\"]+\")", text, re.M))
    assert includes == {"<math.h>", "<stddef.h>", "<stdint.h>"}
    assert "malloc" not in text and "printf" not in text


def test_header_builds_as_float32_and_cplusplus(tmp_path, lib):
    build(tmp_path, real="float")
    if shutil.which("c++") is None:
        pytest.skip("no C++ compiler")
    build(tmp_path, cplusplus=True)
    # declarations only (no implementation) and the static variant compile cleanly too
    (tmp_path / "decl.c").write_text('#include "gsverse_remap.h"\nint main(void) { return 0; }\n')
    (tmp_path / "static.c").write_text(
        "#define GSV_REMAP_STATIC\n#define GSV_REMAP_IMPLEMENTATION\n#include \"gsverse_remap.h\"\n"
        "int main(void) { float v[9] = {0, 0, 0, 1, 0, 0, 0, 1, 0}; gsv_frame f;\n"
        "  gsv_local_frame(v, v + 3, v + 6, &f); return f.regular ? 0 : 1; }\n")
    for name in ("decl", "static"):
        subprocess.run([compiler(), "-std=c99", "-Wall", "-Wextra", "-pedantic", "-Werror",
                        f"-I{HEADER_DIR}", str(tmp_path / f"{name}.c"), "-o",
                        str(tmp_path / name), "-lm"], check=True, capture_output=True)
    assert subprocess.run([str(tmp_path / "static")]).returncode == 0


def test_accessor_rules_match_the_spec_table(lib):
    gtypes = {1: "SCALAR", 2: "VEC2", 3: "VEC3", 4: "VEC4"}
    for prop, code in PROPS.items():
        for ncomp, gtype in gtypes.items():
            for ct in _CTYPES:
                for normalized in (False, True):
                    assert bool(lib.gsv_anchor_accessor_allowed(code, ncomp, ct, int(normalized))) \
                        == accessor_allowed(prop, gtype, ct, normalized), (prop, gtype, ct, normalized)


def test_dequantization_and_little_endian_reading(lib):
    cases = [(5121, [0, 1, 128, 255]), (5123, [0, 1, 32768, 65535]),
             (5120, [-128, -127, -1, 0, 1, 127]), (5122, [-32768, -32767, -1, 0, 32767])]
    for ct, codes in cases:
        dtype = {5121: "<u1", 5123: "<u2", 5120: "<i1", 5122: "<i2"}[ct]
        raw = np.array(codes, dtype=dtype)
        for normalized in (True, False):
            want = dequantize(Raw(raw[:, None], ct, normalized))[:, 0]
            got = np.array([lib.gsv_dequantize(int(c), ct, int(normalized)) for c in codes])
            np.testing.assert_array_equal(got, want)
            # strided, interleaved little-endian bytes: element i at byte 8 i
            blob = np.zeros(len(codes) * 8, np.uint8)
            for i, c in enumerate(raw):
                blob[8 * i:8 * i + raw.itemsize] = np.frombuffer(c.tobytes(), np.uint8)
            out = np.zeros(len(codes), np.float32)
            assert lib.gsv_read_floats(_ptr(blob), 8, len(codes), 1, ct, int(normalized), _ptr(out)) == 0
            np.testing.assert_array_equal(out, want.astype(np.float32))
    f = np.array([1.5, -2.25, 3e-30], "<f4")
    out = np.zeros(3, np.float32)
    lib.gsv_read_floats(_ptr(f), 0, 3, 1, 5126, 0, _ptr(out))
    np.testing.assert_array_equal(out, f)
    assert lib.gsv_read_floats(_ptr(f), 0, 3, 1, 5126, 1, _ptr(out)) == -1  # normalized FLOAT
    u = np.array([7, 70000, 2 ** 32 - 1], "<u4")
    got = np.zeros(3, np.uint32)
    assert lib.gsv_read_uints(_ptr(u), 0, 3, 5125, _ptr(got)) == 0
    np.testing.assert_array_equal(got, u)
    assert lib.gsv_read_uints(_ptr(f), 0, 3, 5126, _ptr(got)) == -1
    q = np.array([[0, 0, 0, 2], [0, 0, 0, 0], [3, 4, 0, 0]], np.float32)
    lib.gsv_normalize_quaternions(_ptr(q), 3)
    np.testing.assert_allclose(q, [[0, 0, 0, 1], [0, 0, 0, 1], [0.6, 0.8, 0, 0]], atol=1e-7)
    assert lib.gsv_all_finite(_ptr(f), 3) == 1
    for bad in (np.nan, np.inf, -np.inf):
        g = f.copy()
        g[1] = bad
        assert lib.gsv_all_finite(_ptr(g), 3) == 0
    face = np.array([0, 3, 2], np.uint32)
    assert lib.gsv_check_face_indices(_ptr(face), 3, 4) == 1
    assert lib.gsv_check_face_indices(_ptr(face), 3, 3) == 0


def _special_triangles(rng) -> np.ndarray:
    tri = rng.normal(size=(300, 3, 3))
    tri[0] = 0.0                                        # a point
    tri[1, 2] = tri[1, 1]                               # v2 = v1 (tie e1/e2)
    tri[2, 1] = tri[2, 0]                               # v1 = v0 (tie e2/e3)
    tri[3, 2] = tri[3, 0]                               # v2 = v0 (tie e1/e3)
    tri[4] = [[1, 2, 0.5], [2, 2, 0.5], [1.25, 2, 0.5]]  # along x (perp ties)
    tri[5] = [[0, 0, 0], [0.5, 0.5, 0.5], [1, 1, 1]]    # along (1,1,1)
    tri[6] = [[-1, 0, 0], [0, 0, 0], [1, 0, 0]]         # v1 = centroid (games)
    tri[7, 2] = tri[7, 0] + 0.3 * (tri[7, 1] - tri[7, 0])  # nearly collinear after rounding
    tri[8, 2] = tri[8, 0] + 1e-3 * rng.normal(size=3)   # a sliver
    return tri.astype(np.float32)


def test_frames_match_the_reference(lib):
    tri = _special_triangles(np.random.default_rng(3))
    ref = F.local_frames(tri.astype(np.float64))
    g_rot, g_base, _ = F.games_frames(tri.astype(np.float64))
    fr = _Frame()
    r = (ctypes.c_double * 9)()
    base = (ctypes.c_double * 3)()
    for i, t in enumerate(tri):
        v = [np.ascontiguousarray(t[k]) for k in range(3)]
        lib.gsv_local_frame(_ptr(v[0]), _ptr(v[1]), _ptr(v[2]), ctypes.byref(fr))
        assert fr.regular == int(ref.regular[i]), i
        np.testing.assert_allclose(np.array(fr.r).reshape(3, 3), ref.rotation[i], atol=1e-12)
        np.testing.assert_allclose(np.array(fr.c).reshape(2, 2), ref.shape[i], atol=1e-12)
        assert abs(fr.area2 - ref.area2[i]) <= 1e-12
        lib.gsv_games_frame(_ptr(v[0]), _ptr(v[1]), _ptr(v[2]), r, base)
        np.testing.assert_allclose(np.array(r).reshape(3, 3), g_rot[i], atol=1e-12)
        np.testing.assert_allclose(np.array(base), g_base[i], atol=1e-12)


_LIB_SIGNATURES = {"gsv_local_frame": [ctypes.c_void_p] * 4,
                   "gsv_games_frame": [ctypes.c_void_p] * 5}


@pytest.fixture(autouse=True)
def _frame_signatures(request):
    if "lib" in request.fixturenames:
        lib = request.getfixturevalue("lib")
        for name, args in _LIB_SIGNATURES.items():
            getattr(lib, name).argtypes = args
            getattr(lib, name).restype = None


def _c_remap(lib, anchoring: Anchoring, vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    mesh, a = anchoring.mesh, anchoring.anchors
    idx = np.ascontiguousarray(mesh.faces.reshape(-1), np.uint32)
    nf, n = mesh.face_count, len(a)
    v = np.ascontiguousarray(vertices, np.float32)
    face = np.ascontiguousarray(a.face_index, np.uint32)
    bary = np.ascontiguousarray(a.barycentrics, np.float32)
    means = np.zeros((n, 3), np.float32)
    cov = np.zeros((n, 6), np.float32)
    if isinstance(a, GamesAnchors):
        cur = np.zeros(nf * lib.gsv_sizeof_games_face(), np.uint8)
        lib.gsv_games_faces(_ptr(v), _ptr(idx), nf, _ptr(cur))
        lib.gsv_games_splats(_ptr(cur), n, _ptr(face), _ptr(bary),
                             _ptr(np.ascontiguousarray(a.rho)), _ptr(means), _ptr(cov), None, None)
    else:
        rest = np.zeros(nf * lib.gsv_sizeof_rest_face(), np.uint8)
        cur = np.zeros(nf * lib.gsv_sizeof_local_face(), np.uint8)
        lib.gsv_prepare_rest(_ptr(mesh.vertices), _ptr(idx), nf, _ptr(rest))
        lib.gsv_local_faces(_ptr(v), _ptr(idx), nf, _ptr(rest), _ptr(cur))
        lib.gsv_local_splats(_ptr(cur), n, _ptr(face), _ptr(bary),
                             _ptr(np.ascontiguousarray(a.normal_offset)),
                             _ptr(np.ascontiguousarray(a.local_rotation)),
                             _ptr(np.ascontiguousarray(a.local_scale)),
                             1 if a.deformation == "rigid" else 0, _ptr(means), _ptr(cov), None, None)
    full = np.empty((n, 3, 3))
    for j, (r, s) in enumerate(((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))):
        full[:, r, s] = full[:, s, r] = cov[:, j]
    return means.astype(np.float64), full


def test_spec_worked_examples(lib):
    """spec/README.md §Worked examples, evaluated by the header."""
    mesh = TriangleMesh([[0, 0, 0], [2, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    ex1 = np.array([[0, 0, 0], [0, 4, 0], [-1, 0, 0]], np.float32)
    args = ([0], [[0.25, 0.5]], [0.125])
    for law, sigma in (("affine", np.diag([0.140625, 0.0625, 0.0078125])),
                       ("rigid", np.diag([0.28125, 0.03125, 0.0078125]))):
        a = LocalAnchors(*args, [[0, 0, 0, 1]], [[0.125, 0.375, 0.0625]], law)
        means, cov = _c_remap(lib, Anchoring(mesh, a), ex1)
        np.testing.assert_allclose(means[0], [-0.5, 1.0, 0.1767766953], atol=1e-7)
        np.testing.assert_allclose(cov[0], sigma, atol=1e-7)
    ex2 = np.array([[0.5, 0.25, 0.125], [2.25, 1, 0.5], [-0.25, 1.5, 1]], np.float32)
    q = [0.102597833, 0.205195665, 0.307793498, 0.923380494]
    expect = {"affine": [[0.1504155097, -0.0800643672, -0.1319521019],
                         [-0.0800643672, 0.0710522307, 0.0785591657],
                         [-0.1319521019, 0.0785591657, 0.1271967727]],
              "rigid": [[0.1516519468, -0.0306877600, -0.1007813439],
                        [-0.0306877600, 0.0320743478, 0.0301091211],
                        [-0.1007813439, 0.0301091211, 0.0804442972]]}
    for law, sigma in expect.items():
        a = LocalAnchors(*args, [q], [[0.125, 0.375, 0.0625]], law)
        means, cov = _c_remap(lib, Anchoring(mesh, a), ex2)
        np.testing.assert_allclose(means[0], [0.5716245404, 0.9742961090, 0.7900765932], atol=1e-7)
        np.testing.assert_allclose(cov[0], sigma, atol=1e-7)
    gmesh = TriangleMesh([[0, 0, 0], [3, 0, 0], [0, 3, 0]], [[0, 1, 2]])
    means, cov = _c_remap(lib, Anchoring(gmesh, GamesAnchors([0], [[0.3, 0.5]], [2.0])),
                          gmesh.vertices)
    r = np.array([[0, 0.8944271910, 0.4472135955], [0, -0.4472135955, 0.8944271910], [1, 0, 0]])
    s = np.array([3e-8, 2.2360679975, 1.3416407965])
    np.testing.assert_allclose(means[0], [0.9, 1.5, 0.0], atol=1e-7)
    np.testing.assert_allclose(cov[0], (r * s**2) @ r.T, atol=1e-7)


def test_remap_matches_reference_on_random_meshes(lib):
    rng = np.random.default_rng(11)
    verts = rng.normal(size=(30, 3))
    faces = np.array([rng.choice(30, 3, replace=False) for _ in range(40)])
    mesh = TriangleMesh(verts, faces)
    n = 200
    face = rng.integers(0, 40, n)
    bary = rng.uniform(-0.2, 1.0, (n, 2))
    pose = (verts + 0.3 * rng.normal(size=verts.shape)).astype(np.float32)
    q = rng.normal(size=(n, 4))
    for a in (LocalAnchors(face, bary, rng.normal(0, 0.1, n), q, rng.uniform(0.01, 0.2, (n, 3)), "affine"),
              LocalAnchors(face, bary, rng.normal(0, 0.1, n), q, rng.uniform(0.01, 0.2, (n, 3)), "rigid"),
              GamesAnchors(face, bary, rng.uniform(0.1, 2.0, n))):
        anchoring = Anchoring(mesh, a)
        ref = remap(anchoring, pose)
        means, cov = _c_remap(lib, anchoring, pose)
        scale = np.linalg.norm(ref.covariances, axis=(1, 2))
        assert np.max(np.linalg.norm(means - ref.means, axis=1)) < 1e-6
        assert np.max(np.linalg.norm(cov - ref.covariances, axis=(1, 2)) / scale) < 1e-6


def test_covariance_to_rotation_scale_round_trip(lib):
    rng = np.random.default_rng(5)
    for _ in range(200):
        m = rng.normal(size=(3, 3)) * rng.uniform(1e-3, 10.0, 3)
        cov = m @ m.T
        c6 = np.array([cov[0, 0], cov[0, 1], cov[0, 2], cov[1, 1], cov[1, 2], cov[2, 2]], np.float32)
        q = np.zeros(4, np.float32)
        s = np.zeros(3, np.float32)
        lib.gsv_cov_to_rot_scale(_ptr(c6), _ptr(q), _ptr(s))
        assert abs(np.linalg.norm(q) - 1) < 1e-6 and q[3] >= 0 and np.all(s >= 0)
        back = np.zeros(6, np.float32)
        lib.gsv_rot_scale_to_cov(_ptr(q), _ptr(s), _ptr(back))
        np.testing.assert_allclose(back, c6, atol=2e-6 * np.abs(c6).max())
