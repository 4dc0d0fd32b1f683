"""``gsverse-convert``: splats from 3DGS, SuGaR, TRELLIS, GaMeS or KHR glTF -> anchored GLB.

One file: ``gsverse-convert IN OUT`` (or ``IN -o OUT``); many: ``gsverse-convert IN...
--output-dir DIR`` (or ``-o DIR`` when DIR is plainly a folder; :mod:`gsverse_format.batch`,
local processes or ``--scheduler`` on Dask). The flags shared by every command (``-o``,
``-w``, ``-q``, ``--json``, ``--version``) are those of :mod:`gsverse_format.cli.grammar`.

Exit codes: 0 success, 1 bad input (a missing or unreadable input included), an output the
system refuses to write, or a failed conversion (in a batch: any asset failed), 2 usage error
(an existing output without ``-w`` included), 130 interrupted (143 SIGTERM, 129 SIGHUP: handled
like Ctrl-C, no output or temporary file left), 141 standard output closed by its reader
(:mod:`gsverse_format.cli.boundary`). Errors are one line on stderr (``gsverse-convert: error:
<file>: <cause>``), never a traceback.
"""
from __future__ import annotations

import argparse
import json
import os
import shutil
import sys
import tempfile
from typing import IO

from ..textsafe import escape, safe_line
from ..converters import SOURCES
from ..pipeline import ConvertOptions, ConvertSummary, convert
from ..edit import SplatEdit
from ..errors import GsverseError, OutputError, UsageError
from ..progress import Progress
from .boundary import closed_stdout_error, parse_args, run_command
from .edit_flags import EDIT_EPILOG, EDIT_OPTIONS, add_edit_flags
from .grammar import (Parser, add_json, add_output, add_overwrite, add_quiet, add_version,
                      output_kind, require_input)

PROG = "gsverse-convert"
#: ``--to`` choices (output suffixes without the dot) and those that can go to standard output.
TO_FORMATS = ("glb", "gltf", "ply", "usda", "usdc", "usd", "usdz")
STDOUT_FORMATS = ("glb", "ply")

EPILOG = """\
examples:
  gsverse-convert splats.ply anchored.glb --mesh mesh.obj
  gsverse-convert splats.ply -o anchored.glb --mesh mesh.obj     # the same
  gsverse-convert scans/*.ply --output-dir out/ --plain          # many files, all CPUs
  gsverse-convert 'library/**/*.ply' manifest.csv -o out/ -j 8   # quoted glob, manifest
  gsverse-convert assets.json -o out/ --scheduler tcp://host:8786   # on a Dask cluster
  cat splats.ply | gsverse-convert - - --to glb --plain > out.glb

-o PATH:
  the output, as in every gsverse command. One input: -o OUT is OUT (a file name ending in
  .glb, .gltf, .ply, .usda, .usdc, .usd or .usdz, or '-'). A folder (one that exists, a path
  ending in '/', or a name without a suffix) makes a batch: -o DIR is --output-dir DIR. Any
  other name is refused (exit 2): a file name never becomes a folder. Several inputs need a
  folder: -o out.glb with several inputs is refused too.

existing outputs:
  like splat-transform, an existing output is never replaced unless -w/--overwrite is given
  (exit 2, nothing written). A batch checks every output before it starts; --skip-existing
  keeps existing outputs and converts the rest (resuming an interrupted batch: outputs are
  written atomically, so an existing output is a complete one).

batch (--output-dir DIR, or -o DIR):
  inputs are files or folders, glob patterns (*, ?, [..], ** for any depth; quote them for
  large libraries) and manifests (.csv or .json). Each output is DIR/<the input's path
  relative to the inputs' common folder> with the --to suffix (default glb), or the
  manifest's output. The command line's options apply to every asset; a manifest overrides
  them per asset. Conversions run in --jobs local processes (default: the CPU count; one asset
  at a time each) with a progress bar over files; a failing asset is reported (one line on
  stderr, or in --json) and the others still convert. Exit status 0 when all converted,
  1 when any failed, 2 for usage errors (nothing converted), 130 when interrupted (143 by
  SIGTERM, 129 by SIGHUP).
  --json prints {output_dir, scheduler, jobs, total, ok, failed, skipped, interrupted,
  seconds, assets: [{input, output, status, error, summary}]} (counts, then one entry per
  asset in input order; status ok, failed, skipped or interrupted; error: one line; summary:
  the single-file --json summary).

manifests:
  CSV with a header row, or JSON: a list of objects (or {"assets": [...]}; a bare string is an
  input). Keys: input (required), output (relative to DIR), mesh, from, pt, k, deformation,
  max-distance, absolute-distance, drop-unanchored, faces, reconstruct-faces, sh-degree,
  keep-order, plain, legacy-trellis-frame, no-frame-change, bake-poses, watertight,
  collider, physics, mass, ground, translate, rotate, scale, mesh-translate, mesh-rotate,
  mesh-scale, drop-nonfinite, crop-box, crop-sphere, min-opacity (one mesh per asset; dashes or
  underscores). Paths are relative to the manifest's folder; booleans true/false, yes/no or
  1/0; an empty cell or a missing key takes the command line's value. Example CSV:
      input,mesh,output,faces
      chair/splats.ply,chair/mesh.obj,chair.glb,5000
      tree/splats.ply,,tree.glb,

Dask (--scheduler ADDRESS):
  the same batch, one task per asset, on a Dask distributed cluster whose workers have
  gsverse-format installed and see the same paths (a shared file system). Memory per worker
  stays bounded by one asset when workers run one task at a time: start them with
  'dask worker ADDRESS --nthreads 1', or with '--resources asset=1' (each task then asks for
  one unit of "asset"); a warning says when a worker could run several assets at once.

scenes (several --mesh):
  gsverse-convert scene.ply scene.glb --mesh fox.obj --mesh chair.glb --max-distance 0.02
  anchors each splat to the nearest triangle over all meshes (a tie goes to the mesh given
  first) when it lies within --max-distance of that object: relative to the bounding-box
  diagonal of that object's mesh (as for one --mesh), or in scene units with
  --absolute-distance; without --max-distance every splat is anchored. Each object becomes
  an anchored primitive and node named after its mesh file's stem ("fox"), the rest one plain
  static primitive ("scene static"). The summary has one "object" line (--json: "objects")
  per mesh: splats, faces, distance percentiles. Same for USD outputs.

physics-ready anchor meshes:
  the summary says whether each anchor mesh is a closed 2-manifold ("manifold" lines, --json
  "anchor_meshes"); --watertight repairs it before binding, --collider hull adds its convex
  hull as a collision mesh (spec/README.md, "Colliders of the extras convention"; --physics
  below also references it from the object's node).

physics (--physics, --mass, --ground; glTF output only):
  gsverse-convert room.ply room.glb --mesh chair.obj --mesh pillow.obj --mesh lamp.obj \\
      --physics chair=rigid,pillow=soft,lamp=kinematic --mass chair=4 --ground
  each object with physics gets KHR_physics_rigid_bodies on its node: a convex-hull collider
  (its anchor mesh's hull, in a node outside the scene; --collider hull is implied) and a
  motion (rigid, soft), a kinematic motion (kinematic) or none (static); extras.gsverse.physics
  names the kind. soft is written as rigid for engines that know only rigid bodies; GS-Verse
  aware engines simulate the anchor mesh itself and remap the splats every frame. --physics
  KIND applies to every object, one --physics per --mesh applies in order, NAME=KIND pairs by
  object name (the mesh file stem; unnamed objects get none). --ground adds a static box (1 %
  of the scene's diagonal thick, 3 times its width and depth) with its top at the lowest
  splat. The summary has one "physics" line per body and a "ground" line (--json: "physics",
  "ground"). USD output carries colliders only (--collider hull): --physics is refused there.

standard input and output ('-'):
  IN '-' reads a PLY or a GLB from standard input (recognised by its first bytes; other
  formats need a file, their parts may live beside it). OUT '-' writes to standard output,
  with --to glb or --to ply (USD and .gltf outputs are refused: they need a file name); the
  summary then goes to standard error. The primitive is named "stdin" for standard input.

mesh fit:
  each anchor mesh is checked against its splats: when few splats lie near it, or it is far
  larger than they are, or a quarter or half turn would make their boxes fit, a "warning:"
  line gives the numbers and the likely fix (an offset, other units, another frame), the
  summary a note and --json a "fit" entry; --strict makes it an error (exit 1, nothing
  written).

{edit}
quiet:
  -q prints no progress, no summary and no warning (also in worker and child processes);
  errors are still printed (with --json also as {"error": ..., "input": ..., "exit": N} on
  standard output).
"""


def build_parser() -> argparse.ArgumentParser:
    p = Parser(
        prog=PROG,
        description="Convert Gaussian splats to a mesh-anchored glTF asset "
                    "(KHR_gaussian_splatting + GSVERSE_gaussian_splatting_mesh_anchor).",
        usage=f"{PROG} IN OUT [options]\n       {PROG} IN -o OUT [options]\n"
              f"       {PROG} IN... --output-dir DIR [options]",
        epilog=EPILOG.replace("{edit}", EDIT_EPILOG), formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("paths", nargs="+", metavar="IN",
                   help="IN OUT: the input (a 3DGS .ply, a KHR_gaussian_splatting .glb/.gltf, "
                        "a USD file .usda/.usdc/.usd/.usdz, a GaMeS / GS-Verse output folder, or "
                        "'-' for standard input) and the output (.glb, .gltf, .usda, .usdc, "
                        ".usd, .usdz, or .ply: plain splats, no anchoring; '-' for standard "
                        "output). With --output-dir: every argument is an input, a glob "
                        "pattern or a manifest (.csv/.json)")
    add_output(p, "OUT|DIR", ": one input and a file name (.glb, .gltf, .ply, .usda, .usdc, "
                             ".usd, .usdz, '-'), or a folder for a batch (--output-dir)")
    add_overwrite(p)
    bat = p.add_argument_group("batch")
    bat.add_argument("--output-dir", metavar="DIR",
                     help="convert every IN into DIR (created if missing)")
    bat.add_argument("--to", choices=TO_FORMATS,
                     help="output format: of a batch (default glb), or of '-' (glb or ply)")
    bat.add_argument("-j", "--jobs", type=int, metavar="N",
                     help="local worker processes (default: the CPU count)")
    bat.add_argument("--scheduler", metavar="ADDRESS",
                     help="run the batch on this Dask distributed scheduler "
                          "(e.g. tcp://host:8786) instead of local processes")
    bat.add_argument("--skip-existing", action="store_true",
                     help="keep existing outputs and convert only the rest")
    src = p.add_argument_group("source")
    src.add_argument("--from", dest="source", default="auto",
                     choices=("auto", *SOURCES),
                     help="which tool made the input (default: detect where unambiguous)")
    src.add_argument("--mesh", action="append",
                     help="anchor triangle mesh (.obj, .ply, .stl, .off, .glb, .gltf) in the "
                          "same frame as the splats; without it a 3DGS PLY gets a mesh "
                          "reconstructed from its splats (see --reconstruct-faces). Repeat it "
                          "for a scene of several objects: each splat is anchored to the "
                          "nearest object's mesh, each object is its own primitive and node "
                          "named after its mesh file (see 'scenes' below)")
    src.add_argument("--pt", dest="pt_path", help="PyTorch checkpoint: SuGaR refined .pt or GaMeS "
                                                  "model_params.pt (needs PyTorch)")
    src.add_argument("--k", type=int, help="splats per face (SuGaR, GaMeS), overriding detection")
    src.add_argument("--legacy-trellis-frame", action="store_true",
                     help="TRELLIS PLY saved before 2024-12-18 (no export rotation)")
    src.add_argument("--no-frame-change", action="store_true",
                     help="keep coordinates as they are (no rotation from the source's frame, "
                          "e.g. the 3DGS +Y-down frame, into glTF's +Y-up frame)")
    anc = p.add_argument_group("anchoring (only what the scene requires)")
    anc.add_argument("--deformation", choices=("affine", "rigid"), default="affine",
                     help="how local-profile splats follow their triangle: affine (stretch and "
                          "shear with it, default) or rigid (rotate, and scale uniformly)")
    anc.add_argument("--max-distance", type=float,
                     help="splats farther than this from the mesh are not anchored: they stay "
                          "plain static splats (relative to the mesh's bounding-box diagonal "
                          "unless --absolute-distance)")
    anc.add_argument("--absolute-distance", action="store_true",
                     help="--max-distance is in scene units")
    anc.add_argument("--drop-unanchored", action="store_true",
                     help="drop the splats beyond --max-distance instead of keeping them static")
    anc.add_argument("--faces", type=int, metavar="N",
                     help="decimate the anchor mesh to about N faces (the resolution the "
                          "physics needs)")
    anc.add_argument("--reconstruct-faces", type=int, metavar="N",
                     help="without --mesh: reconstruct the anchor mesh from the splats with about "
                          "N faces (default: --faces, else 20000)")
    anc.add_argument("--sh-degree", type=int, choices=(0, 1, 2, 3),
                     help="truncate spherical harmonics to this degree")
    anc.add_argument("--keep-order", action="store_true",
                     help="keep the input splat order (default: sort anchored splats by face, "
                          "which roughly halves per-frame remap time)")
    anc.add_argument("--watertight", action="store_true",
                     help="make each anchor mesh a closed 2-manifold (merge duplicate vertices, "
                          "close holes, remove faces on non-manifold edges) before binding the "
                          "splats to it; an error if that fails")
    anc.add_argument("--collider", choices=("hull",),
                     help="also write a collision mesh for each anchor mesh: hull = its convex "
                          "hull (glTF: a mesh marked extras.gsverse.collider, drawn by no node)")
    anc.add_argument("--physics", action="append", metavar="KIND|NAME=KIND",
                     help="make the objects bodies for physics engines (glTF "
                          "KHR_physics_rigid_bodies, each with its anchor mesh's convex hull as "
                          "collider): KIND is rigid, soft, kinematic or static; given once it "
                          "applies to every object, given once per --mesh to each in order, or "
                          "by name: --physics fox=soft,chair=rigid (see 'physics' below)")
    anc.add_argument("--mass", action="append", metavar="NAME=KG",
                     help="the mass of an object with --physics rigid, soft or kinematic, in "
                          "kilograms (default: the engine computes it from the collider)")
    anc.add_argument("--ground", action="store_true",
                     help="add a static, invisible ground box under the scene (its top at the "
                          "lowest splat; glTF KHR_implicit_shapes)")
    anc.add_argument("--plain", action="store_true",
                     help="format conversion only: write plain KHR splats without anchoring")
    add_edit_flags(p)
    gl = p.add_argument_group("glTF output")
    gl.add_argument("--anchors", choices=("explicit", "compact"), default=None,
                    help="compact (default): per-face splat counts, and local anchors derived "
                         "from the rest pose (extension 1.2: 1.1 readers see the rest pose "
                         "only); explicit: per-splat face, barycentrics, offset, rotation and "
                         "scale (extension 1.1 layout). Without the flag, explicit where "
                         "compact cannot be written (--keep-order, splats on faces degenerate "
                         "at rest); the summary says which")
    gl.add_argument("--quantize", type=int, choices=(16, 8), metavar="BITS",
                    help="store barycentrics, local rotations and (where no stored anchor "
                         "depends on it) the rest rotation as normalized 16- or 8-bit integers")
    gl.add_argument("--compress", choices=("spz",), default=None,
                    help="spz: store the rest pose as SPZ streams "
                         "(KHR_gaussian_splatting_compression_spz_2, about 5-8x smaller; needs "
                         "compact anchors; quantization bounds in spec/README.md "
                         "§SPZ-compressed rest pose)")
    usd = p.add_argument_group("USD output")
    usd.add_argument("--bake-poses", metavar="FILE",
                     help="also store the splats remapped onto these anchor-mesh poses as USD "
                          "time samples, for USD renderers that do not know the anchors: an .npz "
                          "with vertices (P, V, 3) and times (P,) (USD time codes; optional "
                          "time_codes_per_second, default 24), or a JSON list of "
                          "{\"time\": t, \"vertices\": [[x, y, z], ...]}; vertices in the frame "
                          "and vertex order of the written anchor mesh (see spec/usd.md)")
    p.add_argument("--strict", action="store_true",
                   help="fail (exit 1, nothing written) when an anchor mesh does not fit its "
                        "splats (far from them, in other units or another frame), or when the "
                        "skin weights of a rigged --mesh do not sum to 1, instead of a warning "
                        "or note")
    add_json(p)
    add_quiet(p)
    add_version(p, PROG)
    return p


def _options(args: argparse.Namespace) -> ConvertOptions:
    meshes = args.mesh or []
    return ConvertOptions(mesh=meshes[0] if len(meshes) == 1 else None,
                          meshes=meshes if len(meshes) > 1 else None,
                          watertight=args.watertight, collider=args.collider,
                          source=args.source, deformation=args.deformation,
                          frame_change=not args.no_frame_change, keep_order=args.keep_order,
                          sh_degree=args.sh_degree, max_distance=args.max_distance,
                          absolute_distance=args.absolute_distance,
                          drop_unanchored=args.drop_unanchored, faces=args.faces,
                          reconstruct_faces=args.reconstruct_faces,
                          pt_path=args.pt_path, k=args.k,
                          legacy_trellis_frame=args.legacy_trellis_frame, plain=args.plain,
                          bake_poses=args.bake_poses, anchors=args.anchors,
                          quantize=args.quantize, compress=args.compress,
                          strict=args.strict, physics=args.physics,
                          mass=args.mass, ground=args.ground,
                          **{name: getattr(args, name) for name in EDIT_OPTIONS})


def _sniff_stdin(head: bytes) -> str:
    """The suffix of what standard input holds, from its first bytes."""
    if head.startswith(b"ply\n") or head.startswith(b"ply\r\n"):
        return ".ply"
    if head.startswith(b"glTF"):
        return ".glb"
    if not head:
        raise UsageError("standard input is empty", "-")
    raise UsageError("standard input is neither a PLY nor a GLB; other formats need a file "
                     "name (their parts may be files beside them)", "-")


def _spool_stdin(folder: str, stream: IO[bytes]) -> str:
    """Standard input copied to ``folder/stdin.<ply|glb>``; its path."""
    head = stream.read(4096)
    path = os.path.join(folder, "stdin" + _sniff_stdin(head))
    with open(path, "wb") as f:
        f.write(head)
        shutil.copyfileobj(stream, f, 1 << 20)
    return path


def _check_arguments(args: argparse.Namespace, parser: argparse.ArgumentParser) -> None:
    """What the parser alone cannot check: ``-o`` made a file or a folder (a batch) by its
    name, and one input and one output without a batch."""
    if args.output is not None:
        if args.output_dir is not None:
            parser.error("give -o or --output-dir, not both")
        kind = "file" if args.output == "-" else \
            output_kind(args.output, ["." + t for t in TO_FORMATS])
        if kind is None:
            parser.error(f"-o {args.output}: neither an output file name "
                         f"(.{', .'.join(TO_FORMATS)}) nor a folder (one that exists, a path "
                         f"ending in '/', or a name without a suffix); for a folder of that "
                         f"name write --output-dir {args.output}")
        if kind == "file":
            if len(args.paths) != 1:
                parser.error(f"-o {args.output} names one output file, but {len(args.paths)} "
                             f"paths were given: write IN -o OUT (or IN OUT) for one file, or "
                             f"IN... --output-dir DIR for a batch")
            args.paths = [args.paths[0], args.output]
        else:
            args.output_dir = args.output
    if args.output_dir is not None:
        return
    for flag, value in (("--jobs", args.jobs), ("--scheduler", args.scheduler),
                        ("--skip-existing", args.skip_existing or None)):
        if value is not None:
            parser.error(f"{flag} needs --output-dir DIR (a batch)")
    if len(args.paths) != 2:
        parser.error("give IN OUT (or IN -o OUT) for one file, or IN... --output-dir DIR for "
                     "a batch")


def _check_single(args: argparse.Namespace, parser: argparse.ArgumentParser) -> None:
    output = args.paths[1]
    if output == "-":
        if args.to is None:
            raise UsageError(f"writing to standard output needs --to "
                             f"{' or --to '.join(STDOUT_FORMATS)}", "-")
        if args.to not in STDOUT_FORMATS:
            raise UsageError(f"{args.to} output cannot go to standard output (it needs a file "
                             f"name); use --to {' or --to '.join(STDOUT_FORMATS)}, or a file", "-")
        closed = closed_stdout_error()
        if closed is not None:
            raise closed
        if sys.stdout.isatty():
            raise UsageError("refusing to write binary data to a terminal; redirect standard "
                             "output", "-")
    else:
        if args.to is not None and os.path.splitext(output)[1].lower() != "." + args.to:
            raise UsageError(f"--to {args.to} does not match the output's suffix", output)
        if os.path.isdir(output):
            raise OutputError("is a folder; give a file name for the output", output)
        if os.path.lexists(output) and not args.overwrite:
            raise UsageError("output exists; use -w/--overwrite to replace it", output)


def _require_inputs(input_path: str, args: argparse.Namespace) -> None:
    """Every file the conversion reads exists: a missing one is bad input (exit 1), named."""
    require_input(input_path)
    for extra in (*(args.mesh or ()), args.pt_path, args.bake_poses):
        if extra is not None:
            require_input(extra)


def _convert_single(args: argparse.Namespace, parser: argparse.ArgumentParser,
                    progress: Progress) -> tuple[ConvertSummary, IO[str]]:
    """One input to one output, through temporary files for '-' (standard input/output)."""
    input_path, output_path = args.paths
    _require_inputs(input_path, args)
    _check_single(args, parser)
    if "-" not in (input_path, output_path):
        return convert(input_path, output_path, _options(args), progress), sys.stdout
    with tempfile.TemporaryDirectory(prefix="gsverse-convert-") as work:
        real_in = _spool_stdin(work, sys.stdin.buffer) if input_path == "-" else input_path
        real_out = os.path.join(work, f"stdout.{args.to}") if output_path == "-" \
            else output_path
        try:
            summary = convert(real_in, real_out, _options(args), progress)
        except GsverseError as exc:
            if exc.path == real_in and input_path == "-":
                raise type(exc)(exc.cause, "<stdin>") from None
            if exc.path == real_out and output_path == "-":
                raise type(exc)(exc.cause, "<stdout>") from None
            raise
        if output_path == "-":
            with open(real_out, "rb") as f:
                shutil.copyfileobj(f, sys.stdout.buffer, 1 << 20)
            sys.stdout.buffer.flush()
        summary.input = "-" if input_path == "-" else summary.input
        summary.output = "-" if output_path == "-" else summary.output
    return summary, (sys.stderr if output_path == "-" else sys.stdout)


def _batch(args: argparse.Namespace, progress: Progress) -> int:
    from ..batch import collect, plan, run_batch

    if args.jobs is not None and args.jobs < 1:
        raise UsageError(f"--jobs must be at least 1, not {args.jobs}")
    if args.jobs is not None and args.scheduler:
        raise UsageError("--jobs is for local processes; a Dask cluster sets its own workers")
    specs = collect(args.paths, _options(args))
    for spec in specs:   # every asset's edits (a manifest's values too) before any converts
        try:
            SplatEdit.from_options(spec.options)
        except UsageError as exc:
            raise UsageError(exc.cause, spec.origin) from None
    todo, skipped = plan(specs, args.output_dir, args.to or "glb", overwrite=args.overwrite,
                         skip_existing=args.skip_existing)
    report = run_batch(todo, args.output_dir, jobs=args.jobs, scheduler=args.scheduler,
                       overwrite=args.overwrite, quiet=args.quiet, skipped=skipped,
                       progress=progress)
    for asset in report.assets:
        if asset.status == "failed":
            print(f"{PROG}: error: {escape(asset.error)}", file=sys.stderr)
    if report.interrupted:
        print(f"{PROG}: interrupted; {report.count('ok')} assets converted, "
              f"{report.count('interrupted')} not written", file=sys.stderr)
    if args.json:
        print(json.dumps(report.as_dict(), indent=2))
    elif not args.quiet:
        print("\n".join(map(safe_line, report.lines())))
    return report.exit_status


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parse_args(parser, argv, lambda args: _check_arguments(args, parser))
    progress = Progress(enabled=None if not (args.quiet or args.json) else False)

    def work() -> int:
        # bad edit values: exit 2 before any reading (a batch's assets: in _batch)
        SplatEdit.from_options(_options(args), require_mesh=args.output_dir is None)
        if args.output_dir is not None:
            return _batch(args, progress)
        summary, out = _convert_single(args, parser, progress)
        if args.json:
            print(json.dumps(summary.as_dict(), indent=2), file=out)
        elif not args.quiet:
            print("\n".join(map(safe_line, summary.lines())), file=out)
        return 0

    return run_command(PROG, args.paths[0], progress, work, quiet=args.quiet,
                       interrupted="interrupted; no output written", json_errors=args.json)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
