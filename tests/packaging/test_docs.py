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
PROTOCOL = ROOT / "docs" / "protocol.md"
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


# --- docs/protocol.md: the one page every citation of the protocol points to -------------

#: The developers' notes docs/protocol.md replaced: no file may cite them (spelt here in
#: pieces, so that this file does not match itself).
ABSENT = tuple(name + ".md" for name in ("PROTOCOL", "VENDOR"))
#: A numbered heading of docs/protocol.md: "## 2. Commands", "### 2.a …", "### 7.5 …".
NUMBERED = re.compile(r"^#{2,6} +(\d+(?:\.[0-9a-z]+)?)\.? ", re.M)
HEADING = re.compile(r"^#{1,6} +(.+?) *$", re.M)
#: A § reference after a mention of protocol.md, up to the line's end or another page's name.
CITED = re.compile(r"protocol\.md(?P<scope>(?:(?!\b[\w-]+\.md\b)[^\n])*)")
SECTION = re.compile(r"§(\d+(?:\.[0-9a-z]+)?)(?:[-–](\d+\.[0-9a-z]+))?")
ANCHOR = re.compile(r"\]\((?:[\w./-]*protocol\.md)?#([^)\s]+)\)")


def tracked_text_files() -> dict[str, str]:
    """Every file git tracks here, by its path, that reads as UTF-8 text."""
    listed = subprocess.run(
        ["git", "ls-files", "-z"], cwd=ROOT, check=True, capture_output=True
    ).stdout.decode()
    files = {}
    for name in filter(None, listed.split("\0")):
        try:
            files[name] = (ROOT / name).read_text(encoding="utf-8")
        except (UnicodeDecodeError, FileNotFoundError, IsADirectoryError):
            continue
    return files


def slug(heading: str) -> str:
    """GitHub's anchor of a heading."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def protocol_sections(text: str) -> set[str]:
    """The numbered sections ("2", "2.a", "7.5") of a page like docs/protocol.md."""
    return set(NUMBERED.findall(text))


def cited_sections(text: str) -> set[str]:
    """The § sections a text cites of docs/protocol.md (ranges give both ends)."""
    found: set[str] = set()
    for citation in CITED.finditer(text):
        for first, last in SECTION.findall(citation["scope"]):
            found.update(filter(None, (first, last)))
    return found


def protocol_anchors(name: str, text: str) -> set[str]:
    """The #anchors of docs/protocol.md that a page links to."""
    own = name == "docs/protocol.md"
    return {match[1] for match in ANCHOR.finditer(text) if own or "protocol.md#" in match[0]}


def test_no_file_cites_the_absent_notes() -> None:
    files = tracked_text_files()
    assert "docs/protocol.md" in files
    citing = sorted(
        f"{name}:{text[: text.index(absent)].count(chr(10)) + 1}"
        for name, text in files.items()
        for absent in ABSENT
        if absent in text
    )
    assert citing == [], "cite docs/protocol.md instead"


def test_every_cited_section_of_protocol_md_exists() -> None:
    text = PROTOCOL.read_text(encoding="utf-8")
    sections = protocol_sections(text)
    anchors = {slug(heading) for heading in HEADING.findall(text)}
    assert {"1", "2", "2.a", "2.h", "3", "4", "5.4", "6.5", "7.2", "7.6"} <= sections
    missing = []
    cited_somewhere = set()
    for name, content in tracked_text_files().items():
        cited = cited_sections(content)
        cited_somewhere |= cited
        missing += [f"{name}: §{s}" for s in sorted(cited - sections)]
        if name.endswith(".md"):
            linked = protocol_anchors(name, content)
            missing += [f"{name}: #{a}" for a in sorted(linked - anchors)]
    assert missing == []
    assert {"1", "2.b", "6.5", "7.5"} <= cited_somewhere  # the scan sees the citations


def test_the_citation_checks_see_what_they_check() -> None:
    page = "## 1. Status\n### 2.a Start and stop\n### 7.5 Command datagrams\n"
    assert protocol_sections(page) == {"1", "2.a", "7.5"}
    assert slug("1. Status frames (robot → host)") == "1-status-frames-robot--host"
    code = "# (docs/protocol.md §1 field 12, §2.g); (docs/protocol.md §7.5-7.6)\n# notes.md §9\n"
    assert cited_sections(code) == {"1", "2.g", "7.5", "7.6"}
    assert cited_sections("[protocol.md](protocol.md) and BENCHMARKS.md §9") == set()
    doc = "see [protocol.md §2.a](protocol.md#2a-start) and [§7](#7-udp) and [x](other.md#y)"
    assert protocol_anchors("docs/guide.md", doc) == {"2a-start"}
    assert protocol_anchors("docs/protocol.md", doc) == {"2a-start", "7-udp"}
