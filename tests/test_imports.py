"""Where the package imports (issue 24): a function-level import is for a module that
importing the file does not already load: a heavy third-party module (scipy, h5py,
matplotlib, dask, CuPy) or a package module only some calls need (the start-up budget of
tests/cli/test_startup.py).  An import inside a function of a module that the file's own
module-level imports already load (directly or through the package modules they import) only
costs a lookup per call, or hides an upward import; this test finds them statically."""

from __future__ import annotations

import ast
import importlib.util
from functools import cache
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "lcpcli"


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def is_module(name: str) -> bool:
    path = ROOT.joinpath(*name.split("."))
    return (path.with_suffix(".py").exists() or (path / "__init__.py").exists()
            or path.with_suffix(".pyx").exists())


def is_package(name: str) -> bool:
    return (ROOT.joinpath(*name.split(".")) / "__init__.py").exists()


def loads(node: ast.Import | ast.ImportFrom, here: str) -> list[str]:
    """The modules an import statement in module ``here`` loads (``from pkg import sub``:
    pkg.sub when that is a module of the package)."""
    if isinstance(node, ast.Import):
        return [a.name for a in node.names]
    base = node.module or ""
    if node.level:
        parts = here.split(".")
        keep = len(parts) - node.level + (1 if is_package(here) else 0)
        base = ".".join(parts[:keep] + ([base] if base else []))
    out = []
    for a in node.names:
        sub = f"{base}.{a.name}"
        out.append(sub if (is_module(sub) if sub.startswith("lcpcli") else submodule(sub))
                   else base)
    return out


@cache
def submodule(name: str) -> bool:
    """Whether third-party ``name`` (pkg.attr) is a module of its own."""
    try:
        return importlib.util.find_spec(name) is not None
    except (ImportError, ValueError, AttributeError):
        return False


def ancestors(name: str) -> list[str]:
    parts = name.split(".")
    return [".".join(parts[:i]) for i in range(1, len(parts))]


FILES = {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}
TREES = {name: ast.parse(p.read_text()) for name, p in FILES.items()}


@cache
def top_level(name: str) -> frozenset[str]:
    """What module ``name`` imports when it is loaded (module-level statements, also inside
    module-level ``if``/``try`` blocks, except ``if TYPE_CHECKING``)."""
    out: set[str] = set()
    for stmt in TREES[name].body:
        if isinstance(stmt, ast.If) and "TYPE_CHECKING" in ast.unparse(stmt.test):
            continue
        nodes = ast.walk(stmt) if isinstance(stmt, (ast.If, ast.Try)) else [stmt]
        for node in nodes:
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                out.update(loads(node, name))
    return frozenset(out)


@cache
def loaded_with(name: str) -> frozenset[str]:
    """Every module that importing ``name`` loads (statically: the package's own modules are
    followed, third-party modules count as loaded where imported)."""
    seen: set[str] = set()
    todo = [name, *ancestors(name)]
    while todo:
        m = todo.pop()
        if m in seen:
            continue
        seen.add(m)
        if m in FILES:
            for x in top_level(m):
                todo.extend(y for y in (x, *ancestors(x)) if y not in seen)
    return frozenset(seen)


def test_no_function_imports_a_module_its_file_already_loads() -> None:
    bad = []
    for name, tree in TREES.items():
        for fn in ast.walk(tree):
            if isinstance(fn, (ast.FunctionDef, ast.AsyncFunctionDef)):
                for node in ast.walk(fn):
                    if isinstance(node, (ast.Import, ast.ImportFrom)):
                        bad += [f"{FILES[name].relative_to(ROOT)}:{node.lineno} imports {m}"
                                for m in loads(node, name) if m in loaded_with(name)]
    assert not bad, "\n".join(sorted(set(bad)))


def test_the_static_closure_sees_known_imports() -> None:
    """The analysis itself: lcpcli.api loads the core and the registry; the CLI package does
    not load the solvers at import (its --help stays light)."""
    api = loaded_with("lcpcli.api")
    assert {"lcpcli.core.problem", "lcpcli.core.errors", "numpy"} <= api
    assert "scipy.linalg" not in loaded_with("lcpcli.cli")
