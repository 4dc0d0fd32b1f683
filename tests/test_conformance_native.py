"""Build native/gsverse_remap.h into a shared library and drive it as an engine plugin would.

Used by tests/test_conformance.py. :func:`build` compiles the header with the system C
compiler (``cc``, or ``$CC``) into a shared library; :class:`CPlugin` is a harness in the
sense of spec/conformance.md: it imports the asset with the minimal reader (no glTF library),
dequantizes and checks the anchors with the header's helpers (refusing what spec v1.2 makes
invalid), normalizes the quaternions and remaps with the header.
"""
from __future__ import annotations

import ctypes
import functools
import os
import shutil
import subprocess
import sys
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
         "localScale": 4, "rho": 5, "faceCounts": 6}


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
    out = _declare(ctypes.CDLL(str(lib)))
    out.gsv_real_type = real
    return out


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
        "gsv_check_quaternions_nonzero": ([P, S], I),
        "gsv_check_scales_nonnegative": ([P, S], I),
        "gsv_faces_from_counts": ([P, S, S, S, P], I),
        "gsv_derive_local": ([P, P, S, P, P, P, P, P, P], I),
        "gsv_splat_local": ([P, S, P, P], I),
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
        stored = dict(a.anchors, **({"faceCounts": a.face_counts} if a.face_counts else {}))
        for prop, raw in stored.items():
            if not self.lib.gsv_anchor_accessor_allowed(PROPS[prop], raw.values.shape[1],
                                                        raw.component_type, int(raw.normalized)):
                raise Refused(f"{prop}: accessor layout not allowed")
        self.raw = a
        self.vertices_rest = np.ascontiguousarray(a.anchor_vertices, dtype=np.float32)
        self.indices = np.ascontiguousarray(a.anchor_faces.reshape(-1), dtype=np.uint32)
        self.faces = len(a.anchor_faces)
        self.n = a.count
        if a.face_counts is not None:     # version 1.2: one count per triangle
            counts = self._uints(a.face_counts)
            self.face = np.zeros(self.n, np.uint32)
            if not self.lib.gsv_faces_from_counts(_ptr(counts), len(counts), self.faces, self.n,
                                                  _ptr(self.face)):
                raise Refused("faceCounts: wrong count or sum")
        else:
            self.face = self._uints(a.anchors["faceIndex"])
        if not self.lib.gsv_check_face_indices(_ptr(self.face), self.n, self.faces):
            raise Refused("faceIndex out of range")
        vertices_ok = self.lib.gsv_all_finite(_ptr(self.vertices_rest), self.vertices_rest.size)
        # the rest pose must be finite too (spec v1.1)
        self.rest_means = self._floats(a.positions)
        self.rest_rotation = self._floats(a.rotations)
        self.rest_scale = self._floats(a.scales)
        if not all(self.lib.gsv_all_finite(_ptr(x), x.size)
                   for x in (self.rest_means, self.rest_rotation, self.rest_scale)):
            raise Refused("non-finite rest pose (POSITION, ROTATION or SCALE)")
        if a.derived and not (
                self.lib.gsv_check_quaternions_nonzero(_ptr(self.rest_rotation), self.n)
                and self.lib.gsv_check_scales_nonnegative(_ptr(self.rest_scale),
                                                          self.rest_scale.size)):
            # derived anchors are used as stored ones (version 1.2)
            raise Refused("derived localRotation of length zero or negative localScale")
        # the rest-pose ROTATION is normalized before use, whatever its component type
        self.lib.gsv_normalize_quaternions(_ptr(self.rest_rotation), self.n)
        self.profile = a.profile
        if a.derived:                     # version 1.2: derived from the rest pose, in double
            self.bary = np.zeros((self.n, 2), np.float32)
            offset = np.zeros(self.n, np.float32)
            rotation = np.zeros((self.n, 4), np.float32)
            if not self.lib.gsv_derive_local(_ptr(self.vertices_rest), _ptr(self.indices), self.n,
                                             _ptr(self.face), _ptr(self.rest_means),
                                             _ptr(self.rest_rotation), _ptr(self.bary),
                                             _ptr(offset), _ptr(rotation)):
                raise Refused("derived anchors on a face degenerate at rest")
            a.anchors.update({"normalOffset": Raw(offset[:, None], 5126, False),
                              "localRotation": Raw(rotation, 5126, False),
                              "localScale": Raw(self.rest_scale, 5126, False)})
        else:
            self.bary = self._floats(a.anchors["barycentrics"])
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
            self.scale = self._floats(a.anchors["localScale"])
            self.rest_faces = np.zeros(self.faces * self.lib.gsv_sizeof_rest_face(), np.uint8)
            self.cur = np.zeros(self.faces * self.lib.gsv_sizeof_local_face(), np.uint8)
            anchors = (self.bary, self.offset, self.rotation, self.scale)
            if not vertices_ok or not all(self.lib.gsv_all_finite(_ptr(x), x.size) for x in anchors):
                raise Refused("non-finite anchor data")
            if not self.lib.gsv_check_quaternions_nonzero(_ptr(self.rotation), self.n):
                raise Refused("zero-length localRotation")
            if not self.lib.gsv_check_scales_nonnegative(_ptr(self.scale), self.scale.size):
                raise Refused("negative localScale component")
            # localRotation of every component type, FLOAT included, is normalized (spec v1.1)
            self.lib.gsv_normalize_quaternions(_ptr(self.rotation), self.n)
            self.lib.gsv_prepare_rest(_ptr(self.vertices_rest), _ptr(self.indices), self.faces,
                                      _ptr(self.rest_faces))

    def rig_pose(self, folder: Path, manifest: dict, p: int) -> np.ndarray:
        """A rig case's pose as a native engine gets it: the deformed vertices p' (what its
        skinning and morphing output) and the splat node's matrix M; the header does M^-1 in
        double for a skinned anchor mesh (spec/conformance.md §Rig cases)."""
        deformed = np.fromfile(folder / manifest["files"]["deformed"][p], "<f4").reshape(-1, 3)
        rig = manifest["rig"]
        if not rig["skinned"]:
            return deformed
        m = np.ascontiguousarray(rig["splat_node_matrix"], dtype=np.float64)
        out = np.zeros_like(deformed)
        if not self.lib.gsv_splat_local(_ptr(deformed), len(deformed), _ptr(m), _ptr(out)):
            raise ValueError("the splat node's matrix is singular")
        return out

    def rest(self) -> dict[str, np.ndarray]:
        rot, scale = self.rest_rotation, self.rest_scale
        cov = np.zeros((self.n, 6), np.float32)
        for i in range(self.n):
            self.lib.gsv_rot_scale_to_cov(_ptr(rot[i]), _ptr(scale[i]), _ptr(cov[i]))
        out = {"means": self.rest_means, "cov": cov}
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
from gsverse_format import quaternion  # noqa: E402
from gsverse_format.conformance.minimal_reader import accessor_allowed, dequantize  # noqa: E402
from gsverse_format.model import Anchoring, GamesAnchors, LocalAnchors, TriangleMesh  # noqa: E402
from gsverse_format.remapping.reference import prepare_rest, remap  # noqa: E402

_CTYPES = (5120, 5121, 5122, 5123, 5125, 5126)
_RS6 = ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))


def _real(real: str):
    return ctypes.c_float if real == "float" else ctypes.c_double


class _Frame(ctypes.Structure):
    _fields_ = [("r", ctypes.c_double * 9), ("c", ctypes.c_double * 4),
                ("area2", ctypes.c_double), ("regular", ctypes.c_int)]


@functools.lru_cache(maxsize=None)
def _rest_face_type(real: str):
    """ctypes layout of gsv_rest_face for a build with GSV_REAL=``real``."""
    t = _real(real)

    class RestFace(ctypes.Structure):
        _fields_ = [("inv", t * 4), ("area2", t), ("inv_sqrt_area2", t),
                    ("regular", ctypes.c_int)]
    return RestFace


@functools.lru_cache(maxsize=None)
def _local_face_type(real: str):
    t = _real(real)

    class LocalFace(ctypes.Structure):
        _fields_ = [("o", t * 3), ("e1", t * 3), ("e2", t * 3), ("m", t * 3),
                    ("a_aff", t * 9), ("r", t * 9), ("k", t)]
    return LocalFace


@functools.lru_cache(maxsize=None)
def _games_face_type(real: str):
    t = _real(real)

    class GamesFace(ctypes.Structure):
        _fields_ = [("o", t * 3), ("e1", t * 3), ("e2", t * 3), ("r", t * 9), ("base", t * 3)]
    return GamesFace


@pytest.fixture(scope="module")
def lib(tmp_path_factory):
    if compiler() is None:
        pytest.skip("no C compiler (cc) on this machine")
    return build(tmp_path_factory.mktemp("native-unit"), real="double")


@pytest.fixture(scope="module")
def flib(tmp_path_factory):
    if compiler() is None:
        pytest.skip("no C compiler (cc) on this machine")
    return build(tmp_path_factory.mktemp("native-unit-float"), real="float")


def test_header_is_standalone_c99():
    text = (HEADER_DIR / "gsverse_remap.h").read_text()
    includes = set(re.findall(r"^\s*#\s*include\s*(<[^>]+>|\"[^\"]+\")", text, re.M))
    assert includes == {"<math.h>", "<stddef.h>", "<stdint.h>"}
    assert "malloc" not in text and "printf" not in text
    assert "version 1.1" in text


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


def test_struct_layouts_match_the_declarations(lib, flib):
    for lb in (lib, flib):
        real = lb.gsv_real_type
        assert ctypes.sizeof(_rest_face_type(real)) == lb.gsv_sizeof_rest_face()
        assert ctypes.sizeof(_local_face_type(real)) == lb.gsv_sizeof_local_face()
        assert ctypes.sizeof(_games_face_type(real)) == lb.gsv_sizeof_games_face()


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


def test_refusal_checks_of_version_1_1(lib):
    q = np.array([[0, 0, 0, 1], [1e-30, 0, 0, 0], [0.1, -0.2, 0.3, 0.4]], np.float32)
    assert lib.gsv_check_quaternions_nonzero(_ptr(q), 3) == 1
    for sign in (1.0, -1.0):                       # +0 and -0 components
        z = q.copy()
        z[1] = sign * 0.0
        assert lib.gsv_check_quaternions_nonzero(_ptr(z), 3) == 0
        assert lib.gsv_check_quaternions_nonzero(_ptr(z), 1) == 1   # only the first counted
    # a quantized zero quaternion dequantizes to zero
    codes = np.zeros((1, 4), "<i2")
    deq = np.zeros((1, 4), np.float32)
    lib.gsv_read_floats(_ptr(codes), 0, 1, 4, 5122, 1, _ptr(deq))
    assert lib.gsv_check_quaternions_nonzero(_ptr(deq), 1) == 0
    s = np.array([[0.0, 1e-30, 2.0], [-0.0, 0.5, 1e4]], np.float32)
    assert lib.gsv_check_scales_nonnegative(_ptr(s), s.size) == 1
    for j in range(s.size):
        t = s.copy().reshape(-1)
        t[j] = -1e-30
        assert lib.gsv_check_scales_nonnegative(_ptr(t), t.size) == 0
        assert lib.gsv_check_scales_nonnegative(_ptr(t), j) == 1


def _special_triangles(rng) -> np.ndarray:
    tri = rng.normal(size=(320, 3, 3))
    tri[0] = 0.0                                        # a point
    tri[1, 2] = tri[1, 1]                               # v2 = v1 (tie e1/e2)
    tri[2, 1] = tri[2, 0]                               # v1 = v0 (tie e2/e3)
    tri[3, 2] = tri[3, 0]                               # v2 = v0 (tie e1/e3: e3 = -e1)
    tri[4] = [[1, 2, 0.5], [2, 2, 0.5], [1.25, 2, 0.5]]  # along x (perp ties)
    tri[5] = [[0, 0, 0], [0.5, 0.5, 0.5], [1, 1, 1]]    # along (1,1,1)
    tri[6] = [[-1, 0, 0], [0, 0, 0], [1, 0, 0]]         # v1 = centroid (games)
    tri[7, 2] = tri[7, 0] + 0.3 * (tri[7, 1] - tri[7, 0])  # nearly collinear after rounding
    tri[8, 2] = tri[8, 0] + 1e-3 * rng.normal(size=3)   # a sliver
    for i in range(9, 19):                              # v1 = float32 midpoint of v0 v2
        t = tri[i].astype(np.float32)
        t[1] = (t[0] + t[2]) / np.float32(2)
        tri[i] = t
    tri[19] = [[0, 0, 0], [1, 0, 0], [2, 0, 0]]         # spec Example 5 (squared lengths 1, 4, 1)
    tri[20] = [[0, 0, 0], [2, 0, 0], [1, 0, 0]]         # spec Example 4 (squared lengths 4, 1, 1)
    tri[21] = [[0, 0, 0], [1, 0, 0], [0.5, 1.0000001e-6, 0]]   # just above the threshold
    tri[22] = [[0, 0, 0], [1, 0, 0], [0.5, 0.9999999e-6, 0]]   # just below it
    tri[23] = [[0, 0, 0], [1, 0, 0], [1, 1e-7, 0]]      # |e1|^2 < |e2|^2 by 1e-14 only
    tri[24] = [[0, 0, 0], [0, 0, 3], [0, 0, -3]]        # e2 longest (squared 9 vs 36)
    tri[25] = [[5, 5, 5], [5, 5, 5], [5, 5, 5]]         # a point away from the origin
    tri[26:36] *= 1e-4                                  # small triangles
    tri[36:46] *= 1e4                                   # large triangles
    for i in range(46, 56):                             # degenerate with a nonzero |r| test
        tri[i, 2] = tri[i, 0] + 2.5 * (tri[i, 1] - tri[i, 0]) + 1e-7 * rng.normal(size=3)
    return tri.astype(np.float32)


def test_frames_match_the_reference(lib):
    tri = _special_triangles(np.random.default_rng(3))
    t64 = tri.astype(np.float64)
    ref = F.local_frames(t64)
    g_rot, g_base, _ = F.games_frames(t64)
    assert not ref.regular[[0, 1, 2, 3, 4, 5, 6, 19, 20, 22, 25]].any() and ref.regular[21]
    fr = _Frame()
    r = (ctypes.c_double * 9)()
    base = (ctypes.c_double * 3)()
    for i, t in enumerate(tri):
        v = [np.ascontiguousarray(t[k]) for k in range(3)]
        lib.gsv_local_frame(_ptr(v[0]), _ptr(v[1]), _ptr(v[2]), ctypes.byref(fr))
        size = max(1.0, float(np.abs(t64[i]).max()))
        assert fr.regular == int(ref.regular[i]), i
        np.testing.assert_allclose(np.array(fr.r).reshape(3, 3), ref.rotation[i], atol=1e-12)
        np.testing.assert_allclose(np.array(fr.c).reshape(2, 2), ref.shape[i], atol=1e-12 * size)
        # a is the true |e1 x e2|, degenerate triangles included (spec v1.1)
        assert abs(fr.area2 - ref.area2[i]) <= 1e-12 * size ** 2, i
        lib.gsv_games_frame(_ptr(v[0]), _ptr(v[1]), _ptr(v[2]), r, base)
        np.testing.assert_allclose(np.array(r).reshape(3, 3), g_rot[i], atol=1e-12, err_msg=str(i))
        np.testing.assert_allclose(np.array(base), g_base[i], atol=1e-12 * size, err_msg=str(i))
    # the area of a degenerate triangle is no longer 0
    assert ref.area2[22] > 0 and ref.area2[7] > 0


_LIB_SIGNATURES = {"gsv_local_frame": [ctypes.c_void_p] * 4,
                   "gsv_games_frame": [ctypes.c_void_p] * 5}


@pytest.fixture(autouse=True)
def _frame_signatures(request):
    for fixture in ("lib", "flib"):
        if fixture in request.fixturenames:
            lb = request.getfixturevalue(fixture)
            for name, args in _LIB_SIGNATURES.items():
                getattr(lb, name).argtypes = args
                getattr(lb, name).restype = None


def _c_rest(lib, mesh: TriangleMesh):
    """gsv_prepare_rest on the rest mesh, as a ctypes array of gsv_rest_face."""
    rest = (_rest_face_type(lib.gsv_real_type) * mesh.face_count)()
    idx = np.ascontiguousarray(mesh.faces.reshape(-1), np.uint32)
    lib.gsv_prepare_rest(_ptr(mesh.vertices), _ptr(idx), mesh.face_count, rest)
    return rest


def _c_remap(lib, anchoring: Anchoring, vertices: np.ndarray, rest=None
             ) -> tuple[np.ndarray, np.ndarray]:
    """Means (N, 3) and covariances (N, 3, 3) from the header; ``rest`` may replace the
    gsv_prepare_rest data (a ctypes array of gsv_rest_face)."""
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
        if rest is None:
            rest = _c_rest(lib, mesh)
        cur = np.zeros(nf * lib.gsv_sizeof_local_face(), np.uint8)
        lib.gsv_local_faces(_ptr(v), _ptr(idx), nf, rest, _ptr(cur))
        lib.gsv_local_splats(_ptr(cur), n, _ptr(face), _ptr(bary),
                             _ptr(np.ascontiguousarray(a.normal_offset)),
                             _ptr(np.ascontiguousarray(a.local_rotation)),
                             _ptr(np.ascontiguousarray(a.local_scale)),
                             1 if a.deformation == "rigid" else 0, _ptr(means), _ptr(cov), None, None)
    full = np.empty((n, 3, 3))
    for j, (r, s) in enumerate(_RS6):
        full[:, r, s] = full[:, s, r] = cov[:, j]
    return means.astype(np.float64), full


@pytest.mark.parametrize("real", ["double", "float"])
def test_spec_worked_examples(lib, flib, real):
    """spec/README.md §Worked examples, evaluated by the header (double and float32 builds)."""
    lb = lib if real == "double" else flib
    tol = 1e-7 if real == "double" else 1e-6
    mesh = TriangleMesh([[0, 0, 0], [2, 0, 0], [0, 1, 0]], [[0, 1, 2]])
    ex1 = np.array([[0, 0, 0], [0, 4, 0], [-1, 0, 0]], np.float32)
    args = ([0], [[0.25, 0.5]], [0.125])
    for law, sigma in (("affine", np.diag([0.140625, 0.0625, 0.0078125])),
                       ("rigid", np.diag([0.28125, 0.03125, 0.0078125]))):
        a = LocalAnchors(*args, [[0, 0, 0, 1]], [[0.125, 0.375, 0.0625]], law)
        means, cov = _c_remap(lb, Anchoring(mesh, a), ex1)
        np.testing.assert_allclose(means[0], [-0.5, 1.0, 0.1767766953], atol=tol)
        np.testing.assert_allclose(cov[0], sigma, atol=tol)
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
        means, cov = _c_remap(lb, Anchoring(mesh, a), ex2)
        np.testing.assert_allclose(means[0], [0.5716245404, 0.9742961090, 0.7900765932], atol=tol)
        np.testing.assert_allclose(cov[0], sigma, atol=tol)
    gmesh = TriangleMesh([[0, 0, 0], [3, 0, 0], [0, 3, 0]], [[0, 1, 2]])
    means, cov = _c_remap(lb, Anchoring(gmesh, GamesAnchors([0], [[0.3, 0.5]], [2.0])),
                          gmesh.vertices)
    r = np.array([[0, 0.8944271910, 0.4472135955], [0, -0.4472135955, 0.8944271910], [1, 0, 0]])
    s = np.array([3e-8, 2.2360679975, 1.3416407965])
    np.testing.assert_allclose(means[0], [0.9, 1.5, 0.0], atol=tol)
    np.testing.assert_allclose(cov[0], (r * s**2) @ r.T, atol=tol)
    # Example 4: a face degenerate at rest (G := I, k := 1, m := n_c, A := R_c)
    dmesh = TriangleMesh([[0, 0, 0], [2, 0, 0], [1, 0, 0]], [[0, 1, 2]])
    ex4 = np.array([[0, 0, 0], [0, 2, 0], [0, 1, 0]], np.float32)
    for law in ("affine", "rigid"):
        a = LocalAnchors([0], [[0.25, 0.25]], [0.125], [[0, 0, 0, 1]], [[0.125, 0.375, 0.0625]],
                         law)
        means, cov = _c_remap(lb, Anchoring(dmesh, a), ex4)
        np.testing.assert_allclose(means[0], [0, 0.75, -0.125], atol=tol)
        np.testing.assert_allclose(cov[0], np.diag([0.140625, 0.015625, 0.00390625]), atol=tol)
        means, cov = _c_remap(lb, Anchoring(dmesh, a), dmesh.vertices)   # the stored splat
        np.testing.assert_allclose(means[0], [0.75, 0, 0.125], atol=tol)
        np.testing.assert_allclose(cov[0], np.diag([0.015625, 0.140625, 0.00390625]), atol=tol)
    # Example 5: games, v1 at the midpoint of v0 v2
    mmesh = TriangleMesh([[0, 0, 0], [1, 0, 0], [2, 0, 0]], [[0, 1, 2]])
    means, cov = _c_remap(lb, Anchoring(mmesh, GamesAnchors([0], [[0.3, 0.5]], [2.0])),
                          mmesh.vertices)
    np.testing.assert_allclose(means[0], [1.300000012, 0, 0], atol=tol)
    np.testing.assert_allclose(cov[0], np.diag([1.00000002, 9e-16, 4e-16]),
                               rtol=1e-6 if real == "double" else 1e-5, atol=1e-20)


def _special_mesh(rng):
    """A random mesh plus faces that v1.1 treats specially: degenerate at rest (segment, point
    and near-threshold slivers), faces that collapse or turn into slivers at the pose, and a
    face whose v1 sits at the midpoint of v0 v2 at the pose. Returns (mesh, pose)."""
    verts = rng.normal(size=(30, 3))
    faces = [rng.choice(30, 3, replace=False) for _ in range(40)]
    pose = verts + 0.3 * rng.normal(size=verts.shape)
    extra_rest, extra_pose = [], []

    def add(rest_tri, pose_tri):
        base = 30 + 3 * len(extra_rest)
        extra_rest.append(np.asarray(rest_tri, float))
        extra_pose.append(np.asarray(pose_tri, float))
        faces.append([base, base + 1, base + 2])

    q = np.linalg.qr(rng.normal(size=(3, 3)))[0]
    tri = np.array([[0.0, 0, 0], [1, 0, 0], [0.3, 0.8, 0]]) @ q.T + 0.5
    add([[0, 0, 0], [1, 0, 0], [0.5, 0, 0]], tri)                     # segment at rest
    add([[0.2, 0.1, 0], [0.2, 0.1, 0], [0.2, 0.1, 0]], tri)           # point at rest
    add([[0, 0, 0], [0, 1, 0], [0, 2, 0]], [[0, 0, 0], [0, 0, 1], [0, 0, 2]])   # segment at both
    add([[0, 0, 0], [1, 0, 0], [0.5, 0.9e-6, 0]], tri)                # sliver below threshold
    add([[0, 0, 0], [1, 0, 0], [0.5, 2e-6, 0]], tri)                  # sliver above threshold
    add(tri, [[0, 0, 0], [1, 0, 0], [0.5, 0, 0]])                     # collapses: a_c = 0
    add(tri, [[1, 1, 1], [1, 1, 1], [1, 1, 1]])                       # collapses to a point
    add(tri, [[0, 0, 0], [1, 0, 0], [0.3, 1e-6, 0]])                  # a_c at the threshold
    add(tri, [[0, 0, 0], [1, 0, 0], [0.3, 1e-7, 0]])                  # a_c below it
    add(tri, [[0, 0, 0], [1, 0, 0], [1, 0, 0]])                       # v2 = v1 (ties)
    mid = np.array([[0.1, -0.2, 0.3], [0, 0, 0], [1.1, 0.7, -0.4]], np.float32)
    mid[1] = (mid[0] + mid[2]) / np.float32(2)
    add(tri, mid)                                                     # v1 at the midpoint
    rest = np.concatenate([verts] + extra_rest).astype(np.float32)
    posed = np.concatenate([pose] + extra_pose).astype(np.float32)
    return TriangleMesh(rest, np.array(faces)), posed


def _random_local_anchors(rng, mesh, n, law):
    face = rng.integers(0, mesh.face_count, n)
    face[:mesh.face_count] = np.arange(mesh.face_count)     # every face carries a splat
    return LocalAnchors(face, rng.uniform(-0.2, 1.0, (n, 2)), rng.normal(0, 0.1, n),
                        rng.normal(size=(n, 4)), rng.uniform(0.01, 0.2, (n, 3)), law)


@pytest.mark.parametrize("real", ["double", "float"])
def test_remap_matches_reference_on_random_meshes(lib, flib, real):
    """Random and special faces (see _special_mesh), both laws and games, against the float64
    reference: double build to 1e-9, float32 build to the float32 tolerances."""
    lb = lib if real == "double" else flib
    rng = np.random.default_rng(11)
    mesh, pose = _special_mesh(rng)
    n = 300
    games = rng.integers(0, mesh.face_count, n)
    games[:mesh.face_count] = np.arange(mesh.face_count)
    for a in (_random_local_anchors(rng, mesh, n, "affine"),
              _random_local_anchors(rng, mesh, n, "rigid"),
              GamesAnchors(games, rng.uniform(-0.2, 1.0, (n, 2)), rng.uniform(0.1, 2.0, n))):
        anchoring = Anchoring(mesh, a)
        for vertices in (mesh.vertices, pose):
            ref = remap(anchoring, vertices)
            means, cov = _c_remap(lb, anchoring, vertices)
            err_mean = (np.linalg.norm(means - ref.means, axis=1)
                        / (np.linalg.norm(ref.means, axis=1) + 1.0))
            # covariances relative to their norm, floored by the splat's stored size (splats
            # on collapsed faces shrink to nothing)
            stored = (np.asarray(a.local_scale, np.float64).max(axis=1) ** 2
                      if isinstance(a, LocalAnchors) else 0.0)
            big = np.linalg.norm(ref.covariances, axis=(1, 2)) + stored
            err_cov = np.linalg.norm(cov - ref.covariances, axis=(1, 2)) / big
            if real == "double":
                # the float32 rounding of the outputs
                assert err_mean.max() < 1e-7, (a.profile, err_mean.max())
                assert err_cov.max() < 2e-7, (a.profile, err_cov.max())
            else:
                # float32 per-frame work: the normal term d m near zero current area adds up
                # to |d| 6 sqrt(u P / a_r) (spec Outputs, precision and epsilons)
                assert err_mean.max() < 1e-4, (a.profile, err_mean.max())
                assert err_cov.max() < 1e-3, (a.profile, err_cov.max())
                assert np.median(err_mean) < 1e-7 and np.median(err_cov) < 1e-6


def _sliver_case(rng, opening: float = 1e5, ratio: float = 1.1e-6):
    """One rest sliver of height ``ratio`` (a = ratio ell^2, just above the threshold),
    rotated and moved away from the origin so that float32 edges carry rounding, opened
    ``opening``x in area at the pose. Returns (mesh, pose, anchors)."""
    offset = np.array([3.7, -2.1, 5.3])
    while True:
        q = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        rest = (np.array([[0, 0, 0], [1, 0, 0], [0.4, ratio, 0]]) @ q.T + offset).astype(np.float32)
        # float32 coordinates move the apex by ~1e-7: keep slivers whose stored ratio
        # a / ell^2 is still within 5% of ``ratio`` (just above the threshold)
        t = rest.astype(np.float64)
        e1, e2 = t[1] - t[0], t[2] - t[0]
        a = np.linalg.norm(np.cross(e1, e2))
        ell2 = max(e1 @ e1, e2 @ e2, (e2 - e1) @ (e2 - e1))
        if abs(a / ell2 / ratio - 1) < 0.05:
            break
    opened = np.array([[0, 0, 0], [1, 0, 0], [0.4, ratio * opening, 0]]) @ q.T + offset
    mesh = TriangleMesh(rest, [[0, 1, 2]])
    n = 64
    d = rng.choice([-1.0, 1.0], n) * rng.uniform(0.05, 0.1, n)
    anchors = LocalAnchors(np.zeros(n, np.uint32), rng.dirichlet([1, 1, 1], n)[:, 1:], d,
                           rng.normal(size=(n, 4)), rng.uniform(1e-4, 1e-3, (n, 3)), "affine")
    return mesh, opened.astype(np.float32), anchors


def _rest_in_float32(lib, mesh: TriangleMesh):
    """The rest data a header that computed it in float32 would produce (the formulas of
    gsv_prepare_rest, evaluated in float32): what spec v1.1 forbids."""
    f32 = np.float32
    tri = mesh.vertices[mesh.faces.astype(np.intp)]           # float32
    e1, e2, e3 = tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0], tri[:, 2] - tri[:, 1]
    cr = np.cross(e1, e2).astype(f32)
    a = np.sqrt((cr * cr).sum(-1, dtype=f32))
    longest2 = np.max([(e * e).sum(-1, dtype=f32) for e in (e1, e2, e3)], axis=0)
    p = np.sqrt((e1 * e1).sum(-1, dtype=f32))
    rest = (_rest_face_type(lib.gsv_real_type) * mesh.face_count)()
    for f in range(mesh.face_count):
        assert a[f] > f32(1e-6) * longest2[f]
        t = e1[f] / p[f]
        qq = (e2[f] * t).sum(dtype=f32)
        h = a[f] / p[f]
        rest[f].inv[0], rest[f].inv[1] = f32(1) / p[f], -qq / (p[f] * h)
        rest[f].inv[2], rest[f].inv[3] = 0.0, f32(1) / h
        rest[f].area2, rest[f].inv_sqrt_area2 = a[f], f32(1) / np.sqrt(a[f])
        rest[f].regular = 1
    return rest


def test_float32_build_computes_rest_quantities_in_double(lib, flib):
    """spec v1.1: rest quantities in binary64 even where the per-frame work is float32. On a
    rest sliver just above the threshold (a = 1.1e-6 ell^2) opened 1e5x in area, the float32
    build stays within about 1e-4 |d| of the float64 reference (the float32 bound of the
    per-frame normal term); the same per-frame code with float32 rest data is off by several
    percent of |d| and more."""
    u = 2.0 ** -24
    rng = np.random.default_rng(7)
    worst, best_float_rest = 0.0, np.inf
    for trial in range(5):
        mesh, pose, anchors = _sliver_case(rng)
        anchoring = Anchoring(mesh, anchors)
        # the stored rest data is the double computation, rounded once to float32
        ref_rest = prepare_rest(mesh.triangles())
        assert ref_rest.regular[0]
        c_rest = _c_rest(flib, mesh)
        assert c_rest[0].regular == 1
        inv = np.array(c_rest[0].inv, np.float32)
        want = ref_rest.inverse_shape[0].reshape(-1).astype(np.float32)
        np.testing.assert_allclose(inv, want, rtol=2 ** -23)
        assert abs(c_rest[0].area2 - np.float32(ref_rest.area2[0])) <= 2 ** -23 * ref_rest.area2[0]
        assert abs(c_rest[0].inv_sqrt_area2 * np.sqrt(ref_rest.area2[0]) - 1) <= 2 ** -22
        ref = remap(anchoring, pose)
        d = np.abs(anchors.normal_offset.astype(np.float64))
        cur = mesh.triangles(pose)[0]
        e1, e2 = cur[1] - cur[0], cur[2] - cur[0]
        a_c, a_r = np.linalg.norm(np.cross(e1, e2)), ref_rest.area2[0]
        assert 290 < np.sqrt(a_c / a_r) < 340                  # k: opened ~1e5x in area
        # the spec's float32 bound of the normal term, plus the rounding of the output
        p = np.linalg.norm(e1) * np.linalg.norm(e2)
        bound = d * min(8 * u * p / np.sqrt(a_c * a_r), 6 * np.sqrt(u * p / a_r)) \
            + 4 * u * np.linalg.norm(ref.means, axis=1)
        means, cov = _c_remap(flib, anchoring, pose)
        err = np.linalg.norm(means - ref.means, axis=1)
        assert np.all(err < bound), np.max(err / bound)
        worst = max(worst, float(np.max(err / d)))
        big = np.linalg.norm(ref.covariances, axis=(1, 2))
        assert np.max(np.linalg.norm(cov - ref.covariances, axis=(1, 2)) / big) < 1e-4
        # the same per-frame float32 code with float32 rest data
        means32, _ = _c_remap(flib, anchoring, pose, rest=_rest_in_float32(flib, mesh))
        err32 = np.linalg.norm(means32 - ref.means, axis=1)
        assert np.max(err32 / bound) > 20
        best_float_rest = min(best_float_rest, float(np.max(err32 / d)))
        # the double build agrees with the reference to float32 output rounding
        means64, _ = _c_remap(lib, anchoring, pose)
        assert np.all(np.linalg.norm(means64 - ref.means, axis=1)
                      < 2 * u * np.linalg.norm(ref.means, axis=1))
    assert worst < 1e-4, worst
    assert best_float_rest > 0.03 and best_float_rest > 300 * worst, (best_float_rest, worst)


def test_games_midpoint_degenerate_is_stable(lib, flib):
    """v1 = the float32 midpoint of v0 v2 (|u| <= eps_deg ell): the splat lies along w with
    scale about rho |w| / 2, as the reference says, in the double and the float32 build, and
    moving v1 by one float32 step either way does not turn it."""
    rng = np.random.default_rng(5)
    tris, rho = [], []
    for _ in range(40):
        v0 = rng.uniform(-0.5, 0.5, 3)
        axis = rng.normal(size=3)
        v0, v2 = np.array([v0, v0 + rng.uniform(2, 3) * axis / np.linalg.norm(axis)], np.float32)
        mid = (v0 + v2) / np.float32(2)
        r = rng.uniform(0.5, 2.0)
        for steps in (0, 1, -1):
            v1 = mid.copy()
            for _ in range(abs(steps)):
                v1 = np.nextafter(v1, np.float32(np.sign(steps) * np.inf), dtype=np.float32)
            tris.append([v0, v1, v2])
            rho.append(r)
    tri = np.array(tris, np.float32)
    nf = len(tri)
    mesh = TriangleMesh(tri.reshape(-1, 3), np.arange(3 * nf).reshape(-1, 3))
    anchors = GamesAnchors(np.arange(nf), np.repeat(rng.dirichlet([1, 1, 1], nf // 3)[:, 1:], 3, 0),
                           rho)
    anchoring = Anchoring(mesh, anchors)
    t64 = tri.astype(np.float64)
    assert F.degenerate_mask(t64).all()
    g = (t64[:, 1] - t64[:, 0] + t64[:, 2] - t64[:, 0]) / 3
    u = t64[:, 1] - t64[:, 0] - g
    w = t64[:, 2] - t64[:, 0] - g
    ell = np.linalg.norm(t64[:, 2] - t64[:, 0], axis=1)
    assert np.all(np.linalg.norm(u, axis=1) <= 1e-6 * ell)    # the midpoint rule applies
    ref = remap(anchoring)
    main = np.asarray(anchors.rho, np.float64) * np.linalg.norm(w, axis=1) / 2 + 1e-8
    for lb, tol in ((lib, 1e-6), (flib, 1e-5)):
        means, cov = _c_remap(lb, anchoring, mesh.vertices)
        assert np.max(np.linalg.norm(means - ref.means, axis=1)) < tol
        big = np.linalg.norm(ref.covariances, axis=(1, 2))
        assert np.max(np.linalg.norm(cov - ref.covariances, axis=(1, 2)) / big) < tol
        vals, vecs = np.linalg.eigh(cov)
        np.testing.assert_allclose(np.sqrt(vals[:, 2]), main, rtol=tol)
        along = np.abs(np.einsum("ni,ni->n", vecs[:, :, 2], w / np.linalg.norm(w, axis=1)[:, None]))
        assert np.all(along > 1 - tol)
        # the same splat for v1 one float32 step either side of the midpoint
        c3 = cov.reshape(-1, 3, 3, 3)
        assert np.max(np.abs(c3 - c3[:, :1]) / big.reshape(-1, 3)[:, :1, None, None]) < 1e-5


def _c_local_faces(lib, mesh: TriangleMesh, vertices: np.ndarray):
    """gsv_local_faces for every face, as a ctypes array of gsv_local_face."""
    idx = np.ascontiguousarray(mesh.faces.reshape(-1), np.uint32)
    cur = (_local_face_type(lib.gsv_real_type) * mesh.face_count)()
    v = np.ascontiguousarray(vertices, np.float32)
    lib.gsv_local_faces(_ptr(v), _ptr(idx), mesh.face_count, _c_rest(lib, mesh), cur)
    return cur


def _moments_from_face(face, anchors: LocalAnchors):
    """Mean and covariance of every splat from one gsv_local_face, in float64 (the formulas
    of gsv_local_splats, without its float32 output rounding)."""
    o, e1, e2, m = (np.array(getattr(face, x)) for x in ("o", "e1", "e2", "m"))
    if anchors.deformation == "rigid":
        a = face.k * np.array(face.r).reshape(3, 3)
    else:
        a = np.array(face.a_aff).reshape(3, 3)
    b = anchors.barycentrics.astype(np.float64)
    d = anchors.normal_offset.astype(np.float64)
    means = o + b[:, :1] * e1 + b[:, 1:] * e2 + d[:, None] * m
    ms = a @ (quaternion.to_matrix(anchors.local_rotation)
              * anchors.local_scale.astype(np.float64)[:, None, :])
    return means, ms @ np.swapaxes(ms, 1, 2)


def test_local_remap_is_continuous_at_the_degenerate_threshold(lib):
    """The mean (scaled normal m) and the affine law ([E_c C_r^-1 | m]) do not depend on the
    current triangle's classification: squashing a current triangle through a = 1e-6 ell^2
    changes the double build's mean and covariance continuously. (Version 1 moved the mean by
    |d| k there: the normal term vanished on degenerate current triangles.)"""
    rng = np.random.default_rng(9)
    mesh = TriangleMesh([[0, 0, 0], [1, 0, 0], [0.3, 0.8, 0]], [[0, 1, 2]])
    n = 50
    f32 = np.float32
    k = np.sqrt(1e-6 / 0.8)                       # k at the threshold (a_r = 0.8)

    def squashed(h):                              # a = h, ell = |e1| = 1
        return np.array([[0, 0, 0], [1, 0, 0], [0.3, h, 0]], np.float32)

    # the float32 heights next to the threshold, and (1 -+ 1e-3) 1e-6
    below = f32(1e-6) if f32(1e-6) <= 1e-6 else np.nextafter(f32(1e-6), f32(0))
    above = np.nextafter(below, f32(1))
    pairs = {"1e-3": (f32(1e-6 * (1 - 1e-3)), f32(1e-6 * (1 + 1e-3))),
             "one float32 step": (below, above)}
    for law in ("affine", "rigid"):
        anchors = LocalAnchors(np.zeros(n), rng.uniform(0, 0.5, (n, 2)),
                               rng.choice([-1.0, 1.0], n) * rng.uniform(0.02, 0.1, n),
                               rng.normal(size=(n, 4)), rng.uniform(0.01, 0.1, (n, 3)), law)
        anchoring = Anchoring(mesh, anchors)
        d = np.abs(anchors.normal_offset.astype(np.float64))
        size = np.maximum(d, np.asarray(anchors.local_scale, np.float64).max(axis=1))
        for name, (h_lo, h_hi) in pairs.items():
            lo, hi = squashed(h_lo), squashed(h_hi)
            assert F.degenerate_mask(lo[None].astype(np.float64))[0]
            assert not F.degenerate_mask(hi[None].astype(np.float64))[0]
            delta = (float(h_hi) - float(h_lo)) / 1e-6      # relative change of a
            # the double computation (per-face data, the splat formulas in float64)
            (m_lo, c_lo), (m_hi, c_hi) = (_moments_from_face(_c_local_faces(lib, mesh, v)[0],
                                                             anchors) for v in (lo, hi))
            jump_mean = np.linalg.norm(m_hi - m_lo, axis=1)
            jump_cov = np.linalg.norm(c_hi - c_lo, axis=(1, 2))
            # only the change of the squashing itself: |m| = k changes by about delta k / 2,
            # which moves the mean by delta d k / 2 and Sigma by about delta k |A| s^2, and v2
            # moves by delta 1e-6 (through b2 e2 and E_c C_r^-1)
            move = delta * 1e-6
            assert np.all(jump_mean < delta * d * k + move), (law, name, jump_mean.max())
            assert np.all(jump_cov < (2 * delta * k + 10 * move) * size ** 2), (law, name)
            if name == "one float32 step":
                assert np.all(jump_mean < 1e-9 * size), (law, jump_mean.max())
                assert np.all(jump_cov < 1e-9 * size ** 2), (law, jump_cov.max())
            # and it is what the reference gives on both sides
            refs = [remap(anchoring, v) for v in (lo, hi)]
            for (means, cov), ref in zip(((m_lo, c_lo), (m_hi, c_hi)), refs):
                assert np.max(np.linalg.norm(means - ref.means, axis=1)) < 1e-14
                assert np.max(np.linalg.norm(cov - ref.covariances, axis=(1, 2))) < 1e-15
            # the float outputs of the header: far below version 1's jump of |d| k
            out = [_c_remap(lib, anchoring, v) for v in (lo, hi)]
            assert np.all(np.linalg.norm(out[1][0] - out[0][0], axis=1) < 1e-2 * d * k)


def _tiny_local_glb(path: Path) -> Path:
    """A small valid local asset (tetrahedron, 6 splats, FLOAT anchors, rest-consistent)."""
    from gsverse_format.io.gltf import write_gltf
    from gsverse_format.model import SplatAsset, SplatCloud, SplatPrimitive

    rng = np.random.default_rng(2)
    mesh = TriangleMesh([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]],
                        [[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])
    q = rng.normal(size=(6, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    anchors = LocalAnchors(np.arange(6) % 4, rng.uniform(0, 0.4, (6, 2)), rng.normal(0, 0.05, 6),
                           q, rng.uniform(0.01, 0.1, (6, 3)), "affine")
    anchoring = Anchoring(mesh, anchors)
    r = remap(anchoring)
    cloud = SplatCloud(r.means, r.rotations, r.scales, rng.uniform(0.2, 0.9, 6),
                       rng.normal(0, 0.3, (6, 1, 3)))
    write_gltf(SplatAsset([SplatPrimitive(cloud, anchoring, "tiny")]), path)
    return path


def _edited_glb(src: Path, dst: Path, edit) -> Path:
    """A copy of ``src`` whose accessors are changed by ``edit(accessors, values)``, where
    ``accessors`` maps anchor properties and rest attributes to accessor indices."""
    from gsverse_format.conformance.glb import accessor_bytes, pack_glb, patch_accessor, unpack_glb

    doc, blob = unpack_glb(src.read_bytes())
    for mesh in doc["meshes"]:
        for prim in mesh["primitives"]:
            khr = prim.get("extensions", {}).get("KHR_gaussian_splatting", {})
            ext = khr.get("extensions", {}).get("GSVERSE_gaussian_splatting_mesh_anchor")
            if ext is not None:
                accessors = {k: v for k, v in ext.items() if isinstance(v, int)}
                accessors.update({k.split(":")[-1]: v for k, v in prim["attributes"].items()})
    for name, values in edit(lambda n: accessor_bytes(doc, blob, accessors[n])).items():
        if not np.all(np.isfinite(values)):       # min/max cannot hold NaN in JSON
            for key in ("min", "max"):
                doc["accessors"][accessors[name]].pop(key, None)
        blob = patch_accessor(doc, blob, accessors[name], values)
    dst.write_bytes(pack_glb(doc, blob))
    return dst


def test_c_plugin_applies_the_version_1_1_reader_rules(lib, tmp_path, monkeypatch):
    """The C plugin refuses zero localRotation, negative localScale and a non-finite rest
    pose, and normalizes FLOAT localRotation (a non-unit quaternion gives the unit result)."""
    good = _tiny_local_glb(tmp_path / "good.glb")
    pose = np.array([[0, 0, 0], [1.5, 0.2, 0], [0, 0.8, 0.3], [0.1, 0, 1.2]], np.float32)
    base = CPlugin(lib)
    base.load(str(good))
    want = base.apply_pose(pose)

    def scaled_rotation(get):
        q = get("localRotation").copy()
        q[1] *= 3.0
        q[4] *= 0.25
        return {"localRotation": q}

    plugin = CPlugin(lib)
    plugin.load(str(_edited_glb(good, tmp_path / "scaled.glb", scaled_rotation)))
    got = plugin.apply_pose(pose)
    np.testing.assert_allclose(got["means"], want["means"], atol=1e-7)
    np.testing.assert_allclose(got["cov"], want["cov"], atol=1e-7)
    assert np.allclose(np.linalg.norm(plugin.rotation, axis=1), 1, atol=1e-6)

    def zero_rotation(get):
        q = get("localRotation").copy()
        q[2] = 0.0
        return {"localRotation": q}

    def negative_scale(get):
        s = get("localScale").copy()
        s[3, 1] = -s[3, 1]
        return {"localScale": s}

    def nan_position(get):
        p = get("POSITION").copy()
        p[0, 2] = np.nan
        return {"POSITION": p}

    def inf_scale(get):
        s = get("SCALE").copy()
        s[5, 0] = np.inf
        return {"SCALE": s}

    # the minimal reader refuses these files itself ...
    for edit in (zero_rotation, negative_scale, nan_position, inf_scale):
        path = _edited_glb(good, tmp_path / f"{edit.__name__}.glb", edit)
        with pytest.raises(Refused):
            CPlugin(lib).load(str(path))

    # ... and the plugin's own checks with the header's helpers refuse the same data when an
    # importer hands it over (here: a reader that does not check)
    original = read_anchored_glb

    def unchecked(name, row, col, value):
        def read(path):
            raw = original(str(good))
            target = raw.anchors.get(name) or getattr(raw, name)
            target.values = target.values.copy()
            target.values[row, col] = value
            return raw
        return read

    for (name, row, col, value), message in (
            (("localRotation", 2, slice(None), 0.0), "zero-length localRotation"),
            (("localScale", 3, 1, -0.01), "negative localScale"),
            (("positions", 0, 2, np.nan), "non-finite rest pose"),
            (("rotations", 1, 0, np.inf), "non-finite rest pose"),
            (("scales", 5, 0, np.inf), "non-finite rest pose")):
        monkeypatch.setattr(sys.modules[__name__], "read_anchored_glb",
                            unchecked(name, row, col, value))
        with pytest.raises(Refused, match=message):
            CPlugin(lib).load("unused.glb")
