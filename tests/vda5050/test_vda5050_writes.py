"""The vehicle's MQTT client writes each packet in the call that queues it (session.py)."""

from __future__ import annotations

import logging
import socket

import aiomqtt
import anyio

from galileo_async.vda5050 import VehicleConfig
from galileo_async.vda5050.models import Connection, ConnectionState
from galileo_async.vda5050.session import Session, write_at_once
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
