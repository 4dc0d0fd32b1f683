"""The web splat formats (.splat, .ksplat, .spz, compressed PLY, SOG) against PlayCanvas
splat-transform, which reads all five and writes three.

Every file is made here: from a generated (or, where ``../shared/data`` is present, a real)
3DGS PLY, splat-transform writes compressed PLY, spz (v3, v4) and SOG; the encoders of
``tests/splat_writers.py`` write ``.splat``, ``.ksplat`` (levels 0, 1, 2), spz v2 and SOG v1
and v2. Each file
is then decoded twice — by :mod:`gsverse_format.io.splatformats` and by splat-transform (back
to a plain PLY) — and the two are compared splat by splat: means, covariances, opacities and SH.
Without splat-transform (``npm ci`` in ``tests/splat_transform``) these tests skip, or fail
under ``GSVERSE_REQUIRE_NODE_TOOLS=1``.

Tolerances: both decoders compute the same dequantization, one in float64 and rounded once,
the other in float32: means and SH to 1e-5 absolute (values of order 1), covariances to
1e-5 of the splat's largest variance, opacities to 2e-6 (splat-transform keeps decoded
opacities 1e-6 away from 0 and 1 for some formats; this package keeps 0 and 1).
``.splat`` is the exception for covariances: splat-transform decodes its quaternion bytes
as ``byte / 127.5 − 1`` and this package as ``(byte − 128) / 128`` (the inverse of
antimatter15's writer), a difference below one quantization step of the rotation: 3 % of
the largest variance.
"""
from __future__ import annotations

import os
import shutil
import struct
import subprocess
from pathlib import Path

import numpy as np
import pytest

from gsverse_format import api
from gsverse_format.errors import FormatError, GsverseError
from gsverse_format.io.ply import read_ply_elements, read_splat_ply, write_splat_ply
from gsverse_format.io.registry import FRAMES, find_format, read_asset
from gsverse_format.io.splatformats import decode
from gsverse_format.model import SplatCloud
from gsverse_format.vocabulary import SH_C0
from gsverse_format.io.splatformats.spz import COORDINATE_SYSTEMS, storage_to_rub
from splat_writers import (spz_coordinate_system, write_antimatter_splat, write_ksplat,
                           write_sog, write_spz_v2)

ROOT = Path(__file__).resolve().parent.parent
TOOL = ROOT / "tests" / "splat_transform"
CLI = TOOL / "node_modules" / "@playcanvas" / "splat-transform" / "bin" / "cli.mjs"


def _require_splat_transform() -> None:
    reason = None
    if shutil.which("node") is None:
        reason = "node is not on PATH"
    elif not CLI.is_file():
        reason = f"splat-transform is not installed: run 'npm ci' in {TOOL}"
    if reason is None:
        return
    if os.environ.get("GSVERSE_REQUIRE_NODE_TOOLS") == "1":
        pytest.fail(reason + "; required by GSVERSE_REQUIRE_NODE_TOOLS=1", pytrace=False)
    pytest.skip(reason)


def splat_transform(*args: str | os.PathLike) -> None:
    """Run splat-transform (quiet, overwriting; SOG compression on the CPU)."""
    _require_splat_transform()
    cmd = ["node", str(CLI), "-q", "-w", "-g", "cpu", *map(str, args)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=600, cwd=TOOL)
    assert proc.returncode == 0, proc.stderr[-2000:]


def their_decode(path: Path) -> SplatCloud:
    """What splat-transform decodes from ``path``, through a plain PLY, activated here with
    numpy (its PLY may hold an opacity logit of −inf for a fully transparent splat, which the
    3DGS PLY reader refuses)."""
    back = path.with_name(path.name + ".decoded.ply")
    splat_transform(path, back)
    v = read_ply_elements(back)["vertex"]
    col = lambda *names: np.stack([v[n].astype(np.float64) for n in names], axis=1)  # noqa: E731
    rest = sorted((n for n in v.dtype.names if n.startswith("f_rest_")),
                  key=lambda n: int(n[7:]))
    k = len(rest) // 3 + 1
    sh = np.zeros((len(v), k, 3))
    sh[:, 0] = col("f_dc_0", "f_dc_1", "f_dc_2")
    if rest:
        sh[:, 1:] = col(*rest).reshape(len(v), 3, k - 1).transpose(0, 2, 1)
    q = col("rot_1", "rot_2", "rot_3", "rot_0")
    with np.errstate(over="ignore"):
        opacity = 1.0 / (1.0 + np.exp(-col("opacity")[:, 0]))
    return SplatCloud(col("x", "y", "z"), q / np.linalg.norm(q, axis=1)[:, None],
                      np.exp(col("scale_0", "scale_1", "scale_2")), opacity, sh)


def random_cloud(n: int = 700, degree: int = 3, seed: int = 5) -> SplatCloud:
    rng = np.random.default_rng(seed)
    q = rng.normal(size=(n, 4))
    sh = rng.normal(size=(n, (degree + 1) ** 2, 3)) * 0.3
    sh[:, 0] = rng.uniform(-1.5, 1.5, (n, 3))
    return SplatCloud(rng.normal(size=(n, 3)) * 2.0, q / np.linalg.norm(q, axis=1)[:, None],
                      np.exp(rng.uniform(-5.0, -1.0, (n, 3))), rng.uniform(0.02, 0.98, n), sh)


def assert_same_splats(ours: SplatCloud, theirs: SplatCloud, cov_tol: float = 1e-5) -> None:
    assert len(ours) == len(theirs)
    assert ours.sh_degree == theirs.sh_degree
    np.testing.assert_allclose(ours.means, theirs.means, rtol=0, atol=1e-5)
    scale = np.maximum(ours.scales.max(axis=1), theirs.scales.max(axis=1)).astype(np.float64) ** 2
    diff = np.abs(ours.covariances() - theirs.covariances()).max(axis=(1, 2)) / scale
    assert diff.max() <= cov_tol, (diff.max(), int(diff.argmax()))
    np.testing.assert_allclose(ours.opacities, theirs.opacities, rtol=0, atol=2e-6)
    np.testing.assert_allclose(ours.sh, theirs.sh, rtol=0, atol=1e-5)


def matched(original: SplatCloud, decoded: SplatCloud) -> SplatCloud:
    """``original`` in the order of ``decoded`` (splat-transform reorders splats spatially
    for compressed PLY and SOG): each decoded splat's nearest original mean."""
    from scipy.spatial import cKDTree

    _, index = cKDTree(original.means).query(decoded.means)
    assert len(set(index.tolist())) == len(decoded), "decoded splats do not match one to one"
    return original.subset(index)


#: format name, splat-transform output suffix, extra splat-transform options
WRITTEN_BY_THEM = [("compressed-ply", ".compressed.ply", ()),
                   ("spz", ".spz", ("--spz-version", "3")),
                   ("spz", ".spz", ("--spz-version", "4")),
                   ("sog", ".sog", ())]


@pytest.mark.parametrize("name,suffix,options", WRITTEN_BY_THEM,
                         ids=["compressed-ply", "spz-v3", "spz-v4", "sog"])
def test_files_splat_transform_writes_decode_as_it_decodes_them(tmp_path, name, suffix, options):
    original = random_cloud()
    source = tmp_path / "in.ply"
    write_splat_ply(original, source)
    path = tmp_path / f"scene{suffix}"
    splat_transform(*options, source, path)
    assert find_format(path).name == name
    ours = decode(name, path)
    assert_same_splats(ours.splats, their_decode(path))
    # and within the format's quantization of what was written
    ref = matched(original, ours.splats)
    extent = np.ptp(original.means, axis=0).max()
    step = {"compressed-ply": extent / 1023, "spz": 2.0 ** -12, "sog": 5e-3}[name]
    assert np.abs(ours.splats.means - ref.means).max() <= step
    assert np.abs(ours.splats.opacities - ref.opacities).max() <= 1 / 255 + 1e-6   # one step
    if name == "sog":   # the same scene unzipped: a folder with meta.json
        import zipfile
        with zipfile.ZipFile(path) as archive:
            archive.extractall(tmp_path / "unzipped")
        meta = tmp_path / "unzipped" / "meta.json"
        assert find_format(meta).name == "sog"
        unzipped = decode("sog", meta)
        np.testing.assert_array_equal(unzipped.splats.means, ours.splats.means)
        np.testing.assert_array_equal(unzipped.splats.sh, ours.splats.sh)
        assert set(unzipped.parts) == set(ours.parts)


@pytest.mark.parametrize("level", [0, 1, 2])
def test_ksplat_levels_decode_as_splat_transform_decodes_them(tmp_path, level):
    original = random_cloud(degree=2)
    path = tmp_path / f"scene{level}.ksplat"
    write_ksplat(original, path, level=level, bucket_capacity=256)   # 2 full + 1 partial
    ours = decode("ksplat", path)
    assert ours.version.endswith(f"level {level}")
    assert_same_splats(ours.splats, their_decode(path))
    assert np.abs(ours.splats.opacities - original.opacities).max() <= 0.5 / 255 + 1e-6
    dc = np.abs(ours.splats.sh[:, 0] - original.sh[:, 0]).max()
    assert dc <= 0.5 / 255 / SH_C0 + 1e-6
    if level == 0:   # float32 storage: exact
        np.testing.assert_array_equal(ours.splats.means, original.means)
        np.testing.assert_array_equal(ours.splats.sh[:, 1:], original.sh[:, 1:])


def test_antimatter_splat_decodes_as_splat_transform_decodes_it(tmp_path):
    original = random_cloud(degree=0)
    path = tmp_path / "scene.splat"
    write_antimatter_splat(original, path)
    ours = decode("splat", path)
    assert_same_splats(ours.splats, their_decode(path), cov_tol=0.03)
    np.testing.assert_array_equal(ours.splats.means, original.means)
    np.testing.assert_array_equal(ours.splats.scales, original.scales)


@pytest.mark.parametrize("version", [1, 2])
def test_sog_versions_decode_as_splat_transform_decodes_them(tmp_path, version):
    """Both SOG layouts (v1: per-channel ranges, v2: codebooks), archived and unbundled."""
    original = random_cloud(n=500, degree=2)
    path = tmp_path / "scene.sog"
    write_sog(original, path, version=version)
    ours = decode("sog", path)
    assert ours.version == f"SOG v{version}"
    assert_same_splats(ours.splats, their_decode(path))
    (tmp_path / "folder").mkdir()
    write_sog(original, tmp_path / "folder" / "meta.json", version=version)
    unbundled = decode("sog", tmp_path / "folder" / "meta.json")
    np.testing.assert_array_equal(unbundled.splats.means, ours.splats.means)
    np.testing.assert_array_equal(unbundled.splats.sh, ours.splats.sh)
    # within the layout's quantization of what was written
    span = np.ptp(np.log1p(np.abs(original.means.astype(np.float64))), axis=0).max()
    bound = span / 65535 * (1 + np.abs(original.means).max()) + 1e-6   # d|x| = e^|v| d|v|
    assert np.abs(ours.splats.means - original.means).max() <= bound
    assert np.abs(ours.splats.opacities - original.opacities).max() <= 1 / 255 + 1e-6


def test_spz_v2_decodes_as_splat_transform_decodes_it(tmp_path):
    original = random_cloud(degree=1)
    path = tmp_path / "scene.spz"
    write_spz_v2(original, path)
    ours = decode("spz", path)
    assert ours.version == "spz v2"
    assert_same_splats(ours.splats, their_decode(path))
    assert np.abs(ours.splats.means - original.means).max() <= 2.0 ** -13 + 1e-7


def test_spz_lands_where_the_ply_of_the_same_splats_goes(tmp_path):
    """spz stores RUB: a PLY's splats with y and z flipped (as spz's own converter writes
    them) read back, frame changed, where the PLY itself is read."""
    original = random_cloud(degree=1)
    write_splat_ply(original, tmp_path / "scene.ply")
    flip = np.diag([1.0, -1.0, -1.0])
    from gsverse_format.transform import rotate_splats
    write_spz_v2(rotate_splats(original, flip), tmp_path / "scene.spz")
    from_ply = read_asset(tmp_path / "scene.ply").primitives[0].splats
    from_spz = read_asset(tmp_path / "scene.spz").primitives[0].splats
    assert np.abs(from_spz.means - from_ply.means).max() <= 2.0 ** -13 + 1e-6
    raw = read_asset(tmp_path / "scene.spz", frame_change=False).primitives[0].splats
    np.testing.assert_allclose(raw.means @ FRAMES["spz-rub"].to_gltf.T, from_spz.means,
                               atol=1e-6)


def test_spz_declaring_its_storage_frame_is_turned_into_rub(tmp_path):
    """SPZ_ADOBE_coordinate_system: a file declaring RDF (the PLY's frame) holds the PLY's
    coordinates and reads like the PLY; an unknown record is skipped with a note; a
    left-handed storage frame is refused."""
    original = random_cloud(degree=2)
    write_splat_ply(original, tmp_path / "scene.ply")
    rdf = COORDINATE_SYSTEMS.index("RDF") + 1
    write_spz_v2(original, tmp_path / "rdf.spz",
                 extensions=struct.pack("<II", 0x12345678, 3) + b"abc" + spz_coordinate_system(rdf))
    decoded = decode("spz", tmp_path / "rdf.spz")
    assert any("stored in RDF" in n for n in decoded.notes)
    assert any("1 spz extension record(s) not read" in n for n in decoded.notes)
    from_ply = read_asset(tmp_path / "scene.ply").primitives[0].splats
    from_spz = read_asset(tmp_path / "rdf.spz").primitives[0].splats
    assert np.abs(from_spz.means - from_ply.means).max() <= 2.0 ** -13 + 1e-6
    scale = from_ply.scales.max(axis=1).astype(np.float64) ** 2
    cov = np.abs(from_spz.covariances() - from_ply.covariances()).max(axis=(1, 2)) / scale
    assert np.median(cov) < 0.05   # spz v2's 8-bit quaternions
    inside = np.abs(from_ply.sh[:, 1:]) < 127 / 128          # spz clamps SH to [-1, 127/128]
    assert np.abs(from_spz.sh[:, 1:] - from_ply.sh[:, 1:])[inside].max() <= 1 / 256 + 1e-6
    ruf = COORDINATE_SYSTEMS.index("RUF") + 1
    write_spz_v2(original, tmp_path / "ruf.spz", extensions=spz_coordinate_system(ruf))
    with pytest.raises(FormatError, match="left-handed RUF frame"):
        decode("spz", tmp_path / "ruf.spz")
    np.testing.assert_array_equal(storage_to_rub("RUB"), np.eye(3))


def test_convert_reads_each_format(tmp_path):
    original = random_cloud(n=300, degree=1)
    source = tmp_path / "in.ply"
    write_splat_ply(original, source)
    splat_transform(source, tmp_path / "a.compressed.ply")
    write_ksplat(original, tmp_path / "a.ksplat", level=1)
    for name in ("a.compressed.ply", "a.ksplat"):
        summary = api.convert(tmp_path / name, tmp_path / f"{name}.out.ply")
        assert summary.source in ("compressed-ply", "ksplat")
        back = read_splat_ply(tmp_path / f"{name}.out.ply")
        assert len(back) == len(original)
    # with a mesh: the source is detected and the splats are anchored to it
    mesh = tmp_path / "mesh.obj"
    mesh.write_text("v -9 -9 0\nv 9 -9 0\nv 0 9 0\nv 0 0 9\nf 1 2 3\nf 1 2 4\nf 2 3 4\n"
                    "f 3 1 4\n")
    summary = api.convert(tmp_path / "a.ksplat", tmp_path / "a.glb", mesh=str(mesh))
    assert summary.source == "ksplat"
    asset = api.read(tmp_path / "a.glb")
    assert asset.splat_count() == len(original) and asset.anchored


@pytest.mark.parametrize("name,content,cause", [
    ("bad.splat", b"\0" * 33, "not a whole number of 32-byte"),
    ("bad.spz", b"hello world", "not an spz file"),
    ("trunc.spz", None, "truncated"),
    ("bad.ksplat", b"\0" * 100, "shorter than the 4096-byte"),
    ("bad.sog", b"PK\x03\x04 broken", "broken zip archive"),
    ("meta.json", b'{"means": 1, "quats": 2}', "meta.json has no"),
])
def test_bad_files_are_one_line_errors(tmp_path, name, content, cause):
    path = tmp_path / name
    if content is None:
        import gzip
        content = gzip.compress(np.array([0x5053474E, 3, 1000, 0], "<u4").tobytes())
    path.write_bytes(content)
    with pytest.raises(FormatError) as info:
        api.read(path)
    assert cause in str(info.value) and str(path) in str(info.value)
    assert "\n" not in str(info.value)
    proc = subprocess.run([os.sys.executable, "-m", "gsverse_format.cli.convert", str(path),
                           str(tmp_path / "out.glb")], capture_output=True, text=True,
                          timeout=300)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    assert len(proc.stderr.strip().splitlines()) == 1 and cause in proc.stderr
    assert not (tmp_path / "out.glb").exists()


def test_compressed_ply_is_told_from_a_3dgs_ply_by_content(tmp_path):
    write_splat_ply(random_cloud(n=20, degree=0), tmp_path / "plain.ply")
    assert find_format(tmp_path / "plain.ply").name == "ply"
    splat_transform(tmp_path / "plain.ply", tmp_path / "packed.compressed.ply")
    os.replace(tmp_path / "packed.compressed.ply", tmp_path / "packed.ply")
    assert find_format(tmp_path / "packed.ply").name == "compressed-ply"
    assert api.read(tmp_path / "packed.ply").splat_count() == 20


SAMPLES = ["3dgs/schwa_test-splat.3-points-from-train.ply",
           "3dgs/donut_mipsplatting_sh0_fused.ply",
           "3dgs/404gen_tmp_model_dreamgaussian_sh0.ply"]


@pytest.mark.parametrize("sample", SAMPLES, ids=lambda s: Path(s).stem.split("_")[0])
def test_real_captures_in_every_format(shared_data, tmp_path, sample):
    """Real 3DGS outputs (SH 3 and SH 0, unnormalized quaternions) through each format."""
    source = shared_data / sample
    original = read_splat_ply(source)
    for name, suffix, options in WRITTEN_BY_THEM:
        path = tmp_path / f"scene{suffix}"
        splat_transform(*options, source, path)
        ours = decode(name, path)
        assert_same_splats(ours.splats, their_decode(path))
        assert len(ours.splats) == len(original)
    write_ksplat(original.with_sh_degree(min(original.sh_degree, 2)), tmp_path / "s.ksplat",
                 level=1)
    assert_same_splats(decode("ksplat", tmp_path / "s.ksplat").splats,
                       their_decode(tmp_path / "s.ksplat"))
    write_antimatter_splat(original, tmp_path / "s.splat")
    assert_same_splats(decode("splat", tmp_path / "s.splat").splats,
                       their_decode(tmp_path / "s.splat"), cov_tol=0.03)


def test_every_format_says_its_frame():
    for suffix in (".splat", ".ksplat", ".spz", ".sog"):
        fmt = find_format(f"x{suffix}")
        assert fmt.frame in FRAMES and fmt.write is None
    assert find_format("x.spz").frame == "spz-rub"
    with pytest.raises(GsverseError, match="unsupported output format .spz"):
        find_format("x.spz", "write")


def test_mutated_files_fail_only_with_one_line_errors(tmp_path):
    """Random byte changes and truncations of each kind of file: a decoder either reads the
    file or raises a GsverseError, never another exception or a numpy warning."""
    import warnings

    cloud = random_cloud(n=300, degree=2)
    seeds = {"splat": tmp_path / "s.splat", "ksplat": tmp_path / "k.ksplat",
             "spz": tmp_path / "s.spz"}
    write_antimatter_splat(cloud, seeds["splat"])
    write_ksplat(cloud, seeds["ksplat"], level=1, bucket_capacity=128)
    write_spz_v2(cloud, seeds["spz"])
    seeds["sog"] = tmp_path / "s.sog"
    write_sog(cloud, seeds["sog"])
    rng = np.random.default_rng(11)
    for name, seed in seeds.items():
        data = seed.read_bytes()
        for trial in range(120):
            d = bytearray(data)
            if trial % 3 == 0:
                d = d[:int(rng.integers(0, len(d)))]
            else:
                for i in rng.integers(0, min(len(d), 8192), int(rng.integers(1, 16))):
                    d[int(i)] = int(rng.integers(0, 256))
            path = tmp_path / f"m{seed.suffix}"
            path.write_bytes(bytes(d))
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                try:
                    decode(name, path)
                except GsverseError as exc:
                    assert "\n" not in str(exc) and str(path) in str(exc)
    # SOG's meta.json: members replaced by values of other types and ranges
    import json
    (tmp_path / "folder").mkdir()
    write_sog(cloud, tmp_path / "folder" / "meta.json")
    meta = json.loads((tmp_path / "folder" / "meta.json").read_text())
    values = [None, True, -1, 0, 10 ** 12, 1.5, "x", [], [1], {}, [1, 2, 3], ["../s.sog"]]
    keys = [(group, key) for group, body in meta.items() if isinstance(body, dict)
            for key in body] + [(key,) for key in meta]
    for trial in range(150):
        bad = json.loads(json.dumps(meta))
        where = keys[int(rng.integers(0, len(keys)))]
        node = bad
        for key in where[:-1]:
            node = node[key]
        node[where[-1]] = values[int(rng.integers(0, len(values)))]
        path = tmp_path / "folder" / "mutated.json"
        path.write_text(json.dumps(bad))
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            try:
                decode("sog", path)
            except GsverseError as exc:
                assert "\n" not in str(exc) and str(path) in str(exc)
