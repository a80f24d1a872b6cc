"""Every way a caller stops waiting: the cancellation matrix of the fleet's tests."""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable

import anyio
import pytest

__all__ = ["WAYS", "stop_waiting"]

#: anyio.fail_after, anyio.move_on_after, asyncio.timeout, task.cancel(), a failing sibling.
WAYS = ("fail_after", "move_on_after", "timeout", "cancel", "sibling")


async def stop_waiting(how: str, call: Callable[[], Awaitable[object]], after: float) -> None:
    """Run ``call()`` and stop it ``after`` seconds in ``how``; the expected error is checked."""
    if how == "fail_after":
        with pytest.raises(TimeoutError), anyio.fail_after(after):
            await call()
    elif how == "move_on_after":
        with anyio.move_on_after(after):
            await call()
    elif how == "timeout":
        with pytest.raises(TimeoutError):
            async with asyncio.timeout(after):
                await call()
    elif how == "cancel":
        task = asyncio.ensure_future(call())
        await asyncio.sleep(after)
        task.cancel()
        with pytest.raises(asyncio.CancelledError):
            await task
    else:
        assert how == "sibling", how

        async def sibling() -> None:
            await asyncio.sleep(after)
            raise RuntimeError("the sibling failed")

        async def run() -> None:
            await call()

        with pytest.raises(BaseException, match="unhandled errors") as info:  # noqa: PT012
            async with anyio.create_task_group() as group:
                group.start_soon(run)
                group.start_soon(sibling)
        assert "the sibling failed" in repr(info.value.exceptions)  # type: ignore[attr-defined]
