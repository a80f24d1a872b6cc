"""Argument checks shared by every layer: a named InvalidArgument before anything is sent.

Pure (no I/O, no asyncio): protocol/ uses them too.
"""

from __future__ import annotations

import contextlib
import difflib
import ipaddress
import math
import numbers
import re
from collections.abc import Collection, Iterable, Iterator, Mapping
from urllib.parse import urlsplit

from .errors import InvalidArgument

__all__ = [
    "check_bool",
    "check_int",
    "check_names",
    "check_number",
    "check_seconds",
    "check_timeout",
    "host_key",
    "ip_literal",
    "naming",
    "near_miss",
    "parse_hosts",
]


def check_number(
    name: str,
    value: object,
    *,
    low: float | None = None,
    high: float | None = None,
    low_open: bool = False,
) -> float:
    """``value`` as a finite float within [low, high] (``low_open``: above low); else raise.

    Rejects bool, str, NaN, ±inf and ints beyond float range (10**400).
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InvalidArgument(f"{name} must be a number, got {value!r}")
    try:
        number = float(value)
    except (OverflowError, ValueError):
        raise InvalidArgument(f"{name} is out of range, got {_short(value)}") from None
    if not math.isfinite(number):
        raise InvalidArgument(f"{name} must be finite, got {value!r}")
    if low is not None and (number <= low if low_open else number < low):
        bound = f"> {low:g}" if low_open else f">= {low:g}"
        raise InvalidArgument(f"{name} must be {bound}, got {value!r}")
    if high is not None and number > high:
        raise InvalidArgument(f"{name} must be <= {high:g}, got {value!r}")
    return number


def check_int(name: str, value: object, low: int, high: int) -> int:
    """``value`` as an int in low..high; bool, float and str raise InvalidArgument."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise InvalidArgument(f"{name} must be an int, got {value!r}")
    if not low <= value <= high:
        raise InvalidArgument(f"{name} must be in {low}..{high}, got {_short(value)}")
    return int(value)


def check_bool(name: str, value: object) -> bool:
    """``value`` if it is True or False (not 1, "no" or None); else raise InvalidArgument."""
    if not isinstance(value, bool):
        raise InvalidArgument(f"{name} must be True or False, got {value!r}")
    return value


def check_seconds(name: str, value: object, *, allow_zero: bool = False) -> float:
    """``value`` as a finite number of seconds, positive (or zero if allowed); else raise."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise InvalidArgument(f"{name} must be a number of seconds, got {value!r}")
    return check_number(name, value, low=0.0, low_open=not allow_zero)


def check_timeout(name: str, value: object, *, allow_none: bool = True) -> float | None:
    """None (no limit, if allowed) or ``value`` as positive finite seconds; else raise."""
    if value is None and allow_none:
        return None
    return check_seconds(name, value)


def near_miss(name: str, accepted: Collection[str]) -> str | None:
    """The name of ``accepted`` that ``name`` is most likely a typo of, if one is close."""
    close = difflib.get_close_matches(name, sorted(accepted), n=1)
    return close[0] if close else None


def check_names(given: Iterable[str], accepted: Collection[str]) -> None:
    """Raise InvalidArgument for the first name not in ``accepted``, with a near miss if any."""
    for name in given:
        if name in accepted:
            continue
        close = near_miss(name, accepted)
        known = ", ".join(sorted(accepted))
        hint = f"; did you mean {close!r}?" if close else f" (known: {known})"
        raise InvalidArgument(f"unknown option {name!r}{hint}")


# RFC 1123 labels; underscores too, which robots' host names do use.
_LABEL = re.compile(r"[A-Za-z0-9_]([A-Za-z0-9_-]{0,61}[A-Za-z0-9_])?\Z")


def _is_host_name(name: str) -> bool:
    labels = name[:-1].split(".") if name.endswith(".") else name.split(".")
    return 0 < len(name) <= 253 and all(_LABEL.match(label) for label in labels)


def host_key(name: str) -> str:
    """The form a host name is looked up by: lower case, without a final dot."""
    return name.lower().rstrip(".")


def ip_literal(text: str) -> str | None:
    """``text`` as a normalised IP address literal, or None when it is not one."""
    try:
        return str(ipaddress.ip_address(text.strip("[]")))
    except ValueError:
        return None


def parse_hosts(hosts: str | Mapping[str, str]) -> dict[str, str]:
    """``name=ip,name2=ip2`` (or a mapping) → {lower-case name: ip}; InvalidArgument if bad."""
    if isinstance(hosts, str):
        pairs: list[tuple[str, str]] = []
        for entry in hosts.split(","):
            name, sep, address = entry.strip().partition("=")
            if not sep:
                raise InvalidArgument(f"hosts: expected name=ip, got {entry.strip()!r}")
            pairs.append((name.strip(), address.strip()))
    elif isinstance(hosts, Mapping):
        pairs = list(hosts.items())
    else:
        raise InvalidArgument(f"hosts must be 'name=ip,…' or a mapping, got {hosts!r}")
    parsed: dict[str, str] = {}
    for name, address in pairs:
        if not isinstance(name, str) or not _is_host_name(name):
            raise InvalidArgument(f"hosts: {name!r} is not a host name")
        ip = ip_literal(address) if isinstance(address, str) else None
        if ip is None:
            raise InvalidArgument(f"hosts: the address of {name} must be an IP, got {address!r}")
        if host_key(name) in parsed:
            raise InvalidArgument(f"hosts: {name} is given twice")
        parsed[host_key(name)] = ip
    return parsed


def hide_secrets(url: str) -> str:
    """``url`` with a password in its user part and ``token``/``password`` values as ``***``."""
    parts = urlsplit(url)
    userinfo, at, host = parts.netloc.rpartition("@")
    netloc = f"{userinfo.partition(':')[0]}:***@{host}" if at and ":" in userinfo else None
    pairs = [item.partition("=") for item in parts.query.split("&") if item]
    query = "&".join(
        f"{k}=***" if k in ("token", "password") else f"{k}{eq}{v}" for k, eq, v in pairs
    )
    if netloc is None and query == parts.query:
        return url
    return parts._replace(netloc=netloc or parts.netloc, query=query).geturl()


@contextlib.contextmanager
def naming(url: str, what: str) -> Iterator[None]:
    """Put ``what`` in front of an InvalidArgument raised inside that does not name ``url``.

    A password or token in ``url`` is shown as ``***`` (hide_secrets).
    """
    try:
        yield
    except InvalidArgument as exc:
        shown = hide_secrets(url)
        if shown != url:  # the cause would show the secret too
            raise InvalidArgument(f"{what}: {exc}".replace(url, shown)) from None
        if url in str(exc):
            raise
        raise InvalidArgument(f"{what}: {exc}") from exc


def _short(value: object) -> str:
    """repr of ``value``, or its size for a huge int (repr of 10**5000 raises ValueError)."""
    if isinstance(value, int) and value.bit_length() > 64:
        return f"an int of {value.bit_length()} bits"
    return repr(value)
