"""The simulator's map as the robot's HTTP API gives it: parameters and a greyscale PNG.

The map covers the map's targets, the dock and the start pose (0, 0) with a margin: free
space inside a wall one pixel wide, each target a dark dot. Pixels are in the robot's map
convention (docs/protocol.md §5.3): ``origin`` is the map pose of the lower left pixel, the
PNG's first row is the top (largest y).
"""

from __future__ import annotations

import math
import struct
import zlib
from collections.abc import Sequence
from dataclasses import dataclass

__all__ = ["FREE", "RESOLUTION", "TARGET", "WALL", "SimMap", "grey_png", "sim_map"]

#: Metres per pixel (the vendor's maps use 0.05).
RESOLUTION = 0.05
#: Metres of free space around the outermost point.
_MARGIN = 1.0
#: Grey levels: free space, the wall around it, a target's dot (as the robot's map PNGs).
FREE, WALL, TARGET = 254, 0, 100
_DOT = 2  # pixels either side of a target's centre


@dataclass(frozen=True)
class SimMap:
    """``origin`` (x, y, yaw) of the lower left pixel, size in pixels, metres a pixel, PNG."""

    origin: tuple[float, float, float]
    width: int
    height: int
    resolution: float
    png: bytes

    def params(self) -> dict[str, object]:
        """The ``map_params`` of GET /map/current_map_image."""
        return {
            "origin": list(self.origin),
            "width": self.width,
            "resolution": self.resolution,
            "height": self.height,
        }


def sim_map(points: Sequence[tuple[float, float]]) -> SimMap:
    """The map around ``points`` (targets, dock; the start pose is always in)."""
    xs = [0.0, *(x for x, _ in points)]
    ys = [0.0, *(y for _, y in points)]
    left, bottom = min(xs) - _MARGIN, min(ys) - _MARGIN
    width = math.ceil((max(xs) + _MARGIN - left) / RESOLUTION) + 1
    height = math.ceil((max(ys) + _MARGIN - bottom) / RESOLUTION) + 1
    rows = [bytearray([FREE]) * width for _ in range(height)]
    for row in (rows[0], rows[-1]):
        row[:] = bytes([WALL]) * width
    for row in rows:
        row[0] = row[-1] = WALL
    for x, y in points:
        col = round((x - left) / RESOLUTION)
        line = height - 1 - round((y - bottom) / RESOLUTION)
        for r in range(max(1, line - _DOT), min(height - 1, line + _DOT + 1)):
            for c in range(max(1, col - _DOT), min(width - 1, col + _DOT + 1)):
                rows[r][c] = TARGET
    return SimMap((left, bottom, 0.0), width, height, RESOLUTION, grey_png(width, rows))


def grey_png(width: int, rows: Sequence[bytes | bytearray]) -> bytes:
    """An 8-bit greyscale PNG of ``rows`` (each ``width`` bytes, top row first)."""

    def chunk(kind: bytes, data: bytes) -> bytes:
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body))

    header = struct.pack(">IIBBBBB", width, len(rows), 8, 0, 0, 0, 0)
    pixels = b"".join(b"\x00" + bytes(row) for row in rows)  # filter 0 on each row
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", header)
        + chunk(b"IDAT", zlib.compress(pixels))
        + chunk(b"IEND", b"")
    )
