"""The CLI knows the firmware's rules: unknown ids, the start lockout, patrol dwell, hints."""

from __future__ import annotations

import os
import signal
import subprocess
from collections.abc import Iterator

import pytest

from galileo_async.cli import ExitCode
from galileo_async.protocol import Command, StartNavigation
from tests.cli.test_cli_served import GALILEO, WAIT, ServedSim, _read_until, serving
from tests.support.ports import refused_port


def galileo(*args: str, timeout: float = WAIT) -> subprocess.CompletedProcess[str]:
    """Run the ``galileo`` command in a subprocess (GALILEO_PORT cleared)."""
    env = {key: value for key, value in os.environ.items() if key != "GALILEO_PORT"}
    env["COLUMNS"] = "200"
    return subprocess.run(
        [*GALILEO, *args], capture_output=True, text=True, timeout=timeout, env=env, check=False
    )


@pytest.fixture
def served() -> Iterator[ServedSim]:
    yield from serving(20.0)


def test_goto_an_unknown_id_on_a_fresh_simulator_is_rejected_at_once() -> None:
    # Rejected, not timed out waiting to be accepted (that is another exit code and message):
    # no wall-clock bound, which a loaded machine's process start alone can exceed.
    result = galileo("--port", "sim://?speed=5", "goto", "42")
    assert result.returncode == ExitCode.REJECTED, result.stderr
    assert "rejected goal 42" in result.stderr
    assert "accept" not in result.stderr.lower(), result.stderr


def test_goto_an_unknown_id_on_a_shared_robot_is_rejected_every_time(served: ServedSim) -> None:
    assert galileo("--port", served.url, "nav", "start").returncode == 0
    codes = [galileo("--port", served.url, "goto", "42").returncode for _ in range(3)]
    assert codes == [ExitCode.REJECTED] * 3


def test_nav_start_right_after_a_stop_says_so_and_sends_it_again() -> None:
    # At 4x the firmware's lockout (10 s) is 2.5 s: the first resend (after 3 s) is heard.
    # The lockout begins as the command's first start arrives, however long the process
    # took to start: as if a start had come a moment before.
    sim = ServedSim(speed=4.0)
    try:
        assert galileo("--port", sim.url, "nav", "start").returncode == 0
        assert galileo("--port", sim.url, "nav", "stop").returncode == 0
        assert sim.simulator is not None
        model = sim.simulator.model
        submit = model.submit

        def locked_out_first(command: Command) -> None:
            if isinstance(command, StartNavigation) and model.submit is locked_out_first:
                model.submit = submit  # type: ignore[method-assign]
                model.lock_out_start()
            submit(command)

        model.submit = locked_out_first  # type: ignore[method-assign]
        result = galileo("--port", sim.url, "nav", "start", timeout=60)
        assert result.returncode == 0, result.stderr
        assert "ignored the start" in result.stderr
        assert "5-30 s" in result.stderr
        assert sim.state.status.navigating
    finally:
        sim.close()


def test_patrol_start_with_dwell_on_document_firmware() -> None:
    result = galileo(
        "--port", "sim://?speed=20&firmware=document", "patrol", "start", "--dwell", "1"
    )
    assert result.returncode == 0, result.stderr
    assert "patrol running" in result.stdout


def test_demo_runs_on_the_v1_layout() -> None:
    result = galileo("--port", "sim://?layout=v1&speed=20", "demo", timeout=60)
    assert result.returncode == 0, result.stdout + result.stderr
    assert "visited targets" in result.stdout


def test_map_command_with_navigation_open_says_close_it(served: ServedSim) -> None:
    assert galileo("--port", served.url, "nav", "start").returncode == 0
    result = galileo("--port", served.url, "map", "save")
    assert result.returncode == ExitCode.NOT_READY
    assert "close navigation first" in result.stderr
    assert "--start-nav" not in result.stderr


def test_vda5050_without_a_broker_says_it_is_retrying_and_when() -> None:
    with refused_port() as port:
        proc = subprocess.Popen(
            [*GALILEO, "--port", "sim://?speed=20", "vda5050", "--broker",
             f"mqtt://127.0.0.1:{port}", "--manufacturer", "acme", "--serial-number", "r9"],
            stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
        )  # fmt: skip
        try:
            assert proc.stderr is not None
            seen = _read_until(proc.stderr, "connecting to mqtt://")
            seen += _read_until(proc.stderr, "next try at")
            seen += _read_until(proc.stderr, "next try at")  # the same reason again: said too
            assert seen.count("retrying: r9: cannot connect to the broker") == 2, seen
        finally:
            proc.send_signal(signal.SIGINT)
            code = proc.wait(WAIT)
            if proc.stderr is not None:
                proc.stderr.close()
        assert code == 0
