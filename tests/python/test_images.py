"""uwhl_rs.images: colour math, reading and writing, against values known
independently (IEC 61966-2-1 constants, hand-made files, rawpy itself)."""

from __future__ import annotations

import os

import numpy as np
import pytest

from datapaths import RAW_DIR

from uwhl_rs import images

# ------------------------------------------------------------ colour math


def test_known_linear_gray_gives_the_standard_srgb_value(tmp_path):
    # IEC 61966-2-1: 18% linear gray encodes to 0.46136 -> 8-bit 118, 16-bit 30235
    assert images.linear_to_srgb(0.18) == pytest.approx(0.461356, abs=1e-6)
    gray = np.full((4, 4, 3), 0.18, np.float32)
    p = tmp_path / "g.png"
    images.write_image(p, gray, encoding="linear")
    img, meta = images.read_image(p)
    from PIL import Image

    assert np.asarray(Image.open(p))[0, 0].tolist() == [118, 118, 118]
    # read back through the inverse curve: 118/255 decodes to 0.1812
    assert img[0, 0, 0] == pytest.approx(((118 / 255 + 0.055) / 1.055) ** 2.4, abs=1e-7)
    p16 = tmp_path / "g16.png"
    images.write_image(p16, gray, bits=16, encoding="linear")
    codes = images._core._decode_png(p16.read_bytes(), 10**6)
    assert codes.dtype == np.uint16 and codes[0, 0, 0] == round(0.46135612950044164 * 65535)


def test_inverse_srgb_then_srgb_is_identity_within_one_16_bit_step():
    x = np.linspace(0, 1, 200001)
    back = images.linear_to_srgb(images.srgb_to_linear(x))
    assert np.max(np.abs(back - x)) < 1 / 65535
    # and through the core's float32 path on every 16-bit code
    codes = np.arange(65536, dtype=np.uint16)
    lin = images._core._decode_u16(codes, True)
    assert np.array_equal(images.quantize(lin, 16, encoding="linear"), codes)
    assert np.max(np.abs(images.linear_to_srgb(lin) - codes / 65535)) < 1 / 65535


def test_srgb_curve_matches_the_core():
    x = np.random.default_rng(0).random(10000).astype(np.float32)
    want = np.floor(images.linear_to_srgb(x) * 65535 + 0.5)
    assert np.array_equal(images.quantize(x, 16, encoding="linear"), want.astype(np.uint16))


def test_camera_matrix_path_on_a_synthetic_matrix():
    m = np.array([[1.6, -0.4, -0.2], [-0.2, 1.5, -0.3], [0.0, -0.5, 1.5]])
    meta = images.ImageMeta("x.dng", "raw", "DNG", 16, 1, 3, camera_matrix=m)
    cam = np.array([[[0.2, 0.3, 0.1], [0.5, 0.5, 0.5], [0.9, 0.1, 0.05]]], np.float32)
    got = images.to_srgb(cam, meta)
    lin = np.clip(np.einsum("ij,hwj->hwi", m, cam.astype(np.float64)), 0, 1)
    want = np.where(lin <= 0.0031308, 12.92 * lin, 1.055 * lin ** (1 / 2.4) - 0.055)
    assert np.allclose(got, want, atol=2e-6)
    # rows summing to 1 keep a neutral gray neutral
    assert np.allclose(got[0, 1], images.linear_to_srgb(0.5), atol=1e-6)
    # without a matrix only the curve is applied; an unlinearised source is only clipped
    assert np.allclose(images.to_srgb(cam), images.linear_to_srgb(cam), atol=1e-6)
    ref = images.ImageMeta("x.jpg", "srgb", "JPEG", 8, 1, 3, linear=False, preprocess="reference")
    assert np.array_equal(images.to_srgb(cam, ref), cam)


def test_camera_matrix_from_xyz_keeps_white_white():
    class FakeRaw:
        color_matrix = np.zeros((3, 4))
        # a camera whose XYZ->camera matrix is the inverse of sRGB's primaries: camera = sRGB
        rgb_xyz_matrix = np.vstack([np.linalg.inv(images._SRGB_TO_XYZ), np.zeros((1, 3))])

    m, notes = images._camera_matrix(FakeRaw())
    assert notes == [] and np.allclose(m @ np.ones(3), 1.0)
    assert np.allclose(m, np.eye(3), atol=1e-6)
    FakeRaw.rgb_xyz_matrix = np.zeros((4, 3))
    assert images._camera_matrix(FakeRaw()) == (None, ["no_camera_matrix"])


# ---------------------------------------------------------------- reading


def _jpeg_with_orientation(path, arr, orientation):
    from PIL import Image

    im = Image.fromarray(arr)
    exif = im.getexif()
    exif[0x0112] = orientation
    im.save(path, quality=100, exif=exif.tobytes(), subsampling=0)


@pytest.mark.parametrize("orientation,expect", [(1, "same"), (3, "rot180"), (6, "cw"), (8, "ccw")])
def test_exif_orientation_is_applied(tmp_path, orientation, expect):
    a = np.zeros((40, 60, 3), np.uint8)
    a[:20, :30] = (250, 20, 20)  # red block at the stored top-left
    p = tmp_path / f"o{orientation}.jpg"
    _jpeg_with_orientation(p, a, orientation)
    img, meta = images.read_image(p)
    assert meta.orientation == orientation
    red = img[..., 0] > 0.5
    h, w = img.shape[:2]
    corner = {
        "same": red[: h // 4, : w // 4],
        "rot180": red[-h // 4 :, -w // 4 :],
        "cw": red[: h // 4, -w // 4 :],  # rotated 90 clockwise: top-left goes top-right
        "ccw": red[-h // 4 :, : w // 4],
    }[expect]
    assert (h, w) == ((40, 60) if expect in ("same", "rot180") else (60, 40))
    assert corner.all()


def test_16_bit_png_and_tiff_round_trip_exactly(tmp_path):
    rng = np.random.default_rng(3)
    codes = rng.integers(0, 65536, size=(17, 23, 3), dtype=np.uint16)
    for ext in (".png", ".tif"):
        p = tmp_path / f"x{ext}"
        images.write_image(p, codes)
        img, meta = images.read_image(p)
        assert meta.bits == 16 and meta.kind == "srgb"
        assert np.array_equal(images.quantize(img, 16, encoding="linear"), codes)


def test_png_writer_is_read_back_exactly_by_pillow_and_zlib(tmp_path):
    import struct
    import zlib

    from PIL import Image

    rng = np.random.default_rng(5)
    # smooth rows with noise (the adaptive filters pick different types) and
    # sizes that are not multiples of anything
    ramp = np.linspace(0, 1, 301)[None, :] * np.linspace(0.2, 1, 67)[:, None]
    g8 = np.clip(ramp * 255 + rng.normal(0, 3, ramp.shape), 0, 255).astype(np.uint8)
    rgb8 = np.stack([g8, 255 - g8, g8 // 2], axis=-1)
    g16 = np.clip(ramp * 65535 + rng.normal(0, 300, ramp.shape), 0, 65535).astype(np.uint16)
    for a in (g8, rgb8, g16):
        p = tmp_path / "w.png"
        images.write_image(p, a)
        with Image.open(p) as im:
            back = np.asarray(im)
        assert np.array_equal(back.astype(a.dtype), a), a.shape
    # 16-bit RGB (Pillow keeps only 8 bits): by hand, inflate and unfilter
    rgb16 = np.stack([g16, 65535 - g16, g16 // 3], axis=-1)
    images.write_image(tmp_path / "w16.png", rgb16)
    data = (tmp_path / "w16.png").read_bytes()
    pos, idat = 8, b""
    while pos < len(data):
        n, tag = struct.unpack(">I4s", data[pos:pos + 8])
        if tag == b"IHDR":
            w, h, depth, color = struct.unpack(">IIBB", data[pos + 8:pos + 18])
            assert (w, h, depth, color) == (301, 67, 16, 2)
        if tag == b"IDAT":
            idat += data[pos + 8:pos + 8 + n]
        pos += 12 + n
    raw = np.frombuffer(zlib.decompress(idat), np.uint8).reshape(67, 1 + 301 * 6)
    out = np.zeros((67, 301 * 6), np.int64)
    bpp = 6
    for y in range(67):
        f, line = raw[y, 0], raw[y, 1:].astype(np.int64)
        prev = out[y - 1] if y else np.zeros_like(line)
        row = np.zeros_like(line)
        for x in range(line.size):
            left = row[x - bpp] if x >= bpp else 0
            up, ul = prev[x], (prev[x - bpp] if x >= bpp else 0)
            if f == 0:
                pred = 0
            elif f == 1:
                pred = left
            elif f == 2:
                pred = up
            elif f == 3:
                pred = (left + up) // 2
            else:
                pa, pb, pc = abs(up - ul), abs(left - ul), abs(left + up - 2 * ul)
                pred = left if pa <= pb and pa <= pc else (up if pb <= pc else ul)
            row[x] = (line[x] + pred) & 255
        out[y] = row
    got = out.astype(np.uint8).reshape(67, 301, 3, 2)
    assert np.array_equal(got[..., 0].astype(np.uint16) * 256 + got[..., 1], rgb16)


def test_png_writer_rejects_what_png_cannot_hold():
    for bad, what in ((np.zeros((4, 4), np.float32), "uint8 or uint16"),
                      (np.zeros((4, 4, 4), np.uint8), "shape"),
                      (np.zeros((0, 4), np.uint8), "shape"),
                      (np.zeros(5, np.uint16), "shape")):
        with pytest.raises(ValueError, match=what):
            images._core._encode_png(bad)


def test_gray_and_rgba_become_rgb(tmp_path):
    from PIL import Image

    g = (np.arange(64, dtype=np.uint8).reshape(8, 8) * 4).astype(np.uint8)
    Image.fromarray(g).save(tmp_path / "g.png")
    img, _ = images.read_image(tmp_path / "g.png")
    assert img.shape == (8, 8, 3) and np.array_equal(img[..., 0], img[..., 2])
    rgba = np.dstack([np.full((8, 8, 3), 200, np.uint8), np.zeros((8, 8), np.uint8)])
    Image.fromarray(rgba, "RGBA").save(tmp_path / "a.png")
    img, _ = images.read_image(tmp_path / "a.png")
    assert img.shape == (8, 8, 3) and np.allclose(img, images.srgb_to_linear(200 / 255), atol=1e-6)


def test_reference_preprocessing_keeps_srgb_unlinearised(tmp_path):
    a = np.random.default_rng(1).integers(20, 200, size=(30, 30, 3), dtype=np.uint8)
    images.write_image(tmp_path / "r.png", a)
    lin, m1 = images.read_image(tmp_path / "r.png")
    ref, m2 = images.read_image(tmp_path / "r.png", preprocess="reference")
    assert m1.linear and not m2.linear and m2.preprocess == "reference"
    assert lin.max() < 0.6  # 199/255 decodes to 0.57
    assert ref.max() == 1.0 and ref.min() == 0.0  # stretched to the full range
    with pytest.raises(ValueError, match="preprocess"):
        images.read_image(tmp_path / "r.png", preprocess="auto")


# ------------------------------------------------------------- bad files


def _error(path, **kw) -> str:
    with pytest.raises(images.ImageReadError) as e:
        images.read_image(path, **kw)
    msg = str(e.value)
    assert str(path) in msg
    return msg


def test_bad_files_give_clear_errors(tmp_path):
    a = (np.random.default_rng(2).random((64, 64, 3)) * 255).astype(np.uint8)
    images.write_image(tmp_path / "ok.jpg", a)
    data = (tmp_path / "ok.jpg").read_bytes()
    (tmp_path / "trunc.jpg").write_bytes(data[: len(data) // 3])
    assert "truncated" in _error(tmp_path / "trunc.jpg").lower()
    (tmp_path / "noise.NEF").write_bytes(np.random.default_rng(4).bytes(5000))
    assert "not a raw file LibRaw can read" in _error(tmp_path / "noise.NEF")
    (tmp_path / "noise.bin").write_bytes(b"hello world, not an image")
    assert "JPEG, PNG, TIFF or raw" in _error(tmp_path / "noise.bin")
    (tmp_path / "empty.png").write_bytes(b"")
    assert "empty file" in _error(tmp_path / "empty.png")
    assert "no such file" in _error(tmp_path / "missing.jpg")
    assert "folder" in _error(tmp_path)
    images.write_image(tmp_path / "p.png", a)
    png = (tmp_path / "p.png").read_bytes()
    (tmp_path / "cut.png").write_bytes(png[: len(png) // 2])
    _error(tmp_path / "cut.png")
    images.write_image(tmp_path / "p16.png", a.astype(np.uint16) * 257)
    png16 = (tmp_path / "p16.png").read_bytes()
    (tmp_path / "cut16.png").write_bytes(png16[: len(png16) // 2])
    # the binary's words: the format is not named, what is wrong with the file is
    assert "cannot decode: the file ends before its image data" in _error(tmp_path / "cut16.png")


def test_absurd_size_is_refused_before_decoding(tmp_path):
    import struct
    import zlib

    # a valid PNG header claiming 100000 x 100000 pixels, with no data
    def chunk(tag, d):
        return struct.pack(">I", len(d)) + tag + d + struct.pack(">I", zlib.crc32(tag + d) & 0xFFFFFFFF)

    hdr = struct.pack(">IIBBBBB", 100000, 100000, 8, 2, 0, 0, 0)
    (tmp_path / "huge.png").write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", hdr) + chunk(b"IEND", b""))
    assert "over the limit" in _error(tmp_path / "huge.png")
    hdr16 = struct.pack(">IIBBBBB", 100000, 100000, 16, 2, 0, 0, 0)
    (tmp_path / "huge16.png").write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", hdr16) + chunk(b"IEND", b""))
    assert "over the limit" in _error(tmp_path / "huge16.png")
    images.write_image(tmp_path / "small.png", np.zeros((10, 10, 3), np.uint8))
    assert "over the limit" in _error(tmp_path / "small.png", max_pixels=99)


# ---------------------------------------------------------------- writing


def test_write_is_atomic_and_leaves_nothing_on_failure(tmp_path, monkeypatch):
    p = tmp_path / "out.png"
    images.write_image(p, np.zeros((4, 4, 3), np.float32))
    before = p.read_bytes()

    def boom(a):
        raise OSError(28, "No space left on device")

    from uwhl_rs import imagewrite
    monkeypatch.setattr(imagewrite, "_png_bytes", boom)
    with pytest.raises(OSError, match="No space left"):
        images.write_image(p, np.ones((4, 4, 3), np.float32))
    assert p.read_bytes() == before  # the old file is untouched
    assert sorted(os.listdir(tmp_path)) == ["out.png"]  # no temporary left
    with pytest.raises(OSError):
        images.write_image(tmp_path / "new.png", np.ones((4, 4, 3), np.float32))
    assert sorted(os.listdir(tmp_path)) == ["out.png"]


def test_written_files_have_normal_permissions(tmp_path):
    # 0666 minus the umask, as any program's new files (not mkstemp's 0600)
    umask = os.umask(0)
    os.umask(umask)
    p = images.write_image(tmp_path / "x.jpg", np.zeros((4, 4, 3), np.uint8))
    assert os.stat(p).st_mode & 0o777 == 0o666 & ~umask


def test_write_rejects_what_it_cannot_write(tmp_path):
    with pytest.raises(ValueError, match="JPEG holds 8 bits"):
        images.write_image(tmp_path / "x.jpg", np.zeros((4, 4, 3), np.uint16))
    with pytest.raises(ValueError, match="shape"):
        images.write_image(tmp_path / "x.png", np.zeros((4, 4, 4), np.uint8))
    with pytest.raises(ValueError, match="shape"):
        images.write_image(tmp_path / "x.png", np.zeros((0, 4, 3), np.uint8))
    with pytest.raises(ValueError, match=".bmp"):
        images.write_image(tmp_path / "x.bmp", np.zeros((4, 4, 3), np.uint8))
    with pytest.raises(ValueError, match="bits"):
        images.write_image(tmp_path / "x.png", np.zeros((4, 4, 3), np.float32), bits=12)
    assert os.listdir(tmp_path) == []


def test_colormap_endpoints_are_viridis():
    c = images.colorize_transmission(np.array([[0.0, 0.5, 1.0]], np.float32))
    assert c.tolist() == [[[68, 1, 84], [33, 145, 140], [253, 231, 37]]]


# -------------------------------------------------------------------- raw

needs_raw = pytest.mark.skipif(not RAW_DIR.is_dir(), reason=f"{RAW_DIR} absent")


@needs_raw
@pytest.mark.parametrize("name", ["Blackmagic.dng", "Nikon_uncompressed.nef", "RAW_KODAK_DC50.KDC", "canon_eos_6d.dng"])
def test_raw_shape_and_orientation_match_libraw(name):
    import rawpy

    p = RAW_DIR / name
    img, meta = images.read_image(p)
    with rawpy.imread(str(p)) as r:
        # LibRaw's own default rendering (flip applied); for the NEF whose
        # declared white level is below its data, at the data's maximum
        sat = int(r.raw_image_visible.max()) if "white_level_below_data" in meta.notes else None
        ref = r.postprocess(user_sat=sat)
        flip = r.sizes.flip
    assert img.shape == ref.shape and img.dtype == np.float32
    assert meta.kind == "raw" and meta.orientation == images._FLIP_TO_EXIF[flip]
    assert (meta.height, meta.width) == img.shape[:2]
    assert np.isfinite(img).all() and img.min() >= 0 and img.max() <= 1
    # linear and not brightened: darker than LibRaw's gamma-encoded default
    assert np.median(img) < np.median(ref / 255.0)

    # same picture the same way up: 8x8 block means of green rank alike,
    # and better than with our image turned upside down
    def blocks(a):
        g = np.asarray(a[..., 1], np.float64)
        bh, bw = g.shape[0] // 8, g.shape[1] // 8
        return g[: 8 * bh, : 8 * bw].reshape(8, bh, 8, bw).mean(axis=(1, 3)).ravel()

    def rank_corr(x, y):  # Spearman: blind to LibRaw's gamma and brightening
        return np.corrcoef(np.argsort(np.argsort(x)), np.argsort(np.argsort(y)))[0, 1]

    same = rank_corr(blocks(img), blocks(ref))
    turned = rank_corr(blocks(img[::-1, ::-1]), blocks(ref))
    assert same > 0.7 and same > turned + 0.3, (same, turned)


@needs_raw
def test_raw_half_size_and_metadata():
    img, meta = images.read_image(RAW_DIR / "Blackmagic.dng", half_size=True)
    assert img.shape == (1088, 2064, 3)
    assert meta.camera_matrix is not None and np.allclose(np.asarray(meta.camera_matrix).sum(axis=1), 1, atol=0.01)
    assert meta.white_balance[0] > 1.5  # as-shot multipliers, red boosted
    img, meta = images.read_image(RAW_DIR / "Nikon_uncompressed.nef")
    # the file declares white = 255 under data up to 54998: not all clipped
    assert "white_level_below_data" in meta.notes and np.mean(img >= 1.0) < 0.05
    plain, _ = images.read_image(RAW_DIR / "RAW_KODAK_DC50.KDC")
    img, meta = images.read_image(RAW_DIR / "RAW_KODAK_DC50.KDC", preprocess="reference")
    # METHOD §2 reference: top 0.1% of each channel clipped to 1, the rest scaled up
    assert meta.preprocess == "reference" and img.max() == 1.0
    assert all(np.mean(img[..., c] >= 1.0) >= 0.001 for c in range(3))
    assert np.median(img) > np.median(plain)


def test_io_functions_are_reachable_from_the_package():
    import uwhl_rs

    assert uwhl_rs.read_image is images.read_image and uwhl_rs.to_srgb is images.to_srgb
    assert uwhl_rs.write_image is images.write_image
    assert uwhl_rs.restore_file is uwhl_rs.files.restore_file
    assert {"read_image", "restore_file"} <= set(dir(uwhl_rs))
    with pytest.raises(AttributeError):
        uwhl_rs.no_such_thing
