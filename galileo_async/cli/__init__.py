"""The ``galileo`` command line: drive, watch, record and simulate a Galileo robot.

It needs the extra ``[cli]`` (typer and rich). Without them this package still imports,
so that the ``galileo`` console script says how to get them instead of a traceback.
"""

from __future__ import annotations

import shlex
import sys
from pathlib import Path
from typing import Any

#: Top-level modules of the extra ``[cli]`` and of what they need themselves.
CLI_MODULES = frozenset({"typer", "rich", "click", "shellingham"})
#: How to get the command line's dependencies from a package index.
INSTALL_HINT = "pip install 'galileo-async[cli]'"
#: Exit code of ``galileo`` without its dependencies (``ExitCode.ERROR``).
MISSING_EXIT_CODE = 1

_missing: str | None = None
try:
    from .app import app
    from .app import main as _run
    from .runner import ExitCode
except ModuleNotFoundError as exc:
    _missing = (exc.name or "").partition(".")[0]
    if _missing not in CLI_MODULES:
        raise

__all__ = [
    "CLI_MODULES",
    "INSTALL_HINT",
    "MISSING_EXIT_CODE",
    "ExitCode",
    "app",
    "install_hint",
    "main",
]


def install_hint() -> str:
    """The install command that works here: from the checkout this runs from, else INSTALL_HINT."""
    root = Path(__file__).resolve().parents[2]
    if not (root / "pyproject.toml").is_file():
        return INSTALL_HINT
    # This interpreter's pip: the extra must land where `galileo` runs.
    return f"{shlex.quote(sys.executable)} -m pip install -e {shlex.quote(f'{root}[cli]')}"


def missing_message() -> str:
    """The one line ``galileo`` prints when a module of the extra ``[cli]`` is missing."""
    return (
        f"galileo: the command line needs typer and rich ({_missing} is not installed): "
        f"{install_hint()}"
    )


def main() -> None:
    """Console-script entry point of ``galileo``; without typer or rich: one line, exit 1."""
    if _missing is not None:
        print(missing_message(), file=sys.stderr)
        raise SystemExit(MISSING_EXIT_CODE)
    _run()


def __getattr__(name: str) -> Any:
    # Only reached when the import above failed: say why instead of "cannot import name".
    if name in ("app", "ExitCode"):
        raise ModuleNotFoundError(missing_message(), name=_missing)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
