"""A scripted fake robot on the device side, over a real TCP loopback byte stream.

It sends status frames (``protocol.encode_status``) every ``period`` seconds and parses
what it receives with ``protocol.CommandDecoder``, the firmware's own parser rules. Each
command type runs a script (an async function of the fake and the command); the defaults
model the real firmware (docs/protocol.md §2), tests replace them per command type. Every
default reacts only after two more frames, so the driver always sees stale frames first.
"""

from __future__ import annotations

import asyncio
import contextlib
from collections.abc import AsyncIterator, Callable, Coroutine
from typing import Any

import anyio

import galileo_async as galileo
from galileo_async.models import ChargeStatus, GalileoStatus, StatusLayout, TargetStatus
from galileo_async.protocol import (
    AddTarget,
    Cancel,
    Command,
    CommandDecoder,
    Goto,
    Pause,
    ResetTargets,
    Resume,
    SetPatrolDwell,
    StartCharging,
    StartMapping,
    StartNavigation,
    StartPatrol,
    Stop,
    StopCharging,
    StopMapping,
    StopNavigation,
    StopPatrol,
    encode_status,
)

Script = Callable[["ScriptedRobot", Any], Coroutine[Any, Any, None]]

#: A robot with navigation open, the visual system tracking and no goal.
READY: dict[str, Any] = {
    "nav_status": 1,
    "visual_status": 1,
    "map_status": 0,
    "gc_status": 0,
    "gba_status": 0,
    "charge_status": 0,
    "loop_status": 0,
    "power": 24.0,
    "target_num_id": -1,
    "target_status": 0,
    "target_distance": -1.0,
    "angle_goal_status": 1,
    "current_pose_x": 0.0,
    "current_pose_y": 0.0,
    "current_angle": 0.0,
    "busy_status": 0,
}
#: What the firmware sends before its first real status (docs/protocol.md §1).
DEFAULTS: dict[str, Any] = READY | {
    "nav_status": 0,
    "visual_status": 0,
    "power": 0.0,
    "target_status": -1,
    "angle_goal_status": -1,
}
#: Seconds between two frames: far faster than 30 Hz, so tests run fast.
FAST_PERIOD = 0.005
#: Frames the default scripts let pass before reacting (the driver sees stale frames).
REACTION_FRAMES = 2


class _DeviceProtocol(asyncio.Protocol):
    def __init__(self, fake: ScriptedRobot) -> None:
        self._fake = fake
        self._decoder = CommandDecoder()

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        self._fake._attach(transport)  # type: ignore[arg-type]

    def data_received(self, data: bytes) -> None:
        for command in self._decoder.feed(data):
            self._fake._on_command(command)

    def connection_lost(self, exc: Exception | None) -> None:
        self._fake._detach()


class ScriptedRobot:
    """Fake device: a status it keeps sending, the commands it got, scripts per command."""

    def __init__(
        self,
        *,
        layout: StatusLayout | str = StatusLayout.V2,
        period: float = FAST_PERIOD,
        map_targets: int = 10,
        start_distance: float = 1.0,
        step: float = 0.1,
        **fields: Any,
    ) -> None:
        self.layout = StatusLayout(layout)
        self.period = period
        self.map_targets = map_targets
        self.dynamic_targets = 0
        #: Where the dynamic targets are, by id - map_targets: arriving there moves the pose.
        self.dynamic_points: list[tuple[float, float]] = []
        self.start_distance = start_distance
        self.step = step
        self.status = GalileoStatus(**(READY | fields))
        self.received: list[Command] = []
        self.frames_sent = 0
        self.sending = True
        self.scripts: dict[type[Command], Script] = dict(FIRMWARE_SCRIPTS)
        self._transport: asyncio.Transport | None = None
        self._server: asyncio.Server | None = None
        self._sender: asyncio.Task[None] | None = None
        self._motion: asyncio.Task[None] | None = None
        self._tasks: set[asyncio.Task[None]] = set()
        self._tick = asyncio.Event()
        self._got_command = asyncio.Event()
        self.port = 0

    @property
    def url(self) -> str:
        """The ``socket://`` URL the driver connects to."""
        return f"socket://127.0.0.1:{self.port}"

    async def start(self) -> ScriptedRobot:
        """Listen on 127.0.0.1 (a free port) and start sending frames."""
        loop = asyncio.get_running_loop()
        self._server = await loop.create_server(lambda: _DeviceProtocol(self), "127.0.0.1", 0)
        self.port = self._server.sockets[0].getsockname()[1]
        self._sender = asyncio.create_task(self._send_frames())
        return self

    async def close(self) -> None:
        """Stop everything the fake runs and close its sockets."""
        tasks = [t for t in (self._sender, self._motion, *self._tasks) if t is not None]
        for task in tasks:
            task.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)
        self.drop()
        if self._server is not None:
            self._server.close()
            await self._server.wait_closed()

    # --- scripting ------------------------------------------------------------------

    def set(self, **fields: Any) -> None:
        """Change the status the fake sends from the next frame on."""
        self.status = self.status.model_validate(self.status.model_dump() | fields)

    async def frames(self, count: int = 1) -> None:
        """Wait until ``count`` more frames were sent."""
        for _ in range(count):
            await self._tick.wait()

    def drop(self) -> None:
        """Close the connection, like an unplugged cable."""
        if self._transport is not None:
            self._transport.close()
            self._transport = None

    def start_motion(self, coroutine: Coroutine[Any, Any, None]) -> None:
        """Run ``coroutine`` as the one goal motion, replacing any previous one."""
        self.stop_motion()
        self._motion = asyncio.create_task(coroutine)

    def stop_motion(self) -> None:
        """Stop the goal motion, if any."""
        if self._motion is not None:
            self._motion.cancel()
            self._tasks.add(self._motion)  # reaped by close()
            self._motion = None

    async def command(self, kind: type[Command], within: float = 2.0) -> Command:
        """The first received command of type ``kind``, waiting up to ``within`` s for it."""
        with anyio.fail_after(within):
            while True:
                for command in self.received:
                    if isinstance(command, kind):
                        return command
                self._got_command.clear()
                await self._got_command.wait()

    def of_type(self, kind: type[Command]) -> list[Command]:
        """Every received command of type ``kind``."""
        return [c for c in self.received if isinstance(c, kind)]

    # --- internals ------------------------------------------------------------------

    def _attach(self, transport: asyncio.Transport) -> None:
        self._transport = transport

    def _detach(self) -> None:
        self._transport = None

    def _on_command(self, command: Command) -> None:
        self.received.append(command)
        self._got_command.set()
        script = self.scripts.get(type(command))
        if script is not None:
            task = asyncio.create_task(script(self, command))
            self._tasks.add(task)
            task.add_done_callback(self._tasks.discard)

    async def _send_frames(self) -> None:
        counter = 0
        while True:
            await asyncio.sleep(self.period)
            if not self.sending or self._transport is None:
                continue
            counter += 1
            status = self.status.model_copy(update={"time_stamp": counter})
            self._transport.write(encode_status(status, self.layout))
            self.frames_sent += 1
            tick, self._tick = self._tick, asyncio.Event()
            tick.set()


# --- default scripts: the real firmware's behaviour (docs/protocol.md §2) -----------------


async def _start_navigation(fake: ScriptedRobot, command: Any) -> None:
    await fake.frames(REACTION_FRAMES)
    fake.set(nav_status=1, visual_status=0)
    await fake.frames(3)
    fake.set(visual_status=1)


async def _stop_navigation(fake: ScriptedRobot, command: Any) -> None:
    await fake.frames(REACTION_FRAMES)
    fake.stop_motion()
    fake.set(nav_status=0, visual_status=-1, loop_status=0, target_num_id=-1, target_status=0)


async def drive(fake: ScriptedRobot, target_id: int) -> None:
    """Motion toward ``target_id``: working, distance shrinking each frame, then free at 0."""
    fake.set(
        target_num_id=target_id,
        target_status=TargetStatus.WORKING,
        target_distance=fake.start_distance,
        angle_goal_status=0,
    )
    distance = fake.start_distance
    while True:
        await fake.frames(1)
        if fake.status.target_status != TargetStatus.WORKING:
            continue  # paused: not an end
        distance = max(0.0, distance - fake.step)
        if distance <= 0.0:
            fake.set(target_status=TargetStatus.FREE, target_distance=0.0, angle_goal_status=1)
            dynamic = target_id - fake.map_targets
            if 0 <= dynamic < len(fake.dynamic_points):
                x, y = fake.dynamic_points[dynamic]
                fake.set(current_pose_x=x, current_pose_y=y)
            return
        fake.set(target_distance=distance)


async def _goto(fake: ScriptedRobot, command: Goto) -> None:
    await fake.frames(REACTION_FRAMES)
    if not fake.status.visual_initialised:
        return  # ignored (docs/protocol.md §2.b)
    if command.target_id >= fake.map_targets + fake.dynamic_targets:
        # Firmware: error as -1, target_num_id left as it was (docs/protocol.md §2.b).
        fake.stop_motion()
        fake.set(target_status=TargetStatus.INVALID)
        return
    fake.start_motion(drive(fake, command.target_id))


async def _cancel(fake: ScriptedRobot, command: Any) -> None:
    await fake.frames(REACTION_FRAMES)
    if fake.status.goal_active:
        fake.stop_motion()
        fake.set(target_num_id=-1, target_status=TargetStatus.FREE, angle_goal_status=1)


async def _pause(fake: ScriptedRobot, command: Any) -> None:
    await fake.frames(REACTION_FRAMES)
    if fake.status.target_status == TargetStatus.WORKING:
        fake.set(target_status=TargetStatus.PAUSED)


async def _resume(fake: ScriptedRobot, command: Any) -> None:
    await fake.frames(REACTION_FRAMES)
    if fake.status.target_status == TargetStatus.PAUSED:
        fake.set(target_status=TargetStatus.WORKING)


def _setter(**fields: Any) -> Script:
    async def script(fake: ScriptedRobot, command: Any) -> None:
        await fake.frames(REACTION_FRAMES)
        fake.set(**fields)

    return script


async def _reset_targets(fake: ScriptedRobot, command: Any) -> None:
    fake.dynamic_targets = 0
    fake.dynamic_points.clear()


async def _add_target(fake: ScriptedRobot, command: AddTarget) -> None:
    fake.dynamic_targets += 1
    fake.dynamic_points.append((command.x, command.y))


FIRMWARE_SCRIPTS: dict[type[Command], Script] = {
    StartNavigation: _start_navigation,
    StopNavigation: _stop_navigation,
    Goto: _goto,
    Cancel: _cancel,
    Pause: _pause,
    Resume: _resume,
    StartPatrol: _setter(loop_status=1),
    SetPatrolDwell: _setter(loop_status=1),
    StopPatrol: _setter(loop_status=0),
    StartMapping: _setter(map_status=1, nav_status=0, visual_status=-1),
    StopMapping: _setter(map_status=0),
    StartCharging: _setter(charge_status=ChargeStatus.FINDING_DOCK),
    StopCharging: _setter(charge_status=ChargeStatus.FREE),
    ResetTargets: _reset_targets,
    AddTarget: _add_target,
}  # RotateTo is absent: no published firmware handles 'a' (docs/protocol.md §2.g).


async def ignore(fake: ScriptedRobot, command: Any) -> None:
    """A script that does nothing: the command is lost or ignored."""


#: Connect options that keep tests fast and bounded.
FAST_OPTIONS: dict[str, Any] = {
    "reconnect": False,
    "stale_timeout": 0.5,
    "accept_timeout": 0.5,
    "first_status_timeout": 2.0,
}


@contextlib.asynccontextmanager
async def connected(
    fake: ScriptedRobot | None = None, **options: Any
) -> AsyncIterator[tuple[galileo.Robot, ScriptedRobot]]:
    """A started fake (ready by default) and a Robot connected to it over TCP loopback."""
    fake = fake or ScriptedRobot()
    await fake.start()
    try:
        async with galileo.connect(fake.url, **(FAST_OPTIONS | options)) as robot:
            yield robot, fake
    finally:
        await fake.close()


#: A goal that never ends by itself: far away and no progress.
ENDLESS: dict[str, Any] = {"start_distance": 100.0, "step": 0.0}


def is_working_on(target_id: int) -> Callable[[GalileoStatus], bool]:
    """A predicate: the robot is working on goal ``target_id``."""
    return lambda s: s.target_num_id == target_id and s.target_status == TargetStatus.WORKING


async def working(robot: galileo.Robot, target_id: int) -> None:
    """Wait until the robot shows goal ``target_id`` working."""
    await robot.wait_until(is_working_on(target_id), timeout=2)


async def flush(robot: galileo.Robot, fake: ScriptedRobot) -> None:
    """Send Stop as a marker: once it arrives, everything sent before it has arrived too."""
    before = len(fake.of_type(Stop))
    await robot.zero_speed()
    with anyio.fail_after(2):
        while len(fake.of_type(Stop)) == before:
            await fake.frames(1)


async def nothing_was_sent_before_marker(robot: galileo.Robot, fake: ScriptedRobot) -> None:
    """Nothing but the marker reached the fake."""
    await flush(robot, fake)
    assert fake.received == [Stop(100)]
