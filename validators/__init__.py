"""Asset validation (installed as ``gsverse_format.validators``)."""
