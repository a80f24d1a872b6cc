"""McapRecorder: a simulated robot and fleet recorded, read back with the mcap package."""

from __future__ import annotations

import asyncio
import json
import subprocess
import sys
import time
from pathlib import Path

import anyio
import pytest
from mcap.reader import make_reader

import galileo_async as galileo
from galileo_async import GalileoStatus, InvalidArgument
from galileo_async.recording import (
    LOG_SCHEMA_NAME,
    STATUS_SCHEMA_NAME,
    McapRecorder,
    read_recording,
    status_json,
)
from galileo_async.recording.writer import McapFileWriter
from galileo_async.robot import Robot
from galileo_async.sim import Simulator
from galileo_async.testing import recorded_statuses, simulated_fleet, simulated_robot
from tests.support.cancel_ways import WAYS, stop_waiting
from tests.support.metrics_support import free_port


async def record_goto(path: Path, **recorder: object) -> dict[str, int]:
    """A simulated robot recorded while it drives to target 1; the messages written."""
    async with simulated_robot() as (robot, _device):
        async with McapRecorder(path, robot, **recorder) as recording:  # type: ignore[arg-type]
            await robot.goto(1)
        assert recording.dropped == 0
        return recording.written


async def test_a_robot_recorded_reads_back_with_the_mcap_package(tmp_path: Path) -> None:
    path = tmp_path / "robot.mcap"
    written = await record_goto(path)
    with path.open("rb") as stream:
        reader = make_reader(stream)
        summary = reader.get_summary()
        assert summary is not None
        assert summary.chunk_indexes  # indexed, with a summary
        assert summary.statistics is not None
        topics = {channel.topic: channel for channel in summary.channels.values()}
        assert set(topics) == {"/robot/raw", "/robot/status", "/robot/events"}
        schemas = {schema.id: schema for schema in summary.schemas.values()}
        status = topics["/robot/status"]
        assert status.message_encoding == "json"
        assert schemas[status.schema_id].name == STATUS_SCHEMA_NAME
        assert schemas[status.schema_id].encoding == "jsonschema"
        assert json.loads(schemas[status.schema_id].data)["properties"]["power"]
        events = topics["/robot/events"]
        assert schemas[events.schema_id].name == LOG_SCHEMA_NAME == "foxglove.Log"
        assert topics["/robot/raw"].schema_id == 0  # bytes, no schema
        counts = summary.statistics.channel_message_counts
        by_topic = {
            topics_id.topic: counts.get(cid, 0) for cid, topics_id in summary.channels.items()
        }
        assert by_topic == {
            "/robot/raw": written["raw"],
            "/robot/status": written["status"],
            "/robot/events": written["events"],
        }
        assert written["status"] > 30
        logs = [json.loads(m.data) for _s, c, m in reader.iter_messages() if c.topic.endswith("s")]
    names = [log["event"]["event"] for log in logs if "event" in log]
    assert names[:1] == ["GoalAccepted"]
    assert "GoalReached" in names
    reached = next(log for log in logs if log.get("event", {}).get("event") == "GoalReached")
    assert reached["level"] == 2
    assert reached["name"] == "robot"
    assert reached["message"].startswith("GoalReached target_id=1")
    assert set(reached["timestamp"]) == {"sec", "nsec"}


async def test_the_raw_bytes_decode_to_the_statuses_recorded(tmp_path: Path) -> None:
    path = tmp_path / "robot.mcap"
    await record_goto(path)
    recorded = read_recording(path).robot()
    decoded = [status_json(status) for status in recorded_statuses(path)]
    assert decoded == [values for _t, values in recorded.statuses]
    times = [t for t, _ in recorded.raw]
    assert times == sorted(times)
    assert times[-1] > 3  # the goal's seconds, on the virtual clock: the pace is kept


async def test_a_replayed_recording_gives_the_same_statuses(tmp_path: Path) -> None:
    from galileo_async.testing import replayed_robot

    path = tmp_path / "robot.mcap"
    await record_goto(path)
    expected = [values for _t, values in read_recording(path).robot().statuses]
    seen: list[dict[str, object]] = []
    async with replayed_robot(path) as (robot, _device):
        robot.add_update_listener(lambda status: seen.append(status_json(status)))
        last = expected[-1]["time_stamp"]
        await robot.wait_until(lambda status: status.time_stamp == last, timeout=60)
    # connect() took the first status or two before the listener was added.
    assert len(seen) >= len(expected) - 3
    assert seen == expected[-len(seen) :]


def test_status_json_is_the_models_json_dump() -> None:
    status = GalileoStatus(nav_status=1, power=24.5, current_pose_x=1.25, target_status=-1)
    assert status_json(status) == status.model_dump(mode="json")


async def test_a_fleet_records_a_channel_set_per_robot(tmp_path: Path) -> None:
    path = tmp_path / "fleet.mcap"
    async with simulated_fleet(["alpha", "beta"]) as (fleet, _devices):
        async with McapRecorder(path, fleet) as recording, anyio.create_task_group() as group:
            group.start_soon(fleet["alpha"].goto, 1)
            group.start_soon(fleet["beta"].goto, 2)
        assert recording.robots == ("alpha", "beta")
    with path.open("rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None
    assert {channel.topic for channel in summary.channels.values()} == {
        f"/{robot}/{kind}" for robot in ("alpha", "beta") for kind in ("raw", "status", "events")
    }
    recording_read = read_recording(path)
    assert list(recording_read.robots) == ["alpha", "beta"]
    for name in ("alpha", "beta"):
        robot = recording_read.robot(name)
        assert [status_json(s) for s in recorded_statuses(path, name)] == [
            values for _t, values in robot.statuses
        ]
    with pytest.raises(InvalidArgument, match="several robots: pick one of alpha, beta"):
        recorded_statuses(path)
    with pytest.raises(InvalidArgument, match=r"no robot 'gamma' \(robots: alpha, beta\)"):
        recorded_statuses(path, "gamma")


async def test_a_fleet_name_with_a_slash_is_read_back(tmp_path: Path) -> None:
    path = tmp_path / "site.mcap"
    async with simulated_fleet(["site/a", "b"]) as (fleet, _devices), McapRecorder(path, fleet):
        await fleet["site/a"].goto(1)
    recording = read_recording(path)
    assert sorted(recording.robots) == ["b", "site/a"]
    assert recording.robot("site/a").statuses
    assert recorded_statuses(path, "site/a")


async def test_a_file_cut_short_reads_up_to_its_last_chunk(tmp_path: Path) -> None:
    path = tmp_path / "robot.mcap"
    await record_goto(path, chunk_size=2048)
    whole = read_recording(path).robot()
    data = path.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) // 2])  # no summary, no footer, a chunk half written
    part = read_recording(cut).robot()
    assert 0 < len(part.statuses) < len(whole.statuses)
    assert part.statuses == whole.statuses[: len(part.statuses)]
    assert part.raw == whole.raw[: len(part.raw)]
    assert [status_json(s) for s in recorded_statuses(cut)][:5] == [
        values for _t, values in part.statuses[:5]
    ]


def test_a_bad_file_is_a_clear_error(tmp_path: Path) -> None:
    garbage = tmp_path / "garbage.mcap"
    garbage.write_bytes(b"\x89MCAP0\r\n" + b"\xff" * 64)
    with pytest.raises(InvalidArgument, match="not a readable MCAP file"):
        read_recording(garbage)
    with pytest.raises(InvalidArgument, match="not a readable MCAP file"):
        recorded_statuses(garbage)
    other = tmp_path / "other.mcap"
    other.write_bytes(b"hello")
    with pytest.raises(InvalidArgument, match="is not an MCAP file"):
        read_recording(other)
    with pytest.raises(InvalidArgument, match="cannot read"):
        read_recording(tmp_path / "missing.mcap")


async def test_the_writer_drops_and_counts_what_it_cannot_queue(tmp_path: Path) -> None:
    path = tmp_path / "drops.mcap"
    writer = McapFileWriter(path.open("wb"), max_queued=3)
    writer.add_robot("robot", raw=True)  # registrations are never dropped
    for index in range(5):
        writer.add_raw("robot", index, b"\xcd")
    assert writer.dropped == {"raw": 3, "status": 0, "events": 0}
    writer.start()
    await writer.finish()
    assert writer.written["raw"] == 2
    assert writer.error is None
    assert finished(path) == 2


async def test_an_unwritable_file_is_refused_before_recording(tmp_path: Path) -> None:
    async with simulated_robot() as (robot, _device):
        with pytest.raises(InvalidArgument, match="cannot write"):
            await McapRecorder(tmp_path / "no" / "such" / "dir.mcap", robot).start()
        with pytest.raises(InvalidArgument, match="records a Robot or a Fleet"):
            McapRecorder(tmp_path / "x.mcap", "robot")  # type: ignore[arg-type]
        with pytest.raises(InvalidArgument, match="without '/'"):
            McapRecorder(tmp_path / "x.mcap", robot, name="a/b")


# --- every exit path finishes the file ------------------------------------------------


def finished(path: Path) -> int:
    """The status messages of a finished file (its summary read through its footer)."""
    with path.open("rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None
    assert summary.statistics is not None
    return summary.statistics.message_count


@pytest.mark.parametrize("how", WAYS)
async def test_every_way_of_stopping_finishes_the_file(tmp_path: Path, how: str) -> None:
    path = tmp_path / f"{how}.mcap"
    async with simulated_robot() as (robot, _device):

        async def record_forever() -> None:
            async with McapRecorder(path, robot):
                await asyncio.Event().wait()

        await stop_waiting(how, record_forever, after=2)
    assert finished(path) > 30  # two virtual seconds of frames, raw and decoded


async def test_an_error_finishes_the_file_and_propagates(tmp_path: Path) -> None:
    path = tmp_path / "error.mcap"

    async def record_then_fail(robot: Robot) -> None:
        async with McapRecorder(path, robot):
            await robot.wait_until(lambda status: status.time_stamp > 20, timeout=30)
            raise RuntimeError("boom")

    async with simulated_robot() as (robot, _device):
        with pytest.raises(RuntimeError, match="boom"):
            await record_then_fail(robot)
    assert finished(path) > 5


async def test_a_cancelled_aclose_still_finishes_the_file(tmp_path: Path) -> None:
    path = tmp_path / "aclose.mcap"
    async with simulated_robot() as (robot, _device):
        recorder = McapRecorder(path, robot)
        await recorder.start()
        await robot.wait_until(lambda status: status.time_stamp > 20, timeout=30)
        closing = asyncio.create_task(recorder.aclose())
        await asyncio.sleep(0)
        closing.cancel()
        with pytest.raises(asyncio.CancelledError):
            await closing
        assert finished(path) > 5  # finished before the cancellation was raised
        await recorder.aclose()  # idempotent


async def test_a_link_without_raw_bytes_records_statuses_and_events(tmp_path: Path) -> None:
    path = tmp_path / "http.mcap"
    async with simulated_robot(link="http") as (robot, _device):
        async with McapRecorder(path, robot) as recording:
            await robot.wait_until(lambda status: status.time_stamp > 20, timeout=30)
        assert recording.written["raw"] == 0
    with path.open("rb") as stream:
        summary = make_reader(stream).get_summary()
    assert summary is not None
    assert {c.topic for c in summary.channels.values()} == {"/robot/status", "/robot/events"}
    assert read_recording(path).robot().statuses
    with pytest.raises(InvalidArgument, match="has no raw bytes"):
        recorded_statuses(path)


def test_a_program_that_never_closes_its_recorder_still_gets_a_whole_file(
    tmp_path: Path,
) -> None:
    path = tmp_path / "forgotten.mcap"
    script = (
        "import asyncio, sys\n"
        "from galileo_async import connect\n"
        "from galileo_async.recording import McapRecorder\n"
        "async def main():\n"
        "    async with connect('sim://?speed=20') as robot:\n"
        "        await McapRecorder(sys.argv[1], robot).start()\n"
        "        await robot.wait_until(lambda status: status.time_stamp > 40, timeout=30)\n"
        "asyncio.run(main())\n"
    )
    ran = subprocess.run(
        [sys.executable, "-c", script, str(path)], capture_output=True, text=True, timeout=60,
        check=False,
    )  # fmt: skip
    assert ran.returncode == 0, ran.stderr
    assert finished(path) > 10


async def test_a_fleet_robot_that_connects_later_is_recorded_from_then_on(tmp_path: Path) -> None:
    port = free_port()
    ports = {"early": "sim://?speed=20", "late": f"socket://127.0.0.1:{port}"}
    path = tmp_path / "fleet.mcap"
    async with (
        galileo.connect_fleet(ports, retry_initial=0.05, retry_max=0.2) as fleet,
        McapRecorder(path, fleet) as recorder,
    ):
        assert recorder.robots == ("early",)
        async with Simulator(speed=20) as sim:
            await sim.serve_tcp(port=port)
            async with asyncio.timeout(20):
                while "late" not in recorder.robots:  # noqa: ASYNC110 - no event to wait on
                    await asyncio.sleep(0.05)
            seen = 0
            async with asyncio.timeout(20):
                async for _ in fleet["late"].statuses():  # recorded: attached before
                    seen += 1
                    if seen == 3:
                        break
            await fleet.close()
    recording = read_recording(path)
    assert set(recording.robots) == {"early", "late"}
    assert recording.robot("late").statuses


def _open_fds(path: Path) -> int:
    """How many of this process's file descriptors point at ``path`` (Linux /proc)."""
    fds = Path("/proc/self/fd")
    return sum(1 for fd in fds.iterdir() if _target(fd) == str(path))


def _target(fd: Path) -> str | None:
    try:
        return str(fd.readlink())
    except OSError:
        return None


@pytest.mark.filterwarnings("error::ResourceWarning")  # a file left for the GC to close
async def test_a_start_cancelled_while_the_file_opens_leaves_it_closed(tmp_path: Path) -> None:
    path = tmp_path / "cancelled.mcap"
    async with simulated_robot() as (robot, _):
        recorder = McapRecorder(path, robot)
        starting = asyncio.ensure_future(recorder.start())
        await asyncio.sleep(0)  # the open is under way on its thread
        starting.cancel()
        with pytest.raises(asyncio.CancelledError):
            await starting
        deadline = time.monotonic() + 10  # the thread's open ends, then its file is closed
        while not path.exists() or _open_fds(path):
            assert time.monotonic() < deadline, "the file opened by the cancelled start is open"
            await asyncio.to_thread(time.sleep, 0.01)
