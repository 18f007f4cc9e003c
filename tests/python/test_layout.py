"""The package's shape (docs/CONTRIBUTING.md "Layout"): its modules import
each other in one direction only, no module reaches into another's private
names, and no module grows past what a reader takes in at once.

The modules are parsed, not imported, so every import counts: at the top
of a module and inside functions (an import hidden in a function to dodge
a cycle is still a cycle)."""

from __future__ import annotations

import ast
import os

import pytest

import uwhl_rs

PKG = os.path.dirname(os.path.abspath(uwhl_rs.__file__))
NAME = "uwhl_rs"
#: the compiled binding layer: its underscored names are its interface
EXEMPT = {f"{NAME}._core"}
MAX_LINES = 600
#: modules allowed to be longer for now, each with its bound and why; an
#: entry goes when its module is split (the test says so)
LONGER = {
    f"{NAME}.synth": (900, "the scene renderer, one concern: noise, painting, the two scenes"),
}


def _modules(root: str = PKG) -> dict[str, str]:
    """Dotted module name -> source path, for every .py file of the package."""
    out = {}
    for d, dirs, files in os.walk(root):
        dirs[:] = [x for x in dirs if not x.startswith((".", "__pycache__"))]
        for f in files:
            if not f.endswith(".py"):
                continue
            rel = os.path.relpath(os.path.join(d, f), os.path.dirname(root))[:-3].split(os.sep)
            if rel[-1] == "__init__":
                rel = rel[:-1]
            out[".".join(rel)] = os.path.join(d, f)
    return out


MODULES = _modules()


def _is_package(mod: str) -> bool:
    return MODULES[mod].endswith("__init__.py")


def _base(mod: str, level: int) -> str:
    """The package a relative import of ``level`` in ``mod`` starts from."""
    parts = mod.split(".")
    if not _is_package(mod):
        parts = parts[:-1]
    return ".".join(parts[: len(parts) - (level - 1)])


def _imports(mod: str, tree: ast.AST):
    """(imported module, imported name or None, node) for every import of
    the package's own modules, wherever it is in ``mod``."""
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if a.name == NAME or a.name.startswith(NAME + "."):
                    yield a.name, None, node
        elif isinstance(node, ast.ImportFrom):
            src = node.module or ""
            if node.level:
                src = _base(mod, node.level) + ("." + src if src else "")
            if not (src == NAME or src.startswith(NAME + ".")):
                continue
            for a in node.names:
                sub = f"{src}.{a.name}"
                yield (sub, None, node) if sub in MODULES or sub in EXEMPT else (src, a.name, node)


def _private(name: str) -> bool:
    return name.startswith("_") and not (name.startswith("__") and name.endswith("__"))


def _trees() -> dict[str, ast.AST]:
    out = {}
    for mod, path in MODULES.items():
        with open(path, encoding="utf-8") as f:
            out[mod] = ast.parse(f.read(), filename=path)
    return out


TREES = _trees()


def _graph() -> dict[str, set[str]]:
    g: dict[str, set[str]] = {m: set() for m in MODULES}
    for mod, tree in TREES.items():
        for target, _, _ in _imports(mod, tree):
            if target in MODULES and target != mod:
                g[mod].add(target)
    return g


def _cycles(g: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(g[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(g):
        if v not in index:
            visit(v)
    return out


def test_the_package_is_parsed_whole():
    # the checks below mean nothing if the walk found nothing
    assert f"{NAME}.files" in MODULES and len(MODULES) >= 10, sorted(MODULES)


def test_imports_point_one_way_only():
    cycles = _cycles(_graph())
    assert not cycles, f"import cycles (top-level and function-level imports counted): {cycles}"


def test_no_private_name_crosses_modules():
    found = []
    for mod, tree in TREES.items():
        bound = {}  # a name this module binds to one of the package's modules
        for target, name, node in _imports(mod, tree):
            if name is not None and _private(name) and target not in EXEMPT and target != mod:
                found.append(f"{mod}:{node.lineno}: from {target} import {name}")
            if name is None and target in MODULES:
                if isinstance(node, ast.ImportFrom):
                    for a in node.names:
                        if target.endswith("." + a.name):
                            bound[a.asname or a.name] = target
                else:
                    for a in node.names:
                        if a.name == target:
                            bound[a.asname or a.name.split(".")[0]] = a.name if a.asname else a.name.split(".")[0]
        for node in ast.walk(tree):
            if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name) and node.value.id in bound:
                target = bound[node.value.id]
                full = f"{target}.{node.attr}"
                if _private(node.attr) and full not in EXEMPT and target != mod:
                    found.append(f"{mod}:{node.lineno}: {node.value.id}.{node.attr}")
    assert not found, "private names used across modules:\n" + "\n".join(found)


@pytest.mark.parametrize("mod", sorted(MODULES))
def test_modules_stay_readable(mod):
    with open(MODULES[mod], encoding="utf-8") as f:
        n = sum(1 for _ in f)
    bound, why = LONGER.get(mod, (MAX_LINES, None))
    assert n <= bound, f"{MODULES[mod]}: {n} lines; split it by concern (at most {bound})"
    if why is not None:
        assert n > MAX_LINES, f"{mod} is {n} lines now: drop its entry in LONGER ({why})"


def test_the_checks_catch_what_they_look_for():
    """The checks themselves, on hand-made graphs and sources."""
    assert _cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert _cycles({"a": {"b"}, "b": set()}) == []
    tree = ast.parse("from .files import _hidden\nfrom . import _core\nfrom ._core import _x\n")
    got = [(t, n) for t, n, _ in _imports(f"{NAME}.batch", tree)]
    assert (f"{NAME}.files", "_hidden") in got and (f"{NAME}._core", None) in got
    assert (f"{NAME}._core", "_x") in got and _private("_hidden") and not _private("__version__")
