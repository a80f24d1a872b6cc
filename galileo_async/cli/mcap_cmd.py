"""MCAP on the command line: ``record --mcap``, ``fleet record`` and ``decode`` of MCAP files."""

from __future__ import annotations

import json
import sys
from dataclasses import asdict
from pathlib import Path
from typing import IO, TYPE_CHECKING, Annotated, Any

import anyio
import typer

from ..errors import InvalidArgument
from ..protocol import StatusDecoder
from .render import rounded, status_dict
from .runner import (
    ExitCode,
    Settings,
    err_console,
    fail,
    out_console,
    print_error,
    run,
    run_robot,
    settings_of,
)
from .signals import stop_requested

if TYPE_CHECKING:
    from ..fleet import Fleet
    from ..recording import McapRecorder, Recording
    from ..robot import Robot

__all__ = ["decode_mcap", "fleet_record", "record_mcap", "wants_mcap"]


def wants_mcap(path: Path, mcap: bool) -> bool:
    """``record`` writes MCAP with ``--mcap`` or to a file whose name ends in ``.mcap``."""
    return mcap or path.suffix.lower() == ".mcap"


def _recorder(path: Path, source: Robot | Fleet) -> McapRecorder:
    from ..recording import McapRecorder

    return McapRecorder(path, source)


async def _record_until_stopped(recorder: McapRecorder, duration: float | None) -> int:
    """Record until Ctrl-C, SIGTERM or ``duration``; say what was written; the exit code."""
    async with recorder:
        with stop_requested() as stop, anyio.move_on_after(duration):
            await stop.wait()
    written = recorder.written
    out_console().print(
        f"recorded {written.get('status', 0)} statuses, {written.get('raw', 0)} raw chunks "
        f"and {written.get('events', 0)} events of {len(recorder.robots)} robot(s) "
        f"to {recorder.path}",
        markup=False,
    )
    if recorder.dropped:
        dropped = ", ".join(f"{count} {kind}" for kind, count in recorder.dropped_by_kind.items())
        print_error(
            f"the file writer fell behind: dropped {recorder.dropped} messages ({dropped}); "
            "the recording has gaps"
        )
        return int(ExitCode.ERROR)
    return int(ExitCode.OK)


def record_mcap(settings: Settings, path: Path, duration: float | None) -> None:
    """``galileo record FILE.mcap``: one robot's raw bytes, statuses and events."""

    async def body(robot: Robot) -> int:
        return await _record_until_stopped(_recorder(path, robot), duration)

    run_robot(settings, body, interrupted=ExitCode.OK, long_running=True)


def fleet_record(
    ctx: typer.Context,
    path: Annotated[Path, typer.Argument(help="MCAP file to write.", dir_okay=False)],
    duration: Annotated[
        float | None, typer.Option(min=0.01, help="Stop after seconds (default: Ctrl-C).")
    ] = None,
) -> None:
    """Record every robot of the fleet into one MCAP file (a channel set per robot)."""
    from .fleet_cmd import fleet_spec, served_options

    settings, spec = settings_of(ctx), fleet_spec(ctx)

    async def main() -> int:
        async with spec.connect(**served_options(spec)) as fleet:
            return await _record_until_stopped(_recorder(path, fleet), duration)

    run(settings, main, interrupted=ExitCode.OK)


def _read(handle: IO[bytes], source: str) -> Recording:
    from ..recording import read_recording

    try:
        return read_recording(handle)
    except InvalidArgument as exc:
        fail(f"{source}: {exc}")


def decode_mcap(
    handle: IO[bytes],
    source: str,
    settings: Settings,
    *,
    robot: str | None,
    summary_only: bool,
    as_json: bool,
    raw: bool,
) -> None:
    """``decode`` of an MCAP recording: ``robot``'s raw bytes decoded as any capture's are;
    without raw bytes (udp://, http://, ros://), its recorded statuses."""
    recording = _read(handle, source)
    try:
        chosen = recording.robot(robot)
    except InvalidArgument as exc:
        fail(f"{source}: {exc}", ExitCode.USAGE)
    out = sys.stdout
    decoder = StatusDecoder(settings.layout)
    total = frames = 0
    if chosen.raw:
        for seconds, data in chosen.raw:
            total += len(data)
            for status in decoder.feed(data):
                if not summary_only:
                    line = {"t": round(seconds, 4)}
                    line |= status.model_dump(mode="json") if raw else status_dict(status)
                    out.write(json.dumps(line) + "\n")
        frames = decoder.stats.frames
    else:
        for seconds, values in chosen.statuses:
            frames += 1
            if not summary_only:
                shown = values if raw else _rounded(values)
                out.write(json.dumps({"t": round(seconds, 4), **shown}) + "\n")
    times = [t for t, _ in (chosen.raw or chosen.statuses)]
    summary: dict[str, Any] = {"format": "mcap", "robot": chosen.name}
    if chosen.raw:
        summary |= {"bytes": total, "chunks": len(chosen.raw), **asdict(decoder.stats)}
        summary["layout"] = None if decoder.stats.layout is None else decoder.stats.layout.value
        summary["bytes_pending"] = decoder.buffered
    else:
        summary |= {"bytes": 0, "chunks": 0, "frames": frames, "source": "status channel"}
    summary["events"] = len(chosen.events)
    summary["duration"] = round(times[-1] - times[0], 3) if times else None
    if as_json:
        out.write(json.dumps({"summary": summary}) + "\n")
    else:
        text = ", ".join(f"{key} {value}" for key, value in summary.items())
        err_console().print(f"summary: {text}", markup=False)
    out.flush()
    raise typer.Exit(0 if frames or not total else int(ExitCode.ERROR))


def _rounded(values: dict[str, Any]) -> dict[str, Any]:
    return {
        key: rounded(key, value) if isinstance(value, float) else value
        for key, value in values.items()
    }
