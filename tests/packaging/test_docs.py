"""Every Python snippet of README.md and docs/*.md runs as written (on the simulator).

A snippet that is not meant to run (a fragment, a real robot's port, a broker) says so in
an HTML comment on the line before its fence: ``<!-- not run: why -->``.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
DOCS = [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
#: A fenced Python snippet, with the line before it (where a "not run" comment goes).
SNIPPET = re.compile(r"(?P<before>[^\n]*)\n```python[^\n]*\n(?P<code>.*?)^```", re.S | re.M)
#: How a snippet runs: top-level await allowed, the names its page's prose assumes imported.
RUNNER = """
import ast, asyncio, sys
import anyio
import galileo_async
import galileo_async as galileo
code = compile(sys.stdin.read(), "snippet", "exec", flags=ast.PyCF_ALLOW_TOP_LEVEL_AWAIT)
namespace = {"__name__": "__main__", "asyncio": asyncio, "anyio": anyio,
             "galileo": galileo, "galileo_async": galileo_async}
result = eval(code, namespace)
if asyncio.iscoroutine(result):
    asyncio.run(result)
"""
#: Real seconds a snippet may take (the simulator runs at 20x through GALILEO_PORT).
TIMEOUT = 60


def snippets() -> list[tuple[str, str]]:
    """(page:line, code) of every Python snippet not marked as not run."""
    found = []
    for page in DOCS:
        text = page.read_text(encoding="utf-8")
        for match in SNIPPET.finditer(text):
            if "<!-- not run" in match["before"]:
                continue
            line = text[: match.start("code")].count("\n")
            found.append((f"{page.relative_to(ROOT)}:{line}", match["code"]))
    return found


def test_snippets_are_found() -> None:
    pages = {name.partition(":")[0] for name, _ in snippets()}
    assert {"README.md", "docs/simulator.md", "docs/guide.md"} <= pages


@pytest.mark.parametrize(("where", "code"), snippets(), ids=[w for w, _ in snippets()])
def test_snippet_runs(where: str, code: str, tmp_path: Path) -> None:
    env = dict(os.environ, GALILEO_PORT="sim://?speed=20")
    result = subprocess.run(
        [sys.executable, "-c", RUNNER], input=code, cwd=tmp_path, env=env,
        capture_output=True, text=True, timeout=TIMEOUT, check=False,
    )  # fmt: skip
    assert result.returncode == 0, f"{where}:\n{code}\n{result.stdout}{result.stderr}"


def test_cli_jq_example_prints_statuses(tmp_path: Path) -> None:
    # docs/cli.md pipes `galileo decode` into jq: that filter must print something.
    text = (ROOT / "docs" / "cli.md").read_text(encoding="utf-8")
    line = next(line for line in text.splitlines() if "| jq" in line and "decode" in line)
    jq_filter = line.split("'")[1]
    capture = tmp_path / "faulty.glc"
    galileo = [sys.executable, "-m", "galileo_async"]
    record = [*galileo, "--port", "sim://?speed=5&drop=0.05", "record", str(capture)]
    subprocess.run([*record, "--duration", "1"], check=True, capture_output=True, timeout=TIMEOUT)
    decoded = subprocess.run(
        [*galileo, "decode", str(capture)], check=True, capture_output=True, text=True,
        timeout=TIMEOUT,
    )  # fmt: skip
    shown = subprocess.run(
        ["jq", "-c", jq_filter], input=decoded.stdout, check=True, capture_output=True, text=True
    )
    assert shown.stdout.splitlines()[0].startswith("[")
