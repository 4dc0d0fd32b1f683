"""Writing rendered images: 8-bit PNG and OpenEXR.

Colour encoding. ``KHR_gaussian_splatting`` says in which colour space a primitive's SH colours
are: ``srgb_rec709_display`` (the default and what 3DGS training produces) means the values are
already sRGB-*encoded* display values, and like the 3DGS rasterizer and every splat viewer the
renderer blends them as they are; ``lin_rec709_display`` means linear Rec.709 values. So:

* **PNG** (8-bit RGBA, straight alpha): sRGB-encoded. sRGB splats are written as blended
  (un-premultiplied, rounded); linear splats go through the sRGB transfer function first.
* **OpenEXR** (half float): *linear* Rec.709 colour, premultiplied as EXR expects — sRGB splats
  are decoded per pixel with the sRGB transfer function (of the un-premultiplied colour), linear
  splats are written as blended — plus ``A`` (alpha) and ``Z`` (float32 camera depth along the
  view axis, the α-weighted mean of what was drawn; +inf where empty).

Written with ``OpenEXR`` (the Academy Software Foundation's bindings, ZIP compression).
"""
from __future__ import annotations

import os
import tempfile

import numpy as np

from ..atomic import atomic_write
from .raster import Image

__all__ = ["srgb_to_linear", "linear_to_srgb", "straight_rgb", "to_rgba8", "write_png",
           "write_exr", "read_exr", "write_image"]


def srgb_to_linear(c: np.ndarray) -> np.ndarray:
    """The sRGB EOTF (IEC 61966-2-1), on values clamped to [0, 1]."""
    c = np.clip(np.asarray(c, np.float64), 0.0, 1.0)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(c: np.ndarray) -> np.ndarray:
    """The inverse of :func:`srgb_to_linear`, on values clamped to [0, 1]."""
    c = np.clip(np.asarray(c, np.float64), 0.0, 1.0)
    return np.where(c <= 0.0031308, c * 12.92, 1.055 * c ** (1 / 2.4) - 0.055)


def straight_rgb(img: Image) -> np.ndarray:
    """Un-premultiplied colour (H, W, 3) float64 in the splats' encoding (0 where alpha is 0)."""
    a = img.alpha.astype(np.float64)[..., None]
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.where(a > 0, img.rgb / np.where(a > 0, a, 1.0), 0.0)


def to_rgba8(img: Image, background: tuple[float, float, float] | None = None) -> np.ndarray:
    """(H, W, 4) uint8 sRGB-encoded pixels; with ``background`` (sRGB-encoded, 0..1) the image
    is composited over it (alpha 255 everywhere)."""
    rgb = straight_rgb(img)
    if img.color_space != "srgb_rec709_display":
        rgb = linear_to_srgb(rgb)
    a = img.alpha.astype(np.float64)
    if background is not None:
        rgb = rgb * a[..., None] + np.asarray(background, np.float64) * (1.0 - a[..., None])
        a = np.ones_like(a)
    out = np.concatenate([np.clip(rgb, 0, 1), np.clip(a, 0, 1)[..., None]], axis=-1)
    return np.round(out * 255.0).astype(np.uint8)


def write_png(img: Image | np.ndarray, path: str | os.PathLike,
              background: tuple[float, float, float] | None = None) -> None:
    """Write ``img`` (an :class:`Image` or an (H, W, 3|4) uint8 array) as PNG, atomically."""
    from PIL import Image as PILImage

    pixels = img if isinstance(img, np.ndarray) else to_rgba8(img, background)
    mode = "RGBA" if pixels.shape[2] == 4 else "RGB"
    with atomic_write(path) as f:
        PILImage.fromarray(np.ascontiguousarray(pixels), mode).save(f, format="PNG")


def write_exr(img: Image, path: str | os.PathLike) -> None:
    """Write linear premultiplied R, G, B and A (half) and Z (float) channels, atomically."""
    import OpenEXR

    a = img.alpha.astype(np.float64)
    if img.color_space == "srgb_rec709_display":
        lin = srgb_to_linear(straight_rgb(img)) * a[..., None]
    else:
        lin = img.rgb.astype(np.float64)
    channels = {
        "R": np.ascontiguousarray(lin[..., 0], np.float16),
        "G": np.ascontiguousarray(lin[..., 1], np.float16),
        "B": np.ascontiguousarray(lin[..., 2], np.float16),
        "A": np.ascontiguousarray(a, np.float16),
        "Z": np.ascontiguousarray(img.depth, np.float32),
    }
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    # OpenEXR writes to a path: write into a private temporary folder, then copy the bytes
    # through atomic_write (a failed write leaves no partial output).
    with tempfile.TemporaryDirectory(prefix="gsverse-exr-") as tmp:
        name = os.path.join(tmp, "image.exr")
        with OpenEXR.File(header, channels) as exr:
            exr.write(name)
        with open(name, "rb") as src:
            data = src.read()
    with atomic_write(path) as f:
        f.write(data)


def read_exr(path: str | os.PathLike) -> dict[str, np.ndarray]:
    """The channels of an EXR file by name (used by the tests and the benchmark)."""
    import OpenEXR

    with OpenEXR.File(os.fspath(path), separate_channels=True) as exr:
        return {name: np.array(ch.pixels) for name, ch in exr.channels().items()}


def write_image(img: Image, path: str | os.PathLike,
                background: tuple[float, float, float] | None = None) -> None:
    """PNG or EXR by the suffix of ``path``."""
    suffix = os.fspath(path).lower().rsplit(".", 1)[-1]
    if suffix == "exr":
        write_exr(img, path)
    else:
        write_png(img, path, background)
