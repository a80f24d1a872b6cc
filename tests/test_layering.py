"""The sans-IO core stays free of I/O libraries (DESIGN.md, layers)."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import galileo_async.protocol

FORBIDDEN = ("asyncio", "serial", "serial_asyncio", "serial_asyncio_fast", "anyio", "trio")
PROTOCOL_DIR = Path(galileo_async.protocol.__file__).parent


REPORT = f"print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in {FORBIDDEN!r})))"
# Puts an empty package object in place of galileo_async/__init__.py, so that only the
# protocol subpackage and what it imports itself get loaded.
BARE_PACKAGE = (
    "import importlib.util, types\n"
    "spec = importlib.util.find_spec('galileo_async')\n"
    "package = types.ModuleType('galileo_async')\n"
    "package.__path__ = list(spec.submodule_search_locations)\n"
    "sys.modules['galileo_async'] = package\n"
)


def loaded_io_modules(setup: str) -> list[str]:
    code = f"import json, sys\n{setup}import galileo_async.protocol\n{REPORT}"
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True
    )
    return list(json.loads(result.stdout))


def test_protocol_and_its_imports_load_no_io_library() -> None:
    assert loaded_io_modules(BARE_PACKAGE) == []


def test_importing_galileo_async_protocol_loads_no_io_library() -> None:
    # Through the real package __init__: it must import the asyncio layers lazily.
    assert loaded_io_modules("") == []


def test_the_subprocess_check_can_see_asyncio() -> None:
    code = "import asyncio, sys; print('asyncio' in sys.modules)"
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True
    )
    assert result.stdout.strip() == "True"


def imported_modules(source: str) -> set[str]:
    """Top-level names of every module an import statement in ``source`` mentions."""
    names = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names |= {alias.name.split(".")[0] for alias in node.names}
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
        elif isinstance(node, ast.Call) and getattr(node.func, "id", None) == "__import__":
            names |= {a.value for a in node.args if isinstance(a, ast.Constant)}
    return names


def test_protocol_sources_import_no_io_library() -> None:
    sources = sorted(PROTOCOL_DIR.rglob("*.py"))
    assert {p.name for p in sources} >= {"__init__.py", "status.py", "commands.py", "device.py"}
    for path in sources:
        found = imported_modules(path.read_text(encoding="utf-8")) & set(FORBIDDEN)
        assert not found, f"{path.name} imports {found}"


def test_import_scan_finds_imports() -> None:
    sample = "import asyncio.events\nfrom anyio import run\nx = __import__('serial')\n"
    assert imported_modules(sample) >= {"asyncio", "anyio", "serial"}
