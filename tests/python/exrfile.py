"""A minimal OpenEXR writer for the tests, from the file layout of the
OpenEXR specification ("OpenEXR File Layout": magic, version, header
attributes, line offset table, uncompressed scan-line chunks), written
independently of the reader under test (the exr crate)."""

from __future__ import annotations

import struct

import numpy as np


def _attr(name: str, kind: str, data: bytes) -> bytes:
    return name.encode() + b"\0" + kind.encode() + b"\0" + struct.pack("<i", len(data)) + data


def exr_bytes(channels: dict[str, np.ndarray], *, display: tuple[int, int, int, int] | None = None,
              extra: int = 0) -> bytes:
    """A single-part scan-line OpenEXR file, uncompressed, 32-bit float
    channels of one H x W size (written in the alphabetical order the
    format requires). ``display``: the display window (x0, y0, x1, y1),
    else the data window's; ``extra``: that many more int attributes."""
    names = sorted(channels)
    h, w = np.asarray(channels[names[0]]).shape
    chlist = b"".join(n.encode() + b"\0" + struct.pack("<i", 2) + b"\0\0\0\0" + struct.pack("<ii", 1, 1)
                      for n in names) + b"\0"  # FLOAT; pLinear + 3 reserved; x, y sampling
    box = struct.pack("<iiii", 0, 0, w - 1, h - 1)
    shown = struct.pack("<iiii", *display) if display else box
    header = (_attr("channels", "chlist", chlist) + _attr("compression", "compression", b"\0")
              + b"".join(_attr(f"x{i}", "int", b"\0\0\0\0") for i in range(extra))
              + _attr("dataWindow", "box2i", box) + _attr("displayWindow", "box2i", shown)
              + _attr("lineOrder", "lineOrder", b"\0") + _attr("pixelAspectRatio", "float", struct.pack("<f", 1.0))
              + _attr("screenWindowCenter", "v2f", struct.pack("<ff", 0.0, 0.0))
              + _attr("screenWindowWidth", "float", struct.pack("<f", 1.0)) + b"\0")
    start = b"\x76\x2f\x31\x01" + struct.pack("<i", 2) + header
    chunks, offsets, pos = [], [], len(start) + 8 * h
    for y in range(h):
        row = b"".join(np.ascontiguousarray(channels[n], dtype="<f4")[y].tobytes() for n in names)
        chunk = struct.pack("<ii", y, len(row)) + row
        offsets.append(pos)
        pos += len(chunk)
        chunks.append(chunk)
    return start + struct.pack(f"<{h}Q", *offsets) + b"".join(chunks)
