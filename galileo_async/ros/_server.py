"""A bounded close for the small asyncio servers of the ROS link."""

from __future__ import annotations

import asyncio
import contextlib

__all__ = ["SERVER_CLOSE_TIMEOUT", "close_server"]

#: Longest a local server may take to finish closing.
SERVER_CLOSE_TIMEOUT = 1.0


async def close_server(server: asyncio.Server | None) -> None:
    """Close ``server`` (if any) and wait, at most SERVER_CLOSE_TIMEOUT, until it has."""
    if server is None:
        return
    server.close()
    with contextlib.suppress(asyncio.TimeoutError):
        await asyncio.wait_for(server.wait_closed(), SERVER_CLOSE_TIMEOUT)
