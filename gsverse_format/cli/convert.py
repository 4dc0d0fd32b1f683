"""``gsverse-convert``: splats from 3DGS, SuGaR, TRELLIS, GaMeS or KHR glTF -> anchored GLB.

Exit codes: 0 success, 1 bad input or failed conversion, 2 usage error. Errors are one line on
stderr (``gsverse-convert: error: <file>: <cause>``), never a traceback.
"""
from __future__ import annotations

import argparse
import json
import os
import sys

from ..version import __version__
from ..converters import SOURCES
from ..pipeline import ConvertOptions, convert
from ..errors import GsverseError, UsageError
from ..progress import Progress

PROG = "gsverse-convert"


def build_parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog=PROG,
        description="Convert Gaussian splats to a mesh-anchored glTF asset "
                    "(KHR_gaussian_splatting + GSVERSE_gaussian_splatting_mesh_anchor).",
        epilog="Example: gsverse-convert splats.ply anchored.glb --mesh mesh.obj")
    p.add_argument("input", help="splats: a 3DGS .ply, a KHR_gaussian_splatting .glb/.gltf, a USD "
                                 "file (.usda/.usdc/.usd/.usdz), or a GaMeS / GS-Verse output "
                                 "folder")
    p.add_argument("output", help="output .glb, .gltf, .usda, .usdc, .usd, .usdz (USD needs "
                                  "usd-core), or .ply (plain splats, no anchoring)")
    src = p.add_argument_group("source")
    src.add_argument("--from", dest="source", default="auto",
                     choices=("auto", *SOURCES),
                     help="which tool made the input (default: detect where unambiguous)")
    src.add_argument("--mesh", help="anchor triangle mesh (.obj, .ply, .stl, .off, .glb, .gltf) in the "
                                    "same frame as the splats; without it a 3DGS PLY gets a mesh "
                                    "reconstructed from its splats (see --reconstruct-faces)")
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
    anc.add_argument("--plain", action="store_true",
                     help="format conversion only: write plain KHR splats without anchoring")
    usd = p.add_argument_group("USD output")
    usd.add_argument("--bake-poses", metavar="FILE",
                     help="also store the splats remapped onto these anchor-mesh poses as USD "
                          "time samples, for USD renderers that do not know the anchors: an .npz "
                          "with vertices (P, V, 3) and times (P,) (USD time codes; optional "
                          "time_codes_per_second, default 24), or a JSON list of "
                          "{\"time\": t, \"vertices\": [[x, y, z], ...]}; vertices in the frame "
                          "and vertex order of the written anchor mesh (see spec/usd.md)")
    p.add_argument("--json", action="store_true", help="print the summary as JSON on stdout")
    p.add_argument("-q", "--quiet", action="store_true", help="no progress bar and no summary")
    p.add_argument("--version", action="version", version=f"{PROG} {__version__}")
    return p


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    options = ConvertOptions(mesh=args.mesh, source=args.source, deformation=args.deformation,
                             frame_change=not args.no_frame_change, keep_order=args.keep_order,
                             sh_degree=args.sh_degree, max_distance=args.max_distance,
                             absolute_distance=args.absolute_distance,
                             drop_unanchored=args.drop_unanchored, faces=args.faces,
                             reconstruct_faces=args.reconstruct_faces,
                             pt_path=args.pt_path, k=args.k,
                             legacy_trellis_frame=args.legacy_trellis_frame, plain=args.plain,
                             bake_poses=args.bake_poses)
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
    except Exception as exc:  # a bug, not bad input: still one line; GSVERSE_DEBUG=1 shows it all
        progress.close()
        if os.environ.get("GSVERSE_DEBUG"):
            raise
        print(f"{PROG}: internal error: {type(exc).__name__}: {exc} "
              f"(set GSVERSE_DEBUG=1 for a traceback, and please report it)".replace("\n", " "),
              file=sys.stderr)
        return 70
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
