"""Checking a harness's pictures of the render cases against the reference pictures.

Per frame of a render case, the harness's ``RESULTS/<id>/frame_NNN.png`` and the suite's
``reference/frame_NNN.png`` (8-bit RGB, sRGB-encoded, over black) are compared by two numbers:

* **coverage IoU** — a pixel is *covered* when one of its channels exceeds ``coverage_level``
  of 255; the intersection over union of the two covered sets. It sees a shape in the wrong
  place, of the wrong size or extent (an ignored node transform, a splat that does not follow
  its triangle, an anchor mesh drawn over the splats);
* **PSNR** over the pixels covered in either picture, the union grown by ``margin_px`` (the
  empty background would otherwise inflate it): it sees the colours, i.e. what is in front
  (depth order) and how each splat is shaped (rotation and scale packing).

A frame passes when PSNR ≥ ``psnr_db`` and IoU ≥ ``iou`` of the manifest's thresholds.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

__all__ = ["FrameScore", "read_rgb", "score_frame", "check_render_case"]


@dataclass
class FrameScore:
    frame: int
    psnr_db: float
    iou: float
    passed: bool


def read_rgb(path: Path) -> np.ndarray:
    """(H, W, 3) uint8 of a PNG (any PNG mode; alpha dropped, palette expanded)."""
    from PIL import Image

    with Image.open(path) as img:
        return np.asarray(img.convert("RGB"))


def _grow(mask: np.ndarray, px: int) -> np.ndarray:
    out = mask.copy()
    for _ in range(px):
        g = out.copy()
        g[1:] |= out[:-1]
        g[:-1] |= out[1:]
        g[:, 1:] |= out[:, :-1]
        g[:, :-1] |= out[:, 1:]
        out = g
    return out


def score_frame(got: np.ndarray, ref: np.ndarray, thresholds: dict, frame: int = 0) -> FrameScore:
    """PSNR over the covered pixels and coverage IoU of two (H, W, 3) uint8 pictures."""
    level = int(thresholds["coverage_level"])
    a = got.max(axis=2) > level
    b = ref.max(axis=2) > level
    union = a | b
    iou = float((a & b).sum() / union.sum()) if union.any() else 1.0
    region = _grow(union, int(thresholds["margin_px"]))
    if region.any():
        diff = got[region].astype(np.float64) - ref[region].astype(np.float64)
        mse = float(np.mean(diff ** 2))
        psnr = math.inf if mse == 0 else 10.0 * math.log10(255.0 ** 2 / mse)
    else:
        psnr = math.inf
    passed = psnr >= float(thresholds["psnr_db"]) and iou >= float(thresholds["iou"])
    return FrameScore(frame, psnr, iou, passed)


def check_render_case(case_dir: Path, manifest: dict, folder: Path) -> tuple[str, str, list[FrameScore]]:
    """(status, message, scores) of one render case: ``pass`` when every frame passes."""
    if (folder / "refused").is_file():
        reason = (folder / "refused").read_text(encoding="utf-8", errors="replace").strip()
        return "fail", f"refused a valid asset: {reason[:300]}", []
    if (folder / "error").is_file():
        reason = (folder / "error").read_text(encoding="utf-8", errors="replace").strip()
        return "fail", f"harness error: {reason[:300]}", []
    th = manifest["thresholds"]
    scores: list[FrameScore] = []
    for f in manifest["frames"]:
        path = folder / f["result"]
        if not path.is_file():
            return "fail", f"missing picture {f['result']}", scores
        got = read_rgb(path)
        ref = read_rgb(case_dir / f["reference"])
        if got.shape != ref.shape:
            return ("fail", f"{f['result']} is {got.shape[1]}x{got.shape[0]}, expected "
                    f"{ref.shape[1]}x{ref.shape[0]}", scores)
        scores.append(score_frame(got, ref, th, f["index"]))
    bad = [s for s in scores if not s.passed]
    if not bad:
        return "pass", "", scores
    worst = min(bad, key=lambda s: (s.psnr_db - th["psnr_db"]) / 10 + (s.iou - th["iou"]))
    label = manifest["frames"][worst.frame]["label"]
    return ("fail", f"frame {worst.frame} ({label}): PSNR {worst.psnr_db:.1f} dB (min "
            f"{th['psnr_db']:g}), coverage IoU {worst.iou:.3f} (min {th['iou']:g})", scores)
