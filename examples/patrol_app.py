"""A patrol application: visit a route of targets, lap after lap, and survive what robots do.

python examples/patrol_app.py [URL]    # default: $GALILEO_PORT, else sim://

Its tests, on a simulated robot and a virtual clock: examples/test_patrol_app.py
(docs/testing.md walks through both).
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import sys
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import galileo_async as galileo
from galileo_async import LinkState


@dataclass
class PatrolReport:
    """What a patrol did: targets reached and skipped (in order), retries, outages, its end."""

    visited: list[int] = field(default_factory=list)
    skipped: list[int] = field(default_factory=list)
    retries: int = 0
    link_outages: int = 0
    laps: int = 0
    #: Why the patrol ended early ("stalled at 2", "link lost"); None: every lap was done.
    stopped: str | None = None


class _EndPatrol(Exception):
    """The patrol cannot go on (the report says why)."""


async def patrol(
    robot: galileo.Robot,
    route: Sequence[int],
    *,
    laps: int | None = 1,
    retry: int = 1,
    goal_timeout: float = 300.0,
    link_timeout: float = 60.0,
    on_event: Callable[[str], object] = print,
) -> PatrolReport:
    """Visit ``route`` in order, ``laps`` times (None: until cancelled); return the report.

    A goal the robot refuses (GoalRejected, AcceptTimeout) is skipped; one the planner
    gave up (GoalAborted) is tried ``retry`` more times, then skipped; a lost link is
    waited for (``link_timeout`` s) and the goal tried again; a busy robot is waited out
    by the driver itself. A stalled robot (GoalStalled) or a link that stays down ends the
    patrol, the robot told to stop. Cancelling the task needs no code here: the goto under
    way sends cancel (``i 2``) before the cancellation goes on, and the robot stops.
    """
    report = PatrolReport()

    async def visit(target: int) -> None:
        """One target: reached, skipped, or _EndPatrol."""
        aborts = 0
        while True:
            try:
                result = await robot.goto(target, timeout=goal_timeout)
            except (galileo.GoalRejected, galileo.AcceptTimeout):
                # Real firmware shows a refusal as target_status -1, which a robot that has
                # had no goal yet shows already: then the goal is just never accepted.
                on_event(f"target {target} not accepted: skipped")
                report.skipped.append(target)
                return
            except galileo.GoalAborted as exc:
                if aborts == retry:
                    on_event(f"target {target} aborted again: skipped")
                    report.skipped.append(target)
                    return
                aborts += 1
                report.retries += 1
                on_event(f"target {target} aborted {exc.distance or 0:.2f} m short: retrying")
            except galileo.GoalStalled as exc:  # the driver has sent cancel (i 2) already
                on_event(f"target {target}: no progress for {exc.stalled_for:.0f} s: stopping")
                report.stopped = f"stalled at {target}"
                raise _EndPatrol from exc
            except galileo.GalileoConnectionError:  # ConnectionLost, LinkStale
                report.link_outages += 1
                on_event(f"target {target}: link down, waiting for it")
                try:
                    await robot.wait_link(LinkState.UP, timeout=link_timeout)
                except galileo.GalileoTimeout as exc:
                    report.stopped = "link lost"
                    raise _EndPatrol from exc
                on_event("link back: trying again")
            else:
                on_event(f"reached {target} in {result.elapsed:.1f} s")
                report.visited.append(target)
                return

    try:
        while laps is None or report.laps < laps:
            for target in route:
                await visit(target)
            report.laps += 1
    except _EndPatrol:
        # A lost link cannot carry the stop, and a silent one cannot show it done.
        with contextlib.suppress(galileo.GalileoConnectionError, galileo.StopUnconfirmed):
            await robot.stop()
    return report


async def main() -> int:
    # Read here, not at import: the tests import this module under pytest's arguments.
    url = sys.argv[1] if len(sys.argv) > 1 else os.environ.get("GALILEO_PORT", "sim://")
    async with galileo.connect(url) as robot:
        await robot.start_navigation(timeout=60)
        report = await patrol(robot, [1, 2, 3], laps=2)
    print(f"visited {report.visited}, skipped {report.skipped}, {report.laps} laps")
    return 0 if report.stopped is None else 1


if __name__ == "__main__":
    sys.exit(asyncio.run(main()))
