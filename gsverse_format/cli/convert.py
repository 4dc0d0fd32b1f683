"""``gsverse-convert``: 3DGS PLY / KHR glTF splats (+ an anchor mesh) -> anchored GLB.

Exit codes: 0 success, 1 bad input or failed conversion, 2 usage error. Errors are one line on
stderr (``gsverse-convert: error: <file>: <cause>``), never a traceback.
"""
from __future__ import annotations

import argparse
import json
import sys

from .. import __version__
from ..convert import ConvertOptions, convert
from ..errors import GsverseError, UsageError
from ..progress import Progress

PROG = "gsverse-convert"


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=PROG,
        description="Convert Gaussian splats to a mesh-anchored glTF asset "
                    "(KHR_gaussian_splatting + GSVERSE_gaussian_splatting_mesh_anchor).",
        epilog="Example: gsverse-convert splats.ply anchored.glb --mesh mesh.obj")
    p.add_argument("input", help="splats: 3DGS .ply, or KHR_gaussian_splatting .glb/.gltf")
    p.add_argument("output", help="output .glb, .gltf, or .ply (plain splats, no anchoring)")
    p.add_argument("--mesh", help="anchor triangle mesh (.obj, .ply, .stl, .off, .glb, .gltf) in the "
                                  "same coordinate frame as the splats; each splat is bound to its "
                                  "nearest triangle (local profile)")
    p.add_argument("--deformation", choices=("affine", "rigid"), default="affine",
                   help="how splats follow their triangle: affine (stretch and shear with it, "
                        "default) or rigid (rotate, and scale uniformly with its area)")
    p.add_argument("--sh-degree", type=int, choices=(0, 1, 2, 3),
                   help="truncate spherical harmonics to this degree")
    p.add_argument("--keep-order", action="store_true",
                   help="keep the input splat order (default: sort anchored splats by face, "
                        "which roughly halves per-frame remap time)")
    p.add_argument("--no-frame-change", action="store_true",
                   help="do not rotate 180 degrees about Z between the 3DGS PLY frame (+Y down) "
                        "and the glTF frame (+Y up)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON on stdout")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar and no summary")
    p.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    options = ConvertOptions(mesh=args.mesh, deformation=args.deformation,
                             frame_change=not args.no_frame_change, keep_order=args.keep_order,
                             sh_degree=args.sh_degree)
    progress = Progress(enabled=None if not (args.quiet or args.json) else False)
    try:
        summary = convert(args.input, args.output, options, progress)
    except UsageError as exc:
        progress.close()
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 2
    except GsverseError as exc:
        progress.close()
        print(f"{PROG}: error: {exc}", file=sys.stderr)
        return 1
    except MemoryError:
        progress.close()
        print(f"{PROG}: error: {args.input}: out of memory", file=sys.stderr)
        return 1
    except KeyboardInterrupt:
        progress.close()
        print(f"{PROG}: interrupted; no output written", file=sys.stderr)
        return 130
    if args.json:
        print(json.dumps(summary.as_dict(), indent=2))
    elif not args.quiet:
        print("\n".join(summary.lines()))
    return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
