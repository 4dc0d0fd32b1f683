"""Fuzz every reader of the toolkit, and the validator, with mutated valid files.

Seeds are small valid files built from the data model: 3DGS splat PLY (binary little and big
endian, ASCII), a PLY triangle mesh, and GLB / glTF assets (``local`` and ``games`` anchors,
quantized anchors, plain splats). Each input is one seed with one to three mutations:

* generic: bit flips, interesting bytes, interesting 32-bit integers, truncation, insertion,
  deletion, duplication of a range, splicing with another seed;
* GLB: edits of the JSON chunk (numbers replaced by interesting values, keys dropped, strings
  changed) with the container rebuilt so the edit reaches the JSON checks, and header edits;
* PLY: header edits (element counts such as 0, −1 or 10¹², property types, format line,
  missing ``end_header``).

Every input is written to a file and passed to each reader that accepts its kind:
``read_splat_ply``, ``read_ply_elements``, ``read_ply_mesh`` and ``read_mesh`` for PLY;
``read_gltf``, ``read_mesh`` and ``validate_file`` for GLB/glTF. The only acceptable outcomes
are a normal return or the toolkit's own :class:`~gsverse_format.errors.GsverseError`; any
other exception (``MemoryError`` included: sizes must be checked before allocating), a
validator ``INTERNAL_ERROR`` finding, or an input that takes longer than ``--timeout`` seconds
is a failure. Inputs that reach a new outcome join the corpus (a crude feedback loop).

``python -m fuzz.fuzz_readers --runs 100000`` is the long run; the test suite runs 2000
inputs. ``--engine atheris`` uses coverage-guided libFuzzer mutation instead, when the
``atheris`` package is installed. Exit status 1 when any input failed; failing inputs are
kept in ``--crash-dir``.
"""
from __future__ import annotations

import argparse
import contextlib
import json
import os
import random
import re
import signal
import struct
import sys
import tempfile
import time
import traceback
from dataclasses import dataclass, field
from typing import Callable

__all__ = ["seeds", "mutate", "Fuzzer", "main"]

INTERESTING_U32 = (0, 1, 2, 3, 4, 7, 8, 12, 16, 255, 256, 0x7FFF, 0x8000, 0xFFFF, 0x10000,
                   0x7FFFFFFF, 0x80000000, 0xFFFFFFFE, 0xFFFFFFFF)
INTERESTING_NUMBERS = ("0", "-1", "1", "2", "3", "4", "5120", "5121", "5123", "5125", "5126",
                       "65535", "65536", "2147483647", "4294967296", "1000000000000", "1e308",
                       "-1e308", "0.5", "1.5", "NaN", "Infinity", "true", "null", '"x"', "[]",
                       "{}")
_NUMBER = re.compile(rb"-?\d+(?:\.\d+)?(?:[eE][+-]?\d+)?")
_KEY = re.compile(rb'"([A-Za-z_:0-9]+)"\s*:')


# ---------------------------------------------------------------------------- seeds

def seeds() -> list[tuple[str, bytes]]:
    """(suffix, bytes) of small valid files of every kind the readers accept."""
    import numpy as np

    from gsverse_format.binding import bind_local
    from gsverse_format.examples import example_mesh, example_splats
    from gsverse_format.io.gltf import asset_to_gltf, gltf_to_bytes
    from gsverse_format.io.ply import write_splat_ply
    from gsverse_format.model import (Anchoring, GamesAnchors, SplatAsset, SplatPrimitive)
    from gsverse_format.remap_reference import remap

    mesh = example_mesh(subdivisions=0)
    cloud = example_splats(mesh, 12, seed=3)
    local = bind_local(cloud, mesh).anchors
    rng = np.random.default_rng(4)
    games = GamesAnchors(np.sort(rng.integers(0, mesh.face_count, 10)),
                         rng.dirichlet([2, 2, 2], 10)[:, 1:], rng.uniform(0.3, 1.0, 10))
    g = remap(Anchoring(mesh, games))
    from gsverse_format.model import SplatCloud

    gcloud = SplatCloud(g.means, g.rotations, g.scales, rng.uniform(0.2, 1, 10),
                        rng.normal(0, 0.2, (10, 1, 3)))
    anchored = SplatAsset([SplatPrimitive(cloud, Anchoring(mesh, local), "body"),
                           SplatPrimitive(cloud.subset([0, 1, 2]), None, "static")])
    out: list[tuple[str, bytes]] = []
    for asset, kw in ((anchored, {}),
                      (anchored, {"quantize": {"barycentrics": "unsigned_short",
                                               "localRotation": "byte"}}),
                      (SplatAsset([SplatPrimitive(gcloud, Anchoring(mesh, games), "g")]), {})):
        gltf = asset_to_gltf(asset, **kw)
        out.append((".glb", gltf_to_bytes(gltf, binary=True)))
    out.append((".gltf", gltf_to_bytes(asset_to_gltf(SplatAsset(
        [SplatPrimitive(gcloud, Anchoring(mesh, games), "g")])), binary=False)))
    with tempfile.TemporaryDirectory() as tmp:
        for name, kw in (("le.ply", {}), ("be.ply", {"byte_order": ">"}),
                         ("ascii.ply", {"binary": False}), ("n.ply", {"normals": True})):
            path = os.path.join(tmp, name)
            write_splat_ply(cloud.subset(range(6)), path, **kw)
            with open(path, "rb") as handle:
                out.append((".ply", handle.read()))
    v = mesh.vertices
    header = (f"ply\nformat ascii 1.0\nelement vertex {len(v)}\nproperty float x\n"
              f"property float y\nproperty float z\nelement face {mesh.face_count}\n"
              f"property list uchar int vertex_indices\nend_header\n")
    body = "".join(f"{a:.6g} {b:.6g} {c:.6g}\n" for a, b, c in v.tolist())
    body += "".join(f"3 {a} {b} {c}\n" for a, b, c in mesh.faces.tolist())
    out.append((".ply", (header + body).encode()))
    binary = (header.replace("ascii", "binary_little_endian").encode()
              + v.astype("<f4").tobytes()
              + b"".join(b"\x03" + struct.pack("<3i", *f) for f in mesh.faces.tolist()))
    out.append((".ply", binary))
    return out


# ---------------------------------------------------------------------------- mutations

def _glb_parts(data: bytes):
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


def _mutate_json(rng: random.Random, text: bytes) -> bytes:
    choice = rng.randrange(5)
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


def mutate(rng: random.Random, suffix: str, data: bytes, pool: list[tuple[str, bytes]]) -> bytes:
    """One random mutation of ``data`` (a file of kind ``suffix``)."""
    kind = rng.randrange(12)
    n = len(data)
    if kind == 0 and suffix == ".glb":
        parts = _glb_parts(data)
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


# ---------------------------------------------------------------------------- targets

class _Hang(Exception):
    pass


def _targets() -> dict[str, list[tuple[str, Callable[[str], object]]]]:
    from gsverse_format.io.gltf import read_gltf
    from gsverse_format.io.mesh import read_mesh
    from gsverse_format.io.ply import read_ply_elements, read_ply_mesh, read_splat_ply
    from gsverse_format.codes import Code
    from gsverse_format.validators.container import Options
    from gsverse_format.validators.validate import validate_file

    def validate(path: str):
        report = validate_file(path, Options(max_bytes=64 * 2 ** 20))
        internal = [f for f in report.findings if f.code == Code.INTERNAL_ERROR]
        if internal:
            raise AssertionError(f"validator INTERNAL_ERROR: {internal[0].message}")
        return report

    def read_usd(path: str):
        from gsverse_format.io.usd import read_usd as read

        return read(path, isolate=True)   # the USD library itself may crash: a child process

    gltf = [("read_gltf", read_gltf), ("read_mesh", read_mesh), ("validate", validate)]
    return {".glb": gltf, ".gltf": gltf, ".usda": [("read_usd", read_usd), ("validate", validate)],
            ".ply": [("read_splat_ply", read_splat_ply), ("read_ply_elements", read_ply_elements),
                     ("read_ply_mesh", read_ply_mesh), ("read_mesh", read_mesh)]}


@dataclass
class Failure:
    target: str
    suffix: str
    kind: str
    detail: str
    saved: str | None = None


@dataclass
class Fuzzer:
    """Runs inputs through the targets; keeps statistics and failures."""

    workdir: str
    timeout: float = 10.0
    crash_dir: str | None = None
    targets: dict = field(default_factory=_targets)
    runs: int = 0
    outcomes: dict[str, dict[str, int]] = field(default_factory=dict)
    failures: list[Failure] = field(default_factory=list)
    slowest: float = 0.0
    signatures: set = field(default_factory=set)
    corpus_size: int = 0

    def run_one(self, suffix: str, data: bytes) -> bool:
        """Run every target of ``suffix`` on ``data``; True when it reached a new outcome."""
        from gsverse_format.errors import GsverseError

        self.runs += 1
        path = os.path.join(self.workdir, "input" + suffix)
        with open(path, "wb") as handle:
            handle.write(data)
        new = False
        for name, fn in self.targets[suffix]:
            start = time.perf_counter()
            outcome = "ok"
            sig = None
            try:
                with _deadline(self.timeout):
                    result = fn(path)
                if hasattr(result, "codes"):  # a validation report: its set of codes
                    sig = (name, tuple(sorted(result.codes())))
            except GsverseError as err:
                outcome = "rejected"
                cause = re.sub(r"'[^']*'|\"[^\"]*\"|\([^)]*\)", "_", err.cause)
                sig = (name, re.sub(r"\d+", "#", cause)[:60])
            except _Hang:
                outcome = "hang"
                self._fail(name, suffix, "hang", f"more than {self.timeout:g} s", data)
            except BaseException as err:  # noqa: BLE001 - any other exception is the finding
                if isinstance(err, KeyboardInterrupt):
                    raise
                outcome = "crash"
                tb = traceback.extract_tb(err.__traceback__)
                where = f"{os.path.basename(tb[-1].filename)}:{tb[-1].lineno}" if tb else "?"
                self._fail(name, suffix, "crash", f"{type(err).__name__}: {err} at {where}"[:400],
                           data)
            if sig is not None and sig not in self.signatures:
                self.signatures.add(sig)
                new = True
            elapsed = time.perf_counter() - start
            self.slowest = max(self.slowest, elapsed)
            if elapsed > self.timeout and outcome != "hang":
                self._fail(name, suffix, "hang", f"took {elapsed:.1f} s", data)
            stats = self.outcomes.setdefault(name, {})
            stats[outcome] = stats.get(outcome, 0) + 1
        return new

    def _fail(self, target: str, suffix: str, kind: str, detail: str, data: bytes) -> None:
        saved = None
        if self.crash_dir:
            os.makedirs(self.crash_dir, exist_ok=True)
            name = f"{kind}-{target}-{len(self.failures):04d}{suffix}"
            saved = os.path.join(self.crash_dir, name)
            with open(saved, "wb") as handle:
                handle.write(data)
        self.failures.append(Failure(target, suffix, kind, detail, saved))


@contextlib.contextmanager
def _deadline(seconds: float):
    """Raise :class:`_Hang` in the main thread after ``seconds`` (POSIX timers)."""
    if not hasattr(signal, "setitimer") or seconds <= 0:
        yield
        return

    def alarm(signum, frame):
        raise _Hang()

    previous = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, seconds)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, previous)


def _limit_memory(limit: int | None) -> None:
    if not limit:
        return
    try:
        import resource

        soft, hard = resource.getrlimit(resource.RLIMIT_AS)
        if hard == resource.RLIM_INFINITY or limit < hard:
            resource.setrlimit(resource.RLIMIT_AS, (limit, hard))
    except (ImportError, ValueError, OSError):
        pass


def run_builtin(runs: int, seed: int, timeout: float, crash_dir: str | None,
                progress: bool = False) -> Fuzzer:
    """The seeded mutation fuzzer: ``runs`` inputs (the seeds themselves first)."""
    rng = random.Random(seed)
    initial = seeds()
    corpus: dict[str, list[bytes]] = {}
    for suffix, data in initial:
        corpus.setdefault(suffix, []).append(data)
    kinds, weights = [".glb", ".gltf", ".ply"], [0.4, 0.2, 0.4]
    with tempfile.TemporaryDirectory(prefix="gsverse-fuzz-") as work:
        fuzzer = Fuzzer(work, timeout, crash_dir)
        for suffix, data in initial[:runs]:
            fuzzer.run_one(suffix, data)
        start = time.perf_counter()
        while fuzzer.runs < runs:
            suffix = rng.choices(kinds, weights)[0]
            pool = corpus[suffix]
            # Favour the seeds: most inputs start from a valid file.
            data = rng.choice(pool[:len(pool) if rng.random() < 0.5 else 8])
            flat = [(s, d) for s in kinds for d in corpus[s][:8]]
            for _ in range(rng.choice((1, 1, 1, 2, 3))):
                data = mutate(rng, suffix, data, flat)
            if len(data) > 4 * 2 ** 20:
                data = data[:4 * 2 ** 20]
            if fuzzer.run_one(suffix, data) and len(pool) < 1000:
                pool.append(data)
            if progress and fuzzer.runs % 5000 == 0:
                rate = fuzzer.runs / max(time.perf_counter() - start, 1e-9)
                sys.stderr.write(f"  {fuzzer.runs} inputs, {len(fuzzer.failures)} failures, "
                                 f"corpus {sum(map(len, corpus.values()))}, {rate:.0f}/s\n")
        fuzzer.corpus_size = sum(map(len, corpus.values()))
    return fuzzer


def run_atheris(runs: int, timeout: float, crash_dir: str | None) -> int:  # pragma: no cover
    """Coverage-guided run under libFuzzer (needs ``pip install atheris``)."""
    import atheris

    with atheris.instrument_imports(include=["gsverse_format"]):
        import gsverse_format.io.gltf  # noqa: F401
        import gsverse_format.io.ply  # noqa: F401
        import gsverse_format.io.mesh  # noqa: F401
        import gsverse_format.validators.validate  # noqa: F401
    from gsverse_format.errors import GsverseError

    work = tempfile.mkdtemp(prefix="gsverse-fuzz-")
    corpus_dir = os.path.join(work, "corpus")
    os.makedirs(corpus_dir)
    for i, (suffix, data) in enumerate(seeds()):
        with open(os.path.join(corpus_dir, f"seed{i}{suffix}"), "wb") as handle:
            handle.write(data)
    targets = _targets()

    def one(data: bytes) -> None:
        suffix = (".glb" if data[:4] == b"glTF" else ".ply" if data[:3] == b"ply"
                  else ".gltf")
        path = os.path.join(work, "input" + suffix)
        with open(path, "wb") as handle:
            handle.write(data)
        for _, fn in targets[suffix]:
            try:
                fn(path)
            except GsverseError:
                pass

    args = [sys.argv[0], f"-runs={runs}", f"-timeout={int(max(timeout, 1))}",
            "-max_len=65536", corpus_dir]
    if crash_dir:
        os.makedirs(crash_dir, exist_ok=True)
        args.insert(1, f"-artifact_prefix={crash_dir.rstrip('/')}/")
    atheris.Setup(args, one)
    atheris.Fuzz()
    return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m fuzz.fuzz_readers",
                                     description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=100000, help="inputs to run (default 100000)")
    parser.add_argument("--seed", type=int, default=0, help="random seed (builtin engine)")
    parser.add_argument("--timeout", type=float, default=10.0,
                        help="seconds one reader may take on one input (default 10)")
    parser.add_argument("--crash-dir", default=None,
                        help="keep failing inputs here (default: a new temporary folder)")
    parser.add_argument("--engine", choices=("builtin", "atheris"), default="builtin")
    parser.add_argument("--memory-limit", type=int, default=8 * 2 ** 30, metavar="BYTES",
                        help="address-space limit of the run, so that an unchecked huge "
                             "allocation fails instead of exhausting the machine (default 8 GiB;"
                             " 0: none)")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")
    args = parser.parse_args(argv)
    _limit_memory(args.memory_limit)
    crash_dir = args.crash_dir or tempfile.mkdtemp(prefix="gsverse-fuzz-crashes-")
    if args.engine == "atheris":
        return run_atheris(args.runs, args.timeout, crash_dir)
    start = time.perf_counter()
    fuzzer = run_builtin(args.runs, args.seed, args.timeout, crash_dir, not args.quiet)
    elapsed = time.perf_counter() - start
    crashes = sum(1 for f in fuzzer.failures if f.kind == "crash")
    hangs = sum(1 for f in fuzzer.failures if f.kind == "hang")
    print(f"inputs: {fuzzer.runs}  crashes: {crashes}  hangs: {hangs}  "
          f"corpus: {fuzzer.corpus_size}  distinct rejections: {len(fuzzer.signatures)}  "
          f"slowest: {fuzzer.slowest:.3f} s  time: {elapsed:.1f} s  seed: {args.seed}")
    for name, stats in sorted(fuzzer.outcomes.items()):
        print(f"  {name:<18} " + "  ".join(f"{k} {v}" for k, v in sorted(stats.items())))
    for f in fuzzer.failures[:20]:
        print(f"FAIL {f.kind} {f.target} {f.suffix}: {f.detail} -> {f.saved}")
    if not fuzzer.failures:
        with contextlib.suppress(OSError):
            os.rmdir(crash_dir)
    return 1 if fuzzer.failures else 0


if __name__ == "__main__":
    sys.exit(main())
