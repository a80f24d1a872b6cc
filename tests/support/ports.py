"""Loopback ports for tests that need a connection to be refused."""

from __future__ import annotations

import contextlib
import socket
from collections.abc import Iterator

__all__ = ["refused_port"]


@contextlib.contextmanager
def refused_port() -> Iterator[int]:
    """A port on 127.0.0.1 held bound but not listening: connections to it are refused.

    Unlike a port found free and released, no other process can start listening on it
    while the test runs (the suite runs ROS nodes and brokers on free ports too).
    """
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as holder:
        holder.bind(("127.0.0.1", 0))
        yield int(holder.getsockname()[1])
