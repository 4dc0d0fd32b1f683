"""The package's module structure: no import circles.

Every module of ``gsverse_format`` (with ``converters/`` and ``validators/``, installed as
``gsverse_format.converters`` and ``gsverse_format.validators``) is parsed with :mod:`ast`, not
imported, and every import statement counts, also those inside functions (a lazy import is
still a dependency) and those under ``TYPE_CHECKING``.
"""
from __future__ import annotations

import ast
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
#: Installed package name -> source folder (pyproject's ``package-dir``).
ROOTS = {"gsverse_format": REPO / "gsverse_format",
         "gsverse_format.converters": REPO / "converters",
         "gsverse_format.validators": REPO / "validators"}
#: Names under which a folder is also importable from the repository root.
ALIASES = {"converters": "gsverse_format.converters", "validators": "gsverse_format.validators"}


def package_modules() -> dict[str, tuple[Path, bool]]:
    """Module name -> (source file, is a package) for every module of the three folders; a
    compiled extension counts by its type stub (``nearest/_native.pyi``), whose imports are
    those of its interface."""
    modules: dict[str, tuple[Path, bool]] = {}
    for root, folder in ROOTS.items():
        for path in sorted([*folder.rglob("*.py"), *folder.rglob("*.pyi")]):
            rel = path.relative_to(folder).with_suffix("")
            if "__pycache__" in rel.parts or (path.suffix == ".pyi"
                                               and path.with_suffix(".py").exists()):
                continue
            parts = list(rel.parts)
            package = parts[-1] == "__init__"
            if package:
                parts = parts[:-1]
            modules[".".join([root, *parts])] = (path, package)
    return modules


def _canonical(name: str) -> str:
    head, _, rest = name.partition(".")
    if head in ALIASES:
        return ALIASES[head] + ("." + rest if rest else "")
    return name


def _known(name: str, modules: dict) -> str | None:
    """The longest prefix of ``name`` that is a package module, or None."""
    parts = _canonical(name).split(".")
    for k in range(len(parts), 0, -1):
        candidate = ".".join(parts[:k])
        if candidate in modules:
            return candidate
    return None


def imports_of(module: str, modules: dict) -> set[str]:
    """The package modules that ``module`` imports (anywhere in its source)."""
    path, package = modules[module]
    tree = ast.parse(path.read_text(encoding="utf-8"), filename=str(path))
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                target = _known(alias.name, modules)
                if target:
                    found.add(target)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = module.split(".") if package else module.split(".")[:-1]
                base = base[:len(base) - (node.level - 1)]
                name = ".".join(base + ([node.module] if node.module else []))
            else:
                name = _canonical(node.module or "")
            for alias in node.names:
                sub = f"{name}.{alias.name}"
                if sub in modules:                 # ``from package import submodule``
                    found.add(sub)
                else:
                    target = _known(name, modules)
                    if target:
                        found.add(target)
    found.discard(module)
    return found


def import_graph() -> dict[str, set[str]]:
    modules = package_modules()
    return {m: imports_of(m, modules) for m in modules}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []
    counter = 0

    def visit(v: str) -> None:
        nonlocal counter
        index[v] = low[v] = counter
        counter += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_graph_sees_the_package():
    graph = import_graph()
    assert "gsverse_format.nearest" in graph and "gsverse_format.converters" in graph
    assert "gsverse_format.validators" in graph
    assert "gsverse_format.nearest.reference" in graph["gsverse_format.nearest"]
    assert "gsverse_format.remapping.reference" in graph["gsverse_format.remapping.fast"]


def test_cycle_finder_finds_a_cycle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert cycles(graph) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycles():
    graph = import_graph()
    found = cycles(graph)
    lines = []
    for component in found:
        members = set(component)
        lines.append("cycle among: " + ", ".join(component))
        lines += [f"    {a} -> {b}" for a in component for b in sorted(graph[a] & members)]
    assert not found, "import cycles among package modules:\n" + "\n".join(lines)


#: Module paths that earlier documentation named, kept as re-exports of the module that now
#: holds the code (README §Using the library).
EARLIER_PATHS = {"gsverse_format.remap_fast": "gsverse_format.remapping.fast",
                 "gsverse_format.remap_reference": "gsverse_format.remapping.reference"}


def test_earlier_paths_only_re_export():
    """An earlier path holds no code: imports from its new module and ``__all__``, nothing
    else, and every name it exports is the new module's object."""
    import importlib

    modules = package_modules()
    for old, new in EARLIER_PATHS.items():
        path, _ = modules[old]
        body = ast.parse(path.read_text(encoding="utf-8")).body
        if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
            body = body[1:]                                  # the docstring
        for node in body:
            if isinstance(node, ast.ImportFrom):
                assert node.module == "__future__" or imports_of(old, modules) == {new}, old
            else:
                assert (isinstance(node, ast.Assign) and len(node.targets) == 1
                        and getattr(node.targets[0], "id", None) == "__all__"), (old, node.lineno)
        before, after = importlib.import_module(old), importlib.import_module(new)
        assert before.__all__ and all(getattr(before, name) is getattr(after, name)
                                      for name in before.__all__), old


def test_no_submodule_shadows_an_exported_name():
    """Importing ``gsverse_format.<name>`` sets the package's attribute ``<name>`` to that
    module: a submodule named like an exported function (``remap``, ``bind``...) would replace
    the function once anything imports it (hence ``remapping/``, not ``remap/``)."""
    import gsverse_format

    top = {name.split(".")[1] for name in package_modules() if name.count(".") >= 1}
    assert not top & set(gsverse_format.__all__), sorted(top & set(gsverse_format.__all__))
