"""Reading PyTorch checkpoints (``.pt``) of training codes (SuGaR, GaMeS) safely: on the CPU,
running no code from the file, and needing none of the training code installed.

PyTorch is optional: it is imported only when a checkpoint is read.
"""
from __future__ import annotations

import os
import pickle
import struct
import types
import zipfile

import numpy as np

from gsverse_format.errors import FormatError, GsverseError

__all__ = ["load_torch_checkpoint", "as_array"]


class _Opaque:
    """Stands in for any class a checkpoint names that is not needed to read its tensors."""

    def __new__(cls, *args, **kwargs):
        return object.__new__(cls)

    def __init__(self, *args, **kwargs) -> None:
        self.args = args

    def __setstate__(self, state) -> None:
        self.state = state


def _numpy_reconstruct(subtype, *args):
    """numpy's array reconstructor, with unknown ndarray subclasses read as plain arrays."""
    try:
        from numpy._core.multiarray import _reconstruct
    except ImportError:  # numpy < 2
        from numpy.core.multiarray import _reconstruct
    if not (isinstance(subtype, type) and issubclass(subtype, np.ndarray)):
        subtype = np.ndarray
    return _reconstruct(subtype, *args)


def _numpy_scalar(*args):
    try:
        from numpy._core.multiarray import scalar
    except ImportError:  # numpy < 2
        from numpy.core.multiarray import scalar
    return scalar(*args)


_SAFE_GLOBALS = {
    ("collections", "OrderedDict"), ("builtins", "set"), ("builtins", "frozenset"),
    ("builtins", "slice"), ("builtins", "complex"), ("builtins", "bytearray"),
    ("builtins", "object"), ("builtins", "tuple"), ("builtins", "list"), ("builtins", "dict"),
    ("copyreg", "_reconstructor"), ("copyreg", "__newobj__"), ("_codecs", "encode"),
    ("numpy", "ndarray"), ("numpy", "dtype"),
    ("torch", "Size"), ("torch", "device"),
}


class _Unpickler(pickle.Unpickler):
    """Resolves only the globals needed to rebuild tensors, arrays and plain containers; every
    other class or function a checkpoint names becomes an inert :class:`_Opaque`, so loading
    runs no code from the file and needs none of the training code installed."""

    def find_class(self, module: str, name: str):
        if module in ("numpy.core.multiarray", "numpy._core.multiarray"):
            if name == "_reconstruct":
                return _numpy_reconstruct
            if name == "scalar":
                return _numpy_scalar
        if (module, name) in _SAFE_GLOBALS or (module == "numpy.dtypes" and name.endswith("DType")):
            return super().find_class(module, name)
        if module == "torch._utils" and name.startswith("_rebuild_") and "qtensor" not in name:
            return super().find_class(module, name)
        if module == "torch":
            import torch

            if isinstance(getattr(torch, name, None), torch.dtype):
                return getattr(torch, name)
        return type(name, (_Opaque,), {"__module__": f"opaque.{module}"})


def _pickle_load(file, **kwargs):
    return _Unpickler(file, **kwargs).load()


#: What ``torch.load`` raises for a truncated, corrupt or foreign file (zip container, pickle
#: stream, storage records); anything else is a bug and propagates.
_BAD_FILE = (pickle.UnpicklingError, RuntimeError, EOFError, ValueError, OSError, KeyError,
             IndexError, struct.error, zipfile.BadZipFile)

_SAFE_PICKLE = types.SimpleNamespace(__name__="pickle", Unpickler=_Unpickler, load=_pickle_load)


def load_torch_checkpoint(path: str | os.PathLike):
    """Read a PyTorch checkpoint (``torch.save`` output) on the CPU, running no code from it.

    Tensors, numpy arrays and plain containers are rebuilt; objects of other classes (for
    example the training code's own point-cloud tuples) come back as inert placeholders.
    Raises :class:`FormatError` when PyTorch is missing or the file cannot be read.
    """
    path = os.fspath(path)
    if not os.path.isfile(path):
        raise FormatError("file not found", path)
    try:
        import torch
    except ImportError:
        raise FormatError("reading .pt needs PyTorch: pip install torch", path) from None
    try:
        return torch.load(path, map_location="cpu", weights_only=False, pickle_module=_SAFE_PICKLE)
    except GsverseError:
        raise
    except _BAD_FILE as exc:  # what torch's zip reader and pickle raise for bad files
        raise FormatError(f"cannot read PyTorch checkpoint: {type(exc).__name__}: {exc}"
                          .splitlines()[0], path) from None


def as_array(value, what: str, path: str) -> np.ndarray:
    """A tensor, Parameter, array or nested list as a numpy array (FormatError otherwise)."""
    if hasattr(value, "detach"):
        value = value.detach().cpu().numpy()
    try:
        array = np.asarray(value)
    except (ValueError, TypeError):
        raise FormatError(f"{what} is not an array", path) from None
    if array.dtype == object or array.dtype.kind not in "biuf":
        raise FormatError(f"{what} is not a numeric array", path)
    return array
