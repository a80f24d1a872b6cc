"""Robot.stop(): what it sends, what confirms it, and the StopReport it returns."""

from __future__ import annotations

import asyncio
import dataclasses
import logging
from collections.abc import Collection
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from ..errors import (
    ConnectionLost,
    GalileoConnectionError,
    GalileoTimeout,
    LinkStale,
    StopUnconfirmed,
)
from ..models import ChargeStatus, GalileoStatus
from ..protocol import ApiCall, Cancel, Command, Stop, StopCharging, StopPatrol

if TYPE_CHECKING:
    from .operations import Operations

__all__ = [
    "DEFAULT_STOP_TIMEOUT",
    "STILL_ANGULAR",
    "STILL_LINEAR",
    "StopReport",
    "in_motion",
    "standing_still",
    "stop_motion",
]

_log = logging.getLogger(__name__)

#: Seconds stop() waits for the status to show the robot stopped (goal, patrol, speed).
DEFAULT_STOP_TIMEOUT = 5.0


@dataclass(frozen=True, slots=True)
class StopReport:
    """What stop() stopped; every part is confirmed by ``status`` (None: no status seen).

    ``goal``: the id of the goal that was working or paused and was cancelled (None: none).
    ``patrol``: a patrol was running and was stopped. ``docking``: the robot was finding or
    docking onto its charger (``j 0``) and that was stopped. ``drive``: a drive() or turn_to()
    session of this Robot was ended. ``task``: the id of the HTTP nav task stopped
    (http:// only). ``chains``: the ids of the task chains (http:// only) that were WORKING
    or PAUSED and were stopped. ``moving``: the status showed a speed when stop() was called.
    """

    goal: int | None = None
    patrol: bool = False
    docking: bool = False
    drive: bool = False
    task: str | None = None
    chains: tuple[str, ...] = ()
    moving: bool = False
    status: GalileoStatus | None = None

    @property
    def stopped(self) -> tuple[str, ...]:
        """What was stopped, in words ("goal 3 cancelled", "patrol stopped", …); may be empty."""
        parts: list[str] = []
        if self.goal is not None:
            parts.append(f"goal {self.goal} cancelled")
        if self.task is not None:
            parts.append(f"task {self.task} stopped")
        parts += [f"task chain {chain} stopped" for chain in self.chains]
        if self.patrol:
            parts.append("patrol stopped")
        if self.docking:
            parts.append("docking stopped")
        if self.drive:
            parts.append("drive ended")
        if self.moving:
            parts.append("speed zeroed")
        return tuple(parts)

    def __str__(self) -> str:
        return ", ".join(self.stopped) or "nothing was moving"


#: Below these speeds (m/s, rad/s) the status shows the robot standing still.
STILL_LINEAR = 0.01
STILL_ANGULAR = 0.02


def standing_still(status: GalileoStatus) -> bool | None:
    """True when the status shows no speed (measured, else commanded); None: no speed field."""
    linear = status.current_speed_x
    angular = status.current_speed_theta
    if linear is None and angular is None:
        linear, angular = status.control_speed_x, status.control_speed_theta
    if linear is None and angular is None:
        return None  # the layout has no speed (UDP): it cannot show one
    return abs(linear or 0.0) <= STILL_LINEAR and abs(angular or 0.0) <= STILL_ANGULAR


#: The charge states in which the robot drives to or onto its dock.
_DOCKING = (ChargeStatus.FINDING_DOCK, ChargeStatus.DOCKING)


def in_motion(status: GalileoStatus) -> tuple[str, ...]:
    """The parts of ``status`` showing motion: "goal", "patrol", "docking", "speed"; ()."""
    parts: list[str] = []
    if status.goal_active:
        parts.append("goal")
    if status.patrolling:
        parts.append("patrol")
    if status.charge_status in _DOCKING:
        parts.append("docking")
    if standing_still(status) is False:
        parts.append("speed")
    return tuple(parts)


async def stop_motion(
    ops: Operations,
    stop: Stop,
    timeout: float | None,
    *,
    goal: int | None,
    drive: bool,
    tasks: list[str | None],
    chains: Collection[str] | None = None,
) -> StopReport:
    """Write stop()'s commands and wait for a status showing the robot stopped; see Robot.stop.

    The user stop (supersession, drive sessions, halted calls) is done by the caller.
    ``chains`` (http:// only; None elsewhere): the task chains this Robot started, stopped
    first; after the other commands every task the robot shows WORKING or PAUSED is too.
    """
    before = ops.store.status
    # (command, needed): a command not needed is sent only in case the status is behind,
    # and its failure (e.g. an HTTP call refused: no task) does not fail stop().
    commands: list[tuple[Command, bool]] = []
    if before is None or before.loop_status != 0:  # patrolling, or it cannot be seen
        # A patrol would start its next leg as soon as the goal ends: stopped first.
        commands.append((StopPatrol(), before is not None and before.patrolling))
    goal_shown = before is None or before.goal_active or goal is not None
    if before is not None and before.charge_status in _DOCKING:
        commands.append((StopCharging(), True))  # the robot drives onto the dock
    commands += [(Cancel(), goal_shown), (stop, True)]
    # Its own task, held by the Supersession: a caller cancelled meanwhile (a timeout, Ctrl-C, a
    # failing sibling) cannot keep the rest of the stop from being written.
    nav_task = next((task for task in tasks if task is not None), None)
    sending = ops.supersession.hold(_send(ops, commands, chains, nav_task))
    failed, stopped = await asyncio.shield(sending)
    if failed is not None:
        raise failed
    report = StopReport(
        goal=before.target_num_id if before is not None and before.goal_active else goal,
        patrol=before is not None and before.patrolling,
        docking=before is not None and before.charge_status in _DOCKING,
        drive=drive,
        task=nav_task,
        chains=stopped,
        moving=before is not None and standing_still(before) is False,
    )
    try:
        status = await ops.store.wait_until(lambda s: not in_motion(s), timeout)
    except (GalileoTimeout, LinkStale) as exc:
        raise _unconfirmed(ops, timeout, exc) from None
    return dataclasses.replace(report, status=status)


async def _send(
    ops: Operations,
    commands: list[tuple[Command, bool]],
    chains: Collection[str] | None,
    nav_task: str | None,
) -> tuple[GalileoConnectionError | None, tuple[str, ...]]:
    """Send each command in order; the first failure of a needed one (ConnectionLost raises).

    With ``chains`` (http://), the known chains are stopped before, the ones GET /task shows
    running after: (the failure, the chains stopped).
    """
    stopped: list[str] = []
    if chains is not None:
        for chain in sorted(chains):
            if await _stop_chain(ops, chain):
                stopped.append(chain)
    failed = await _send_commands(ops, commands)
    if chains is not None:
        for chain in await _running_chains(ops):
            if chain not in stopped and chain != nav_task and await _stop_chain(ops, chain):
                stopped.append(chain)
    return failed, tuple(stopped)


async def _stop_chain(ops: Operations, chain: str) -> bool:
    """GET /task/stop of ``chain``: True if it was running (WORKING or PAUSED) before."""
    try:
        before = await ops.ask(ApiCall("GET", "/task", {"id": chain}), what="stop")
        if not _running(before):
            return False
        await ops.ask(ApiCall("GET", "/task/stop", {"id": chain}), what="stop")
    except ConnectionLost:
        raise
    except GalileoConnectionError as exc:  # no such task (deleted): nothing to stop
        _log.warning("stop: task chain %s was not stopped: %s", chain, exc)
        return False
    return True


async def _running_chains(ops: Operations) -> list[str]:
    """The ids of the tasks GET /task shows WORKING or PAUSED (none if it fails)."""
    try:
        tasks = await ops.ask(ApiCall("GET", "/task"), what="stop")
    except ConnectionLost:
        raise
    except GalileoConnectionError as exc:
        _log.warning("stop: GET /task failed, running task chains not looked for: %s", exc)
        return []
    if not isinstance(tasks, list):
        return []
    return [str(task["id"]) for task in tasks if _running(task) and "id" in task]


def _running(task: Any) -> bool:
    return isinstance(task, dict) and task.get("state") in ("WORKING", "PAUSED")


async def _send_commands(
    ops: Operations, commands: list[tuple[Command, bool]]
) -> GalileoConnectionError | None:
    failed: GalileoConnectionError | None = None
    for command, needed in commands:
        try:
            await ops.send(command, what="stop", even_stale=True)
        except ConnectionLost:
            raise
        except GalileoConnectionError as exc:  # the rest are still sent
            _log.warning("stop: %s was not carried: %s", command, exc)
            if needed and failed is None:
                failed = exc
    return failed


def _unconfirmed(ops: Operations, timeout: float | None, exc: Exception) -> StopUnconfirmed:
    latest = ops.store.status
    parts = ("goal", "patrol", "speed") if latest is None else in_motion(latest)
    if isinstance(exc, LinkStale):
        why = f"the link is stale ({exc}), so the status cannot show it"
        parts = parts or ("goal", "patrol", "speed")
    elif latest is None:
        came = "only placeholder frames came" if ops.store.awaiting_robot else "no status came"
        why = f"{came} within {timeout} s, so nothing could be confirmed"
    else:
        why = f"the status still showed {', '.join(parts)} after {timeout} s"
    return StopUnconfirmed(
        f"stop: sent, but {why}", latest, unconfirmed=parts or ("goal", "patrol", "speed")
    )
