"""Image files from a hostile review of 2026-12-06, built byte by byte here:
each case says what must happen independently of the code (both commands)."""

from __future__ import annotations

import io
import json
import struct

import numpy as np
import pytest
from PIL import Image

from bothcmds import cmds, run_restore

IMPLS = ["python", "rust"]


def _tiff(ifds: list[dict]) -> bytes:
    """A little-endian classic TIFF of uncompressed RGB images, one strip
    each. Each IFD: ``pixels`` (H x W x 3 uint8 or uint32), ``subfile``
    (NewSubfileType), ``sub`` (images put in IFD0's SubIFDs instead of the
    chain), ``orientation``, ``photometric``."""
    out = bytearray(b"II*\x00\x00\x00\x00\x00")

    def put(data: bytes) -> int:
        at = len(out)
        out.extend(data)
        if len(out) % 2:
            out.append(0)
        return at

    def ifd(img: dict, subs: list[int]) -> tuple[int, int]:
        px = np.ascontiguousarray(img["pixels"])
        h, w = px.shape[:2]
        bits = px.dtype.itemsize * 8
        data_at = put(px.astype(px.dtype.newbyteorder("<")).tobytes())
        bits_at = put(struct.pack("<3H", bits, bits, bits))
        entries = [(0x00FE, 4, 1, img.get("subfile", 0)), (0x0100, 4, 1, w), (0x0101, 4, 1, h),
                   (0x0102, 3, 3, bits_at), (0x0103, 3, 1, 1), (0x0106, 3, 1, img.get("photometric", 2)),
                   (0x0111, 4, 1, data_at), (0x0112, 3, 1, img.get("orientation", 1)),
                   (0x0115, 3, 1, 3), (0x0116, 4, 1, h), (0x0117, 4, 1, px.nbytes), (0x011C, 3, 1, 1)]
        if px.dtype.kind == "f":  # SampleFormat: IEEE floating point
            entries.append((0x0153, 3, 3, put(struct.pack("<3H", 3, 3, 3))))
        if subs:
            entries.append((0x014A, 4, 1, subs[0]) if len(subs) == 1 else (0x014A, 4, len(subs), put(struct.pack(f"<{len(subs)}I", *subs))))
        entries.sort()
        at = put(struct.pack("<H", len(entries)) + b"".join(struct.pack("<HHII", *e) for e in entries) + b"\0\0\0\0")
        return at, at + 2 + 12 * len(entries)  # the IFD, its next-IFD link

    subs = [ifd(i, [])[0] for i in ifds if i.get("sub")]
    chain = [i for i in ifds if not i.get("sub")]
    links = [ifd(i, subs if k == 0 else []) for k, i in enumerate(chain)]
    struct.pack_into("<I", out, 4, links[0][0])
    for (_, link), (nxt, _) in zip(links, links[1:]):
        struct.pack_into("<I", out, link, nxt)
    return bytes(out)


def _scene(h, w, seed=0):
    rng = np.random.default_rng(seed)
    return np.clip(rng.normal((40, 110, 150), 30, (h, w, 3)), 0, 255).astype(np.uint8)


def _restore(impl, binary, path, out):
    r = run_restore(cmds(binary)[impl], path, "-o", out, "-q")
    side = out / (path.stem + ".json")
    return r, (json.loads(side.read_text()) if side.exists() else None)


@pytest.mark.parametrize("impl", IMPLS)
def test_a_thumbnail_stored_first_is_not_taken_for_the_photo(impl, binary, tmp_path):
    p = tmp_path / "thumb_first.tif"
    p.write_bytes(_tiff([{"pixels": _scene(6, 8), "subfile": 1}, {"pixels": _scene(48, 64, 1)}]))
    r, side = _restore(impl, binary, p, tmp_path / "o")
    assert r.returncode == 0, r.stderr
    assert (side["source"]["height"], side["source"]["width"]) == (48, 64)
    assert any("reduced-resolution" in n and "IFD 1" in n for n in side["source"]["notes"]), side["source"]["notes"]


@pytest.mark.parametrize("impl", IMPLS)
def test_a_file_of_several_pages_says_the_first_is_read(impl, binary, tmp_path):
    p = tmp_path / "pages.tif"
    p.write_bytes(_tiff([{"pixels": _scene(48, 64)}, {"pixels": _scene(30, 40, 1)}]))
    r, side = _restore(impl, binary, p, tmp_path / "o")
    assert r.returncode == 0, r.stderr
    assert (side["source"]["height"], side["source"]["width"]) == (48, 64)
    assert any("2 full-resolution images; the first is read" in n for n in side["source"]["notes"])


@pytest.mark.parametrize("impl", IMPLS)
def test_32_bit_integer_samples_are_refused_not_taken_for_floats(impl, binary, tmp_path):
    # codes 0-255 held in uint32: as float bits they are ~1e-43, a black photo
    p = tmp_path / "u32.tif"
    p.write_bytes(_tiff([{"pixels": _scene(48, 64).astype(np.uint32)}]))
    r, side = _restore(impl, binary, p, tmp_path / "o")
    assert r.returncode == 3 and side is None, r.stderr
    assert "32-bit unsigned integer samples are not read" in r.stderr


@pytest.mark.parametrize("impl", IMPLS)
def test_a_raw_file_named_tif_is_named_as_raw_not_restored_from_its_preview(impl, binary, tmp_path):
    p = tmp_path / "camera.tif"
    p.write_bytes(_tiff([{"pixels": _scene(6, 8), "subfile": 1}, {"pixels": _scene(48, 64, 1), "sub": True}]))
    r, side = _restore(impl, binary, p, tmp_path / "o")
    assert r.returncode == 3 and side is None, r.stderr
    assert "a raw camera file" in r.stderr and "raw extension" in r.stderr


@pytest.mark.parametrize("impl", IMPLS)
def test_a_tiny_jpeg_claiming_a_large_frame_is_refused_from_its_size(impl, binary, tmp_path):
    # 16 x 16 pixels of scan data under a frame header of 6000 x 4000 (4:2:0):
    # 375,000 luma and 2 x 93,750 chroma blocks need at least one bit each
    buf = io.BytesIO()
    Image.fromarray(_scene(16, 16)).save(buf, "JPEG", quality=90, subsampling=2)
    b = bytearray(buf.getvalue())
    sof = b.index(b"\xff\xc0")
    struct.pack_into(">HH", b, sof + 5, 4000, 6000)
    p = tmp_path / "claims.jpg"
    p.write_bytes(bytes(b))
    need = -(-(750 * 500 + 2 * 375 * 250) // 8)
    r, side = _restore(impl, binary, p, tmp_path / "o")
    assert r.returncode == 3 and side is None, r.stderr
    assert f"a damaged JPEG: its 6000x4000 pixels need at least {need} bytes of scan data" in r.stderr


@pytest.mark.parametrize("impl", IMPLS)
def test_transparent_pixels_are_named_not_restored_silently(impl, binary, tmp_path):
    rgba = np.dstack([_scene(48, 64), np.full((48, 64), 255, np.uint8)])
    rgba[:, :16, 3] = 0  # a quarter of the pixels transparent
    p = tmp_path / "cutout.png"
    Image.fromarray(rgba, "RGBA").save(p)
    r, side = _restore(impl, binary, p, tmp_path / "o")
    assert r.returncode == 0, r.stderr
    assert any("alpha channel is ignored: 25.0% of the pixels are not opaque" in n for n in side["source"]["notes"])
    # opaque alpha says nothing
    rgba[..., 3] = 255
    Image.fromarray(rgba, "RGBA").save(tmp_path / "opaque.png")
    r, side = _restore(impl, binary, tmp_path / "opaque.png", tmp_path / "o2")
    assert r.returncode == 0 and not any("alpha" in n for n in side["source"]["notes"])


@pytest.mark.parametrize("impl", IMPLS)
def test_a_file_that_is_no_image_is_refused_whatever_its_size(impl, binary, tmp_path):
    # 4,771,840 bytes is a headerless camera's raw size in LibRaw's table:
    # a text file of that size named .jpg was "restored" as a photo of noise
    p = tmp_path / "dive_log.jpg"
    line = b"12:00:01 depth 18.2 m temp 21.5 C\n"
    p.write_bytes((line * (4_771_840 // len(line) + 1))[:4_771_840])
    r, side = _restore(impl, binary, p, tmp_path / "o")
    assert r.returncode == 3 and side is None, r.stderr


@pytest.mark.parametrize("impl", IMPLS)
def test_a_header_pointing_at_itself_is_named_as_such(impl, binary, tmp_path):
    b = bytearray(_tiff([{"pixels": _scene(48, 64)}]))
    struct.pack_into("<I", b, 4, 0)  # IFD0 "at 0": the header read as a directory
    p = tmp_path / "zero.tif"
    p.write_bytes(bytes(b))
    r, side = _restore(impl, binary, p, tmp_path / "o")
    assert r.returncode == 3 and side is None, r.stderr
    assert "gives IFD0 at offset 0, inside the header" in r.stderr, r.stderr


@pytest.mark.parametrize("impl", IMPLS)
def test_the_reference_preprocessing_says_it_leaves_float_samples_alone(impl, binary, tmp_path):
    import uwhl_rs._core as core
    p = tmp_path / "linear.tif"
    p.write_bytes(_tiff([{"pixels": (_scene(48, 64) / 255.0).astype(np.float32)}]))
    r = run_restore(cmds(binary)[impl], p, "-o", tmp_path / "o", "-q", "--preprocess", "reference")
    assert r.returncode == 0, r.stderr
    side = json.loads((tmp_path / "o" / "linear.json").read_text())
    assert core.FLOAT_NOT_PREPROCESSED in side["source"]["notes"], side["source"]["notes"]


def _png_with(img: np.ndarray, chunks: list[tuple[bytes, bytes]]) -> bytes:
    """``img`` as PNG with ``chunks`` (type, data) put right after IHDR."""
    import zlib
    buf = io.BytesIO()
    Image.fromarray(img).save(buf, "PNG")
    b = buf.getvalue()
    end = 8 + 8 + 13 + 4  # signature, IHDR
    extra = b"".join(struct.pack(">I", len(d)) + t + d + struct.pack(">I", zlib.crc32(t + d)) for t, d in chunks)
    return b[:end] + extra + b[end:]


def test_a_png_whose_gamma_is_one_is_read_as_linear_and_other_colour_chunks_are_named(tmp_path):
    from uwhl_rs import images
    flat = np.full((24, 32, 3), 128, np.uint8)
    (tmp_path / "lin.png").write_bytes(_png_with(flat, [(b"gAMA", struct.pack(">I", 100000))]))
    img, meta = images.read_image(tmp_path / "lin.png")
    assert np.allclose(img, 128 / 255, atol=1e-6)  # not the sRGB curve's 0.2158
    assert any("linear light (gamma 1.0)" in n for n in meta.notes)
    # an sRGB chunk overrides gAMA (the PNG rule): the curve, no note
    (tmp_path / "both.png").write_bytes(_png_with(flat, [(b"sRGB", b"\0"), (b"gAMA", struct.pack(">I", 100000))]))
    img, meta = images.read_image(tmp_path / "both.png")
    assert np.allclose(img, ((128 / 255 + 0.055) / 1.055) ** 2.4, atol=1e-6) and not meta.notes
    # BT.2020 / PQ (cICP 9, 16): not applied, and said
    (tmp_path / "pq.png").write_bytes(_png_with(flat, [(b"cICP", bytes([9, 16, 0, 1]))]))
    _, meta = images.read_image(tmp_path / "pq.png")
    assert any("cICP chunk (colour primaries 9, transfer 16) is not applied" in n for n in meta.notes)


def test_an_animated_png_says_its_first_frame_is_read(tmp_path):
    from uwhl_rs import images
    first, second = _scene(24, 32), _scene(24, 32, 1)
    Image.fromarray(first).save(tmp_path / "anim.png", save_all=True, append_images=[Image.fromarray(second)])
    img, meta = images.read_image(tmp_path / "anim.png")
    assert "an animated PNG: its first frame is read" in meta.notes
    assert np.allclose(img, images.srgb_to_linear(first / 255.0), atol=1e-6)


@pytest.mark.parametrize("impl", IMPLS)
def test_the_orientation_is_the_picked_images_own(impl, binary, tmp_path):
    # the thumbnail says 6 (rotate), the full image 1: upright as stored; then the other way round
    p = tmp_path / "o1.tif"
    p.write_bytes(_tiff([{"pixels": _scene(6, 8), "subfile": 1, "orientation": 6}, {"pixels": _scene(48, 64, 1)}]))
    r, side = _restore(impl, binary, p, tmp_path / "a")
    assert r.returncode == 0, r.stderr
    assert (side["source"]["height"], side["source"]["width"], side["source"]["orientation"]) == (48, 64, 1)
    p = tmp_path / "o6.tif"
    p.write_bytes(_tiff([{"pixels": _scene(6, 8), "subfile": 1}, {"pixels": _scene(48, 64, 1), "orientation": 6}]))
    r, side = _restore(impl, binary, p, tmp_path / "b")
    assert r.returncode == 0, r.stderr
    assert (side["source"]["height"], side["source"]["width"], side["source"]["orientation"]) == (64, 48, 6)


@pytest.mark.parametrize("impl", IMPLS)
def test_a_transparency_mask_first_and_a_sensor_mosaic_are_no_photo(impl, binary, tmp_path):
    p = tmp_path / "masked.tif"  # NewSubfileType 4: a transparency mask stored before the image
    p.write_bytes(_tiff([{"pixels": _scene(6, 8), "subfile": 4}, {"pixels": _scene(48, 64, 1)}]))
    r, side = _restore(impl, binary, p, tmp_path / "a")
    assert r.returncode == 0 and (side["source"]["height"], side["source"]["width"]) == (48, 64), r.stderr
    p = tmp_path / "mosaic.tif"  # PhotometricInterpretation CFA in IFD0: a raw file renamed
    p.write_bytes(_tiff([{"pixels": _scene(48, 64), "photometric": 32803}]))
    r, side = _restore(impl, binary, p, tmp_path / "b")
    assert r.returncode == 3 and side is None and "a raw camera file" in r.stderr, r.stderr


def test_colour_chunks_after_the_pixel_data_are_not_read(tmp_path):
    # the PNG rule (libpng and PIL too): gAMA, sRGB and cICP count before the first IDAT only
    import zlib
    from uwhl_rs import images
    buf = io.BytesIO()
    Image.fromarray(np.full((24, 32, 3), 128, np.uint8)).save(buf, "PNG")
    b = buf.getvalue()
    gama = struct.pack(">I", 100000)
    chunk = struct.pack(">I", 4) + b"gAMA" + gama + struct.pack(">I", zlib.crc32(b"gAMA" + gama))
    end = b.rindex(b"IEND") - 4
    (tmp_path / "late.png").write_bytes(b[:end] + chunk + b[end:])
    img, meta = images.read_image(tmp_path / "late.png")
    assert np.allclose(img, ((128 / 255 + 0.055) / 1.055) ** 2.4, atol=1e-6) and not meta.notes


@pytest.mark.parametrize("impl", IMPLS)
def test_a_mask_of_the_stored_size_of_a_turned_photo_is_told_why_it_does_not_fit(impl, binary, tmp_path):
    # stored 64 x 48 with EXIF orientation 6: upright it is 48 x 64, and masks are drawn on that
    exif = Image.Exif()
    exif[0x0112] = 6
    Image.fromarray(_scene(48, 64)).save(tmp_path / "turned.jpg", exif=exif.tobytes(), quality=95)
    Image.fromarray(np.full((48, 64), 255, np.uint8)).save(tmp_path / "stored.png")
    r = run_restore(cmds(binary)[impl], tmp_path / "turned.jpg", "-o", tmp_path / "o", "--mask", tmp_path / "stored.png")
    assert r.returncode == 2, r.stderr
    assert ("--mask is 64x48 pixels but the input is 48x64 upright (after its EXIF orientation 6; "
            "a mask is drawn on the upright photo)") in r.stderr, r.stderr


@pytest.mark.parametrize("impl", IMPLS)
def test_a_mask_drawn_only_in_its_alpha_is_named_not_read_as_empty(impl, binary, tmp_path):
    # black everywhere, the left half opaque: read by its colour it is all false (no water region, silently)
    rgba = np.zeros((48, 64, 4), np.uint8)
    rgba[:, :32, 3] = 255
    Image.fromarray(rgba, "RGBA").save(tmp_path / "alpha.png")
    Image.fromarray(_scene(48, 64)).save(tmp_path / "p.png")
    r = run_restore(cmds(binary)[impl], tmp_path / "p.png", "-o", tmp_path / "o", "--water-mask", tmp_path / "alpha.png")
    assert r.returncode == 2, r.stderr
    assert "only its alpha varies: a mask is read from its colour (nonzero = true), not from its alpha" in r.stderr
    # the same mask drawn in its colour is read
    rgba[:, :32, :3] = 255
    Image.fromarray(rgba, "RGBA").save(tmp_path / "colour.png")
    r = run_restore(cmds(binary)[impl], tmp_path / "p.png", "-o", tmp_path / "o2", "--water-mask", tmp_path / "colour.png")
    assert r.returncode == 0, r.stderr
