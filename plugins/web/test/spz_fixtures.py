"""Fixtures of plugins/web/test/spz.test.mjs, made by the Python package at test time:

    python spz_fixtures.py OUT

OUT/capsule-spz.glb (gsverse-convert --compress spz of examples/capsule) and the rest pose the
Python reader decodes from it (OUT/capsule.<attr>.f32); random SPZ streams of versions 2 and 3
(OUT/random-v<N>.spz, gzipped) and what the Python decoder makes of them in glTF's frame
(OUT/random-v<N>.<attr>.f32).
"""
from __future__ import annotations

import gzip
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np

import gsverse_format
from gsverse_format.io import spz_stream
from gsverse_format.io.gltf.spz import _from_stream

ROOT = Path(__file__).resolve().parents[3]


def dump(out: Path, stem: str, cloud) -> None:
    for name, values in (("means", cloud.means), ("rotations", cloud.rotations),
                         ("scales", cloud.scales), ("opacity", cloud.opacities), ("sh", cloud.sh)):
        (out / f"{stem}.{name}.f32").write_bytes(np.ascontiguousarray(values, "<f4").tobytes())


def main() -> None:
    out = Path(sys.argv[1])
    out.mkdir(parents=True, exist_ok=True)
    glb = out / "capsule-spz.glb"
    subprocess.run([sys.executable, "-m", "gsverse_format.cli.convert",
                    str(ROOT / "examples/capsule/splats.ply"), str(glb), "--mesh",
                    str(ROOT / "examples/capsule/mesh.obj"), "--compress", "spz", "-q"], check=True)
    dump(out, "capsule", gsverse_format.read(glb).primitives[0].splats)
    rng = np.random.default_rng(7)
    for version in (2, 3):
        n, degree, bits = 64, 3, 10
        sizes = spz_stream.attribute_sizes(version, n, degree)
        body = rng.integers(0, 256, sum(sizes.values()), dtype=np.uint8).tobytes()
        data = struct.pack("<IIIBBBB", spz_stream.MAGIC, version, n, degree, bits, 0, 0) + body
        (out / f"random-v{version}.spz").write_bytes(gzip.compress(data, mtime=0))
        header = spz_stream.parse_header(data, "random")
        parts, _ = spz_stream.split_stream(data, header, "random")
        dump(out, f"random-v{version}", _from_stream(spz_stream.decode(header, parts), "srgb_rec709_display"))


if __name__ == "__main__":
    main()
