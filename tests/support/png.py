"""Reading the greyscale PNGs of the simulator's map, by hand (IHDR, IDAT, filter 0 rows)."""

from __future__ import annotations

import struct
import zlib

__all__ = ["grey_pixels"]

SIGNATURE = b"\x89PNG\r\n\x1a\n"


def grey_pixels(png: bytes) -> list[bytes]:
    """The rows of an 8-bit greyscale PNG whose rows are all unfiltered, top row first."""
    assert png.startswith(SIGNATURE)
    at, data, size = len(SIGNATURE), b"", (0, 0)
    while at < len(png):
        (length,) = struct.unpack(">I", png[at : at + 4])
        kind, body = png[at + 4 : at + 8], png[at + 8 : at + 8 + length]
        (crc,) = struct.unpack(">I", png[at + 8 + length : at + 12 + length])
        assert crc == zlib.crc32(kind + body), kind
        if kind == b"IHDR":
            width, height, depth, colour = struct.unpack(">IIBB", body[:10])
            assert (depth, colour) == (8, 0), "8-bit greyscale"
            size = (width, height)
        elif kind == b"IDAT":
            data += body
        at += 12 + length
    width, height = size
    raw = zlib.decompress(data)
    assert len(raw) == height * (width + 1)
    rows = [raw[r * (width + 1) : (r + 1) * (width + 1)] for r in range(height)]
    assert all(row[0] == 0 for row in rows), "filter 0 on every row"
    return [row[1:] for row in rows]
