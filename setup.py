"""The package's compiled extensions; everything else is declared in pyproject.toml.

``gsverse_format.nearest._native``: the exact nearest-triangle search in C
(``native/search/gsverse_nearest.h``), which binding uses instead of the numba search.
``-ffp-contract=off``: no fused multiply-adds, so that the search gives the numpy reference's
results bit for bit.

``gsverse_format._rows``: the row gathers that group the splats' arrays by face
(``native/rows/rows_module.c``, :mod:`gsverse_format.rows`).

Both are optional: without a C compiler the package installs all the same, the search runs
on numba (``gsverse_format.nearest.native.native_unavailable_reason`` says why) and the
gathers on numpy.
"""
from setuptools import Extension, setup

setup(ext_modules=[Extension(
    "gsverse_format.nearest._native",
    sources=["native/search/nearest_module.c"],
    include_dirs=["native/search"],
    depends=["native/search/gsverse_nearest.h"],
    extra_compile_args=["-std=c99", "-ffp-contract=off", "-fno-fast-math", "-pthread"],
    extra_link_args=["-pthread"],
    optional=True,
), Extension(
    "gsverse_format._rows",
    sources=["native/rows/rows_module.c"],
    extra_compile_args=["-std=c99", "-pthread"],
    extra_link_args=["-pthread"],
    optional=True,
)])
