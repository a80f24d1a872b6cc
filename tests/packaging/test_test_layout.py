"""The tests sit in folders by part, each a package, all of them on docs/architecture.md's map."""

from __future__ import annotations

import re
from pathlib import Path

TESTS = Path(__file__).resolve().parents[1]
ROOT = TESTS.parent
#: The map of the test folders in docs/architecture.md ("## The tests" section).
MAP = (ROOT / "docs" / "architecture.md").read_text(encoding="utf-8").partition("## The tests")[2]


def folders() -> list[Path]:
    """Every folder under tests/ that holds Python files (caches aside)."""
    return sorted({p.parent for p in TESTS.rglob("*.py") if "__pycache__" not in p.parts} - {TESTS})


def test_no_test_file_sits_at_the_top() -> None:
    assert sorted(p.name for p in TESTS.glob("test_*.py")) == []


def test_every_folder_is_a_package() -> None:
    assert (TESTS / "__init__.py").is_file()
    assert [f for f in folders() if not (f / "__init__.py").is_file()] == []


def test_every_folder_is_on_the_map_and_the_map_names_no_other() -> None:
    drawn = {m[1] for m in re.finditer(r"^ [│ ]*[├└]── (\w+)/", MAP, re.M)}
    assert drawn == {f.name for f in folders()}
    assert len(drawn) >= 10


def test_support_is_imported_by_its_full_name() -> None:
    support = {p.stem for p in (TESTS / "support").glob("*.py")} - {"__init__"}
    bare = re.compile(rf"^\s*(from|import) ({'|'.join(sorted(support))}|test_\w+)\b", re.M)
    found = [
        f"{p.relative_to(ROOT)}: {m[0].strip()}"
        for p in TESTS.rglob("*.py")
        for m in bare.finditer(p.read_text(encoding="utf-8"))
    ]
    assert found == []
