"""The ``KHR_gaussian_splatting`` attribute semantics and primitive modes the reader, the
writer and the compressed rest pose share."""
from __future__ import annotations

from ...vocabulary import KHR

__all__ = ["ROTATION", "SCALE", "OPACITY", "sh_attribute", "POINTS", "TRIANGLES"]

#: ``KHR_gaussian_splatting`` attribute semantics.
ROTATION = f"{KHR}:ROTATION"
SCALE = f"{KHR}:SCALE"
OPACITY = f"{KHR}:OPACITY"
#: glTF primitive modes.
POINTS, TRIANGLES = 0, 4


def sh_attribute(degree: int, coefficient: int) -> str:
    """The attribute of SH coefficient ``coefficient`` (0 .. 2·degree) of ``degree``."""
    return f"{KHR}:SH_DEGREE_{degree}_COEF_{coefficient}"
