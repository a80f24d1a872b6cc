"""``galileo replay`` and ``sim://?replay=FILE``: a recording served back as a robot."""

from __future__ import annotations

import asyncio
import json
import logging
import os
import signal
import subprocess
from pathlib import Path

import pytest

from galileo_async.cli import ExitCode
from galileo_async.errors import InvalidArgument
from galileo_async.protocol import Goto, encode
from galileo_async.sim import Simulator
from tests.cli.test_cli_served import GALILEO, WAIT, _read_until

#: Seconds of simulator output recorded (real time).
RECORDED = 1.0


def galileo(*args: str) -> subprocess.CompletedProcess[str]:
    env = {key: value for key, value in os.environ.items() if key != "GALILEO_PORT"}
    return subprocess.run(
        [*GALILEO, *args], capture_output=True, text=True, timeout=WAIT, env=env, check=False
    )


@pytest.fixture(scope="module")
def capture(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A recording of a simulated robot (layout v1, so a replay is told apart)."""
    path = tmp_path_factory.mktemp("replay") / "robot.cap"
    result = galileo(
        "--port", "sim://?speed=5&layout=v1", "record", str(path), "--duration", str(RECORDED)
    )
    assert result.returncode == 0, result.stderr
    return path


def test_status_from_a_replayed_recording(capture: Path) -> None:
    result = galileo("--port", f"sim://?replay={capture}", "--json", "status")
    assert result.returncode == 0, result.stderr
    assert json.loads(result.stdout)["status"]["layout"] == "v1"


class _Arrivals(asyncio.Protocol):
    def __init__(self) -> None:
        self.times: list[float] = []
        self.lost = asyncio.Event()

    def data_received(self, data: bytes) -> None:
        self.times.append(asyncio.get_running_loop().time())

    def connection_lost(self, exc: Exception | None) -> None:
        self.lost.set()


@pytest.mark.parametrize("speed", [1.0, 4.0])
async def test_frames_come_at_their_recorded_pace(capture: Path, speed: float) -> None:
    async with Simulator.from_url(f"sim://?replay={capture}&speed={speed}") as simulator:
        arrivals = _Arrivals()
        await simulator.connector()(asyncio.get_running_loop(), lambda: arrivals)
        await asyncio.wait_for(arrivals.lost.wait(), WAIT)  # closed once the capture ended
    took = arrivals.times[-1] - arrivals.times[0]
    expected = RECORDED / speed
    assert expected * 0.8 < took < expected * 1.5 + 0.2


async def test_a_replay_logs_the_commands_it_gets(
    capture: Path, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.INFO, logger="galileo_async.sim.replay")
    async with Simulator.from_url(f"sim://?replay={capture}") as simulator:
        transport, _ = await simulator.connector()(asyncio.get_running_loop(), _Arrivals)
        assert isinstance(transport, asyncio.WriteTransport)
        transport.write(encode(Goto(3)))

        async def logged() -> None:
            # The log has no event to wait on: look again after each loop turn.
            while "command Goto(target_id=3)" not in caplog.text:  # noqa: ASYNC110
                await asyncio.sleep(0.01)

        await asyncio.wait_for(logged(), WAIT)
        transport.close()


def test_replay_serves_over_tcp_and_prints_commands(capture: Path) -> None:
    replay = subprocess.Popen(
        [*GALILEO, "replay", str(capture), "--tcp", "127.0.0.1:0", "--speed", "0.5"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )  # fmt: skip
    try:
        assert replay.stdout is not None
        url = _read_until(replay.stdout, "socket://").strip()
        sent = galileo("--port", url, "send", "Goto", "3")
        assert sent.returncode == 0, sent.stderr
        watched = galileo("--port", url, "monitor", "--json", "--duration", "1")
        assert watched.returncode == 0, watched.stderr
        lines = [json.loads(line) for line in watched.stdout.splitlines()]
        assert any(line.get("status", {}).get("layout") == "v1" for line in lines)
    finally:
        replay.send_signal(signal.SIGINT)
        _, errors = replay.communicate(timeout=WAIT)
    assert replay.returncode == 0, errors
    assert "command Goto(target_id=3)" in errors


def test_a_raw_dump_cannot_be_replayed(tmp_path: Path) -> None:
    raw = tmp_path / "raw.bin"
    raw.write_bytes(b"\xcd\xeb\xd7\x01")
    result = galileo("replay", str(raw), "--tcp", "127.0.0.1:0")
    assert result.returncode == ExitCode.USAGE
    assert "without --raw" in result.stderr
    with pytest.raises(InvalidArgument, match="cannot read the capture"):
        Simulator.from_url(f"sim://?replay={tmp_path / 'missing.cap'}")
