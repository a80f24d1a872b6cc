"""The sans-IO core stays free of I/O libraries (DESIGN.md, layers)."""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

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


#: The goal machine (goal.py) and the events of two statuses (derive.py).
TRANSITIONS_SOURCES = sorted((PACKAGE_DIR / "transitions").rglob("*.py"))


def test_transitions_and_its_imports_load_no_io_library() -> None:
    # The goal rule is pure: goto, rotate_to and events() share it, none of its I/O.
    assert loaded_io_modules(BARE_PACKAGE, "galileo_async.transitions") == []


def test_transitions_imports_only_the_models_and_the_event_types() -> None:
    assert {p.name for p in TRANSITIONS_SOURCES} >= {"__init__.py", "goal.py", "derive.py"}
    names = set().union(*(imports_of(p) for p in TRANSITIONS_SOURCES))
    for path in TRANSITIONS_SOURCES:
        assert not imported_modules(path.read_text(encoding="utf-8")) & set(FORBIDDEN)
    own = {n for n in names if n.startswith("galileo_async")}
    own -= within(own, "galileo_async.transitions")
    assert within(own, "galileo_async.models")
    assert within(own, "galileo_async.events")
    assert within(own, "galileo_async.models", "galileo_async.events") == own, own
    events = {n for n in imports_of(PACKAGE_DIR / "events.py") if n.startswith("galileo_async")}
    assert within(events, "galileo_async.models") == events, events


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


# --- layers above protocol (DESIGN.md: dependencies point one way, downwards) -------------

#: Each part of the package, by the dotted prefix of its modules (longest prefix wins).
PARTS = {
    "galileo_async.models": "base",
    "galileo_async._wire": "base",
    "galileo_async.errors": "base",
    "galileo_async._checks": "base",
    "galileo_async.battery": "base",
    "galileo_async.schemas": "schemas",
    "galileo_async.protocol": "protocol",
    "galileo_async.options": "options",
    "galileo_async.sim": "sim",
    "galileo_async.events": "transitions",
    "galileo_async.transitions": "transitions",
    "galileo_async.transports": "transports",
    "galileo_async.ros": "ros",
    "galileo_async.http": "http",
    "galileo_async.links": "links",
    "galileo_async.state": "state",
    "galileo_async.robot": "robot",
    "galileo_async.fleet": "fleet",
    "galileo_async.vda5050": "vda5050",
    "galileo_async.foxglove": "foxglove",
    "galileo_async.missions": "missions",
    "galileo_async.metrics": "metrics",
    "galileo_async.cli": "cli",
    "galileo_async.testing": "testing",
    "galileo_async.recording": "recording",
}
#: What each part may import besides itself. transports and ros know nothing of goals or
#: state; state knows no transport; sim speaks from the device side on protocol and models
#: only, so a bug in robot cannot hide behind a matching bug in the simulator.
MAY_IMPORT = {
    "base": {"base"},
    "protocol": {"base"},
    "sim": {"base", "protocol"},
    "transitions": {"base"},
    # The option description: below every part that takes options (it owns their defaults).
    "options": {"base", "protocol", "transitions"},
    "transports": {"base", "protocol", "options"},
    "ros": {"base", "protocol", "transports", "options"},
    "http": {"base", "protocol", "transports", "options"},
    # The scheme table: above every link kind, below robot (sim, http and ros lazily).
    "links": {"base", "protocol", "transports", "options"},
    "state": {"base", "transitions"},
    "robot": {"base", "protocol", "transitions", "state", "transports", "links", "options"},
    "fleet": {"base", "transitions", "state", "robot", "links", "options"},
    "vda5050": {"base", "transitions", "robot"},
    # The Foxglove live view: on the public Robot API, like VDA 5050.
    "schemas": {"base", "transitions"},
    "foxglove": {"base", "transitions", "robot", "schemas"},
    # Plans of steps on the public Robot and Fleet API (docs/missions.md).
    "missions": {"base", "transitions", "state", "robot", "fleet", "links", "options"},
    # MCAP recordings of a Robot or a Fleet; the file's reading is the simulator's (replay).
    "recording": {"base", "transitions", "robot", "fleet", "sim", "schemas"},
    # Prometheus metrics on the public Robot and Fleet API (docs/observability.md).
    "metrics": {"base", "transitions", "robot", "fleet"},
    # Tests of applications: a Robot on the simulator, from both sides.
    "testing": {"base", "protocol", "options", "sim", "robot", "fleet", "missions"},
}
#: The only imports beyond MAY_IMPORT: the scheme table loads the simulator for sim://, and
#: the optional http and ros links for their URLs, inside the functions that need them (or
#: for type checking); the Robot and the Fleet load the mission runner likewise.
LAZY_ONLY = {
    "galileo_async.links": {"sim", "ros", "http"},
    # Robot.run_mission and Fleet.run_missions load the missions layer above them on use.
    "galileo_async.robot.robot": {"missions"},
    "galileo_async.fleet.fleet": {"missions"},
}
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
    """Dotted name of a source file of the package (``galileo_async.transports.link``)."""
    parts = path.relative_to(PACKAGE_DIR).with_suffix("").parts
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(("galileo_async", *parts))


def _import_nodes(tree: ast.Module, *, eager_only: bool) -> list[ast.Import | ast.ImportFrom]:
    """Import statements; ``eager_only``: those run at import time (not in functions or
    ``if TYPE_CHECKING:``)."""
    if not eager_only:
        return [n for n in ast.walk(tree) if isinstance(n, (ast.Import, ast.ImportFrom))]
    found: list[ast.Import | ast.ImportFrom] = []
    todo: list[ast.stmt] = list(tree.body)
    while todo:
        node = todo.pop()
        if isinstance(node, (ast.Import, ast.ImportFrom)):
            found.append(node)
        elif isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            todo.extend(node.orelse)
        elif isinstance(node, (ast.If, ast.Try, ast.With)):
            todo.extend(ast.iter_child_nodes(node))  # type: ignore[arg-type]
    return [n for n in found if isinstance(n, (ast.Import, ast.ImportFrom))]


def full_imports(
    source: str, module: str = "", *, is_package: bool = False, eager_only: bool = False
) -> set[str]:
    """Every dotted name an import in ``source`` mentions, relative imports made absolute."""
    package = module if is_package else module.rpartition(".")[0]
    names: set[str] = set()
    tree = ast.parse(source)
    for node in _import_nodes(tree, eager_only=eager_only):
        if isinstance(node, ast.Import):
            names |= {alias.name for alias in node.names}
        else:
            base = ""
            if node.level:
                parts = package.split(".")
                base = ".".join(parts[: len(parts) - node.level + 1])
            target = ".".join(p for p in (base, node.module or "") if p)
            names.add(target)
            names |= {f"{target}.{alias.name}" for alias in node.names}  # `from . import state`
    if eager_only:
        return names
    for node in ast.walk(tree):
        if isinstance(node, ast.Call):
            func = node.func
            called = func.attr if isinstance(func, ast.Attribute) else getattr(func, "id", None)
            if called in ("import_module", "__import__"):
                names |= {
                    a.value
                    for a in node.args
                    if isinstance(a, ast.Constant) and isinstance(a.value, str)
                }
    return names


def imports_of(path: Path, *, eager_only: bool = False) -> set[str]:
    return full_imports(
        path.read_text(encoding="utf-8"),
        module_name(path),
        is_package=path.name == "__init__.py",
        eager_only=eager_only,
    )


def within(names: set[str], *modules: str) -> set[str]:
    """The names that are one of ``modules`` or inside one."""
    return {n for n in names for m in modules if n == m or n.startswith(m + ".")}


def part_of(name: str) -> str | None:
    """The part (PARTS) a dotted name of the package belongs to, if any."""
    while name:
        if name in PARTS:
            return PARTS[name]
        name = name.rpartition(".")[0]
    return None


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


SOURCES = sorted(PACKAGE_DIR.rglob("*.py"))
LAYERED = [p for p in SOURCES if part_of(module_name(p)) in MAY_IMPORT]


def test_import_resolution_makes_relative_imports_absolute() -> None:
    sample = (
        "from ..state import StatusStore\n"
        "from .. import robot\n"
        "from .link import Link\n"
        "import asyncio.streams\n"
        "import importlib\n"
        "importlib.import_module('galileo_async.cli')\n"
        "def f():\n    from ..sim import Simulator\n"
    )
    names = full_imports(sample, "galileo_async.transports.stream")
    assert within(names, "galileo_async.state") == {
        "galileo_async.state",
        "galileo_async.state.StatusStore",
    }
    assert within(names, "galileo_async.robot") == {"galileo_async.robot"}
    assert "galileo_async.transports.link" in names
    assert "galileo_async.cli" in names
    assert within(names, *TRANSPORT_MODULES) == {"asyncio.streams"}
    eager = full_imports(sample, "galileo_async.transports.stream", eager_only=True)
    assert "galileo_async.sim.Simulator" in names
    assert not within(eager, "galileo_async.sim")
    assert "galileo_async.cli" not in eager
    sample_uses = "t: asyncio.Transport\nasyncio.get_running_loop()\n"
    assert asyncio_names(sample_uses) & TRANSPORT_ASYNCIO_NAMES == {"Transport"}
    package = full_imports(
        "from .stream import StreamChannel\n", "galileo_async.transports", is_package=True
    )
    assert "galileo_async.transports.stream" in package
    assert part_of("galileo_async.transports.stream.StreamChannel") == "transports"
    assert part_of("galileo_async.events.GoalReached") == "transitions"
    assert part_of("galileo_async") is None


def test_every_module_has_a_part() -> None:
    unplaced = {module_name(p) for p in SOURCES if part_of(module_name(p)) is None}
    assert unplaced == {"galileo_async", "galileo_async.__main__"}  # the package front door
    assert {part_of(module_name(p)) for p in SOURCES} >= set(MAY_IMPORT) | {"cli"}


@pytest.mark.parametrize("path", LAYERED, ids=lambda p: p.relative_to(PACKAGE_DIR).as_posix())
def test_each_module_imports_only_its_part_and_those_below(path: Path) -> None:
    module = module_name(path)
    part = part_of(module)
    assert part is not None
    eager = imports_of(path, eager_only=True)
    every = imports_of(path)
    lazy_allowed = LAZY_ONLY.get(module, set())
    wrong = sorted(
        name
        for name in every
        if (other := part_of(name)) is not None
        and other != part
        and other not in MAY_IMPORT[part]
        and not (other in lazy_allowed and name not in eager)
    )
    assert not wrong, f"{module} ({part}) imports {wrong}"


def test_the_scheme_table_loads_sim_http_and_ros_lazily_only() -> None:
    path = PACKAGE_DIR / "links.py"
    eager = imports_of(path, eager_only=True)
    assert {part_of(n) for n in imports_of(path)} >= {"sim", "ros", "http"}
    assert not {part_of(n) for n in eager} & {"sim", "ros", "http"}


@pytest.mark.parametrize("part", ["transports", "http", "ros"])
def test_no_link_kind_imports_up_to_the_scheme_table_or_the_simulator(part: str) -> None:
    for path in sorted((PACKAGE_DIR / part).rglob("*.py")):
        found = within(imports_of(path), *package_modules("links", "sim"))
        assert not found, f"{module_name(path)} imports {found}"


def test_vda5050_uses_the_public_robot_api_only() -> None:
    for path in sorted((PACKAGE_DIR / "vda5050").rglob("*.py")):
        robot = within(imports_of(path), "galileo_async.robot")
        assert robot <= {"galileo_async.robot", "galileo_async.robot.Robot"}, robot


def test_sim_imports_none_of_robot_state_transports_or_cli() -> None:
    sources = sorted((PACKAGE_DIR / "sim").rglob("*.py"))
    assert {p.name for p in sources} >= {"__init__.py", "simulator.py", "device.py"}
    upper = package_modules("robot", "state", "transitions", "events", "transports", "ros", "cli")
    for path in sources:
        found = within(imports_of(path), *upper)
        assert not found, f"sim/{path.name} imports {found}"


STATE_SOURCES = [
    *sorted((PACKAGE_DIR / "state").rglob("*.py")),
    PACKAGE_DIR / "events.py",
    *TRANSITIONS_SOURCES,
]


@pytest.mark.parametrize("path", STATE_SOURCES, ids=lambda p: p.relative_to(PACKAGE_DIR).as_posix())
def test_state_knows_no_transport(path: Path) -> None:
    names = imports_of(path)
    found = within(names, *TRANSPORT_MODULES, *package_modules("transports", "ros", "sim"))
    assert not found, f"{path.name} imports {found}"
    uses = asyncio_names(path.read_text(encoding="utf-8")) & TRANSPORT_ASYNCIO_NAMES
    assert not uses, f"{path.name} uses asyncio.{uses}"


LINK_SOURCES = [
    path
    for part in ("transports", "ros", "http")
    for path in sorted((PACKAGE_DIR / part).rglob("*.py"))
]


@pytest.mark.parametrize("path", LINK_SOURCES, ids=lambda p: p.relative_to(PACKAGE_DIR).as_posix())
def test_transports_import_nothing_from_robot_or_state(path: Path) -> None:
    upper = ("robot", "state", "events", "transitions", "fleet", "cli", "vda5050", "missions")
    found = within(imports_of(path), *package_modules(*upper))
    assert not found, f"{module_name(path)} imports {found}"


def test_transport_checks_cover_the_transport_packages() -> None:
    names = {p.relative_to(PACKAGE_DIR).as_posix() for p in LINK_SOURCES}
    assert names >= {
        "transports/__init__.py", "transports/link.py", "transports/channel.py",
        "transports/stream.py", "transports/connectors.py",
        "ros/channel.py", "http/channel.py",
    }  # fmt: skip


# --- module shape: modules split by concern, classes whole --------------------------------

#: A generous limit: a module past it holds more than one concern. No cap decides the
#: structure below it; a class is not cut in halves to fit (test_no_class_is_a_half).
MAX_LINES = 800


def test_no_module_is_over_800_lines() -> None:
    long = {
        module_name(p): n
        for p in SOURCES
        if (n := len(p.read_text(encoding="utf-8").splitlines())) > MAX_LINES
    }
    assert long == {}


#: Bases and decorators whose class annotations are fields or an interface, not borrowed
#: attributes (a subclass of such a class in the same module is one too).
RECORD_BASES = {"NamedTuple", "TypedDict", "BaseModel", "Protocol", "Enum", "IntEnum", "Flag"}
RECORD_DECORATORS = {"dataclass", "define", "frozen"}
ABSTRACT_BASES = {"ABC", "ABCMeta", "Protocol"}

_Function = ast.FunctionDef | ast.AsyncFunctionDef


def _last_name(node: ast.expr) -> str:
    """The name ``node`` ends with: ``abc.ABC`` -> ABC, ``Protocol[T]`` -> Protocol."""
    if isinstance(node, ast.Subscript):
        return _last_name(node.value)
    if isinstance(node, ast.Call):
        return _last_name(node.func)
    if isinstance(node, ast.Attribute):
        return node.attr
    return node.id if isinstance(node, ast.Name) else ""


def _statements(function: _Function) -> list[ast.stmt]:
    """The body of ``function`` after its docstring."""
    body = function.body
    if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
        return body[1:]
    return body


def _stubbed(function: _Function) -> bool:
    """``function`` only raises NotImplementedError."""
    body = _statements(function)
    return (
        len(body) == 1
        and isinstance(body[0], ast.Raise)
        and body[0].exc is not None
        and _last_name(body[0].exc) == "NotImplementedError"
    )


def _empty(function: _Function) -> bool:
    """``function`` does nothing (pass, ``...`` or its docstring alone)."""
    return all(
        isinstance(s, ast.Pass) or (isinstance(s, ast.Expr) and isinstance(s.value, ast.Constant))
        for s in _statements(function)
    )


def _class_body(cls: ast.ClassDef) -> list[ast.stmt]:
    """The statements of a class, those under ``if TYPE_CHECKING:`` included."""
    return [
        s
        for stmt in cls.body
        for s in (stmt.body + stmt.orelse if isinstance(stmt, ast.If) else [stmt])
    ]


def _of_self(node: ast.AST) -> str | None:
    """The attribute name of ``self.NAME``, else None."""
    if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Name):
        return node.attr if node.value.id == "self" else None
    return None


def _assigned(cls: ast.ClassDef) -> set[str]:
    """Attributes of ``self`` that the class's own code assigns (setattr and the like too)."""
    names = set()
    for node in ast.walk(cls):
        targets: list[ast.expr] = []
        if isinstance(node, ast.Assign):
            targets = node.targets
        elif isinstance(node, (ast.AnnAssign, ast.AugAssign)):
            targets = [node.target]
        elif isinstance(node, ast.Call) and _last_name(node.func) in {"setattr", "__setattr__"}:
            names |= {str(a.value) for a in node.args[1:2] if isinstance(a, ast.Constant)}
        names |= {n for t in targets for each in ast.walk(t) if (n := _of_self(each))}
    return names


def _called(cls: ast.ClassDef) -> set[str]:
    """Methods the class's own code calls on ``self``."""
    return {
        name
        for node in ast.walk(cls)
        if isinstance(node, ast.Call) and (name := _of_self(node.func)) is not None
    }


def class_halves(source: str) -> dict[str, list[str]]:
    """The classes of ``source`` that are halves of a class, each with why (none: {}).

    A half leaves part of itself to the class it is mixed into. It stubs a method with
    ``raise NotImplementedError`` while it has no base (whose method the stub would refuse)
    and is neither an ABC or Protocol nor a base that subclasses in its module implement;
    calls a method of its own that is empty for another class to fill; declares attributes
    it never assigns; or calls ``super()`` for a method while it has no base but object.
    """
    classes = [n for n in ast.walk(ast.parse(source)) if isinstance(n, ast.ClassDef)]
    records: set[str] = set()
    halves: dict[str, list[str]] = {}
    for cls in classes:
        bases = {_last_name(b) for b in cls.bases} | {_last_name(k.value) for k in cls.keywords}
        body = _class_body(cls)
        methods = {s.name: s for s in body if isinstance(s, _Function)}
        decorators = {_last_name(d) for d in cls.decorator_list}
        if bases & (RECORD_BASES | records) or decorators & RECORD_DECORATORS:
            records.add(cls.name)
        abstract = bases & ABSTRACT_BASES or any(
            "abstractmethod" in {_last_name(d) for d in m.decorator_list} for m in methods.values()
        )
        implemented = {
            name
            for sub in classes
            if cls.name in {_last_name(b) for b in sub.bases}
            for name, m in ((s.name, s) for s in sub.body if isinstance(s, _Function))
            if not _stubbed(m)
        }
        based = bool(bases - {"object", "Generic"})
        why = []
        if not abstract and not based:  # with a base, a stub says "not supported" of its method
            why += [
                f"{name}() raises NotImplementedError"
                for name, method in methods.items()
                if _stubbed(method) and name not in implemented
            ]
        if not abstract:
            why += [
                f"{name}() is empty, for another class to fill"
                for name, method in methods.items()
                if _empty(method) and name in _called(cls) and not name.startswith("__")
            ]
        if cls.name not in records:
            assigned = _assigned(cls)
            why += [
                f"declares {s.target.id} and never assigns it"
                for s in body
                if isinstance(s, ast.AnnAssign) and s.value is None
                and isinstance(s.target, ast.Name) and s.target.id not in assigned
                and _last_name(s.annotation) != "ClassVar"
            ]  # fmt: skip
        if not based:
            why += [
                f"calls super().{node.attr}() but has no base"
                for node in ast.walk(cls)
                if isinstance(node, ast.Attribute) and isinstance(node.value, ast.Call)
                and _last_name(node.value.func) == "super" and not node.attr.startswith("__")
            ]  # fmt: skip
        if why:
            halves[cls.name] = why
    return halves


def test_no_class_is_a_half() -> None:
    halves = {
        f"{module_name(p)}.{name}": why
        for p in SOURCES
        for name, why in class_halves(p.read_text(encoding="utf-8")).items()
    }
    assert halves == {}


HALVES = '''
class Watchdog:
    store: Store  # set by the link it is mixed into
    def _abandon(self, reason: str) -> None:
        """BaseLink's."""
        raise NotImplementedError
    def check(self) -> None:
        self._on_stale()
        self._abandon("stale")
    def _on_stale(self) -> None:
        """A hook of the link's."""
class Checking:
    if TYPE_CHECKING:
        _ops: Operations
    async def rotate_to(self, degrees: float) -> None:
        await super().rotate_to(degrees)
'''

WHOLES = '''
class Base(ABC):
    @abstractmethod
    def payload(self) -> bytes: ...
class Stub(abc.ABC):
    def payload(self) -> bytes:
        raise NotImplementedError
class Sink(Protocol):
    store: Store
    def update(self, status: Status) -> None:
        raise NotImplementedError
class Command:
    def payload(self) -> bytes:
        raise NotImplementedError
class Goto(Command):
    def payload(self) -> bytes:
        return b"g"
class Transport(asyncio.Transport):
    closing: bool
    def __init__(self) -> None:
        self.closing = False
    def write_eof(self) -> None:
        raise NotImplementedError("not supported")
    async def close(self) -> None:
        await super().close()
@dataclass
class Point:
    x: float
class Header(BaseModel):
    version: str
class Order(Header):
    nodes: list[str]
class Goal(NamedTuple):
    target_id: int
class Link:
    kinds: ClassVar[set[str]]
    def hook(self) -> None:
        """Empty, and nobody calls it on self."""
'''


def test_the_half_check_flags_halves_and_not_abstract_bases_or_records() -> None:
    assert class_halves(HALVES) == {
        "Watchdog": [
            "_abandon() raises NotImplementedError",
            "_on_stale() is empty, for another class to fill",
            "declares store and never assigns it",
        ],
        "Checking": [
            "declares _ops and never assigns it",
            "calls super().rotate_to() but has no base",
        ],
    }
    assert class_halves(WHOLES) == {}


# --- optional parts (DESIGN.md: cli behind the extra [cli]; the core needs neither) --------

#: What the extra ``[cli]`` brings (typer needs click): only ``cli/`` may import them.
CLI_ONLY = ("typer", "rich", "click")
CLI_DIR = PACKAGE_DIR / "cli"
CORE_SOURCES = sorted(p for p in PACKAGE_DIR.rglob("*.py") if CLI_DIR not in p.parents)


def test_no_core_module_imports_the_command_line_libraries() -> None:
    assert {module_name(p) for p in CORE_SOURCES} >= {
        "galileo_async", "galileo_async.robot", "galileo_async.fleet", "galileo_async.ros",
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
