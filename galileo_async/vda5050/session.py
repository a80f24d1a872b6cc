"""Session: one vehicle's MQTT connection (aiomqtt): last will, reconnect with back-off."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import ssl
import threading
import time
from collections.abc import Awaitable, Callable
from typing import Any

import aiomqtt
import anyio
from paho.mqtt.client import MQTTMessageInfo  # aiomqtt's MQTT client
from pydantic import BaseModel

from ..errors import DuplicateVehicle, InvalidArgument
from .config import BrokerAddress, VehicleConfig
from .models import Connection, ConnectionState

__all__ = [
    "CONNECT_TIMEOUT",
    "LAST_WORDS_TIMEOUT",
    "MQTT_LOGGER",
    "OFFLINE_TIMEOUT",
    "PROBE_WAIT",
    "YOUNG_SESSION",
    "PacketWriter",
    "Session",
    "tls_context",
    "write_at_once",
]

_log = logging.getLogger(__name__)
#: The MQTT client's own log lines (socket and TLS errors) go here.
MQTT_LOGGER = f"{__package__}.mqtt"
# The client logs every packet at DEBUG: only on request (setLevel on this logger).
logging.getLogger(MQTT_LOGGER).setLevel(logging.INFO)

#: Seconds a clean stop may spend saying OFFLINE and disconnecting.
OFFLINE_TIMEOUT = 3.0
#: Seconds a clean stop may spend on its last words before OFFLINE (the vehicle's shut_down).
LAST_WORDS_TIMEOUT = 20.0
#: Seconds a connection attempt to the broker may take.
CONNECT_TIMEOUT = 6.0
#: Seconds after connecting within which a lost session is checked for a duplicate vehicle;
#: longer than an established vehicle takes to reconnect (reconnect_initial, default 0.5 s).
YOUNG_SESSION = 2.0
#: Seconds the duplicate check waits for another vehicle's retained ONLINE.
PROBE_WAIT = 1.0
#: Topics the vehicle subscribes to (master control → vehicle).
SUBSCRIBED = ("order", "instantActions")


def _payload(message: aiomqtt.Message) -> bytes:
    payload = message.payload
    if isinstance(payload, (bytes, bytearray)):
        return bytes(payload)
    return str(payload).encode()


def write_at_once(client: aiomqtt.Client) -> bool:
    """Make ``client`` write each packet in the call that queues it; False if it cannot.

    aiomqtt writes through a writer callback that a thread-safe call registers on the
    loop: per message a self-pipe wake-up, two epoll changes, a poll and an awaited
    confirmation. In this thread the packet goes to the socket at once instead (QoS 0:
    publish() then returns without waiting); what the socket does not take, and packets
    queued by another thread (the connect), still go through the writer callback. Call it
    on the loop's thread, before the client connects.
    """
    # aiomqtt's paho-mqtt client; looked for by what it does, not by name.
    mqtt: Any = getattr(client, "_client", None)
    if not all(hasattr(mqtt, name) for name in ("loop_write", "want_write")):
        return False
    if getattr(mqtt, "on_socket_register_write", None) is None:
        return False
    register = mqtt.on_socket_register_write
    owner = threading.get_ident()
    writing = False

    def register_write(mqtt: Any, userdata: Any, sock: Any) -> None:
        nonlocal writing
        if threading.get_ident() == owner and not writing:
            writing = True
            try:
                mqtt.loop_write()
            except Exception:  # the writer callback meets it again and reports it
                pass
            else:
                if not mqtt.want_write():
                    return
            finally:
                writing = False
        register(mqtt, userdata, sock)

    mqtt.on_socket_register_write = register_write
    return True


#: The first byte of a PUBLISH packet at QoS 0, not retained, not a duplicate (MQTT 3.1.1 §3.3.1).
_PUBLISH_QOS0 = 0x30
#: The protocol level of MQTT 5 (paho-mqtt's MQTTv5), whose PUBLISH carries properties.
_MQTT5 = 5


def _remaining_length(length: int) -> bytes:
    """MQTT's variable-length encoding of ``length`` (MQTT 3.1.1 §2.2.3)."""
    encoded = bytearray()
    while True:
        length, digit = length >> 7, length & 0x7F
        encoded.append(digit | 0x80 if length else digit)
        if not length:
            return bytes(encoded)


class PacketWriter:
    """QoS 0 PUBLISH packets built here and written to the client's socket in one call.

    The same bytes paho-mqtt's ``publish`` would write, without its per-message Python
    path (message info, packet queue, writer callbacks, the on_publish callback); the
    topic's part of the packet is made once. Whatever this path cannot take (packets
    already queued, a socket that does not take everything, per-packet DEBUG logging on,
    a client that is not the expected paho-mqtt one) goes through paho-mqtt as before, so
    the order of packets and the keep-alive bookkeeping stay paho-mqtt's.
    """

    def __init__(self, client: aiomqtt.Client) -> None:
        # aiomqtt's paho-mqtt client; its lower layer, looked for by what it does.
        mqtt: Any = getattr(client, "_client", None)
        names = ("_sock", "_out_packet", "_packet_queue", "_mid_generate", "_protocol",
                 "_last_msg_out", "_msgtime_mutex", "_logger", "on_log", "publish")  # fmt: skip
        self._mqtt: Any = mqtt
        self._direct = all(hasattr(mqtt, name) for name in names)
        self._prefixes: dict[str, bytes] = {}

    def _prefix(self, topic: str) -> bytes:
        """The topic name (and MQTT 5's empty properties) of a PUBLISH packet."""
        prefix = self._prefixes.get(topic)
        if prefix is None:
            name = topic.encode()
            prefix = len(name).to_bytes(2, "big") + name
            if self._mqtt._protocol == _MQTT5:
                prefix += b"\x00"
            self._prefixes[topic] = prefix
        return prefix

    def publish(self, topic: str, payload: bytes) -> MQTTMessageInfo | None:
        """Write ``payload`` on ``topic`` at QoS 0; paho-mqtt's message info, or None.

        None: written whole to the socket. Otherwise the info of what paho-mqtt queued
        (its ``rc`` not 0 when it could not).
        """
        mqtt = self._mqtt
        sock = mqtt._sock
        if (
            not self._direct or sock is None or mqtt._out_packet or mqtt.on_log is not None
            or (mqtt._logger is not None and mqtt._logger.isEnabledFor(logging.DEBUG))
        ):  # fmt: skip
            info: MQTTMessageInfo = mqtt.publish(topic, payload, 0, False)
            return info
        body = self._prefix(topic)
        packet = b"".join(
            (bytes((_PUBLISH_QOS0,)), _remaining_length(len(body) + len(payload)), body, payload)
        )
        try:
            sent = sock.send(packet)
        except (BlockingIOError, ssl.SSLWantReadError, ssl.SSLWantWriteError):
            sent = 0
        except OSError:
            sent = 0  # paho-mqtt meets the error again on its write and handles it
        if sent == len(packet):
            with mqtt._msgtime_mutex:
                mqtt._last_msg_out = time.monotonic()  # paho-mqtt's clock: no ping needed yet
            return None
        return self._queue(packet[sent:])

    def _queue(self, rest: bytes) -> MQTTMessageInfo:
        """Hand the unsent end of a packet to paho-mqtt's queue (its writer callback)."""
        mqtt = self._mqtt
        info = MQTTMessageInfo(mqtt._mid_generate())
        info.rc = mqtt._packet_queue(_PUBLISH_QOS0, rest, info.mid, 0, info)
        return info


def _json(message: BaseModel) -> bytes:
    """``message`` as model_dump_json(exclude_none=True) makes it, UTF-8."""
    return message.__pydantic_serializer__.to_json(message, exclude_none=True)


def _no_key_password() -> str:
    # Without a callback OpenSSL would prompt on the terminal for an encrypted key's password.
    raise InvalidArgument("the TLS key is encrypted; give an unencrypted key (PEM)")


def tls_context(config: VehicleConfig) -> ssl.SSLContext | None:
    """The TLS context of the mqtts:// brokers (CA, client certificate); InvalidArgument."""
    if not any(address.tls for address in config.addresses):
        return None
    try:
        context = ssl.create_default_context(cafile=config.tls_ca_file)
        if config.tls_cert_file is not None:
            context.load_cert_chain(
                config.tls_cert_file, config.tls_key_file, password=_no_key_password
            )
    except (OSError, ssl.SSLError) as exc:
        files = [config.tls_ca_file, config.tls_cert_file, config.tls_key_file]
        named = ", ".join(path for path in files if path is not None)
        raise InvalidArgument(f"cannot load the TLS files ({named}): {exc}") from None
    return context


class _Recorder(logging.Logger):
    """The MQTT client's logger: forwards to MQTT_LOGGER and keeps the last error line."""

    def __init__(self) -> None:
        super().__init__(MQTT_LOGGER)  # level NOTSET: MQTT_LOGGER's level applies
        self.parent = logging.getLogger(MQTT_LOGGER)
        self.last_error: str | None = None

    def handle(self, record: logging.LogRecord) -> None:
        if record.levelno >= logging.ERROR:
            self.last_error = record.getMessage()
        super().handle(record)


def _hint(reason: str) -> str:
    text = reason.lower()
    if "certificate required" in text or "certificate_required" in text:
        return " (the broker requires a client certificate: tls_cert_file, --tls-cert)"
    if "not authorized" in text or "bad user name or password" in text:
        return " (check the user name and the password)"
    return ""


class Session:
    """Keeps a vehicle on the broker until cancelled: ONLINE on connect, OFFLINE on a stop.

    ``before_offline``: awaited on a clean stop while still connected, before OFFLINE
    (shielded, at most LAST_WORDS_TIMEOUT s): the vehicle's last state.
    """

    def __init__(
        self,
        config: VehicleConfig,
        connection: Callable[[ConnectionState], Connection],
        on_connect: Callable[[], Awaitable[None]],
        on_message: Callable[[str, bytes], None],
        before_offline: Callable[[], Awaitable[object]] | None = None,
    ) -> None:
        self.config = config
        self._connection = connection
        self._on_connect = on_connect
        self._on_message = on_message
        self._before_offline = before_offline
        #: True once OFFLINE went to the broker (a clean stop while connected).
        self.offline_published = False
        self._tls = tls_context(config)
        self._addresses = config.addresses
        #: The index in config.addresses of the broker tried or connected now.
        self._turn = 0
        #: Why the last connection attempt failed; None once connected.
        self.last_error: str | None = None
        self._client: aiomqtt.Client | None = None
        #: The connected client's QoS 0 writer.
        self._writer: PacketWriter | None = None
        self._online = anyio.Event()
        self._offline = anyio.Event()
        self._offline.set()
        #: The ONLINE message of the current (or last) session, as published.
        self._online_sent = b""

    @property
    def address(self) -> BrokerAddress:
        """The broker the session is connected to, or tries next."""
        return self._addresses[self._turn]

    def _next_broker(self) -> None:
        """Move to the next broker of the config (round robin); the same one when alone."""
        if len(self._addresses) > 1:
            self._turn = (self._turn + 1) % len(self._addresses)
            address = self.address
            _log.info("%s: moving to the broker %s:%d", self.config.serial_number,
                      address.host, address.port)  # fmt: skip

    def _tls_for(self, address: BrokerAddress) -> ssl.SSLContext | None:
        return self._tls if address.tls else None

    @property
    def connected(self) -> bool:
        """True while the session is up."""
        return self._client is not None

    async def wait_online(self) -> None:
        """Return once the session is up (at once if it is)."""
        while self._client is None:
            await self._online.wait()

    async def wait_offline(self) -> None:
        """Return once the session is down (at once if it is)."""
        await self._offline.wait()

    async def publish(
        self, topic: str, message: BaseModel, *, qos: int = 0, retain: bool = False
    ) -> bool:
        """Publish ``message`` on the vehicle's ``topic``; False when the broker is away."""
        return await self._publish_on(self._client, topic, message, qos=qos, retain=retain)

    def publish_now(self, topic: str, message: BaseModel) -> bool:
        """Publish ``message`` at QoS 0 without waiting; False when the broker is away.

        What the socket does not take at once goes out with the client's writer callback.
        """
        writer = self._writer
        if writer is None:
            return False
        info = writer.publish(self.config.topic(topic), _json(message))
        if info is not None and info.rc != 0:
            _log.debug("%s: publish %s failed: %s", self.config.serial_number, topic, info.rc)
            return False
        return True

    async def _publish_on(
        self, client: aiomqtt.Client | None, topic: str, message: BaseModel, *, qos: int,
        retain: bool,
    ) -> bool:  # fmt: skip
        if client is None:
            return False
        writer = self._writer
        if qos == 0 and not retain and writer is not None and client is self._client:
            return await self._publish_qos0(client, writer, topic, message)
        payload = message.model_dump_json(exclude_none=True)
        try:
            await client.publish(self.config.topic(topic), payload, qos=qos, retain=retain)
        except aiomqtt.MqttError as exc:
            _log.debug("%s: publish %s failed: %s", self.config.serial_number, topic, exc)
            return False
        return True

    async def _publish_qos0(
        self, client: aiomqtt.Client, writer: PacketWriter, topic: str, message: BaseModel
    ) -> bool:
        """As aiomqtt's publish at QoS 0: returns once the packet is written, False if not."""
        info = writer.publish(self.config.topic(topic), _json(message))
        if info is None:
            return True
        failure: object = info.rc
        if info.rc == 0 and not info.is_published():
            # aiomqtt's wait for its writer callback's on_publish, at most its timeout.
            pending: dict[int, asyncio.Event] = client._pending_publishes
            written = pending[info.mid] = asyncio.Event()
            try:
                with anyio.move_on_after(client.timeout):
                    await written.wait()
            finally:
                pending.pop(info.mid, None)
            failure = 0 if info.is_published() else "not written in time"
        if failure != 0:
            _log.debug("%s: publish %s failed: %s", self.config.serial_number, topic, failure)
            return False
        return True

    def _password(self) -> str | None:
        password = self.address.password
        return None if password is None else password.get_secret_value()

    def _client_for(self, log: logging.Logger) -> aiomqtt.Client:
        address = self.address
        password = self._password()
        will = aiomqtt.Will(
            self.config.topic("connection"),
            self._connection("CONNECTIONBROKEN").model_dump_json(exclude_none=True),
            qos=1, retain=True,
        )  # fmt: skip
        client = aiomqtt.Client(
            address.host, address.port, username=address.username, password=password,
            identifier=f"{self.config.manufacturer}-{self.config.serial_number}", will=will,
            keepalive=self.config.keepalive, tls_context=self._tls_for(address),
            timeout=CONNECT_TIMEOUT,
            logger=log,
        )  # fmt: skip
        write_at_once(client)
        return client

    async def run(self) -> None:
        """Connect, serve, reconnect with exponential back-off; runs until cancelled.

        DuplicateVehicle when the session is lost within YOUNG_SESSION s of connecting and
        another vehicle with this identity is ONLINE meanwhile: the broker gives a client
        identifier to the newest connection, and that one took it back, so it was there
        first and keeps the broker. A failed connect or a lost session moves to the next
        broker of the config (round robin) after the back-off delay.
        """
        delay = self.config.reconnect_initial
        while True:
            log = _Recorder()
            client = self._client_for(log)
            # aiomqtt connects in a thread: a cancelled connect would leave a socket nobody
            # closes (and the broker would send the last will), so a stop waits for it.
            connecting = asyncio.ensure_future(client.__aenter__())
            try:
                await asyncio.shield(connecting)
            except aiomqtt.MqttError as exc:
                self._failed(f"{exc} ({log.last_error})" if log.last_error else str(exc), delay)
                self._next_broker()
            except asyncio.CancelledError:
                await self._abandon(client, connecting)
                raise
            else:
                delay = self.config.reconnect_initial
                self.last_error = None
                connected_at = anyio.current_time()
                await self._serve(client)
                age = anyio.current_time() - connected_at
                if age < YOUNG_SESSION and await self._another_online():
                    raise self._duplicate(age)
                self._next_broker()
            await anyio.sleep(delay)
            delay = min(delay * 2, self.config.reconnect_max)

    def _duplicate(self, age: float) -> DuplicateVehicle:
        config = self.config
        return DuplicateVehicle(
            f"another vehicle {config.manufacturer}/{config.serial_number} is connected to "
            f"the broker {self.address.host}:{self.address.port}: it took the session "
            f"back {age:.1f} s after this one connected; two vehicles must not share a "
            "manufacturer and serial number"
        )

    async def _another_online(self) -> bool:
        """True when the retained connection message is an ONLINE this session did not send."""
        address = self.address
        client = aiomqtt.Client(
            address.host, address.port, username=address.username, password=self._password(),
            identifier=f"{self.config.manufacturer}-{self.config.serial_number}-check",
            tls_context=self._tls_for(address), timeout=CONNECT_TIMEOUT, logger=_Recorder(),
        )  # fmt: skip
        with contextlib.suppress(aiomqtt.MqttError):
            async with client:
                await client.subscribe(self.config.topic("connection"), qos=1)
                with anyio.move_on_after(PROBE_WAIT):
                    async for message in client.messages:
                        payload = _payload(message)
                        if payload != self._online_sent and b'"ONLINE"' in payload:
                            return True
        return False

    def _failed(self, reason: str, delay: float) -> None:
        # A new reason is a warning (shown by `galileo vda5050`); the same one again is not.
        level = logging.INFO if reason == self.last_error else logging.WARNING
        self.last_error = reason
        _log.log(level, "%s: cannot connect to the broker %s:%d: %s%s; retry in %.1f s",
                 self.config.serial_number, self.address.host, self.address.port,
                 reason, _hint(reason), delay)  # fmt: skip

    async def _abandon(self, client: aiomqtt.Client, connecting: asyncio.Future[Any]) -> None:
        """Stopped while connecting: let the connect end (bounded), then leave cleanly."""
        with anyio.CancelScope(shield=True):
            with anyio.move_on_after(CONNECT_TIMEOUT):
                await asyncio.wait([connecting])
            if not connecting.done():
                connecting.cancel()
                await asyncio.wait([connecting])
            if not connecting.cancelled() and connecting.exception() is None:
                await self._leave(client, clean_stop=True)

    async def _serve(self, client: aiomqtt.Client) -> None:
        clean_stop = False
        try:
            for topic in SUBSCRIBED:
                await client.subscribe(self.config.topic(topic), qos=0)
            self._client = client
            self._writer = PacketWriter(client)
            self._offline = anyio.Event()
            self._online.set()
            online = self._connection("ONLINE")
            self._online_sent = online.model_dump_json(exclude_none=True).encode()
            await self.publish("connection", online, qos=1, retain=True)
            await self._on_connect()
            async for message in client.messages:
                self._on_message(str(message.topic).rsplit("/", 1)[-1], _payload(message))
        except aiomqtt.MqttError as exc:
            _log.info("%s: broker connection lost: %s", self.config.serial_number, exc)
        except anyio.get_cancelled_exc_class():
            clean_stop = True
            raise
        finally:
            await self._leave(client, clean_stop=clean_stop)

    async def _leave(self, client: aiomqtt.Client, *, clean_stop: bool) -> None:
        """End a session: last words and OFFLINE on a clean stop, then disconnect; shielded."""
        if clean_stop and self._before_offline is not None and self._client is client:
            with anyio.move_on_after(LAST_WORDS_TIMEOUT, shield=True):
                await self._before_offline()
        with anyio.CancelScope(shield=True), anyio.move_on_after(OFFLINE_TIMEOUT):
            self._client = None
            self._writer = None
            self._online = anyio.Event()
            self._offline.set()
            if clean_stop:
                offline = self._connection("OFFLINE")
                published = await self._publish_on(
                    client, "connection", offline, qos=1, retain=True
                )
                self.offline_published = self.offline_published or published
            with contextlib.suppress(aiomqtt.MqttError):
                await client.__aexit__(None, None, None)
