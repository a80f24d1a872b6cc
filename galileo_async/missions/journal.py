"""The journal: where a mission run is, in a small JSON file, so a restart can resume there.

Written when each step starts and ends, atomically (a temporary file, then os.replace): a
reader sees the old or the new record, never half of one. The record is a few hundred
bytes written to the page cache without fsync, which takes microseconds, so it is written
on the event loop; a power cut may lose the last record, and then the resume starts at
the step before (never at a step of another plan: the plan's hash is checked).
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from .model import Mission, step_paths
from .report import MissionRejected

__all__ = [
    "DEFAULT_JOURNAL_MAX_AGE",
    "Journal",
    "JournalRecord",
    "ResumePoint",
    "plan_hash",
]

#: Seconds after which a journal is too old to resume from (a day).
DEFAULT_JOURNAL_MAX_AGE = 24 * 3600.0

_INDEX = re.compile(r"\[(\d+)\]")


def plan_hash(mission: Mission) -> str:
    """The sha256 of the mission's canonical JSON: another plan, another hash."""
    data = mission.model_dump(mode="json", by_alias=True)
    text = json.dumps(data, sort_keys=True, separators=(",", ":"), ensure_ascii=False)
    return "sha256:" + hashlib.sha256(text.encode()).hexdigest()


@dataclass(frozen=True)
class JournalRecord:
    """One record: the step at ``path`` ``state`` ("started", "ended", or the mission's ending).

    ``loops``: the 0-based iteration of each loop (by path) the step is in; ``at``: wall
    clock seconds (time.time()).
    """

    mission: str
    plan: str
    state: str
    path: str | None
    loops: dict[str, int] = field(default_factory=dict)
    at: float = 0.0


@dataclass(frozen=True)
class ResumePoint:
    """Where a resumed run starts: the step's indices through loops, after it or at it."""

    path: str
    address: tuple[int, ...]
    after: bool
    loops: dict[str, int]


class Journal:
    """The journal file of one run: ``write`` records, ``resume_point`` reads and checks."""

    def __init__(self, path: str | Path) -> None:
        self.path = Path(path)

    def read(self) -> JournalRecord | None:
        """The record in the file, or None when there is no file."""
        try:
            text = self.path.read_text(encoding="utf-8")
        except FileNotFoundError:
            return None
        try:
            data: dict[str, Any] = json.loads(text)
            return JournalRecord(
                mission=str(data["mission"]), plan=str(data["plan"]), state=str(data["state"]),
                path=None if data.get("path") is None else str(data["path"]),
                loops={str(k): int(v) for k, v in dict(data.get("loops") or {}).items()},
                at=float(data["at"]),
            )  # fmt: skip
        except (ValueError, KeyError, TypeError) as exc:
            raise MissionRejected(
                "?", [f"journal {self.path}: not a mission journal ({exc})"]
            ) from None

    def write(self, record: JournalRecord) -> None:
        """Replace the file's record with ``record``, atomically."""
        data = asdict(record)
        text = json.dumps(data, indent=1, sort_keys=True)
        temporary = self.path.with_name(f".{self.path.name}.{os.getpid()}.tmp")
        temporary.write_text(text + "\n", encoding="utf-8")
        os.replace(temporary, self.path)

    def resume_point(
        self, mission: Mission, *, max_age: float = DEFAULT_JOURNAL_MAX_AGE
    ) -> ResumePoint | None:
        """Where to resume ``mission`` (None: no journal, start at the beginning).

        MissionRejected, with the reason, when the journal is of another plan (the mission
        changed), says the mission completed, or is older than ``max_age`` seconds.
        """
        record = self.read()
        if record is None:
            return None
        where = f"journal {self.path}"
        problems = []
        if record.mission != mission.mission:
            problems.append(f"{where} is of mission {record.mission!r}")
        elif record.plan != plan_hash(mission):
            problems.append(f"{where}: the plan changed since it was written")
        if record.state == "completed":
            problems.append(f"{where}: the mission completed; nothing to resume")
        age = time.time() - record.at
        if age > max_age:
            problems.append(f"{where} is {age / 3600:.1f} h old (more than {max_age / 3600:g} h)")
        if problems:
            raise MissionRejected(mission.mission, problems)
        if record.path is None:
            return None
        paths = {path for path, _ in step_paths(mission.steps)}
        if record.path not in paths:
            raise MissionRejected(mission.mission, [f"{where}: no step {record.path}"])
        address = tuple(int(i) for i in _INDEX.findall(record.path))
        return ResumePoint(record.path, address, record.state == "ended", dict(record.loops))
