"""The timing loops latency.py, latency_udp.py and latency_http.py share, one per path.

Each link's module supplies only its device end and its bare host; the loops time the
same steps for the driver and its baseline.
"""

from __future__ import annotations

import asyncio
import time
from collections.abc import Awaitable, Callable

from galileo_async import GalileoStatus, Robot

__all__ = ["COMMAND_GAP", "Arrivals", "bare_status", "driver_status", "timed_commands"]

COMMAND_GAP = 0.012  # above the driver's 10 ms pacing, so pacing never delays a sample
TIMEOUT = 5.0


class Arrivals:
    """When each message reached the device (perf_counter), and a wait for the next one."""

    def __init__(self) -> None:
        self.times: list[float] = []
        self._arrived = asyncio.Event()

    def __call__(self, when: float) -> None:
        self.times.append(when)
        self._arrived.set()

    async def after(self, before: int) -> float:
        """The arrival time of message number ``before`` (0-based), once it is there."""
        while len(self.times) == before:
            self._arrived.clear()
            await self._arrived.wait()
        return self.times[before]


async def driver_status(
    robot: Robot,
    send: Callable[[int], Awaitable[None]],
    mark: Callable[[GalileoStatus], int | None],
    samples: int,
) -> tuple[list[float], list[float]]:
    """Device sends status ``k`` → ``wait_until(mark(s) == k)`` returns; and the status age.

    The age runs from the device's send to ``robot.link.last_frame_at``, set when the
    status reached the store (both on time.monotonic). Seconds.
    """
    latencies: list[float] = []
    ages: list[float] = []
    perf, monotonic = time.perf_counter, time.monotonic
    for k in range(2, samples + 2):

        def wanted(status: GalileoStatus, k: int = k) -> bool:
            return mark(status) == k

        waiter = asyncio.create_task(robot.wait_until(wanted, timeout=TIMEOUT))
        await asyncio.sleep(0)  # registered before the status is sent
        sent, t0 = monotonic(), perf()
        await send(k)
        await waiter
        latencies.append(perf() - t0)
        arrived = robot.link.last_frame_at
        assert arrived is not None
        ages.append(arrived - sent)
    return latencies, ages


async def bare_status(
    send: Callable[[int], Awaitable[None]], wait: Callable[[int], Awaitable[None]], samples: int
) -> list[float]:
    """Device sends status ``k`` → the bare host's ``wait(k)`` returns, in seconds."""
    latencies: list[float] = []
    perf = time.perf_counter
    for k in range(2, samples + 2):
        waiter = asyncio.create_task(asyncio.wait_for(wait(k), TIMEOUT))
        await asyncio.sleep(0)
        t0 = perf()
        await send(k)
        await waiter
        latencies.append(perf() - t0)
    return latencies


async def timed_commands(
    call: Callable[[], Awaitable[object]], arrivals: Arrivals, samples: int
) -> list[float]:
    """``await call()`` started → its message at the device, ``COMMAND_GAP`` apart, seconds."""
    latencies: list[float] = []
    for _ in range(samples):
        await asyncio.sleep(COMMAND_GAP)
        before = len(arrivals.times)
        t0 = time.perf_counter()
        await call()
        latencies.append(await asyncio.wait_for(arrivals.after(before), TIMEOUT) - t0)
    return latencies
