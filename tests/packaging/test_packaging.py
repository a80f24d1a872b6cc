"""The package as others get it: type checkers see the development install; the wheel works.

``make test``'s editable install must be one mypy can follow from any directory, and
``make dist``'s wheel must install into a fresh virtual environment and run ``galileo``.
The wheel test builds in an isolated environment and installs the dependencies with pip
(PyPI, or pip's cache): it is marked ``pypi``, and ``slow`` (about a minute).
"""

from __future__ import annotations

import os
import subprocess
import sys
import tarfile
import zipfile
from pathlib import Path

import pytest

import galileo_async

ROOT = Path(__file__).resolve().parents[2]
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


def test_the_docs_install_from_a_checkout_or_a_wheel_and_name_the_index_for_later() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    install = readme[readme.index("## Install") :].split("\n## ", 1)[0]
    for needed in ("pip install '/path/to/checkout[cli]'", "make dist",
                   "pip install 'galileo_async-0.1.0-py3-none-any.whl[cli]'",
                   "once it is published there | `pip install 'galileo-async[cli]'`"):  # fmt: skip
        assert needed in install, needed
    assert f"galileo_async-{galileo_async.__version__}-py3" in install
    # The index name alone fails while the package is on no index: every other place that
    # gives it says that it adds an extra to an installed package.
    for page in [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]:
        lines = page.read_text(encoding="utf-8").splitlines()
        for number, line in enumerate(lines):
            if "pip install 'galileo-async" not in line or line.strip().startswith("| a package"):
                continue
            around = " ".join(lines[max(0, number - 2) : number + 2])
            assert "installed" in around, f"{page.name}:{number + 1}: {line}"


def run(*command: str | Path, cwd: Path, timeout: float = 300) -> subprocess.CompletedProcess[str]:
    """Run ``command`` in ``cwd`` with clean_env(); output captured, the exit status kept."""
    return subprocess.run(
        [str(part) for part in command], cwd=cwd, env=clean_env(), capture_output=True,
        text=True, timeout=timeout, check=False,
    )  # fmt: skip


@pytest.mark.slow
@pytest.mark.pypi
@pytest.mark.timeout(900)
def test_make_dist_builds_a_wheel_that_installs_into_a_fresh_venv(tmp_path: Path) -> None:
    dist = tmp_path / "dist"
    # The Makefile's own recipe, with this interpreter's tools and the venv left as it is.
    built = run(
        "make", "-C", ROOT, "--no-print-directory", "-o", ".venv/.installed-dev",
        f"BIN={Path(sys.executable).parent}", f"DIST={dist}", "dist",
        cwd=tmp_path, timeout=600,
    )  # fmt: skip
    assert built.returncode == 0, built.stdout + built.stderr
    version = galileo_async.__version__
    (wheel,) = dist.glob(f"galileo_async-{version}-py3-none-any.whl")
    (sdist,) = dist.glob(f"galileo_async-{version}.tar.gz")
    with zipfile.ZipFile(wheel) as archive:
        names = set(archive.namelist())
        (entry_points,) = (name for name in names if name.endswith(".dist-info/entry_points.txt"))
        entries = archive.read(entry_points).decode()
    assert "galileo_async/py.typed" in names
    assert not any(name.startswith(("tests/", "benchmarks/", "examples/")) for name in names)
    assert "galileo = galileo_async.cli:main" in entries
    assert "[pytest11]\ngalileo_async = galileo_async_pytest" in entries
    assert "galileo_async_pytest.py" in names  # the plugin module beside the package
    with tarfile.open(sdist) as archive:
        members = {Path(name).relative_to(f"galileo_async-{version}").as_posix()
                   for name in archive.getnames() if "/" in name}  # fmt: skip
    assert {"pyproject.toml", "README.md", "LICENSE", "galileo_async/py.typed"} <= members

    venv = tmp_path / "venv"
    assert run(sys.executable, "-m", "venv", venv, cwd=tmp_path).returncode == 0
    python, galileo = venv / "bin" / "python", venv / "bin" / "galileo"
    pip = (python, "-m", "pip", "install", "--disable-pip-version-check")
    installed = run(*pip, wheel, cwd=tmp_path)
    assert installed.returncode == 0, installed.stdout + installed.stderr
    where = run(python, "-c", "import galileo_async; print(galileo_async.__file__)", cwd=tmp_path)
    assert where.stdout.startswith(str(venv)), where.stdout + where.stderr  # not the checkout
    # Without the extra [cli], the command says how to add it: by the package's name, which
    # pip resolves from the installed wheel (the package is not on an index yet).
    bare = run(galileo, "--version", cwd=tmp_path)
    assert bare.returncode == 1
    assert "pip install 'galileo-async[cli]'" in bare.stderr, bare.stderr
    extra = run(*pip, "galileo-async[cli]", cwd=tmp_path)
    assert extra.returncode == 0, extra.stdout + extra.stderr
    shown = run(galileo, "--version", cwd=tmp_path)
    assert (shown.returncode, shown.stdout.strip()) == (0, f"galileo {version}"), shown.stderr
