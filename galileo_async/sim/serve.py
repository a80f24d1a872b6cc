"""Serving the simulated device over a pseudo-terminal (Linux/macOS)."""

from __future__ import annotations

import asyncio
import contextlib
import os
import sys

__all__ = ["PTY_BACKLOG_LIMIT", "PtyTransport", "open_pty"]

#: Unread bytes on the device path above which nobody is reading: they are flushed so a
#: host opening the path later does not get seconds-old frames (about 11 v2 frames).
PTY_BACKLOG_LIMIT = 1024


class PtyTransport(asyncio.Transport):
    """The device end of a pty: writes go to the master, reads come from it (non-blocking)."""

    def __init__(self, loop: asyncio.AbstractEventLoop, protocol: asyncio.Protocol) -> None:
        if sys.platform == "win32":  # pragma: no cover - os.openpty is POSIX only
            raise OSError("pseudo-terminals need Linux or macOS")
        import termios
        import tty

        self._termios = termios
        master, slave = os.openpty()
        tty.setraw(slave)  # no echo, no line discipline: a clean 8-bit serial line
        os.set_blocking(master, False)
        self.path = os.ttyname(slave)
        super().__init__({"pty": self.path})
        self._loop, self._protocol = loop, protocol
        self._master, self._slave = master, slave
        self._closing = False
        self.bytes_dropped = 0
        self._unread_after_write = 0
        protocol.connection_made(self)
        loop.add_reader(master, self._on_readable)

    def _on_readable(self) -> None:
        try:
            data = os.read(self._master, 4096)
        except (BlockingIOError, InterruptedError):
            return
        except OSError:  # the pty broke: behave like an unplugged adapter
            self.close()
            return
        if data:
            self._protocol.data_received(data)

    def _backlog(self) -> int:
        import fcntl

        request = getattr(self._termios, "FIONREAD", None)
        if request is None:  # pragma: no cover - every supported POSIX has it
            return 0
        buffer = bytearray(4)
        fcntl.ioctl(self._slave, request, buffer)
        return int.from_bytes(buffer, sys.byteorder)

    def write(self, data: bytes | bytearray | memoryview) -> None:
        """Write without blocking; what does not fit is dropped, like a full serial buffer."""
        if self._closing:
            return
        backlog = 0
        with contextlib.suppress(OSError):
            backlog = self._backlog()
            # Flush only when nobody read anything since our last write: a slow reader
            # keeps its frames, a path nobody has open does not pile them up.
            if backlog > PTY_BACKLOG_LIMIT and backlog >= self._unread_after_write:
                self._termios.tcflush(self._slave, self._termios.TCIFLUSH)
                backlog = 0
        view = memoryview(bytes(data))
        try:
            written = os.write(self._master, view)
        except OSError:  # EAGAIN included: the frame is lost, as on a saturated line
            written = 0
        self.bytes_dropped += len(view) - written
        self._unread_after_write = backlog + written

    def is_closing(self) -> bool:
        """True once closed."""
        return self._closing

    def close(self) -> None:
        """Remove the device path: the host's reads fail as if the adapter was unplugged."""
        if self._closing:
            return
        self._closing = True
        self._loop.remove_reader(self._master)
        for fd in (self._master, self._slave):
            with contextlib.suppress(OSError):
                os.close(fd)
        self._loop.call_soon(self._protocol.connection_lost, None)

    def abort(self) -> None:
        """Same as close."""
        self.close()

    def get_write_buffer_size(self) -> int:
        """Always 0: the pty buffers in the kernel."""
        return 0

    def set_write_buffer_limits(self, high: int | None = None, low: int | None = None) -> None:
        """No-op."""

    def get_protocol(self) -> asyncio.BaseProtocol:
        """The device protocol."""
        return self._protocol

    def set_protocol(self, protocol: asyncio.BaseProtocol) -> None:
        """Deliver to another protocol."""
        assert isinstance(protocol, asyncio.Protocol)
        self._protocol = protocol

    def is_reading(self) -> bool:
        """True until closed."""
        return not self._closing

    def pause_reading(self) -> None:
        """No-op."""

    def resume_reading(self) -> None:
        """No-op."""


def open_pty(loop: asyncio.AbstractEventLoop, protocol: asyncio.Protocol) -> PtyTransport:
    """Create a pty served by ``protocol``; the host opens ``transport.path``."""
    return PtyTransport(loop, protocol)
