"""Writes the hostile inputs of tests/binary.rs (committed; rerun to
regenerate): each is small on disk and attacks the decoder or the budget.

- huge_header.png: a valid PNG header claiming 100000 x 100000 RGB pixels
  (30 GB decoded) followed by one row of data.
- truncated.jpg: a 256 x 192 JPEG cut after 40% of its bytes.
- bomb.tif: 12000 x 12000 RGB, deflate: 432 MB of zeros in ~0.4 MB.
- bad_offsets.tif: a 64 x 64 RGB TIFF whose strip lies 2 GB past the end.
"""

import os
import struct
import zlib

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))


def png_chunk(tag: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + tag + data + struct.pack(">I", zlib.crc32(tag + data) & 0xFFFFFFFF)


def huge_header_png() -> bytes:
    w = h = 100_000
    ihdr = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)
    row = b"\x00" + bytes(3 * w)
    return b"\x89PNG\r\n\x1a\n" + png_chunk(b"IHDR", ihdr) + png_chunk(b"IDAT", zlib.compress(row, 9)) + png_chunk(b"IEND", b"")


def truncated_jpeg() -> bytes:
    import io

    from PIL import Image

    y, x = np.mgrid[0:192, 0:256]
    img = np.stack([(x * 255 // 256), (y * 255 // 192), ((x + y) % 64) * 4], axis=2).astype(np.uint8)
    buf = io.BytesIO()
    Image.fromarray(img).save(buf, format="JPEG", quality=90)
    data = buf.getvalue()
    return data[: len(data) * 4 // 10]


def tiff(width: int, height: int, strip: bytes, compression: int, offset: int | None, count: int) -> bytes:
    """A little-endian baseline RGB TIFF with one strip."""
    entries = []

    def entry(tag, typ, n, value):
        entries.append(struct.pack("<HHII", tag, typ, n, value))

    header = 8
    n_entries = 11
    ifd_size = 2 + 12 * n_entries + 4
    bits_at = header + ifd_size
    strip_at = bits_at + 6
    entry(256, 4, 1, width)  # ImageWidth
    entry(257, 4, 1, height)  # ImageLength
    entry(258, 3, 3, bits_at)  # BitsPerSample -> 8,8,8
    entry(259, 3, 1, compression)  # Compression
    entry(262, 3, 1, 2)  # Photometric RGB
    entry(273, 4, 1, strip_at if offset is None else offset)  # StripOffsets
    entry(277, 3, 1, 3)  # SamplesPerPixel
    entry(278, 4, 1, height)  # RowsPerStrip
    entry(279, 4, 1, count)  # StripByteCounts
    entry(284, 3, 1, 1)  # PlanarConfiguration contiguous
    entry(339, 3, 1, 1)  # SampleFormat unsigned
    ifd = struct.pack("<H", n_entries) + b"".join(entries) + struct.pack("<I", 0)
    return b"II*\x00" + struct.pack("<I", header) + ifd + struct.pack("<HHH", 8, 8, 8) + strip


def bomb_tiff() -> bytes:
    w = h = 12_000
    comp = zlib.compressobj(9)
    row = bytes(3 * w)
    strip = b"".join(comp.compress(row) for _ in range(h)) + comp.flush()
    return tiff(w, h, strip, 8, None, len(strip))


def bad_offsets_tiff() -> bytes:
    return tiff(64, 64, b"", 1, 0x7FFF_FFF0, 64 * 64 * 3)


if __name__ == "__main__":
    for name, make in [
        ("huge_header.png", huge_header_png),
        ("truncated.jpg", truncated_jpeg),
        ("bomb.tif", bomb_tiff),
        ("bad_offsets.tif", bad_offsets_tiff),
    ]:
        data = make()
        with open(os.path.join(HERE, name), "wb") as f:
            f.write(data)
        print(f"{name}: {len(data)} bytes")
