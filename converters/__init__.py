"""Converters from other tools' outputs to anchored assets (installed as ``gsverse_format.converters``)."""
