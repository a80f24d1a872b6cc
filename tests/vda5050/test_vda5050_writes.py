"""The vehicle's MQTT client writes each packet in the call that queues it (session.py)."""

from __future__ import annotations

import logging
import socket
from typing import Any

import aiomqtt
import anyio
import pytest

import galileo_async as galileo
from galileo_async.vda5050 import Vehicle, VehicleConfig
from galileo_async.vda5050.models import Connection, ConnectionState, Visualization
from galileo_async.vda5050.session import PacketWriter, Session, write_at_once
from tests.support.vda5050_support import WAIT, Broker, broker_fixture

__all__ = ["broker_fixture"]


async def test_a_qos0_publish_is_on_the_socket_when_publish_returns(broker: Broker) -> None:
    async with aiomqtt.Client("127.0.0.1", broker.port, identifier="plain") as plain:
        info = plain._client.publish("t/plain", b"x")
        assert not info.is_published()  # aiomqtt's own path: a writer callback, later
    client = aiomqtt.Client("127.0.0.1", broker.port, identifier="at-once")
    assert write_at_once(client)  # a new aiomqtt that hides its paho client fails here
    async with client:
        for _ in range(100):
            info = client._client.publish("t/at-once", b"x")
            assert info.is_published()
            assert not client._client.want_write()
            await client.publish("t/at-once", b"y")


async def test_what_the_socket_does_not_take_goes_out_later(broker: Broker) -> None:
    big = bytes(range(256)) * 4096  # 1 MiB, far more than the send buffer set below
    async with (
        aiomqtt.Client("127.0.0.1", broker.port, identifier="master") as master,
        anyio.create_task_group() as group,
    ):
        await master.subscribe("t/#")
        received: list[bytes] = []
        done = anyio.Event()

        async def listen() -> None:
            async for message in master.messages:
                assert isinstance(message.payload, bytes)
                received.append(message.payload)
                if len(received) == 3:
                    done.set()
                    return

        group.start_soon(listen)
        client = aiomqtt.Client("127.0.0.1", broker.port, identifier="sender")
        assert write_at_once(client)
        async with client:
            sock = client._client.socket()
            assert isinstance(sock, socket.socket)
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4096)
            with anyio.fail_after(WAIT):
                await client.publish("t/1", b"before")
                client._client.publish("t/2", big)
                assert client._client.want_write()  # partly written: the writer callback's turn
                await client.publish("t/3", b"after")
                await done.wait()
    assert received == [b"before", big, b"after"]


def test_a_client_without_paho_inside_is_left_alone() -> None:
    class Other:
        pass

    assert not write_at_once(Other())  # type: ignore[arg-type]


async def test_a_vehicle_session_makes_its_clients_write_at_once() -> None:
    config = VehicleConfig(broker="mqtt://127.0.0.1:1", manufacturer="m", serial_number="s")

    def connection(state: ConnectionState) -> Connection:
        return Connection(headerId=0, timestamp="t", version="2.0.0", manufacturer="m",
                          serialNumber="s", connectionState=state)  # fmt: skip

    async def nothing() -> None:
        pass

    session = Session(config, connection, nothing, lambda topic, payload: None)
    client = session._client_for(logging.getLogger("test"))
    assert "write_at_once" in client._client.on_socket_register_write.__qualname__


async def _listening(master: aiomqtt.Client, count: int, received: list[bytes]) -> None:
    """Receive until ``received`` holds ``count`` payloads."""
    async for message in master.messages:
        assert isinstance(message.payload, bytes)
        received.append(message.payload)
        if len(received) == count:
            return


async def _publishes_through_paho(client: aiomqtt.Client) -> list[str]:
    """Count the messages that take paho-mqtt's own publish from now on."""
    calls: list[str] = []
    publish = client._client.publish

    def counted(topic: str, *args: Any, **kwargs: Any) -> Any:
        calls.append(topic)
        return publish(topic, *args, **kwargs)

    client._client.publish = counted  # type: ignore[method-assign]
    return calls


@pytest.mark.parametrize(
    "protocol", [aiomqtt.ProtocolVersion.V311, aiomqtt.ProtocolVersion.V5], ids=["3.1.1", "5"]
)
async def test_a_packet_writer_writes_the_packet_paho_would_whole(
    broker: Broker, protocol: aiomqtt.ProtocolVersion
) -> None:
    message = Connection(headerId=7, timestamp="2026-11-28T16:00:00.000Z", version="2.0.0",
                         manufacturer="m", serialNumber="s/ü",
                         connectionState="ONLINE")  # fmt: skip
    payload = message.model_dump_json(exclude_none=True).encode()
    async with (
        aiomqtt.Client("127.0.0.1", broker.port, identifier="master") as master,
        aiomqtt.Client("127.0.0.1", broker.port, identifier="w", protocol=protocol) as client,
    ):
        await master.subscribe("t/#")
        through_paho = await _publishes_through_paho(client)
        writer = PacketWriter(client)
        big = b"x" * 20_000  # a remaining length of three bytes
        client._client._last_msg_out = 0.0
        assert writer.publish("t/ü", payload) is None  # None: written whole, here
        assert client._client._last_msg_out > 0.0  # no keep-alive ping needed now
        assert writer.publish("t/big", big) is None
        assert writer.publish("t/empty", b"") is None
        received: list[bytes] = []
        with anyio.fail_after(WAIT):
            await _listening(master, 3, received)
        assert through_paho == []
        assert received == [payload, big, b""]


async def test_what_a_packet_writer_cannot_write_goes_through_paho_in_order(
    broker: Broker, caplog: pytest.LogCaptureFixture
) -> None:
    big = bytes(range(256)) * 4096  # 1 MiB, far more than the send buffer set below
    log = logging.getLogger("tests.vda5050.sender")
    client = aiomqtt.Client("127.0.0.1", broker.port, identifier="sender", logger=log)
    assert write_at_once(client)
    async with (
        aiomqtt.Client("127.0.0.1", broker.port, identifier="master") as master,
        client,
    ):
        await master.subscribe("t/#")
        sock = client._client.socket()
        assert isinstance(sock, socket.socket)
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4096)
        writer = PacketWriter(client)
        through_paho = await _publishes_through_paho(client)
        received: list[bytes] = []
        info = writer.publish("t/big", big)
        assert info is not None  # the rest queued in paho-mqtt, for its writer callback
        assert info.rc == 0
        assert client._client.want_write()
        assert writer.publish("t/after", b"after") is not None  # behind it
        with anyio.fail_after(WAIT):
            await _listening(master, 2, received)
        assert not client._client.want_write()
        with caplog.at_level(logging.DEBUG, log.name):
            writer.publish("t/logged", b"logged")  # paho-mqtt logs each packet: its path
        assert any("Sending PUBLISH" in r.getMessage() for r in caplog.records)
        assert writer.publish("t/last", b"last") is None
        with anyio.fail_after(WAIT):
            await _listening(master, 4, received)
        assert through_paho == ["t/after", "t/logged"]
    assert received == [big, b"after", b"logged", b"last"]


async def test_a_vehicle_writes_its_visualizations_and_states_itself(broker: Broker) -> None:
    config = VehicleConfig(broker=broker.url, manufacturer="m", serial_number="s")
    async with (
        galileo.connect("sim://") as robot,
        aiomqtt.Client("127.0.0.1", broker.port, identifier="master") as master,
        anyio.create_task_group() as group,
    ):
        await master.subscribe("uagv/v2/m/s/visualization")
        await master.subscribe("uagv/v2/m/s/state")
        vehicle = Vehicle(robot, config)
        group.start_soon(vehicle.session.run)  # the session alone: nothing publishes by itself
        received: list[bytes] = []
        with anyio.fail_after(WAIT):
            await _listening(master, 1, received)  # the state on connect, the factsheet before
        client = vehicle.session._client
        assert client is not None
        through_paho = await _publishes_through_paho(client)
        message = Visualization(headerId=1, timestamp="2026-11-28T16:00:00.000Z",
                                version="2.0.0", manufacturer="m",
                                serialNumber="s")  # fmt: skip
        assert vehicle.session.publish_now("visualization", message)
        state = vehicle.state()
        assert await vehicle.publish("state", state)
        received.clear()
        with anyio.fail_after(WAIT):
            await _listening(master, 2, received)
        assert through_paho == []
        assert received == [message.model_dump_json(exclude_none=True).encode(),
                            state.model_dump_json(exclude_none=True).encode()]  # fmt: skip
        group.cancel_scope.cancel()
