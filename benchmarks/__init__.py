"""Benchmarks: reproducible timings of the package against other tools, run as modules."""
