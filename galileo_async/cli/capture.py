"""``record`` raw bytes from a link (with timestamps) and ``decode`` captures into JSON lines.

The recording format is described in galileo_async/sim/replay.py (which replays it).
``decode`` reads recordings and plain raw byte dumps (anything without the magic) alike,
and MCAP recordings (mcap_cmd.py), told by their first bytes.
"""

from __future__ import annotations

import asyncio
import io
import json
import sys
from dataclasses import asdict
from pathlib import Path
from typing import IO, Annotated, Any

import anyio
import typer

from ..protocol import StatusDecoder
from ..sim.mcap_read import MCAP_MAGIC, is_mcap
from ..sim.replay import MAGIC, RECORD, iter_capture
from . import connectors
from .mcap_cmd import decode_mcap, record_mcap, wants_mcap
from .render import status_dict
from .runner import (
    ExitCode,
    err_console,
    fail,
    out_console,
    print_error,
    robot_url,
    run,
    settings_of,
)
from .signals import stop_requested

__all__ = ["MAGIC", "RECORD", "decode", "iter_capture", "record", "stop_requested"]


def decode(
    ctx: typer.Context,
    source: Annotated[str, typer.Argument(help="Capture file (raw bytes or a recording), or -.")],
    summary_only: Annotated[
        bool, typer.Option("--summary-only", "-s", help="Print only the summary.")
    ] = False,
    json_output: Annotated[bool, typer.Option("--json", help="Summary as JSON too.")] = False,
    raw: Annotated[
        bool, typer.Option("--raw", help="Every digit of the floats (default: rounded as shown).")
    ] = False,
    robot: Annotated[
        str | None, typer.Option("--robot", help="The robot of an MCAP fleet recording.")
    ] = None,
) -> None:
    """Decode captured bytes: one JSON line per status, then a summary of the stream."""
    settings = settings_of(ctx)
    as_json = settings.json or json_output
    try:
        handle: IO[bytes] = (
            sys.stdin.buffer if source == "-" else Path(source).open("rb")  # noqa: SIM115
        )
    except OSError as exc:
        fail(f"cannot read {source}: {exc.strerror or exc}")
    head, handle = _peek(handle, len(MCAP_MAGIC))
    if is_mcap(head):
        with handle:
            decode_mcap(
                handle, source, settings, robot=robot, summary_only=summary_only,
                as_json=as_json, raw=raw,
            )  # fmt: skip
    if robot is not None:
        handle.close()
        fail(f"--robot picks a robot of an MCAP recording; {source} is not one", ExitCode.USAGE)
    decoder = StatusDecoder(settings.layout)
    out = sys.stdout
    total = chunks = 0
    first: float | None = None
    last: float | None = None
    recording = False
    with handle:
        for seconds, data in iter_capture(handle):
            chunks += 1
            total += len(data)
            if seconds is not None:
                recording = True
                first = seconds if first is None else first
                last = seconds
            for status in decoder.feed(data):
                if summary_only:
                    continue
                line: dict[str, Any] = {} if seconds is None else {"t": round(seconds, 4)}
                line |= status.model_dump(mode="json") if raw else status_dict(status)
                out.write(json.dumps(line) + "\n")
    stats = asdict(decoder.stats)
    summary: dict[str, Any] = {
        "format": "recording" if recording else "raw",
        "bytes": total,
        "chunks": chunks,
        **stats,
        "layout": None if decoder.stats.layout is None else decoder.stats.layout.value,
        "bytes_pending": decoder.buffered,
        "duration": None if first is None or last is None else round(last - first, 3),
    }
    if as_json:
        out.write(json.dumps({"summary": summary}) + "\n")
    else:
        text = ", ".join(f"{key} {value}" for key, value in summary.items())
        err_console().print(f"summary: {text}", markup=False)
    out.flush()
    raise typer.Exit(0 if decoder.stats.frames or not total else int(ExitCode.ERROR))


def record(
    ctx: typer.Context,
    path: Annotated[Path, typer.Argument(help="File to write.", dir_okay=False)],
    duration: Annotated[
        float | None, typer.Option(min=0.01, help="Stop after seconds (default: Ctrl-C).")
    ] = None,
    raw: Annotated[bool, typer.Option("--raw", help="Plain bytes, no timestamps.")] = False,
    mcap: Annotated[
        bool,
        typer.Option(
            "--mcap", help="Write MCAP: raw bytes, statuses and events (also for FILE.mcap)."
        ),
    ] = False,
) -> None:
    """Capture the raw byte stream from --port into a file (a recording, --raw bytes, or
    MCAP with --mcap or a FILE ending in .mcap)."""
    settings = settings_of(ctx)
    if wants_mcap(path, mcap):
        if raw:
            fail("--raw and MCAP (--mcap, FILE.mcap) exclude each other", ExitCode.USAGE)
        record_mcap(settings, path, duration)
    url = robot_url(settings)

    async def main() -> int:
        chunks = connectors.ChunkQueue(connectors.RECORD_QUEUE_CHUNKS)
        written = count = 0
        closed_after: float | None = None
        async with (
            connectors.open_raw(url, chunks) as started,
            await anyio.open_file(path, "wb") as file,
        ):
            if not raw:
                await file.write(MAGIC)
            with stop_requested() as stop:
                async with anyio.create_task_group() as group:
                    group.start_soon(_cancel_on, stop, group.cancel_scope)
                    with anyio.move_on_after(duration):
                        while (item := await chunks.get()) is not None:
                            seconds, data = item[0] - started, item[1]
                            header = b"" if raw else RECORD.pack(seconds, len(data))
                            await file.write(header + data)
                            written += len(data)
                            count += 1
                        closed_after = asyncio.get_running_loop().time() - started
                    group.cancel_scope.cancel()
        out_console().print(f"recorded {written} bytes in {count} chunks to {path}")
        code = ExitCode.OK
        if chunks.dropped_chunks:
            print_error(
                f"the file writer fell behind: dropped {chunks.dropped_chunks} chunks "
                f"({chunks.dropped_bytes} bytes); the recording has gaps"
            )
            code = ExitCode.ERROR
        if closed_after is not None:  # the link ended before Ctrl-C or --duration
            why = f" ({chunks.reason})" if chunks.reason else ""
            wanted = "" if duration is None else f", before the requested {duration:g} s"
            print_error(f"the link closed{why} after {closed_after:.1f} s{wanted}")
            code = ExitCode.CONNECTION
        return int(code)

    run(settings, main)


def _peek(handle: IO[bytes], size: int) -> tuple[bytes, IO[bytes]]:
    """The first ``size`` bytes of ``handle`` and a stream that still starts with them."""
    peek = getattr(handle, "peek", None)
    head = b"" if peek is None else bytes(peek(size)[:size])
    if len(head) < size:  # no buffer to peek into, or a pipe's first bytes: read into one
        read = io.BytesIO(handle.read())
        if handle is not sys.stdin.buffer:
            handle.close()
        handle, head = read, read.getvalue()[:size]
    return head, handle


async def _cancel_on(event: asyncio.Event, scope: anyio.CancelScope) -> None:
    await event.wait()
    scope.cancel()
