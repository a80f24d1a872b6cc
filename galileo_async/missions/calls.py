"""A call step: an HTTP request to an outside system (a door, a lift) and the answer it expects."""

from __future__ import annotations

import asyncio
import json
from typing import Any

from .model import CallOut

__all__ = ["CallFailed", "call_out", "holds"]


class CallFailed(Exception):
    """The call got no answer in time, or not the answer expected."""


def holds(expected: Any, answer: Any) -> bool:
    """True when ``answer`` holds ``expected``: the same value, or for dicts every key's."""
    if isinstance(expected, dict):
        return isinstance(answer, dict) and all(
            key in answer and holds(value, answer[key]) for key, value in expected.items()
        )
    return bool(expected == answer)


async def call_out(call: CallOut, session: Any = None) -> Any:
    """Make ``call`` (aiohttp, ``session`` or one of its own); its JSON answer, or None.

    CallFailed for no answer within ``call.timeout``, a status not in ``expect_status``, or
    a JSON answer without ``expect_json``'s keys and values.
    """
    import aiohttp  # the http extra; only call steps need it

    timeout = aiohttp.ClientTimeout(total=call.timeout)
    own = session is None
    client: aiohttp.ClientSession = aiohttp.ClientSession() if own else session
    try:
        async with client.request(
            call.method, call.url, json=call.json_body, headers=call.headers, timeout=timeout
        ) as response:
            status, text = response.status, await response.text()
    except asyncio.TimeoutError:  # TimeoutError from 3.11 on
        raise CallFailed(f"{call.method} {call.url}: no answer within {call.timeout:g} s") from None
    except aiohttp.ClientError as exc:
        raise CallFailed(f"{call.method} {call.url}: {exc}") from None
    finally:
        if own:
            await client.close()
    if status not in call.expect_status:
        expected = " or ".join(str(code) for code in call.expect_status)
        raise CallFailed(f"{call.method} {call.url}: status {status}, expected {expected}")
    try:
        answer = json.loads(text) if text.strip() else None
    except ValueError:
        answer = None
    if call.expect_json is not None and not holds(call.expect_json, answer):
        raise CallFailed(
            f"{call.method} {call.url}: the answer {text[:200]!r} does not hold "
            f"{json.dumps(call.expect_json)}"
        )
    return answer
