"""Shards: one fleet file split over N processes or machines, every robot in exactly one.

Robot ``name`` belongs to shard ``crc32(name as UTF-8) % N + 1`` (shards are counted from 1):
the assignment depends on the name and N only, never on the order of the file or on the
other robots, so adding a robot moves no other robot to another shard.
"""

from __future__ import annotations

import zlib
from collections.abc import Iterable
from dataclasses import dataclass

from ..errors import InvalidArgument

__all__ = ["Shard", "parse_shard", "shard_of"]


def shard_of(name: str, count: int) -> int:
    """The shard (1..``count``) that robot ``name`` belongs to."""
    return zlib.crc32(name.encode("utf-8")) % count + 1


@dataclass(frozen=True)
class Shard:
    """Shard ``index`` of ``count`` (1 <= index <= count)."""

    index: int
    count: int

    def __post_init__(self) -> None:
        for name in ("index", "count"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int):
                raise InvalidArgument(f"shard {name} must be an int, got {value!r}")
        if self.count < 1 or not 1 <= self.index <= self.count:
            raise InvalidArgument(
                f"shard must be K/N with 1 <= K <= N, got {self.index}/{self.count}"
            )

    def __str__(self) -> str:
        return f"{self.index}/{self.count}"

    def holds(self, name: str) -> bool:
        """True when robot ``name`` belongs to this shard."""
        return shard_of(name, self.count) == self.index

    def select(self, names: Iterable[str]) -> list[str]:
        """The names of ``names`` that belong to this shard, in their order."""
        return [name for name in names if self.holds(name)]


def parse_shard(text: str) -> Shard:
    """``"K/N"`` (shard K of N, from 1) as a Shard; InvalidArgument naming the form."""
    index, slash, count = text.partition("/")
    try:
        if not slash:
            raise ValueError(text)
        return Shard(int(index), int(count))
    except ValueError:
        raise InvalidArgument(
            f"shard must be K/N (e.g. 1/4: the first of 4), got {text!r}"
        ) from None
