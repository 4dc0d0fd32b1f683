"""The package version (its own module, so that any layer can import it without importing
the package top and its public API)."""

__version__ = "0.1.0"
