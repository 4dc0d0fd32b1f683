"""Fuzz harnesses for the readers and the validator (``python -m fuzz.fuzz_readers``)."""
