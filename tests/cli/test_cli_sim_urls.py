"""Every URL that ``galileo sim`` prints works as printed, on every face of the simulator."""

from __future__ import annotations

import json
import os
import queue
import shlex
import signal
import socket
import subprocess
import threading
from collections.abc import Iterator
from typing import IO

import pytest

from galileo_async.cli import ExitCode
from tests.cli.test_cli_served import GALILEO

#: Tries at finding a port pair that stays free until the simulator listens on it.
PORT_TRIES = 5
#: Bound on a wait for a line of a child process, seconds: a guard only (a process start
#: on a loaded machine may take long), never a pace.
LINE_WAIT = 60.0


def free_port_pair() -> int:
    """A port P of 127.0.0.1 with P and P + 1 both free just now (HTTP and its WebSocket)."""
    while True:
        with socket.socket() as first:
            first.bind(("127.0.0.1", 0))
            port = int(first.getsockname()[1])
            if port >= 65535:
                continue
            with socket.socket() as second:
                try:
                    second.bind(("127.0.0.1", port + 1))
                except OSError:
                    continue
        return port


class Lines:
    """The lines of a child's stream, read by a thread of their own: next() waits for one."""

    def __init__(self, stream: IO[str]) -> None:
        self._stream = stream
        self._lines: queue.Queue[str | None] = queue.Queue()
        self._thread = threading.Thread(target=self._read, args=(stream,), daemon=True)
        self._thread.start()

    def _read(self, stream: IO[str]) -> None:
        for line in stream:
            self._lines.put(line.strip())
        self._lines.put(None)  # the end

    def next(self, what: str) -> str:
        """The next line (failing after LINE_WAIT s or at the stream's end)."""
        try:
            line = self._lines.get(timeout=LINE_WAIT)
        except queue.Empty:
            raise AssertionError(f"no {what} within {LINE_WAIT} s") from None
        assert line is not None, f"the stream ended before the {what}"
        return line

    def close(self) -> None:
        """Close the stream once its reader saw the end (the child has ended)."""
        self._thread.join(LINE_WAIT)
        self._stream.close()

    def rest(self) -> str:
        """Every line up to the stream's end (once the child has ended)."""
        lines = []
        while (line := self._lines.get(timeout=LINE_WAIT)) is not None:
            lines.append(line)
        return "\n".join(lines)


class Sim:
    """``galileo sim`` in a child process, the URL lines it printed and its hint line."""

    def __init__(
        self, process: subprocess.Popen[str], streams: list[Lines], urls: list[str]
    ) -> None:
        self.process = process
        self.streams = streams
        self.urls = urls
        self.hint = streams[1].next("hint line")

    def close(self) -> None:
        self.process.send_signal(signal.SIGINT)
        try:
            assert self.process.wait(LINE_WAIT) == 0
        finally:
            end(self.process, self.streams)


def end(process: subprocess.Popen[str], streams: list[Lines]) -> None:
    """Kill ``process`` (when still running) and close its streams."""
    process.kill()
    process.wait(LINE_WAIT)
    for stream in streams:
        stream.close()


def start_sim(*args: str, faces: int) -> Sim:
    """``galileo sim args… --http P`` (P, P + 1 free), with ``faces`` ways besides HTTP.

    Should another process take P or P + 1 before the simulator listens, another pair.
    """
    for _ in range(PORT_TRIES):
        command = [*GALILEO, "sim", "--speed", "5", *args, "--http", str(free_port_pair())]
        process = subprocess.Popen(
            command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
        )
        assert process.stdout is not None
        assert process.stderr is not None
        stdout, stderr = Lines(process.stdout), Lines(process.stderr)
        try:
            urls = [stdout.next("URL line") for _ in range(faces + 1)]
            return Sim(process, [stdout, stderr], urls)
        except AssertionError:
            process.kill()
            taken = "already in use" in stderr.rest()
            end(process, [stdout, stderr])
            if not taken:
                raise
    raise AssertionError(f"no free port pair for galileo sim --http in {PORT_TRIES} tries")


#: (arguments of galileo sim besides --http, how many faces they open).
FACES = [
    pytest.param((("--tcp", "127.0.0.1:0", "--udp", "0"), 2), id="tcp-udp-http"),
    pytest.param(((), 0), id="http"),
    pytest.param(
        (("--pty", "--udp", "0"), 2),
        id="pty-udp-http",
        marks=pytest.mark.skipif(not hasattr(os, "openpty"), reason="needs a POSIX pty"),
    ),
]


@pytest.fixture(params=FACES)
def sim(request: pytest.FixtureRequest) -> Iterator[Sim]:
    args, faces = request.param
    served = start_sim(*args, faces=faces)
    try:
        yield served
    finally:
        served.close()


def status_of(*args: str) -> dict[str, object]:
    """``galileo args… --json status``'s JSON object; the command must exit 0."""
    env = {key: value for key, value in os.environ.items() if key != "GALILEO_PORT"}
    done = subprocess.run(
        [*GALILEO, *args, "--json", "status"],
        capture_output=True, text=True, timeout=LINE_WAIT * 2, env=env, check=False,
    )  # fmt: skip
    assert done.returncode == 0, (args, done.stdout, done.stderr)
    data: dict[str, object] = json.loads(done.stdout)
    return data


def test_every_printed_url_connects_as_printed(sim: Sim) -> None:
    assert sim.urls[-1].startswith("http://"), sim.urls
    for url in sim.urls:
        data = status_of("--port", url)
        assert data["port"] == url
        assert isinstance(data["status"], dict)


def test_the_connect_hint_on_stderr_works_as_printed(sim: Sim) -> None:
    command = sim.hint.partition("connect with: ")[2].partition(" · ")[0]
    words = shlex.split(command)  # as a shell splits it
    assert words == ["galileo", "--port", sim.urls[0], "status"], sim.hint
    assert shlex.quote(sim.urls[0]) in command  # quoted where a shell needs it (?, &)
    status_of(*words[1:-1])


def test_a_taken_websocket_port_is_a_connection_error_that_says_so() -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = int(taken.getsockname()[1])
        done = subprocess.run(
            [*GALILEO, "sim", "--http", str(port - 1)],
            capture_output=True, text=True, timeout=LINE_WAIT * 2, check=False,
        )  # fmt: skip
    assert done.returncode == ExitCode.CONNECTION, done.stderr
    assert f"(WebSocket: {port}) is already in use" in done.stderr
