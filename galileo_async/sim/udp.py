"""The simulator's UDP face: port 20001 as system_monitor serves it (docs/protocol.md §7)."""

from __future__ import annotations

import asyncio
import random
from typing import Any, cast

from ..protocol import DatagramCommandDecoder, RawCommand, RotateTo
from ..protocol.udp import encode_env_frame
from .device import FrameEncoder, SimDevice
from .robot_model import WireValues

__all__ = ["ENV_FRAME_EVERY", "UdpFace"]

#: The environment-sensor frame follows every third status frame, the first the fourth.
ENV_FRAME_EVERY = 3
#: Typical readings the environment frame carries: 22 °C, 45 %RH, no smoke, clean air, quiet.
_ENV_READINGS = (22.0, 45.0, 0.0, 5.0, 8.0, 10.0, 0.0, 40.0)


class UdpFace(asyncio.DatagramProtocol):
    """Status to the last sender only, 30 frames a (simulated) second; commands from anyone.

    Nothing is sent before the first datagram. Several frames in one datagram run in
    order; a frame split over datagrams is completed as the vendor's parser does. An empty
    datagram ends the service (no more status); a ``gi`` shorter than 10 bytes ends its
    command handling (status keeps flowing); ``a`` (rotate) is ignored (docs/protocol.md §7.5-7.6).
    """

    def __init__(self, device: SimDevice) -> None:
        self.device = device
        self.encoder = FrameEncoder(device.config.udp_layout)
        self.parser = DatagramCommandDecoder()
        self.transport: asyncio.DatagramTransport | None = None
        #: Where every status frame goes: the source of the last datagram received.
        self.remote: Any = None
        #: Datagrams received, and status frames sent.
        self.datagrams = 0
        self.frames_sent = 0
        #: True after a datagram that stops the vendor's command thread.
        self.commands_dead = False
        self._since_env = 0
        self._closed = asyncio.Event()
        self._rng = random.Random(device.config.seed)

    @property
    def address(self) -> tuple[str, int]:
        """(host, port) the face listens on."""
        assert self.transport is not None
        host, port = self.transport.get_extra_info("sockname")[:2]
        return host, port

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        """Listening."""
        # Not an asyncio.DatagramTransport subclass on every Python (3.11's selector one).
        self.transport = cast(asyncio.DatagramTransport, transport)

    def connection_lost(self, exc: Exception | None) -> None:
        """The socket closed."""
        self._closed.set()

    async def wait_closed(self) -> None:
        """Return once the face's socket has closed (close(), the robot off, an empty datagram)."""
        await self._closed.wait()

    def datagram_received(self, data: bytes, addr: Any) -> None:
        """Any datagram makes its sender the one the status goes to; its commands run in order."""
        if self.device.closed:
            return
        self.datagrams += 1
        self.remote = addr
        if not data:  # the vendor's receive loop ends on an empty datagram
            self.close()
            return
        if self.commands_dead:
            return
        commands = self.parser.feed(data)
        self.device.stats.commands_received += len(commands)
        kept = []
        for command in commands:
            if isinstance(command, RawCommand) and command.data[:2] == b"gi":
                self.commands_dead = True  # struct.error in the vendor's parse_data
                break
            if not isinstance(command, RotateTo):  # the UDP service has no 'a' handler
                kept.append(command)
        self.device.execute(kept)

    def send_statuses(self, frames: list[WireValues]) -> None:
        """One datagram per frame to the last sender, each third followed by the env frame."""
        transport, remote = self.transport, self.remote
        if transport is None or remote is None or transport.is_closing():
            return
        encode = self.encoder.encode
        config = self.device.config
        env, faulty = config.env_sensors, config.faults.any_stream_fault
        for values in frames:
            frame = encode(values)
            if faulty:
                frame = self._with_faults(frame)
            if frame:
                transport.sendto(frame, remote)
                self.frames_sent += 1
                self.device.stats.frames_sent += 1
            if env:
                self._since_env += 1
                if self._since_env > ENV_FRAME_EVERY:
                    self._since_env = 1
                    transport.sendto(encode_env_frame(_ENV_READINGS), remote)

    def _with_faults(self, frame: bytes) -> bytes:
        """The datagram ``frame`` becomes: lost (empty), bit-flipped, or after a garbage one."""
        faults, rng, stats = self.device.config.faults, self._rng, self.device.stats
        if faults.drop and rng.random() < faults.drop:
            stats.frames_dropped += 1
            return b""
        if faults.garbage and rng.random() < faults.garbage and self.transport is not None:
            # A datagram of its own, without 0xCD so that it cannot hold a header.
            noise = bytes(b if b != 0xCD else 0 for b in rng.randbytes(rng.randint(1, 16)))
            stats.garbage_bytes += len(noise)
            self.transport.sendto(noise, self.remote)
        if faults.bitflip and rng.random() < faults.bitflip:
            flipped = bytearray(frame)
            flipped[rng.randrange(len(flipped))] ^= 1 << rng.randrange(8)
            stats.bit_flips += 1
            return bytes(flipped)
        return frame

    def close(self) -> None:
        """Stop serving: no more status, no more commands."""
        self.device.listeners.pop(self, None)
        if self.transport is not None and not self.transport.is_closing():
            self.transport.close()
