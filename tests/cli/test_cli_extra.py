"""The ``galileo`` command without the extra ``[cli]``: one line saying how to get it, exit 1.

Each case runs the installed entry point in a fresh interpreter in which typer or rich
cannot be imported (``sys.modules[name] = None`` makes Python's import refuse it, as when
it is not installed).
"""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import pytest

from galileo_async.cli import INSTALL_HINT, MISSING_EXIT_CODE, ExitCode, install_hint

if sys.version_info >= (3, 11):
    import tomllib
else:
    import tomli as tomllib

#: Runs the ``galileo`` console script as pyproject.toml declares it.
CONSOLE_SCRIPT = (
    "from importlib.metadata import entry_points\n"
    "(script,) = entry_points(group='console_scripts', name='galileo')\n"
    "script.load()()\n"
)
#: Runs ``python -m galileo_async``.
MODULE = "import runpy\nrunpy.run_module('galileo_async', run_name='__main__')\n"
ENTRY_POINTS = {"console script": CONSOLE_SCRIPT, "python -m galileo_async": MODULE}


def run_without(blocked: str, entry: str, *args: str) -> subprocess.CompletedProcess[str]:
    """Run ``entry`` with ``args`` in a fresh interpreter where ``blocked`` cannot be imported."""
    code = f"import sys\nsys.modules[{blocked!r}] = None\nsys.argv = ['galileo', *{args!r}]\n"
    return subprocess.run(
        [sys.executable, "-c", code + entry], capture_output=True, text=True, timeout=60
    )


@pytest.mark.parametrize("blocked", ["typer", "rich"])
@pytest.mark.parametrize("entry", list(ENTRY_POINTS))
def test_galileo_without_the_cli_extra_says_how_to_get_it(blocked: str, entry: str) -> None:
    result = run_without(blocked, ENTRY_POINTS[entry], "status")
    assert result.returncode == MISSING_EXIT_CODE == ExitCode.ERROR
    assert result.stdout == ""
    lines = result.stderr.splitlines()
    assert len(lines) == 1, result.stderr  # one line, no traceback
    assert f"({blocked} is not installed)" in lines[0]
    assert lines[0].endswith(install_hint())
    assert INSTALL_HINT == "pip install 'galileo-async[cli]'"


def test_the_hint_from_a_checkout_installs_that_checkout() -> None:
    # The package name is not on any index: from a checkout, pip must be given its path.
    root = Path(__file__).resolve().parents[2]
    assert install_hint().endswith(f"-m pip install -e '{root}[cli]'")
    assert install_hint().startswith(sys.executable)


def test_the_blocking_reaches_the_command_line() -> None:
    # With nothing blocked the same wrapper runs the real command (it would not fail above
    # for another reason): --version needs typer.
    result = run_without("no_such_module", CONSOLE_SCRIPT, "--version")
    assert result.returncode == 0, result.stderr
    assert result.stdout.startswith("galileo ")


def test_the_typer_application_without_typer_is_a_clear_import_error() -> None:
    code = (
        "import sys\nsys.modules['typer'] = None\n"
        "try:\n    from galileo_async.cli import app\n"
        "except ModuleNotFoundError as exc:\n    print(exc.name, exc)\n"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True
    )
    assert result.stdout.startswith("typer galileo: the command line needs typer and rich")
    assert result.stdout.rstrip().endswith(install_hint())


def test_another_missing_module_is_not_mistaken_for_the_extra() -> None:
    # A module the command line does not get from [cli] must fail loudly, as a bug.
    result = run_without("galileo_async.cli.runner", CONSOLE_SCRIPT, "status")
    assert result.returncode != 0
    assert "Traceback" in result.stderr
    assert install_hint() not in result.stderr


def requirement_names(requirements: list[str]) -> set[str]:
    """The distribution names of ``requirements`` (``"anyio>=4"`` → ``"anyio"``)."""
    return {re.split(r"[^A-Za-z0-9_.-]", r, maxsplit=1)[0].lower() for r in requirements}


def test_the_core_needs_no_extra_and_dev_installs_every_extra() -> None:
    pyproject = tomllib.loads((Path(__file__).parents[2] / "pyproject.toml").read_text())
    project = pyproject["project"]
    assert requirement_names(project["dependencies"]) == {
        "pyserial-asyncio-fast", "pyserial-asyncio", "anyio", "pydantic", "tomli",
    }  # fmt: skip
    extras = project["optional-dependencies"]
    assert requirement_names(extras["cli"]) == {"typer", "rich"}
    assert extras["ros"] == []
    # `make demo` and `make test` install [dev]: the command line and every extra's tests.
    for extra in ("cli", "vda5050", "foxglove"):
        assert set(extras[extra]) <= set(extras["dev"]), extra
    assert project["scripts"] == {"galileo": "galileo_async.cli:main"}
