"""The event loop the driver runs on: asyncio's, or a clear error saying so."""

from __future__ import annotations

import asyncio
import sys

from .errors import AsyncioRequired

__all__ = ["running_loop"]


def running_loop(what: str) -> asyncio.AbstractEventLoop:
    """The running asyncio loop; AsyncioRequired (naming ``what``) when none runs here."""
    try:
        return asyncio.get_running_loop()
    except RuntimeError:
        pass
    raise AsyncioRequired(
        f"{what}: the driver runs on asyncio, but {_running_library()}; run it under "
        "asyncio (asyncio.run, or anyio.run(..., backend='asyncio'))"
    ) from None


def _running_library() -> str:
    """What runs instead of asyncio, as far as can be told without importing anything."""
    trio = sys.modules.get("trio")
    if trio is not None:
        try:
            trio.lowlevel.current_task()
        except RuntimeError:
            pass
        else:
            return "this code runs under trio"
    return "no asyncio event loop is running in this thread"
