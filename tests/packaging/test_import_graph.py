"""The package's import graph has no circle, and every import of its own modules is visible.

Every import statement counts, wherever it sits: at module level, inside functions (loaded
lazily) and inside ``if TYPE_CHECKING:`` blocks. A lazy or type-only import still ties two
modules together, and a circle through one is a circle a refactoring can close by moving
one line, so none is allowed.
"""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from collections.abc import Iterator, Mapping
from pathlib import Path

import pytest

import galileo_async

PACKAGE = "galileo_async"
PACKAGE_DIR = Path(galileo_async.__file__).parent
#: The package's lazy loaders (``galileo_async.X`` on first use, so that ``import
#: galileo_async.protocol`` loads no asyncio layer; ``galileo_async.testing.X`` likewise, so
#: that importing galileo_async.testing loads no simulator); their targets must be imported
#: visibly too.
LAZY_LOADERS = (PACKAGE, f"{PACKAGE}.testing")


def module_files(root: Path = PACKAGE_DIR, package: str = PACKAGE) -> dict[str, Path]:
    """Dotted module name → source file, for every module under ``root``."""
    files = {}
    for path in sorted(root.rglob("*.py")):
        parts = path.relative_to(root).with_suffix("").parts
        if parts[-1] == "__init__":
            parts = parts[:-1]
        files[".".join((package, *parts))] = path
    return files


def _owner(name: str, modules: Mapping[str, object]) -> str | None:
    """The module ``name`` is, or the nearest module containing it (an attribute's owner)."""
    while name and name not in modules:
        name = name.rpartition(".")[0]
    return name or None


def imported_modules(
    source: str, module: str, modules: Mapping[str, object], *, is_package: bool
) -> set[str]:
    """The package's own modules that the import statements in ``source`` load."""
    package = module if is_package else module.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            targets = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                parts = package.split(".")
                base = ".".join([*parts[: len(parts) - node.level + 1], *([base] if base else [])])
            # `from . import state` loads the module state; `from .state import X` loads state.
            targets = [
                f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base
                for alias in node.names
            ]
        else:
            continue
        found |= {owner for t in targets if (owner := _owner(t, modules)) is not None}
    found.discard(module)
    return found


def import_graph(files: Mapping[str, Path]) -> dict[str, set[str]]:
    """Module → the package modules it imports (every import statement, at any depth)."""
    return {
        module: imported_modules(
            path.read_text(encoding="utf-8"), module, files, is_package=path.name == "__init__.py"
        )
        for module, path in files.items()
    }


def cycles(graph: Mapping[str, set[str]]) -> list[list[str]]:
    """Every strongly connected group of more than one module (Tarjan), sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    found: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            group = []
            while True:
                member = stack.pop()
                group.append(member)
                if member == node:
                    break
            if len(group) > 1:
                found.append(sorted(group))

    for node in sorted(graph):
        if node not in index:
            visit(node)
    return sorted(found)


def import_by_name_calls(source: str) -> Iterator[ast.Call]:
    """``importlib.import_module(…)``, ``import_module(…)`` and ``__import__(…)`` calls."""
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Call):
            func = node.func
            called = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
            if called in ("import_module", "__import__"):
                yield node


def lazy_targets(source: str) -> set[str]:
    """The module names of the package ``__init__``'s ``_LAZY`` table."""
    for node in ast.walk(ast.parse(source)):
        if (
            isinstance(node, ast.AnnAssign)
            and getattr(node.target, "id", None) == "_LAZY"
            and isinstance(node.value, ast.Dict)
        ):
            return {v.value for v in node.value.values if isinstance(v, ast.Constant)}
    raise AssertionError("no _LAZY table")


# --- the package -------------------------------------------------------------------------

FILES = module_files()
GRAPH = import_graph(FILES)


def test_the_package_has_no_import_circle() -> None:
    assert cycles(GRAPH) == []


def test_the_graph_covers_the_package() -> None:
    assert {
        "galileo_async.state.store", "galileo_async.state.streams", "galileo_async.links"
    } <= set(GRAPH)  # fmt: skip
    assert "galileo_async.state.streams" in GRAPH["galileo_async.state.store"]
    # Imports inside functions count: the scheme table loads the simulator for sim:// only.
    assert {"galileo_async.sim", "galileo_async.ros"} <= GRAPH["galileo_async.links"]


def test_no_own_module_is_loaded_by_name() -> None:
    """Only the lazy loaders may; every module they load is also imported visibly."""
    hidden = []
    for module, path in FILES.items():
        if module in LAZY_LOADERS:
            continue
        for call in import_by_name_calls(path.read_text(encoding="utf-8")):
            name = (
                call.args[0].value if call.args and isinstance(call.args[0], ast.Constant) else None
            )
            if not isinstance(name, str) or name == PACKAGE or name.startswith(f"{PACKAGE}."):
                hidden.append(f"{module}:{call.lineno} loads {name or 'a computed name'}")
    assert hidden == [], "import own modules with import statements"
    for loader in LAZY_LOADERS:
        lazy = {f"{loader}.{name}" for name in lazy_targets(FILES[loader].read_text())}
        assert lazy, loader
        assert lazy <= GRAPH[loader], f"import {loader}'s lazy modules under TYPE_CHECKING"


@pytest.mark.parametrize("loader", LAZY_LOADERS)
def test_a_lazy_loader_loads_its_modules_on_first_use_only(loader: str) -> None:
    lazy = sorted({f"{loader}.{name}" for name in lazy_targets(FILES[loader].read_text())})
    names = sorted(_lazy_table(loader))
    script = (
        "import importlib, json, sys\n"
        f"package = importlib.import_module({loader!r})\n"
        f"before = [m for m in {lazy!r} if m in sys.modules]\n"
        f"getattr(package, {names[0]!r})\n"
        f"after = [m for m in {lazy!r} if m in sys.modules]\n"
        "print(json.dumps([before, after]))\n"
    )
    ran = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, timeout=60, check=False
    )
    assert ran.returncode == 0, ran.stderr
    before, after = json.loads(ran.stdout)
    assert before == [], f"importing {loader} loaded {before}"
    assert after, f"{loader}.{names[0]} loaded none of {lazy}"


def _lazy_table(loader: str) -> dict[str, str]:
    """The ``_LAZY`` table of a lazy loader: public name → module."""
    for node in ast.walk(ast.parse(FILES[loader].read_text(encoding="utf-8"))):
        if isinstance(node, ast.AnnAssign) and getattr(node.target, "id", None) == "_LAZY":
            return dict(ast.literal_eval(node.value))
    raise AssertionError(f"{loader} has no _LAZY table")


# --- the checks themselves ---------------------------------------------------------------


def _graph_of(sources: dict[str, str]) -> dict[str, set[str]]:
    modules = dict.fromkeys(sources)
    return {
        name: imported_modules(text, name, modules, is_package=name == "pkg")
        for name, text in sources.items()
    }


def test_a_circle_through_a_lazy_or_type_only_import_is_found() -> None:
    sources = {
        "pkg": "",
        "pkg.a": "from .b import B\n",
        "pkg.b": "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    from .c import C\n",
        "pkg.c": "def f():\n    from . import a\n",
        "pkg.d": "import pkg.a.thing\n",
    }
    graph = _graph_of(sources)
    assert graph["pkg.c"] == {"pkg.a"}
    assert graph["pkg.d"] == {"pkg.a"}
    assert cycles(graph) == [["pkg.a", "pkg.b", "pkg.c"]]
    del sources["pkg.c"]
    assert cycles(_graph_of(sources)) == []


def test_relative_imports_resolve_to_modules() -> None:
    modules = dict.fromkeys(["p", "p.x", "p.x.y", "p.z"])
    source = "from .. import z\nfrom ..x import y\nfrom . import thing\nfrom ...outside import q\n"
    assert imported_modules(source, "p.x.w", modules, is_package=False) == {"p.z", "p.x.y", "p.x"}


def test_loading_by_name_is_seen() -> None:
    source = "import importlib\nimportlib.import_module('galileo_async.sim')\n__import__(name)\n"
    calls = list(import_by_name_calls(source))
    assert [getattr(c.args[0], "value", None) for c in calls] == ["galileo_async.sim", None]
    assert lazy_targets("_LAZY: dict[str, str] = {'Robot': 'robot'}\n") == {"robot"}


def foreign_private_attributes(source: str) -> list[str]:
    """``x._name`` where ``x`` is not ``self``: reaching into another object's internals."""
    return [
        f"{node.lineno}: {ast.unparse(node)}"
        for node in ast.walk(ast.parse(source))
        if isinstance(node, ast.Attribute)
        and node.attr.startswith("_")
        and not node.attr.startswith("__")
        and not (isinstance(node.value, ast.Name) and node.value.id == "self")
    ]


def test_the_store_reaches_into_no_subscription() -> None:
    # The store feeds subscriptions through offer/fail/close (and, per frame, the batch
    # offers of state/streams.py); they read it as a StatusSource.
    state = FILES["galileo_async.state.store"].read_text(encoding="utf-8")
    assert foreign_private_attributes(state) == []
    assert "galileo_async.state.store" not in GRAPH["galileo_async.state.streams"]
    sample = "self._ok = 1\nstream._wakeup = None\nwatch._push(x)\n"
    assert foreign_private_attributes(sample) == ["2: stream._wakeup", "3: watch._push"]
