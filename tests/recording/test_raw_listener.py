"""Robot.add_raw_listener: the bytes of every read, before they are decoded."""

from __future__ import annotations

from galileo_async import connect
from galileo_async.protocol import StatusDecoder
from galileo_async.sim import Simulator


async def test_a_socket_links_reads_reach_the_raw_listener() -> None:
    async with Simulator(speed=20) as simulator:
        server = await simulator.serve_tcp()
        port = server.sockets[0].getsockname()[1]
        async with connect(f"socket://127.0.0.1:{port}") as robot:
            reads: list[bytes] = []
            assert robot.add_raw_listener(reads.append) is True
            await robot.wait_until(lambda status: status.time_stamp > 30, timeout=30)
            robot.remove_raw_listener(reads.append)
            count = len(reads)
            last = robot.status
            assert last is not None
            await robot.wait_until(lambda s: s.time_stamp > last.time_stamp + 3, timeout=30)
            assert len(reads) == count  # removed: no more calls
    decoded = StatusDecoder().feed(b"".join(reads))
    assert len(decoded) >= 10
    stamps = [status.time_stamp for status in decoded]
    assert stamps == list(range(stamps[0], stamps[0] + len(stamps)))  # every frame, in order
    assert all(isinstance(read, bytes) for read in reads)


async def test_a_udp_link_has_no_raw_bytes() -> None:
    async with Simulator(speed=20) as simulator:
        face = await simulator.serve_udp()
        async with connect(f"udp://127.0.0.1:{face.address[1]}") as robot:
            assert robot.add_raw_listener(lambda data: None) is False
            robot.remove_raw_listener(lambda data: None)  # no-op
