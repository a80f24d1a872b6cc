"""The sans-IO core stays free of I/O libraries (DESIGN.md, layers)."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

import galileo_async
import galileo_async.protocol

FORBIDDEN = ("asyncio", "serial", "serial_asyncio", "serial_asyncio_fast", "anyio", "trio")
PROTOCOL_DIR = Path(galileo_async.protocol.__file__).parent
PACKAGE_DIR = Path(galileo_async.__file__).parent


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


def loaded_io_modules(setup: str, module: str = "galileo_async.protocol") -> list[str]:
    code = f"import json, sys\n{setup}import {module}\n{REPORT}"
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True
    )
    return list(json.loads(result.stdout))


def test_protocol_and_its_imports_load_no_io_library() -> None:
    assert loaded_io_modules(BARE_PACKAGE) == []


def test_importing_galileo_async_protocol_loads_no_io_library() -> None:
    # Through the real package __init__: it must import the asyncio layers lazily.
    assert loaded_io_modules("") == []


def test_transitions_and_its_imports_load_no_io_library() -> None:
    # The goal rule is pure: goto, rotate_to and events() share it, none of its I/O.
    assert loaded_io_modules(BARE_PACKAGE, "galileo_async.transitions") == []


def test_transitions_imports_only_the_models() -> None:
    names = imports_of(PACKAGE_DIR / "transitions.py")
    assert not imported_modules((PACKAGE_DIR / "transitions.py").read_text()) & set(FORBIDDEN)
    own = {n for n in names if n.startswith("galileo_async")}
    assert own
    assert within(own, "galileo_async.models") == own, own


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


# --- layers above protocol (docs/architecture.md: a module never imports one above it) -----

ROBOT_LAYER = ("robot", "_services", "_operations", "_goal", "_targets")
STATE_LAYER = ("state", "events", "transitions")
#: Link modules that still import the state layer until their pending one-line change lands;
#: each case XPASSes (strict: fails) once it does, so the entry must then be removed.
LINK_PENDING: dict[str, str] = {}
#: Modules that open or speak to a transport: state must do no I/O and know no transport.
TRANSPORT_MODULES = (
    "socket",
    "ssl",
    "selectors",
    "serial",
    "serial_asyncio",
    "serial_asyncio_fast",
    "asyncio.transports",
    "asyncio.protocols",
    "asyncio.streams",
    "asyncio.base_events",
    "asyncio.selector_events",
    "asyncio.proactor_events",
    "asyncio.unix_events",
    "asyncio.windows_events",
    "asyncio.sslproto",
    "asyncio.subprocess",
)
TRANSPORT_ASYNCIO_NAMES = {
    "BaseTransport",
    "ReadTransport",
    "WriteTransport",
    "Transport",
    "DatagramTransport",
    "BaseProtocol",
    "Protocol",
    "BufferedProtocol",
    "StreamReader",
    "StreamWriter",
    "open_connection",
    "start_server",
    "open_unix_connection",
    "start_unix_server",
}


def module_name(path: Path) -> str:
    """Dotted name of a source file of the package (``galileo_async.link.base``)."""
    parts = path.relative_to(PACKAGE_DIR).with_suffix("").parts
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(("galileo_async", *parts))


def full_imports(source: str, module: str = "", *, is_package: bool = False) -> set[str]:
    """Every dotted name an import in ``source`` mentions, relative imports made absolute."""
    package = module if is_package else module.rpartition(".")[0]
    names: set[str] = set()
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            names |= {alias.name for alias in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = ""
            if node.level:
                parts = package.split(".")
                base = ".".join(parts[: len(parts) - node.level + 1])
            target = ".".join(p for p in (base, node.module or "") if p)
            names.add(target)
            names |= {f"{target}.{alias.name}" for alias in node.names}  # `from . import state`
        elif isinstance(node, ast.Call):
            func = node.func
            called = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
            if called in ("import_module", "__import__"):
                names |= {
                    a.value
                    for a in node.args
                    if isinstance(a, ast.Constant) and isinstance(a.value, str)
                }
    return names


def imports_of(path: Path) -> set[str]:
    return full_imports(
        path.read_text(encoding="utf-8"), module_name(path), is_package=path.name == "__init__.py"
    )


def within(names: set[str], *modules: str) -> set[str]:
    """The names that are one of ``modules`` or inside one."""
    return {n for n in names for m in modules if n == m or n.startswith(m + ".")}


def asyncio_names(source: str) -> set[str]:
    """Every ``asyncio.<name>`` that ``source`` uses."""
    return {
        node.attr
        for node in ast.walk(ast.parse(source))
        if isinstance(node, ast.Attribute)
        and isinstance(node.value, ast.Name)
        and node.value.id == "asyncio"
    }


def package_modules(*layer: str) -> list[str]:
    return [f"galileo_async.{name}" for name in layer]


def test_import_resolution_makes_relative_imports_absolute() -> None:
    sample = (
        "from ..state import StatusStore\n"
        "from .. import robot\n"
        "from .base import BaseLink\n"
        "import asyncio.streams\n"
        "import importlib\n"
        "importlib.import_module('galileo_async.cli')\n"
    )
    names = full_imports(sample, "galileo_async.link.stream")
    assert within(names, *package_modules(*STATE_LAYER)) == {
        "galileo_async.state",
        "galileo_async.state.StatusStore",
    }
    assert within(names, "galileo_async.robot") == {"galileo_async.robot"}
    assert "galileo_async.link.base" in names
    assert "galileo_async.cli" in names
    assert within(names, *TRANSPORT_MODULES) == {"asyncio.streams"}
    sample_uses = "t: asyncio.Transport\nasyncio.get_running_loop()\n"
    assert asyncio_names(sample_uses) & TRANSPORT_ASYNCIO_NAMES == {"Transport"}
    package = full_imports(
        "from .stream import StreamLink\n", "galileo_async.link", is_package=True
    )
    assert "galileo_async.link.stream" in package


def test_sim_imports_none_of_robot_state_link_or_cli() -> None:
    sources = sorted((PACKAGE_DIR / "sim").rglob("*.py"))
    assert {p.name for p in sources} >= {"__init__.py", "simulator.py", "device.py"}
    upper = package_modules(*ROBOT_LAYER, *STATE_LAYER, "link", "cli", "discovery")
    for path in sources:
        found = within(imports_of(path), *upper)
        assert not found, f"sim/{path.name} imports {found}"


@pytest.mark.parametrize("name", ["state.py", "events.py", "transitions.py"])
def test_state_knows_no_transport(name: str) -> None:
    path = PACKAGE_DIR / name
    names = imports_of(path)
    found = within(names, *TRANSPORT_MODULES, *package_modules("link", "memory", "sim"))
    assert not found, f"{name} imports {found}"
    uses = asyncio_names(path.read_text(encoding="utf-8")) & TRANSPORT_ASYNCIO_NAMES
    assert not uses, f"{name} uses asyncio.{uses}"


LINK_DIR = PACKAGE_DIR / "link"
LINK_SOURCES = sorted(LINK_DIR.rglob("*.py"))


def link_case(path: Path) -> Any:
    rel = path.relative_to(LINK_DIR).as_posix()
    marks = []
    if rel in LINK_PENDING:
        reason = f"pending: {LINK_PENDING[rel]}"
        marks.append(pytest.mark.xfail(strict=True, raises=AssertionError, reason=reason))
    return pytest.param(path, id=rel, marks=marks)


@pytest.mark.parametrize("path", [link_case(path) for path in LINK_SOURCES])
def test_link_imports_nothing_from_robot_or_state(path: Path) -> None:
    found = within(imports_of(path), *package_modules(*ROBOT_LAYER, *STATE_LAYER, "cli"))
    assert not found, f"{module_name(path)} imports {found}"


def test_link_layer_checks_cover_the_link_package() -> None:
    names = {p.relative_to(LINK_DIR).as_posix() for p in LINK_SOURCES}
    assert names >= {"__init__.py", "base.py", "stream.py", "connectors.py", "ros/link.py"}
    assert set(LINK_PENDING) <= names


# --- optional parts (DESIGN.md: cli behind the extra [cli]; the core needs neither) --------

#: What the extra ``[cli]`` brings (typer needs click): only ``cli/`` may import them.
CLI_ONLY = ("typer", "rich", "click")
CLI_DIR = PACKAGE_DIR / "cli"
CORE_SOURCES = sorted(p for p in PACKAGE_DIR.rglob("*.py") if CLI_DIR not in p.parents)


def test_no_core_module_imports_the_command_line_libraries() -> None:
    assert {module_name(p) for p in CORE_SOURCES} >= {
        "galileo_async", "galileo_async.robot", "galileo_async.fleet", "galileo_async.link.ros",
        "galileo_async.vda5050",
    }  # fmt: skip
    for path in CORE_SOURCES:
        found = imported_modules(path.read_text(encoding="utf-8")) & set(CLI_ONLY)
        assert not found, f"{module_name(path)} imports {found}"


def test_every_core_module_imports_without_the_command_line_libraries() -> None:
    # At run time too: nothing below cli/ reaches typer or rich through another module.
    blocked = "".join(f"sys.modules[{name!r}] = None\n" for name in CLI_ONLY)
    imports = "".join(f"import {module_name(p)}\n" for p in CORE_SOURCES)
    code = f"import json, sys\n{blocked}{imports}print(json.dumps(sorted(sys.modules)))"
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60
    )
    assert result.returncode == 0, result.stderr
    loaded = set(json.loads(result.stdout))
    assert {module_name(p) for p in CORE_SOURCES} <= loaded
