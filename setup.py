"""The package's one compiled extension; everything else is declared in pyproject.toml.

``gsverse_format.nearest._native``: the exact nearest-triangle search in C
(``native/search/gsverse_nearest.h``), which binding uses instead of the numba search. It is
optional: without a C compiler the package installs all the same and the search runs on numba
(``gsverse_format.nearest.native.native_unavailable_reason`` says why).
``-ffp-contract=off``: no fused multiply-adds, so that the search gives the numpy reference's
results bit for bit.
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
)])
