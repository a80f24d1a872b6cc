"""examples/test_patrol_app.py passes as a user's project would run it (pytest, the plugin)."""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
TEST_FILE = ROOT / "examples" / "test_patrol_app.py"
#: The tests in that file, all of which must pass.
EXPECTED = 10
#: Real seconds the whole file may take (it runs on a virtual clock: about one).
TIMEOUT = 60


@pytest.mark.parametrize("mode", ["strict", "auto"])
def test_patrol_app_tests_pass(mode: str) -> None:
    # strict is pytest-asyncio's default, auto this repository's: the file works in both.
    path = os.pathsep.join(filter(None, [str(ROOT), os.environ.get("PYTHONPATH")]))
    result = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider",
         "-o", f"asyncio_mode={mode}", str(TEST_FILE)],
        cwd=ROOT, env=dict(os.environ, PYTHONPATH=path),
        capture_output=True, text=True, timeout=TIMEOUT, check=False,
    )  # fmt: skip
    assert result.returncode == 0, result.stdout + result.stderr
    summary = result.stdout.strip().splitlines()[-1]
    assert re.fullmatch(rf"{EXPECTED} passed in [\d.]+s", summary), summary


def test_docs_excerpts_are_the_examples() -> None:
    # docs/testing.md quotes the example files: every quoted block is in its file as is.
    text = (ROOT / "docs" / "testing.md").read_text(encoding="utf-8")
    excerpt = re.compile(
        r"<!-- not run: an excerpt of (?P<file>examples/\S+) -->\n```python\n(?P<code>.*?)^```",
        re.S | re.M,
    )
    quoted = [(match["file"], match["code"]) for match in excerpt.finditer(text)]
    assert {file for file, _ in quoted} == {"examples/patrol_app.py", "examples/test_patrol_app.py"}
    for file, code in quoted:
        assert code in (ROOT / file).read_text(encoding="utf-8"), f"{file} no longer has:\n{code}"
