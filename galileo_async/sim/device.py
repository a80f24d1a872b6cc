"""The asyncio side of the simulator: frame clock, connections, command intake, faults."""

from __future__ import annotations

import asyncio
import math
import random
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Protocol

from ..models import StatusLayout
from ..protocol import Command, CommandDecoder, StatusEncoder
from .config import FRAME_RATE, SimConfig
from .robot_model import WIRE_FIELDS, RobotModel, WireValues

__all__ = [
    "DeviceConnection",
    "DeviceStats",
    "FrameEncoder",
    "SimDevice",
    "StatusListener",
    "Ticker",
]

#: Most frames one tick may emit to catch up after the loop stalled; beyond it time slips.
MAX_CATCH_UP_FRAMES = 120
#: A connection whose unsent bytes exceed this drops frames (a full serial buffer).
WRITE_BUFFER_LIMIT = 64 * 1024


class FrameEncoder(StatusEncoder):
    """The protocol's StatusEncoder for the model's wire values (WIRE_FIELDS order)."""

    __slots__ = ()

    def __init__(self, layout: StatusLayout) -> None:
        super().__init__(layout, WIRE_FIELDS)


@dataclass
class DeviceStats:
    """What the simulated device sent and received, over all connections."""

    frames: int = 0
    frames_sent: int = 0
    frames_dropped: int = 0
    garbage_bytes: int = 0
    bit_flips: int = 0
    commands_received: int = 0
    commands_lost: int = 0
    connections: int = 0
    disconnects: int = 0


class Ticker:
    """One loop timer stepping any number of devices at 30 x ``speed`` frames per real second."""

    def __init__(self, speed: float = 1.0, *, max_tick_rate: float = 100.0) -> None:
        self.speed = speed
        self._period = 1.0 / (FRAME_RATE * speed)
        self._frames_per_tick = max(1, math.ceil(FRAME_RATE * speed / max_tick_rate))
        self._devices: dict[SimDevice, None] = {}
        self._loop: asyncio.AbstractEventLoop | None = None
        self._handle: asyncio.TimerHandle | None = None
        self._origin = 0.0
        self._done = 0

    @property
    def running(self) -> bool:
        """True while the timer is scheduled."""
        return self._handle is not None

    def add(self, device: SimDevice) -> None:
        """Start stepping ``device``; starts the timer on the running loop if needed."""
        self._devices[device] = None
        if self._handle is None:
            self._loop = asyncio.get_running_loop()
            self._origin, self._done = self._loop.time(), 0
            self._schedule()

    def remove(self, device: SimDevice) -> None:
        """Stop stepping ``device``; the timer stops with the last one."""
        self._devices.pop(device, None)
        if not self._devices and self._handle is not None:
            self._handle.cancel()
            self._handle = None

    def _schedule(self) -> None:
        assert self._loop is not None
        when = self._origin + (self._done + self._frames_per_tick) * self._period
        self._handle = self._loop.call_at(when, self._tick)

    def _tick(self) -> None:
        assert self._loop is not None
        # The tolerance keeps a timer that runs exactly on time (a virtual clock) from
        # computing one frame less and re-arming for the same instant for ever.
        due = int((self._loop.time() - self._origin) / self._period + 1e-6) - self._done
        if due > MAX_CATCH_UP_FRAMES:  # the loop stalled: let simulated time slip
            self._origin += (due - MAX_CATCH_UP_FRAMES) * self._period
            due = MAX_CATCH_UP_FRAMES
        try:
            if due > 0:
                self._done += due
                for device in list(self._devices):
                    device.advance(due)
        finally:
            if self._devices:
                self._schedule()
            else:
                self._handle = None


class DeviceConnection(asyncio.Protocol):
    """One host connection to the device: its own command parser, fault dice and clock."""

    def __init__(self, device: SimDevice, *, disconnectable: bool = True) -> None:
        self.device = device
        #: Whether Faults.disconnect_after applies (not to a pty: closing it removes the path).
        self.disconnectable = disconnectable
        self.decoder = CommandDecoder()
        self.transport: asyncio.WriteTransport | None = None
        self.rng = random.Random()
        self.opened_at = 0.0
        self.paused = False

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        """Register with the device; frames start with the next tick."""
        assert isinstance(transport, asyncio.WriteTransport)
        self.transport = transport
        transport.set_write_buffer_limits(high=WRITE_BUFFER_LIMIT)
        self.device.attach(self)

    def data_received(self, data: bytes) -> None:
        """Command bytes from the host."""
        self.device.receive(self, data)

    def connection_lost(self, exc: Exception | None) -> None:
        """Unregister from the device."""
        self.device.detach(self)

    def pause_writing(self) -> None:
        """The host stopped reading: drop frames until it catches up."""
        self.paused = True

    def resume_writing(self) -> None:
        """The host reads again."""
        self.paused = False

    def close(self) -> None:
        """Close the transport (the host sees the connection drop)."""
        if self.transport is not None and not self.transport.is_closing():
            self.transport.close()


class StatusListener(Protocol):
    """Takes the wire values (WIRE_FIELDS order) of every frame the robot makes (UDP faces)."""

    def send_statuses(self, frames: list[WireValues]) -> None:
        """The frames of one tick, oldest first."""

    def close(self) -> None:
        """Stop serving (the robot stopped)."""


class SimDevice:
    """The robot model plus its connections: emits frames, takes commands, injects faults."""

    def __init__(self, config: SimConfig, ticker: Ticker, on_shutdown: Callable[[], Any]) -> None:
        self.config = config
        self.model = RobotModel(config)
        self.stats = DeviceStats()
        self.encoder = FrameEncoder(config.layout)
        self.connections: dict[DeviceConnection, None] = {}
        #: Faces that encode frames themselves (the UDP port): handed each frame's values.
        self.listeners: dict[StatusListener, None] = {}
        #: Called with every command the robot takes, in order (testing's command log).
        self.command_listeners: list[Callable[[Command], Any]] = []
        #: True: the robot runs on but sends no frame (a serial node gone silent).
        self.muted = False
        self._ticker = ticker
        self._on_shutdown = on_shutdown
        self._concat_loss = config.effective_concat_loss
        self._running = False
        self.closed = False

    def start(self) -> None:
        """Start the frame clock (needs a running loop); idempotent."""
        if not self._running and not self.closed:
            self._running = True
            self._ticker.add(self)

    def stop(self) -> None:
        """Stop the frame clock and close every connection; idempotent."""
        self.closed = True
        if self._running:
            self._running = False
            self._ticker.remove(self)
        for connection in list(self.connections):
            connection.close()
        for listener in list(self.listeners):
            listener.close()
        self.listeners.clear()

    def attach(self, connection: DeviceConnection) -> None:
        """A host connected: seed its fault dice deterministically."""
        self.stats.connections += 1
        connection.rng.seed(self.config.seed * 1_000_003 + self.stats.connections)
        connection.opened_at = self.model.time
        self.connections[connection] = None
        if self.closed:
            connection.close()
        else:
            self.start()

    def detach(self, connection: DeviceConnection) -> None:
        """A host went away."""
        self.connections.pop(connection, None)

    def receive(self, connection: DeviceConnection, data: bytes) -> None:
        """Parse command bytes with the firmware's rules and hand them to the model."""
        if self.closed:
            return
        commands = connection.decoder.feed(data)
        self.stats.commands_received += len(commands)
        if self._concat_loss and len(commands) > 2:
            # The serial node's queue of one keeps only the first and the last command of
            # one write (docs/protocol.md §2, "Firmware (measured…)").
            self.stats.commands_lost += len(commands) - 2
            commands = [commands[0], commands[-1]]
        self.execute(commands)

    def execute(self, commands: list[Command]) -> None:
        """Hand parsed commands to the model, in order; the host-shutdown command stops all."""
        for command in commands:
            for listener in self.command_listeners:
                listener(command)
            self.model.submit(command)
        if self.model.shutdown:
            self._shut_down()

    def advance(self, frames: int) -> None:
        """Step the model ``frames`` frames and send them to every connection and listener."""
        model = self.model
        if self.muted or (not self.connections and not self.listeners):
            for _ in range(frames):
                model.tick()
            self.stats.frames += frames
            if model.shutdown:  # a queued shutdown ran when busy ended
                self._shut_down()
            return
        start = model.time
        listeners = self.listeners
        count, out, values = self._tick(frames, bool(self.connections), bool(listeners))
        self.stats.frames += count
        if model.shutdown:
            self._shut_down()
            return
        for listener in list(listeners):
            listener.send_statuses(values)
        if out:
            self._send_frames(out, start)

    def _tick(
        self, frames: int, encode: bool, keep: bool
    ) -> tuple[int, list[bytes], list[WireValues]]:
        """Step up to ``frames`` frames (until a shutdown): their count, frames and values."""
        model = self.model
        encoder = self.encoder.encode
        out: list[bytes] = []
        values: list[WireValues] = []
        count = 0
        for _ in range(frames):
            model.tick()
            if model.shutdown:
                break
            count += 1
            wire = model.wire_values()
            if encode:
                out.append(encoder(wire, model.time_stamp))
            if keep:
                values.append(wire)
        return count, out, values

    def _send_frames(self, out: list[bytes], start: float) -> None:
        frames = len(out)
        faults = self.config.faults
        if not faults.any_stream_fault and faults.disconnect_after is None:
            data = b"".join(out) if frames > 1 else out[0]
            for connection in self.connections:  # _send never closes: no copy needed
                self._send(connection, data)
            self.stats.frames_sent += frames * len(self.connections)
            return
        for connection in list(self.connections):
            mine, expired = out, False
            if faults.disconnect_after is not None and connection.disconnectable:
                # Cut the batch at the deadline so the host gets exactly its frames.
                deadline = connection.opened_at + faults.disconnect_after
                allowed = math.floor((deadline - start) * FRAME_RATE + 1e-6)
                expired = allowed <= frames
                mine = out[: max(0, allowed)]
            if faults.any_stream_fault:
                self._send(connection, self._with_faults(connection, mine))
            else:
                self._send(connection, b"".join(mine))
                self.stats.frames_sent += len(mine)
            if expired:
                self.stats.disconnects += 1
                connection.close()

    def _send(self, connection: DeviceConnection, data: bytes) -> None:
        transport = connection.transport
        if transport is None or transport.is_closing() or connection.paused or not data:
            return
        transport.write(data)

    def _with_faults(self, connection: DeviceConnection, frames: list[bytes]) -> bytes:
        faults, rng, stats = self.config.faults, connection.rng, self.stats
        chunks = []
        for frame in frames:
            if faults.drop and rng.random() < faults.drop:
                stats.frames_dropped += 1
                continue
            if faults.garbage and rng.random() < faults.garbage:
                # Garbage never holds 0xCD, so it cannot fake a header: the decoder's
                # discard count then equals garbage_bytes exactly.
                noise = bytes(b if b != 0xCD else 0x00 for b in rng.randbytes(rng.randint(1, 16)))
                stats.garbage_bytes += len(noise)
                chunks.append(noise)
            if faults.bitflip and rng.random() < faults.bitflip:
                flipped = bytearray(frame)
                flipped[rng.randrange(len(flipped))] ^= 1 << rng.randrange(8)
                stats.bit_flips += 1
                frame = bytes(flipped)
            stats.frames_sent += 1
            chunks.append(frame)
        return b"".join(chunks)

    def _shut_down(self) -> None:
        # 0xAA 0x44 powers the navigation computer off: no more frames, no connections.
        self.stop()
        self._on_shutdown()
