"""Option: how one option of connect() is described (its field of ConnectOptions holds it)."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, Literal

from .checks import Check

__all__ = ["LINK_KINDS", "OWNERS", "Option", "Owner"]

#: The built-in link kinds (links.link_kind): what a URL opens.
LINK_KINDS = ("serial", "socket", "udp", "sim", "ros", "http")
#: Who takes an option: the Robot, connect() itself, or the link.
Owner = Literal["robot", "connect", "link"]
OWNERS: tuple[Owner, ...] = ("robot", "connect", "link")


@dataclasses.dataclass(frozen=True)
class Option:
    """One option: its default, owner, the link kinds that take it (None: all), doc, check.

    ``name`` and ``type`` come from its field of ConnectOptions; ``by_kind``: a check of
    its own on some link kinds.
    """

    default: Any
    doc: str
    check_value: Check
    owner: Owner = "link"
    kinds: frozenset[str] | None = None
    by_kind: Mapping[str, Check] = dataclasses.field(default_factory=dict)
    name: str = ""
    type: Any = None

    def takes(self, kind: str | None) -> bool:
        """True when a link of ``kind`` (None: any) takes this option."""
        return self.kinds is None or kind is None or kind in self.kinds

    def check(self, value: object, kind: str | None = None) -> None:
        """Raise InvalidArgument, naming the option, when a ``kind`` link cannot use ``value``."""
        self.by_kind.get(kind or "", self.check_value)(self.name, value)
