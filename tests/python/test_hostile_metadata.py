"""Hostile metadata through the binary (issue 30): a photo never fails, and
never eats the machine, because of its EXIF, ICC profile or text chunks.
The files are built here byte by byte (no blobs); the binary runs under an
address-space limit so that a regression fails the test instead of
exhausting memory."""

import io
import json
import os
import resource
import struct
import subprocess
import zlib

import numpy as np
import pytest
from PIL import Image

#: the binary's address space: far above what a 48x64 photo needs, far below
#: what an unbounded reader reaches (24 GB for the looping IFD)
ADDRESS_SPACE = 2 << 30


def _limit():
    resource.setrlimit(resource.RLIMIT_AS, (ADDRESS_SPACE, ADDRESS_SPACE))


def _pixels():
    rng = np.random.default_rng(3)
    base = np.linspace(20, 200, 48 * 64 * 3).reshape(48, 64, 3)
    return np.clip(base + rng.normal(0, 12, base.shape), 0, 255).astype(np.uint8)


def looping_exif(little=True) -> bytes:
    """A TIFF-structured EXIF block whose IFD0 holds Orientation 1 and
    whose next-IFD pointer points back at IFD0 itself."""
    e = "<" if little else ">"
    head = (b"II*\0" if little else b"MM\0*") + struct.pack(e + "I", 8)
    ifd = struct.pack(e + "H", 1) + struct.pack(e + "HHIHH", 0x0112, 3, 1, 1, 0) + struct.pack(e + "I", 8)
    return head + ifd


def jpeg_with_app1(payload: bytes) -> bytes:
    buf = io.BytesIO()
    Image.fromarray(_pixels()).save(buf, format="JPEG", quality=90)
    j = buf.getvalue()
    seg = b"\xff\xe1" + struct.pack(">H", len(payload) + 2) + payload
    return j[:2] + seg + j[2:]


def png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)


def png_with_chunks(*chunks: bytes) -> bytes:
    """A valid RGB PNG with `chunks` (already framed) placed before IDAT."""
    px = _pixels()
    h, w, _ = px.shape
    raw = b"".join(b"\0" + px[y].tobytes() for y in range(h))
    ihdr = png_chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0))
    return (b"\x89PNG\r\n\x1a\n" + ihdr + b"".join(chunks) + png_chunk(b"IDAT", zlib.compress(raw))
            + png_chunk(b"IEND", b""))


def zeros_deflated(n: int) -> bytes:
    """`n` zero bytes deflated (about n/1000 bytes) without holding them."""
    c = zlib.compressobj(9)
    block = bytes(1 << 20)
    out = [c.compress(block) for _ in range(n >> 20)]
    out.append(c.flush())
    return b"".join(out)


def run(binary, tmp_path, name, data, *extra):
    src = tmp_path / name
    src.write_bytes(data)
    out = tmp_path / "out"
    r = subprocess.run([binary, "restore", str(src), "-o", str(out), "-q", *extra], capture_output=True,
                       text=True, timeout=600, preexec_fn=_limit)
    side = out / (src.stem + ".json")
    return r, (json.loads(side.read_text()) if side.exists() else None)


def notes_of(side) -> str:
    return " ".join(side["source"].get("notes", []) + side.get("metadata", {}).get("notes", []))


@pytest.mark.parametrize("little", [True, False])
def test_a_looping_exif_ifd_in_jpeg_is_dropped_with_a_note(binary, tmp_path, little):
    r, side = run(binary, tmp_path, "loop.jpg", jpeg_with_app1(b"Exif\0\0" + looping_exif(little)))
    assert r.returncode == 0, (r.returncode, r.stderr[-2000:])
    assert side["metadata"]["exif_tags_carried"] == 0
    assert "loop" in notes_of(side) or "EXIF" in notes_of(side), notes_of(side)


def test_a_looping_exif_ifd_in_png_is_dropped_with_a_note(binary, tmp_path):
    r, side = run(binary, tmp_path, "loop.png", png_with_chunks(png_chunk(b"eXIf", looping_exif())))
    assert r.returncode == 0, (r.returncode, r.stderr[-2000:])
    assert side["metadata"]["exif_tags_carried"] == 0
    assert "EXIF" in notes_of(side), notes_of(side)


def test_a_huge_compressed_icc_profile_is_ignored_within_the_budget(binary, tmp_path):
    iccp = png_chunk(b"iCCP", b"bomb\0\0" + zeros_deflated(300 << 20))
    r, side = run(binary, tmp_path, "bomb.png", png_with_chunks(iccp), "--max-memory", "100M")
    assert r.returncode == 0, (r.returncode, r.stderr[-2000:])
    assert "ICC" in notes_of(side), notes_of(side)
    assert side["source"]["icc_profile"] is None or not side["source"]["icc_profile"].get("converted")
    # the default budget: the profile is refused by its size, not by the memory left
    r, side = run(binary, tmp_path, "bomb2.png", png_with_chunks(iccp))
    assert r.returncode == 0, (r.returncode, r.stderr[-2000:])
    assert "ICC" in notes_of(side), notes_of(side)


def test_huge_compressed_text_chunks_do_not_fail_the_photo(binary, tmp_path):
    bomb = zeros_deflated(300 << 20)
    chunks = [png_chunk(b"zTXt", b"Raw profile type exif\0\0" + bomb),
              png_chunk(b"iTXt", b"XML:com.adobe.xmp\0\1\0\0\0" + bomb)]
    r, side = run(binary, tmp_path, "text.png", png_with_chunks(*chunks), "--max-memory", "200M")
    assert r.returncode == 0, (r.returncode, r.stderr[-2000:])
    assert side["metadata"]["exif_tags_carried"] == 0


def ifd0_orientation(kind: int, count: int, values: bytes) -> bytes:
    """Big-endian EXIF block: IFD0 with only Orientation (type, count, the
    value bytes inline, or after the IFD when longer than 4)."""
    inline = values if len(values) <= 4 else struct.pack(">I", 8 + 2 + 12 + 4)
    tail = b"" if len(values) <= 4 else values
    return (b"MM\0*" + struct.pack(">I", 8) + struct.pack(">H", 1)
            + struct.pack(">HHI", 0x0112, kind, count) + inline.ljust(4, b"\0") + struct.pack(">I", 0) + tail)


XMP_HEADER = b"http://ns.adobe.com/xap/1.0/\0"


@pytest.mark.parametrize("case,segments,expected", [
    ("long", [b"Exif\0\0" + ifd0_orientation(4, 1, struct.pack(">I", 6))], 6),
    ("short_count_2", [b"Exif\0\0" + ifd0_orientation(3, 2, struct.pack(">HH", 6, 1))], 6),
    ("long_count_2", [b"Exif\0\0" + ifd0_orientation(4, 2, struct.pack(">II", 8, 1))], 8),
    ("two_exif_first_wins", [b"Exif\0\0" + ifd0_orientation(3, 1, struct.pack(">H", 6)),
                             b"Exif\0\0" + ifd0_orientation(3, 1, struct.pack(">H", 3))], 6),
    ("xmp_only", [XMP_HEADER + b'<x:xmpmeta><rdf:RDF><rdf:Description tiff:Orientation="8"/></rdf:RDF></x:xmpmeta>'], 8),
    ("xmp_malformed", [XMP_HEADER + b'<x:xmpmeta><rdf:Description tiff:Orientation="8'], 1),
    ("exif_invalid_then_xmp", [b"Exif\0\0" + ifd0_orientation(3, 1, struct.pack(">H", 0)),
                               XMP_HEADER + b"<tiff:Orientation>6</tiff:Orientation>"], 6),
])
def test_orientation_follows_the_one_rule(binary, tmp_path, case, segments, expected):
    buf = io.BytesIO()
    Image.fromarray(_pixels()).save(buf, format="JPEG", quality=90)
    j = buf.getvalue()
    segs = b"".join(b"\xff\xe1" + struct.pack(">H", len(s) + 2) + s for s in segments)
    r, side = run(binary, tmp_path, case + ".jpg", j[:2] + segs + j[2:])
    assert r.returncode == 0, (r.returncode, r.stderr[-2000:])
    assert side["source"]["orientation"] == expected
    with Image.open(tmp_path / "out" / (case + ".jpg")) as im:
        assert im.size == ((48, 64) if expected in (5, 6, 7, 8) else (64, 48))


def test_a_non_ascii_date_time_original_is_no_time_not_a_crash(binary, tmp_path):
    """The Exif sub-IFD's DateTimeOriginal holding UTF-8 beyond ASCII where
    the clock is: the binary panicked slicing it (found by fuzz/meta_carry)."""
    text = "2026:01:02 03:ÿÿÿ".encode() + b"\0"
    sub = 8 + 2 + 12 + 4
    block = (b"II*\0" + struct.pack("<I", 8) + struct.pack("<H", 1) + struct.pack("<HHII", 0x8769, 4, 1, sub)
             + struct.pack("<I", 0) + struct.pack("<H", 1)
             + struct.pack("<HHII", 0x9003, 2, len(text), sub + 2 + 12 + 4) + struct.pack("<I", 0) + text)
    r, side = run(binary, tmp_path, "time.jpg", jpeg_with_app1(b"Exif\0\0" + block))
    assert r.returncode == 0, (r.returncode, r.stderr[-2000:])
    assert side["metadata"]["taken_at"] is None
