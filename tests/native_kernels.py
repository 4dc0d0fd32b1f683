"""The remap kernels of native/kernels/ (GLSL 450 and HLSL compute) on a real Vulkan driver, and
the C# core of plugins/unity/ under Mono.

A harness in the sense of spec/conformance.md: the importer is the C header's (the minimal
reader, the header's dequantization and refusals, the rest quantities in double:
:class:`test_conformance_native.CPlugin`), and every pose is remapped by the kernel, compiled to
SPIR-V by glslang (its GLSL or its HLSL front-end) and dispatched through Vulkan on Mesa's
software driver lavapipe (``VK_ICD_FILENAMES`` names its ICD, so no other driver is picked)
by the small C host ``native/kernels/vulkan/gsv_vk.c``, built here with the system C compiler
against libvulkan. ``RESULTS/harness.json`` names the kernel, the compiler and the device.

    python tests/native_kernels.py glsl|hlsl|csharp SUITE RESULTS [--fault NAME] [--rotation-scale]

The C# core (``plugins/unity/Runtime``: reader, refusals, rest quantities in double, CPU remap in
float) is its own importer: ``plugins/unity/Conformance~/Harness.cs`` writes the dumps; it is
compiled with Mono's ``mcs`` and run with ``mono``.

(``scripts/native-conformance`` installs the tools, runs this and ``gsverse-conformance check``.)
``--fault`` builds a deliberately broken kernel (:data:`FAULTS`), which the suite must catch;
``--rotation-scale`` dumps the rotation + scale outputs instead of the covariances.
"""
from __future__ import annotations

import argparse
import ctypes
import glob
import json
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from test_conformance_native import CPlugin, build, compiler  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
KERNELS = ROOT / "native" / "kernels"
HOST = KERNELS / "vulkan" / "gsv_vk.c"
UNITY = ROOT / "plugins" / "unity"
#: the shading languages (run on lavapipe) and the C# core (run under Mono)
KERNEL_LANGUAGES = ("glsl", "hlsl")
LANGUAGES = KERNEL_LANGUAGES + ("csharp",)

#: per language: the kernel's entry file, the core file the faults edit, glslang's arguments
_SOURCES = {
    "glsl": ("glsl/gsverse_remap.comp", "glsl/gsverse_remap_core.glsl", ["-V"]),
    "hlsl": ("hlsl/engines/vulkan.hlsl", "hlsl/gsverse_remap_core.hlsli",
             ["-D", "-V", "-S", "comp", "-e", "main"]),
}

#: deliberately broken variants of the kernels and the C# core: (what is wrong, {language:
#: (correct text, broken text)}), the correct text occurring exactly once in the sources
FAULTS = {
    "frame-axis": ("the local profile's normal taken as e2 x e1 (a wrong frame axis)",
                   {"glsl": ("\n    cr = cross(e1, e2);", "\n    cr = cross(e2, e1);"),
                    "hlsl": ("\n    cr = cross(e1, e2);", "\n    cr = cross(e2, e1);"),
                    "csharp": ("\n            cr = Float3.Cross(e1, e2);",
                               "\n            cr = Float3.Cross(e2, e1);")}),
    "games-axis": ("the games frame's b1 built from w (towards v2) instead of u",
                   {"glsl": ("vec3 u = e1 - g, w = e2 - g", "vec3 u = e2 - g, w = e1 - g"),
                    "hlsl": ("float3 u = e1 - g, w = e2 - g", "float3 u = e2 - g, w = e1 - g"),
                    "csharp": ("Float3 u = e1 - g, w = e2 - g", "Float3 u = e2 - g, w = e1 - g")}),
    # the rotation + scale outputs (--rotation-scale): eigenvalues paired with the
    # wrong eigenvectors in the affine law's decomposition
    "scale-order": ("the affine decomposition's scales in the order (y, x, z)",
                    {"glsl": ("vec3(a[0][0], a[1][1], a[2][2])", "vec3(a[1][1], a[0][0], a[2][2])"),
                     "hlsl": ("float3(a[0][0], a[1][1], a[2][2])",
                              "float3(a[1][1], a[0][0], a[2][2])"),
                     "csharp": ("scale = new Float3(Sqrt(Math.Max(a.C0.X * norm, 0f)), "
                                "Sqrt(Math.Max(a.C1.Y * norm, 0f)),",
                                "scale = new Float3(Sqrt(Math.Max(a.C1.Y * norm, 0f)), "
                                "Sqrt(Math.Max(a.C0.X * norm, 0f)),")}),
    # the C# core is its own importer: one of its refusals dropped
    "zero-rotation-accepted": ("a zero localRotation (or derived rest ROTATION) not refused",
                               {"csharp": ("if (q[4 * i] == 0 && q[4 * i + 1] == 0",
                                           "if (q.Length < 0 && q[4 * i + 1] == 0")}),
}

#: the number of float32 values per face of the rest buffer (binding 3)
REST_STRIDE = 8


class ToolMissing(RuntimeError):
    """glslang, libvulkan, lavapipe or Mono is not installed."""


def glslang() -> str | None:
    return shutil.which("glslangValidator")


def lavapipe_icd() -> str | None:
    """The ICD manifest of Mesa's lavapipe (``lvp_icd.<arch>.json``), or None."""
    for folder in ("/usr/share/vulkan/icd.d", "/etc/vulkan/icd.d", "/usr/local/share/vulkan/icd.d"):
        found = sorted(glob.glob(os.path.join(folder, "lvp_icd*.json")))
        if found:
            return found[0]
    return None


def missing_tools(language: str = "glsl") -> list[str]:
    """What the harness of ``language`` needs and does not find (empty when it can run)."""
    out = []
    if language == "csharp":
        return [f"{tool} (Debian: {package})"
                for tool, package in (("mcs", "mono-mcs"), ("mono", "mono-runtime"))
                if shutil.which(tool) is None]
    if glslang() is None:
        out.append("glslangValidator (Debian: glslang-tools)")
    if lavapipe_icd() is None:
        out.append("lavapipe (Debian: mesa-vulkan-drivers)")
    if not Path("/usr/include/vulkan/vulkan.h").is_file():
        out.append("vulkan/vulkan.h and libvulkan (Debian: libvulkan-dev)")
    if compiler() is None:
        out.append("a C compiler (cc)")
    return out


def compile_kernel(language: str, out_dir: Path, fault: str | None = None) -> Path:
    """The kernel of ``language`` compiled to SPIR-V by glslang in ``out_dir`` (a copy of the
    sources, with ``fault`` applied to the copy)."""
    entry, core, args = _SOURCES[language]
    src = Path(out_dir) / f"src-{language}-{fault or 'ok'}"
    shutil.copytree(KERNELS / language, src / language, dirs_exist_ok=True)
    if fault is not None:
        good, bad = FAULTS[fault][1][language]
        text = (src / core).read_text(encoding="utf-8")
        if text.count(good) != 1:
            raise ValueError(f"fault {fault}: {good!r} is not in {core} exactly once")
        (src / core).write_text(text.replace(good, bad), encoding="utf-8")
    spv = Path(out_dir) / f"gsverse_remap-{language}-{fault or 'ok'}.spv"
    run = subprocess.run([glslang(), *args, str(src / entry), "-o", str(spv)],
                         capture_output=True, text=True, timeout=120)
    if run.returncode != 0:
        raise RuntimeError(f"glslangValidator failed on {entry}:\n{run.stdout}{run.stderr}")
    return spv


def build_host(out_dir: Path) -> ctypes.CDLL:
    """native/kernels/vulkan/gsv_vk.c as a shared library (strict warnings as errors)."""
    lib = Path(out_dir) / "libgsv_vk.so"
    cmd = [compiler(), "-std=c99", "-D_POSIX_C_SOURCE=200809L", "-O2", "-Wall", "-Wextra",
           "-Wno-missing-field-initializers", "-pedantic", "-Werror", "-fPIC", "-shared",
           str(HOST), "-o", str(lib), "-lvulkan"]
    subprocess.run(cmd, check=True, capture_output=True, text=True, timeout=120)
    out = ctypes.CDLL(str(lib))
    P, S, U = ctypes.c_void_p, ctypes.c_size_t, ctypes.c_uint32
    for name, args, res in (
            ("gsv_vk_open", [P, S, ctypes.c_char_p, S, ctypes.c_char_p, S], P),
            ("gsv_vk_upload", [P, ctypes.c_uint, P, S], ctypes.c_int),
            ("gsv_vk_download", [P, ctypes.c_uint, P, S], ctypes.c_int),
            ("gsv_vk_dispatch", [P, U, U, ctypes.POINTER(ctypes.c_double)], ctypes.c_int),
            ("gsv_vk_close", [P], None)):
        fn = getattr(out, name)
        fn.argtypes = args
        fn.restype = res
    return out


class Kernel:
    """One compiled kernel on lavapipe: its buffers (bindings 0..12 of the kernels) and
    dispatches."""

    def __init__(self, host: ctypes.CDLL, spirv: Path) -> None:
        icd = lavapipe_icd()
        if icd is None:
            raise ToolMissing("lavapipe is not installed (Debian: mesa-vulkan-drivers)")
        code = np.frombuffer(Path(spirv).read_bytes(), np.uint32).copy()
        device, error = ctypes.create_string_buffer(256), ctypes.create_string_buffer(256)
        self.host = host
        # the loader reads these when the instance is created: lavapipe and nothing else; put
        # back afterwards, so that processes started later (a browser) see the environment
        # they had
        names = ("VK_ICD_FILENAMES", "VK_DRIVER_FILES")
        saved = {name: os.environ.get(name) for name in names}
        os.environ.update({name: icd for name in names})
        try:
            self.handle = host.gsv_vk_open(code.ctypes.data, code.nbytes, device, 256, error,
                                           256)
        finally:
            for name, value in saved.items():
                if value is None:
                    os.environ.pop(name, None)
                else:
                    os.environ[name] = value
        if not self.handle:
            raise RuntimeError(f"Vulkan: {error.value.decode()}")
        self.device = device.value.decode()
        if "llvmpipe" not in self.device:   # lavapipe's device name (llvmpipe's JIT)
            raise RuntimeError(f"Vulkan picked {self.device!r}, not lavapipe")

    def upload(self, binding: int, array: np.ndarray) -> None:
        a = np.ascontiguousarray(array)
        if self.host.gsv_vk_upload(self.handle, binding, a.ctypes.data, a.nbytes) != 0:
            raise RuntimeError(f"Vulkan: upload to binding {binding} failed")

    def dispatch(self, splats: int, repeats: int = 1) -> float:
        seconds = ctypes.c_double(0)
        rc = self.host.gsv_vk_dispatch(self.handle, splats, repeats, ctypes.byref(seconds))
        if rc != 0:
            raise RuntimeError(f"Vulkan: dispatch failed ({rc})")
        return seconds.value

    def download(self, binding: int, shape: tuple[int, ...]) -> np.ndarray:
        out = np.zeros(shape, np.float32)
        if self.host.gsv_vk_download(self.handle, binding, out.ctypes.data, out.nbytes) != 0:
            raise RuntimeError(f"Vulkan: download of binding {binding} failed")
        return out

    def close(self) -> None:
        if self.handle:
            self.host.gsv_vk_close(self.handle)
            self.handle = None


def rest_buffer(lib: ctypes.CDLL, rest_faces: np.ndarray, faces: int) -> np.ndarray:
    """The kernels' rest buffer (float[8F]) from gsv_prepare_rest's output of a double build:
    C_r^-1, a_r, 1/sqrt(a_r), computed in double, rounded once to float32; regular as 1.0/0.0."""
    size = lib.gsv_sizeof_rest_face()
    dtype = np.dtype({"names": ["inv", "area2", "inv_sqrt", "regular"],
                      "formats": [("<f8", 4), "<f8", "<f8", "<i4"],
                      "offsets": [0, 32, 40, 48], "itemsize": size})
    rows = np.frombuffer(rest_faces.tobytes(), dtype, count=faces)
    out = np.zeros((faces, REST_STRIDE), np.float32)
    out[:, :4] = rows["inv"]
    out[:, 4] = rows["area2"]
    out[:, 5] = rows["inv_sqrt"]
    out[:, 6] = rows["regular"] != 0
    return out


def anchor_buffers(plugin: CPlugin) -> dict[int, np.ndarray]:
    """Bindings 0, 2..8 of an imported asset (everything but the current vertices)."""
    games = plugin.profile == "games"
    n = plugin.n
    params = np.array([n, 0, 1 if games else 0, 0 if games else plugin.law,
                       1 if plugin.form == "rotscale" else 0], np.uint32)
    out = {0: params, 2: plugin.indices, 4: plugin.face, 5: plugin.bary}
    if games:
        out.update({3: np.zeros(REST_STRIDE, np.float32), 6: plugin.rho,
                    7: np.zeros(4, np.float32), 8: np.zeros(3, np.float32)})
    else:
        out.update({3: rest_buffer(plugin.lib, plugin.rest_faces, plugin.faces),
                    6: plugin.offset, 7: plugin.rotation, 8: plugin.scale})
    return out


class KernelPlugin(CPlugin):
    """The C header's importer, the kernel's remap on lavapipe. ``form`` ``"rotscale"`` dumps
    the kernel's rotation + scale outputs instead of its covariances."""

    def __init__(self, lib: ctypes.CDLL, kernel: Kernel, form: str = "cov") -> None:
        super().__init__(lib, form)
        self.kernel = kernel

    def load(self, asset_path: str) -> None:
        super().load(asset_path)
        for binding, array in anchor_buffers(self).items():
            self.kernel.upload(binding, array)
        # outputs of this asset's size (the buffers are shared by the cases of a run)
        self.kernel.upload(9, np.zeros((self.n, 3), np.float32))
        self.kernel.upload(10, np.zeros((self.n, 6), np.float32))
        self.kernel.upload(11, np.zeros((self.n, 4), np.float32))
        self.kernel.upload(12, np.zeros((self.n, 3), np.float32))

    def apply_pose(self, vertices: np.ndarray) -> dict[str, np.ndarray]:
        self.kernel.upload(1, np.ascontiguousarray(vertices, np.float32))
        self.kernel.dispatch(self.n)
        means = self.kernel.download(9, (self.n, 3))
        if self.form == "rotscale":
            return {"means": means, "rotation": self.kernel.download(11, (self.n, 4)),
                    "scale": self.kernel.download(12, (self.n, 3))}
        return {"means": means, "cov": self.kernel.download(10, (self.n, 6))}


def numbers_level(manifest: dict) -> bool:
    """The cases of the numbers level (remap, rig and invalid; not the render cases)."""
    return manifest.get("kind") in ("remap", "rig", "invalid")


def build_csharp(out_dir: Path, fault: str | None = None) -> Path:
    """plugins/unity/Runtime/*.cs + Conformance~/Harness.cs compiled by mcs (a copy of the
    sources, with ``fault`` applied to the one file it edits), warnings as errors."""
    src = Path(out_dir) / f"src-csharp-{fault or 'ok'}"
    shutil.copytree(UNITY / "Runtime", src / "Runtime", dirs_exist_ok=True)
    if fault is not None:
        good, bad = FAULTS[fault][1]["csharp"]
        texts = {p: p.read_text(encoding="utf-8") for p in (src / "Runtime").glob("*.cs")}
        where = [p for p, text in texts.items() if good in text]
        if len(where) != 1 or texts[where[0]].count(good) != 1:
            raise ValueError(f"fault {fault}: {good!r} is not in Runtime/*.cs exactly once")
        where[0].write_text(texts[where[0]].replace(good, bad), encoding="utf-8")
    exe = Path(out_dir) / f"harness-{fault or 'ok'}.exe"
    sources = sorted(str(p) for p in (src / "Runtime").glob("*.cs"))
    run = subprocess.run([shutil.which("mcs"), "-warnaserror+", "-warn:4", f"-out:{exe}",
                          *sources, str(UNITY / "Conformance~" / "Harness.cs")],
                         capture_output=True, text=True, timeout=300)
    if run.returncode != 0:
        raise RuntimeError(f"mcs failed:\n{run.stdout}{run.stderr}")
    return exe


def run_csharp(suite: Path, results: Path, *, fault: str | None = None,
               work: Path | None = None, form: str = "cov") -> dict:
    """Compile the C# core and its harness, run it under Mono; returns harness.json."""
    missing = missing_tools("csharp")
    if missing:
        raise ToolMissing("missing: " + ", ".join(missing))
    with tempfile.TemporaryDirectory(prefix="gsv-csharp-") as tmp:
        exe = build_csharp(Path(work or tmp), fault)
        extra = ["--rotation-scale"] if form == "rotscale" else []
        done = subprocess.run([shutil.which("mono"), str(exe), str(suite), str(results), *extra],
                              capture_output=True, text=True, timeout=600)
        if done.returncode != 0:
            raise RuntimeError(f"the C# harness failed (exit {done.returncode}): "
                               f"{(done.stderr or done.stdout).strip()}")
    path = Path(results) / "harness.json"
    info = json.loads(path.read_text(encoding="utf-8"))
    info["fault"] = fault
    path.write_text(json.dumps(info, indent=1), encoding="utf-8")
    return info


def run(language: str, suite: Path, results: Path, *, fault: str | None = None,
        work: Path | None = None, form: str = "cov") -> dict:
    """Compile, build, run the kernel (or the C# core) over every numbers-level case; returns
    what RESULTS/harness.json holds. ``form``: ``"cov"`` dumps covariances, ``"rotscale"``
    the rotation + scale outputs."""
    from gsverse_format.conformance.harness import run_plugin

    if language == "csharp":
        return run_csharp(suite, results, fault=fault, work=work, form=form)
    missing = missing_tools()
    if missing:
        raise ToolMissing("missing: " + ", ".join(missing))
    with tempfile.TemporaryDirectory(prefix="gsv-kernels-") as tmp:
        folder = Path(work or tmp)
        spirv = compile_kernel(language, folder, fault)
        lib = build(folder, real="double")
        kernel = Kernel(build_host(folder), spirv)
        try:
            info = {"name": f"gsverse {language.upper()} compute kernel "
                            f"(native/kernels/{_SOURCES[language][0]})",
                    "compiler": f"glslang ({'HLSL' if language == 'hlsl' else 'GLSL'} "
                                "front-end) to SPIR-V",
                    "device": f"lavapipe: {kernel.device}", "precision": "float32",
                    "importer": "native/gsverse_remap.h (rest quantities in double)",
                    "fault": fault, "outputs": "rotation + scale" if form == "rotscale"
                    else "covariance"}
            run_plugin(suite, results, lambda: KernelPlugin(lib, kernel, form), info=info,
                       only=numbers_level)
        finally:
            kernel.close()
    return info


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("language", choices=LANGUAGES)
    p.add_argument("suite")
    p.add_argument("results")
    p.add_argument("--fault", choices=sorted(FAULTS), default=None,
                   help="build a deliberately broken kernel")
    p.add_argument("--rotation-scale", action="store_true",
                   help="dump the rotation + scale outputs instead of covariances")
    args = p.parse_args(argv)
    if args.fault is not None and args.language not in FAULTS[args.fault][1]:
        p.error(f"fault {args.fault} has no {args.language} variant")
    try:
        info = run(args.language, Path(args.suite), Path(args.results), fault=args.fault,
                   form="rotscale" if args.rotation_scale else "cov")
    except (ToolMissing, RuntimeError, ValueError, OSError, subprocess.CalledProcessError) as err:
        print(f"native_kernels: error: {err}", file=sys.stderr)
        return 1
    where = info.get("device") or info.get("runtime")
    print(f"native_kernels: {info['name']} on {where} -> {args.results}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
