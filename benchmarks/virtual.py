"""The virtual clock of galileo_async.testing: a 60 s goal, in real time.

A simulated_robot() drives 48 m straight at 0.8 m/s: 60 simulated seconds, 1800 status
frames, each going through the whole driver (decode, store, goal tracking). Baseline,
in the same run: the clock alone stepping through 1800 empty timers 1/30 s apart, which
is what the loop does between frames.
"""

from __future__ import annotations

import asyncio
import statistics
import time

from galileo_async.testing import VirtualClock, simulated_robot

from .common import Row

__all__ = ["run"]

#: Target 0: 48 m straight ahead of the start pose, 60 s at the default 0.8 m/s.
_TARGETS = ((48.0, 0.0),)
_FRAMES = 1800


async def _goal() -> tuple[float, float]:
    """(real seconds, simulated seconds) of one 60 s goal on the virtual clock."""
    async with simulated_robot(targets=_TARGETS) as (robot, device):
        began, simulated = time.perf_counter(), device.time
        await robot.goto(0, timeout=120)
        return time.perf_counter() - began, device.time - simulated


async def _timers() -> float:
    """Real seconds for the clock alone to run 1800 timers 1/30 s apart."""
    clock = VirtualClock.install()
    try:
        loop = asyncio.get_running_loop()
        done = loop.create_future()
        count = 0

        def tick() -> None:
            nonlocal count
            count += 1
            if count == _FRAMES:
                done.set_result(None)
            else:
                loop.call_later(1 / 30, tick)

        began = time.perf_counter()
        loop.call_later(1 / 30, tick)
        await done
        return time.perf_counter() - began
    finally:
        clock.release()


def run(*, quick: bool = False) -> list[Row]:
    """Median of several goals and of as many bare timer runs, interleaved."""
    rounds = 3 if quick else 9
    goals: list[float] = []
    simulated: list[float] = []
    bare: list[float] = []
    for _ in range(rounds):
        real, sim = asyncio.run(_goal())
        goals.append(real)
        simulated.append(sim)
        bare.append(asyncio.run(_timers()))
    goal_ms = statistics.median(goals) * 1e3
    bare_ms = statistics.median(bare) * 1e3
    sim_s = statistics.median(simulated)
    return [
        Row(
            "virtual", "60 s goal on the virtual clock", round(goal_ms, 1), "ms real",
            baseline=round(bare_ms, 1), baseline_name="1800 empty timers, clock alone",
            target="< 1000 ms", ok=goal_ms < 1000,
            extra={"simulated_s": round(sim_s, 2), "rounds": rounds,
                   "per_frame_us": round(goal_ms * 1e3 / (sim_s * 30), 1)},
        ),
    ]  # fmt: skip
