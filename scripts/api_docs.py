"""Build the Python API reference (HTML, from the docstrings) with pdoc.

    python scripts/api_docs.py [OUT_DIR]          # default: build/api; open OUT_DIR/index.html

Every module of ``gsverse_format`` (the package, its formats, sources, validators, conformance
suite and command-line entry points) gets a page. Any warning pdoc raises (an unresolvable
reference, a module that fails to import, a duplicate page) fails the build: exit status 1.
"""
from __future__ import annotations

import pkgutil
import subprocess
import sys
from pathlib import Path


def modules() -> list[str]:
    """The package and its top-level modules (pdoc walks the subpackages itself)."""
    import gsverse_format

    return ["gsverse_format"] + sorted(
        m.name for m in pkgutil.iter_modules(gsverse_format.__path__, "gsverse_format."))


def build(out_dir: Path) -> subprocess.CompletedProcess:
    """Run pdoc with warnings as errors; returns the finished process."""
    return subprocess.run([sys.executable, "-W", "error", "-m", "pdoc", "--docformat", "restructuredtext",
                           *modules(), "-o", str(out_dir)],
                          capture_output=True, text=True, check=False)


def main(argv: list[str]) -> int:
    out = Path(argv[0]) if argv else Path("build/api")
    proc = build(out)
    if proc.returncode != 0:
        lines = (proc.stderr or proc.stdout).strip().splitlines()
        print(f"api_docs: error: pdoc failed: {lines[-1] if lines else proc.returncode}", file=sys.stderr)
        return 1
    pages = sum(1 for _ in out.rglob("*.html"))
    print(f"api_docs: {pages} pages in {out}/ (open {out}/index.html)")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
