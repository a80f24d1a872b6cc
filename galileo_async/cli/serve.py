"""``galileo sim`` (serve the simulator), ``galileo ports`` and ``galileo discover``."""

from __future__ import annotations

import contextlib
import errno
import json
import logging
import shlex
import socket
import ssl
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Annotated, Any
from urllib.parse import urlencode

import typer

from ..errors import GalileoConnectionError, InvalidArgument
from ..options import DEFAULT_WS_PORT
from .runner import ExitCode, err_console, fail, out_console, run, settings_of
from .signals import stop_requested

__all__ = ["discover", "ports", "replay", "sim"]

#: Where ``galileo sim`` listens by default: loopback only.
DEFAULT_TCP = "127.0.0.1:7000"


def _host_port(text: str, option: str = "--tcp") -> tuple[str, int]:
    host, sep, port = text.rpartition(":")
    if not sep or not port.isdigit():
        raise InvalidArgument(f"{option} wants HOST:PORT, got {text!r}")
    if int(port) > 65535:
        raise InvalidArgument(f"{option}: port {port} is out of range 0..65535")
    return host.strip("[]") or "127.0.0.1", int(port)


def _udp_address(text: str) -> tuple[str, int]:
    """``--udp``: a PORT (on loopback) or HOST:PORT."""
    return _host_port(f"127.0.0.1:{text}" if text.isdigit() else text, "--udp")


@contextlib.contextmanager
def _listening(where: str, option: str) -> Iterator[None]:
    """Turn a failure to listen on ``where`` into one error that names it, with a hint."""
    try:
        yield
    except OSError as exc:
        if exc.errno == errno.EADDRINUSE:
            why = f"{where} is already in use (another `galileo sim`?): pick another {option}"
            raise GalileoConnectionError(f"{why}, or port 0 for a free one") from exc
        if isinstance(exc, socket.gaierror):
            unknown = f"{option} {where}: unknown host ({exc.strerror})"
            raise GalileoConnectionError(unknown) from exc
        raise GalileoConnectionError(f"cannot listen on {where}: {exc.strerror or exc}") from exc


def _url(scheme: str, address: tuple[str, int]) -> str:
    host, port = address[:2]
    return f"{scheme}://{f'[{host}]' if ':' in host else host}:{port}"


def _tls_context(cert: Path | None, key: Path | None, http: str | None) -> ssl.SSLContext | None:
    """The server context of --tls-cert/--tls-key (both or neither, with --http only)."""
    if cert is None and key is None:
        return None
    if cert is None or key is None or http is None:
        fail("--tls-cert and --tls-key go together, with --http", ExitCode.USAGE)
    context = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
    try:
        context.load_cert_chain(cert, key)
    except (OSError, ssl.SSLError) as exc:
        fail(f"cannot load --tls-cert/--tls-key: {exc}", ExitCode.USAGE)
    return context


def sim(
    ctx: typer.Context,
    tcp: Annotated[
        str | None,
        typer.Option(help=f"Serve on HOST:PORT (default {DEFAULT_TCP}; port 0 picks one)."),
    ] = None,
    pty: Annotated[bool, typer.Option("--pty", help="Serve on a pseudo-terminal.")] = False,
    udp: Annotated[
        str | None,
        typer.Option(
            help="Also serve the robot's UDP port on PORT or HOST:PORT (loopback by default; "
            "alone, UDP only)."
        ),
    ] = None,
    http: Annotated[
        str | None,
        typer.Option(
            help="Also serve the HTTP API on PORT or HOST:PORT (loopback by default) and its "
            "WebSocket on the next port (alone, HTTP only)."
        ),
    ] = None,
    ws_port: Annotated[
        int | None, typer.Option("--ws-port", help="The WebSocket's port (default: HTTP + 1).")
    ] = None,
    tls_cert: Annotated[
        Path | None,
        typer.Option(help="Serve --http over TLS (https://, wss://) with this PEM certificate."),
    ] = None,
    tls_key: Annotated[Path | None, typer.Option(help="The PEM key of --tls-cert.")] = None,
    udp_layout: Annotated[
        str, typer.Option(help="UDP status layout: udp_v2 (48 bytes) or udp_v1 (44).")
    ] = "udp_v2",
    speed: Annotated[float, typer.Option(min=0.01, help="Time scale (20 = 20x).")] = 1.0,
    layout: Annotated[str, typer.Option(help="Status layout: v2, v2_truncated, v1, v1_charge.")] = (
        "v2"
    ),
    firmware: Annotated[str, typer.Option(help="real (default) or document.")] = "real",
    seed: Annotated[int, typer.Option(help="Random seed (faults, planner).")] = 0,
    options: Annotated[
        str | None,
        typer.Option("--options", help="More simulator options, as a sim:// query: drop=0.1&…"),
    ] = None,
) -> None:
    """Serve a simulated robot until Ctrl-C: over TCP (loopback default), a pty and/or UDP."""
    settings = settings_of(ctx)
    if tcp is not None and pty:
        fail("choose --tcp or --pty, not both", ExitCode.USAGE)
    tls = _tls_context(tls_cert, tls_key, http)
    from ..sim import Simulator

    query = f"speed={speed}&layout={layout}&udp_layout={udp_layout}&firmware={firmware}&seed={seed}"
    if options:
        query += "&" + options.lstrip("?&")

    async def main() -> int:
        simulator = Simulator.from_url(f"sim://?{query}")
        server: Any = None
        try:
            served: list[tuple[str, str]] = []  # (where, its status layout)
            if pty:
                served.append((simulator.open_pty(), layout))
            elif tcp is not None or (udp is None and http is None):
                host, port = _host_port(tcp or DEFAULT_TCP)
                with _listening(f"{host}:{port}", "--tcp"):
                    server = await simulator.serve_tcp(host, port)
                served.append((_url("socket", server.sockets[0].getsockname()), layout))
            if udp is not None:
                address = _udp_address(udp)
                with _listening("{}:{}".format(*address), "--udp"):
                    face = await simulator.serve_udp(*address)
                served.append((_url("udp", face.address), udp_layout))
            if http is not None:
                host, port = _udp_address(http)
                ws = ws_port if ws_port is not None or port == 0 else port + 1
                with _listening(f"{host}:{port} (WebSocket: {ws})", "--http"):
                    web = await simulator.serve_http(host, port, ws_port=ws_port, ssl_context=tls)
                where = _url("https" if tls else "http", web.address)
                if web.ws_address[1] != DEFAULT_WS_PORT:  # where clients look unless told
                    where += f"?ws_port={web.ws_address[1]}"
                served.append((where, "JSON"))
            console = out_console()
            for where, _ in served:
                console.print(where, markup=False)
            console.file.flush()
            places = ", ".join(f"{where} ({what})" for where, what in served)
            # A certificate of a CA the system does not trust needs the client's ca_file=.
            trust = "; https:// clients trust its CA with ca_file=CA.pem" if tls else ""
            err_console().print(
                f"simulator (firmware {firmware}, speed {speed:g}x) on {places}{trust}; "
                f"connect with: galileo --port {shlex.quote(served[0][0])} status · Ctrl-C stops",
                markup=False,
            )
            with stop_requested() as stop:
                await stop.wait()
        finally:
            if server is not None:
                server.close()
            await simulator.close()
        return 0

    run(settings, main, interrupted=ExitCode.OK)


def replay(
    ctx: typer.Context,
    capture: Annotated[
        Path,
        typer.Argument(help="A recording made by galileo record (or MCAP).", dir_okay=False),
    ],
    tcp: Annotated[
        str | None,
        typer.Option(help=f"Serve on HOST:PORT (default {DEFAULT_TCP}; port 0 picks one)."),
    ] = None,
    pty: Annotated[bool, typer.Option("--pty", help="Serve on a pseudo-terminal.")] = False,
    speed: Annotated[float, typer.Option(min=0.01, help="Pace (2 = twice as fast).")] = 1.0,
    robot: Annotated[
        str | None, typer.Option("--robot", help="The robot of an MCAP fleet recording.")
    ] = None,
) -> None:
    """Serve a recording as a robot until Ctrl-C: each connection gets its bytes at their
    recorded pace from the start; the commands it sends are printed on stderr, not acted on."""
    settings = settings_of(ctx)
    if tcp is not None and pty:
        fail("choose --tcp or --pty, not both", ExitCode.USAGE)
    from ..sim import Simulator

    query: dict[str, object] = {"speed": speed, "replay": str(capture)}
    if robot is not None:
        query["robot"] = robot
    try:
        simulator = Simulator.from_url("sim://?" + urlencode(query))
    except InvalidArgument as exc:
        fail(str(exc), ExitCode.USAGE)

    async def main() -> int:
        server: Any = None
        commands = logging.getLogger("galileo_async.sim.replay")
        handler = logging.StreamHandler(sys.stderr)
        handler.setFormatter(logging.Formatter("%(message)s"))
        commands.addHandler(handler)
        level = commands.level
        commands.setLevel(logging.INFO)
        try:
            if pty:
                where = simulator.open_pty()
            else:
                host, port = _host_port(tcp or DEFAULT_TCP)
                server = await simulator.serve_tcp(host, port)
                where = _url("socket", server.sockets[0].getsockname())
            console = out_console()
            console.print(where, markup=False)
            console.file.flush()
            err_console().print(
                f"replaying {capture} (speed {speed:g}x) on {where}; connect with: "
                f"galileo --port {where} monitor · Ctrl-C stops",
                markup=False,
            )
            with stop_requested() as stop:
                await stop.wait()
        finally:
            commands.removeHandler(handler)
            commands.setLevel(level)
            if server is not None:
                server.close()
            await simulator.close()
        return 0

    run(settings, main, interrupted=ExitCode.OK)


def ports(
    ctx: typer.Context,
    json_output: Annotated[bool, typer.Option("--json", help="JSON output.")] = False,
) -> None:
    """List serial ports (the robot is usually /dev/galileo or /dev/ttyUSB*)."""
    from serial.tools import list_ports

    found = sorted(list_ports.comports(), key=lambda port: str(port.device))
    rows = [{"device": p.device, "description": p.description, "hwid": p.hwid} for p in found]
    if settings_of(ctx).json or json_output:
        out_console().print(json.dumps(rows), markup=False)
        return
    if not rows:
        err_console().print("no serial ports found")
        return
    from rich.table import Table

    table = Table("device", "description", "hwid", box=None)
    for row in rows:
        table.add_row(row["device"], row["description"], row["hwid"])
    out_console().print(table)


def discover(
    ctx: typer.Context,
    timeout: Annotated[float, typer.Option("--timeout", "-t", help="Seconds to listen.")] = 1.5,
    port: Annotated[
        int, typer.Option("--udp-port", min=0, max=65535, help="UDP port robots announce on.")
    ] = 22002,
    bind: Annotated[str, typer.Option("--bind", help="Local address to listen on.")] = "",
    json_output: Annotated[bool, typer.Option("--json", help="JSON output.")] = False,
) -> None:
    """List robots announcing themselves on the LAN, with the URLs they offer (http://, ros://)."""
    from ..ros.discovery import discover as listen

    settings = settings_of(ctx)

    async def main() -> int:
        robots = await listen(timeout, bind=bind, port=port)
        rows: list[dict[str, Any]] = [
            {"id": r.id, "url": r.url, "urls": list(r.urls), "mac": r.mac, "version": r.version}
            for r in robots
        ]
        if settings.json or json_output:
            # The announced port (3546, HTTP, on newer firmware) is not the master's.
            ports = [{"announced_port": robot.port} for robot in robots]
            listed = [{**row, **port} for row, port in zip(rows, ports, strict=True)]
            out_console().print(json.dumps(listed), markup=False)
            return int(ExitCode.OK)
        if not rows:
            err_console().print(f"no robot announced itself on UDP {port} within {timeout} s")
            return int(ExitCode.OK)
        from rich.table import Table

        table = Table("id", "urls", "mac", "version", box=None)
        for row in rows:
            urls = "\n".join(row["urls"])  # one a line: a URL is never wrapped
            table.add_row(
                str(row["id"]), urls, *(str(row[key] or "-") for key in ("mac", "version"))
            )
        out_console().print(table)
        return int(ExitCode.OK)

    run(settings, main)
