"""The package as others get it: type checkers see the development install.

``make test``'s editable install must be one mypy can follow from any directory.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: A program of a project that uses the package: one deliberate type error proves mypy
#: knows the package's types (an unresolved import would make them Any, and no error).
PROGRAM = """\
import galileo_async
from galileo_async.models import GalileoStatus, float32_decimal

reveal_type(galileo_async.connect)
power: float | None = GalileoStatus().power
half: float = float32_decimal(0.5)
version: int = galileo_async.__version__
"""


def clean_env() -> dict[str, str]:
    """This environment without what would show Python or mypy the checkout by other ways."""
    hidden = ("PYTHONPATH", "MYPYPATH", "PYTHONHOME", "VIRTUAL_ENV", "PYTHONWARNINGS")
    return {key: value for key, value in os.environ.items() if key not in hidden}


def test_mypy_sees_the_development_install_from_another_directory(tmp_path: Path) -> None:
    program = tmp_path / "app.py"
    program.write_text(PROGRAM)
    result = subprocess.run(
        [sys.executable, "-m", "mypy", "--strict", "--follow-imports=silent",
         "--cache-dir", str(tmp_path / "cache"), str(program)],
        cwd=tmp_path, env=clean_env(), capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    out = result.stdout + result.stderr
    hint = (
        "mypy cannot follow this install of galileo_async: reinstall it with "
        f"`make .venv/.installed-dev` (setuptools' editable_mode=compat).\n{out}"
    )
    assert "import-not-found" not in out, hint
    assert "import-untyped" not in out, hint
    assert "-> galileo_async.robot.connection.Connection" in out, out
    assert 'app.py:7: error: Incompatible types in assignment (expression has type "str", ' in out
    assert "Found 1 error in 1 file" in out, out
