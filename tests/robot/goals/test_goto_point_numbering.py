"""goto_point() arrives at the point it was given, or fails (issue 21 item 9).

The simulator's default map has 6 targets; ``map_targets=3`` makes the dynamic target's
id 3, a map target's (at (-3, 2)). Over TCP the link cannot tell the map's size, so only
the end pose shows it; over sim:// the link can, and the call is refused before a send.
"""

from __future__ import annotations

import anyio
import pytest

import galileo_async as galileo
from galileo_async import GoalAborted, InvalidArgument
from galileo_async.cli import ExitCode
from galileo_async.protocol import AddTarget, Goto, ResetTargets
from galileo_async.sim import DEFAULT_TARGETS, Simulator
from tests.cli.test_cli_served import ServedSim, invoke
from tests.support.sim_integration import WAIT, record_commands

SPEED = 50.0
WRONG = 3
assert len(DEFAULT_TARGETS) == 6


async def test_a_goal_that_ends_away_from_the_point_is_an_error_naming_map_targets() -> None:
    async with Simulator(speed=SPEED) as sim:
        server = await sim.serve_tcp()
        url = f"socket://127.0.0.1:{server.sockets[0].getsockname()[1]}"
        async with galileo.connect(url, map_targets=WRONG) as robot:
            assert robot.map_targets == WRONG
            await robot.start_navigation(timeout=WAIT)
            log = record_commands(sim)
            with anyio.fail_after(WAIT), pytest.raises(GoalAborted, match="map_targets") as caught:
                await robot.goto_point(1.0, 1.0)
        assert [command for command, _ in log] == [ResetTargets(), AddTarget(1.0, 1.0), Goto(WRONG)]
        error = caught.value
        assert error.target_id == WRONG
        assert error.distance == pytest.approx(4.12, abs=0.01)  # (-3, 2) to (1, 1)
        assert "target numbering looks wrong" in str(error)


async def test_the_right_count_over_tcp_arrives() -> None:
    async with Simulator(speed=SPEED) as sim:
        server = await sim.serve_tcp()
        url = f"socket://127.0.0.1:{server.sockets[0].getsockname()[1]}"
        async with galileo.connect(url, map_targets=len(DEFAULT_TARGETS)) as robot:
            await robot.start_navigation(timeout=WAIT)
            with anyio.fail_after(WAIT):
                result = await robot.goto_point(1.0, 1.0)
        assert result.target_id == len(DEFAULT_TARGETS)
        assert (sim.state.pose.x, sim.state.pose.y) == pytest.approx((1.0, 1.0), abs=1e-3)


@pytest.mark.parametrize("map_targets", [WRONG, 7])
async def test_a_map_targets_the_link_contradicts_is_refused_before_anything_is_sent(
    map_targets: int,
) -> None:
    async with galileo.connect(f"sim://?speed={SPEED}", map_targets=map_targets) as robot:
        await robot.start_navigation(timeout=WAIT)
        sent = robot.link.commands_sent
        for call in (lambda: robot.goto_point(1.0, 1.0), lambda: robot.add_target(1.0, 1.0)):
            with pytest.raises(InvalidArgument, match=f"map_targets={map_targets} contradicts"):
                await call()
        assert robot.link.commands_sent == sent


# --- the CLI: `galileo --map-targets 3 goto-point 1 1` --------------------------------


def test_cli_goto_point_with_a_too_small_map_targets_exits_aborted() -> None:
    served = ServedSim(speed=SPEED)  # over TCP: the link cannot tell the map's size
    try:
        args = ("--map-targets", str(WRONG), "goto-point", "1", "1", "--start-nav")
        result = invoke(served.url, *args)
        assert result.exit_code == ExitCode.ABORTED, result.output
        assert "map_targets" in result.output
        assert (served.state.pose.x, served.state.pose.y) != pytest.approx((1.0, 1.0), abs=0.3)
    finally:
        served.close()


def test_cli_goto_point_with_a_map_targets_the_simulator_contradicts_exits_usage() -> None:
    result = invoke(f"sim://?speed={SPEED}", "--map-targets", str(WRONG), "goto-point", "1", "1")
    assert result.exit_code == ExitCode.USAGE, result.output
    assert f"map_targets={WRONG} contradicts" in result.output
