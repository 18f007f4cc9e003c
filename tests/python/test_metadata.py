"""The photograph's metadata in the corrected photo (src/files/metadata.rs,
docs/OUTPUTS.md "Metadata"), for both commands: EXIF (camera, exposure,
time, GPS) and XMP carried over, Orientation and size tags made true of
the written pixels, the restoration recorded in XMP, and a photo with
broken metadata still restored. Everything is read back with Pillow and
tifffile, which share no code with the writer (little_exif, img-parts)."""

import hashlib
import io
import json
import os
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image

from datapaths import IMAGES_DIR, RAW_DIR
from uwhl_rs import synth

EXIF_IFD, GPS_IFD = 0x8769, 0x8825
#: IFD0 tags that describe the photograph (carried); the rest describe pixels
IFD0_CARRIED = (0x010E, 0x010F, 0x0110, 0x0131, 0x0132, 0x013B, 0x8298)
#: Exif tags that describe the written pixels (rewritten)
REWRITTEN = (0xA001, 0xA002, 0xA003, 0xA005)
NS = b"https://uwhl-rs.github.io/ns/restoration/1.0/"


def restore(face, binary, inputs, out, *extra):
    if face == "python":
        cmd = [sys.executable, "-m", "uwhl_rs", "restore"]
    else:
        cmd = [binary, "restore"]
    r = subprocess.run(cmd + [str(i) for i in inputs] + ["-o", str(out), "-q", *extra], capture_output=True,
                       text=True, timeout=600)
    return r


def exif_of(path):
    with Image.open(path) as im:
        ex = im.getexif()
        return ({k: ex[k] for k in ex}, dict(ex.get_ifd(EXIF_IFD)), dict(ex.get_ifd(GPS_IFD)),
                im.size, im.info.get("xmp") or im.info.get("XML:com.adobe.xmp"))


def xmp_of(path):
    x = exif_of(path)[4]
    return x.encode() if isinstance(x, str) else x


def record(xmp: bytes) -> dict:
    """The uwhl: properties of a packet."""
    import re

    return dict(re.findall(rb"<uwhl:(\w+)>([^<]*)</uwhl:\1>", xmp))


def _scene(h=120, w=160, seed=1):
    img, _ = synth.demo_input(h, w, water_type="3C", seed=seed)
    return (np.clip(img, 0, 1) ** (1 / 2.2) * 255 + 0.5).astype(np.uint8)


def _gps_exif():
    """An EXIF block as a camera with GPS writes it (through Pillow), with
    the EXIF types of the standard (rationals, not floats)."""
    from PIL.TiffImagePlugin import IFDRational as R

    ex = Image.Exif()
    ex[0x010F], ex[0x0110], ex[0x013B], ex[0x8298] = "SeaCam", "Housing 7", "Survey Team", "(c) 2026 Survey"
    ex[0x0112] = 1
    e = ex.get_ifd(EXIF_IFD)
    e[0x9003] = "2026:11:30 10:15:42"  # DateTimeOriginal
    e[0x9291] = "437"  # SubSecTimeOriginal
    e[0x829A] = R(1, 250)  # ExposureTime
    e[0x829D] = R(28, 5)  # FNumber
    e[0x8827] = 400  # ISO
    e[0xA434] = "Nauticam 12-60mm"  # LensModel
    g = ex.get_ifd(GPS_IFD)
    g[1], g[2] = "S", (R(33, 1), R(51, 1), R(359, 10))
    g[3], g[4] = "E", (R(151, 1), R(12, 1), R(405, 10))
    g[5], g[6] = b"\x01", R(37, 2)  # below sea level: a depth
    g[7] = (R(23, 1), R(15, 1), R(42, 1))
    g[29] = "2026:11:30"
    return ex


@pytest.fixture(scope="module")
def gps_jpeg(tmp_path_factory):
    p = tmp_path_factory.mktemp("gps") / "dive_0001.jpg"
    Image.fromarray(_scene()).save(p, quality=92, exif=_gps_exif())
    return p


FACES = ["python", "rust"]


@pytest.mark.parametrize("face", FACES)
def test_gps_time_camera_and_exposure_survive_exactly(face, binary, gps_jpeg, tmp_path):
    r = restore(face, binary, [gps_jpeg], tmp_path)
    assert r.returncode == 0, r.stderr
    ifd0_in, exif_in, gps_in, _, _ = exif_of(gps_jpeg)
    ifd0, exif, gps, size, xmp = exif_of(tmp_path / "dive_0001.jpg")
    assert gps == gps_in and gps[2] == (33.0, 51.0, 35.9) and gps[6] == 18.5
    for k in (0x9003, 0x9291, 0x829A, 0x829D, 0x8827, 0xA434):
        assert exif[k] == exif_in[k], hex(k)
    for k in (0x010F, 0x0110, 0x013B, 0x8298):
        assert ifd0[k] == ifd0_in[k], hex(k)
    assert ifd0[0x0112] == 1 and exif[0xA001] == 1 and (exif[0xA002], exif[0xA003]) == size
    rec = record(xmp)
    side = json.load(open(tmp_path / "dive_0001.json"))
    assert rec[b"WaterType"].decode() == side["water_type"]
    assert [float(v) for v in rec[b"VeilingLight"].split()] == pytest.approx(side["veiling_light"], abs=1e-6)
    assert rec[b"Method"] == b"revised" and rec[b"Sidecar"] == b"dive_0001.json"
    # where the colours come from, as the sidecar has it (METHOD §12.5)
    assert rec[b"Fallback"] == b"input_balance"
    assert float(rec[b"FallbackShare"]) == pytest.approx(side["fallback_share"], abs=5e-5)
    assert float(rec[b"VeilExcess"]) == pytest.approx(side["veil_excess"], abs=5e-5)
    assert side["metadata"]["written"] and side["metadata"]["exif_tags_carried"] >= 15


def test_both_commands_write_the_same_metadata(binary, gps_jpeg, tmp_path):
    """The parity of docs/CLI.md, for metadata: the same tags and the same
    XMP record from both commands (the JPEG encoders differ, so the bytes
    of the pixels do)."""
    got = {}
    for face in FACES:
        out = tmp_path / face
        assert restore(face, binary, [gps_jpeg], out, "--max-side", "100").returncode == 0
        ifd0, exif, gps, size, xmp = exif_of(out / "dive_0001.jpg")
        got[face] = (ifd0, exif, gps, size, record(xmp))
        side = json.load(open(out / "dive_0001.json"))["metadata"]
        # the hash is of the file each wrote; the image UUID, of input and restoration: the same
        assert side.pop("photo_sha256") == hashlib.sha256((out / "dive_0001.jpg").read_bytes()).hexdigest()
        assert side["input_sha256"] == hashlib.sha256(gps_jpeg.read_bytes()).hexdigest()
        assert exif[0xA420] == side["image_uuid"]
        got[face + "_side"] = side
    assert got["python"] == got["rust"]
    assert got["python_side"] == got["rust_side"]


@pytest.mark.parametrize("face", FACES)
def test_orientation_is_reset_with_the_pixels_rotated(face, binary, tmp_path):
    """A camera held upright stores the pixels sideways with Orientation 6:
    the corrected photo is upright, so its Orientation is 1 and its size
    tags are the rotated size."""
    src = tmp_path / "upright.jpg"
    ex = _gps_exif()
    ex[0x0112] = 6
    Image.fromarray(_scene(120, 160)).save(src, quality=92, exif=ex)  # stored 160 wide, shown 120 wide
    out = tmp_path / "out"
    assert restore(face, binary, [src], out).returncode == 0
    ifd0, exif, gps, size, _ = exif_of(out / "upright.jpg")
    assert size == (120, 160) and ifd0[0x0112] == 1
    assert (exif[0xA002], exif[0xA003]) == (120, 160)


@pytest.mark.parametrize("face", FACES)
def test_size_tags_follow_max_side(face, binary, gps_jpeg, tmp_path):
    assert restore(face, binary, [gps_jpeg], tmp_path, "--max-side", "64").returncode == 0
    _, exif, _, size, _ = exif_of(tmp_path / "dive_0001.jpg")
    assert max(size) <= 64 and (exif[0xA002], exif[0xA003]) == size


@pytest.mark.parametrize("face", FACES)
@pytest.mark.parametrize("fmt, ext", [("png", ".png"), ("tiff", ".tif")])
def test_png_and_tiff_outputs_carry_it_too(face, binary, gps_jpeg, tmp_path, fmt, ext):
    assert restore(face, binary, [gps_jpeg], tmp_path, "--format", fmt).returncode == 0
    out = tmp_path / ("dive_0001" + ext)
    ifd0, exif, gps, size, _ = exif_of(out)
    assert gps == exif_of(gps_jpeg)[2] and ifd0[0x010F] == "SeaCam" and exif[0x9003] == "2026:11:30 10:15:42"
    if fmt == "tiff":
        import tifffile

        with tifffile.TiffFile(out) as t:
            page = t.pages[0]
            assert NS in bytes(page.tags[700].value)
            assert page.shape[:2] == (size[1], size[0]) and page.dtype == np.uint16
    else:
        assert NS in xmp_of(out)


@pytest.mark.parametrize("face", FACES)
def test_a_tiff_input_carries_its_exif(face, binary, tmp_path):
    """A TIFF keeps camera and author in its own IFD0 (written here by
    tifffile): they are carried, its pixel layout is not."""
    import tifffile

    src = tmp_path / "frame.tif"
    tags = [(0x010F, "s", 0, "SeaCam", True), (0x0110, "s", 0, "Housing 7", True),
            (0x013B, "s", 0, "Survey Team", True), (0x0132, "s", 0, "2026:11:30 10:15:42", True)]
    tifffile.imwrite(src, _scene(), photometric="rgb", extratags=tags)
    assert restore(face, binary, [src], tmp_path / "o").returncode == 0
    ifd0, exif, gps, size, _ = exif_of(tmp_path / "o" / "frame.jpg")
    assert (ifd0[0x010F], ifd0[0x0110], ifd0[0x013B], ifd0[0x0132]) == (
        "SeaCam", "Housing 7", "Survey Team", "2026:11:30 10:15:42")
    assert 0x0111 not in ifd0 and 0x0100 not in ifd0  # StripOffsets, ImageWidth: the TIFF's, not the JPEG's


@pytest.mark.parametrize("face", FACES)
def test_a_photo_with_corrupt_exif_still_restores(face, binary, tmp_path):
    good = io.BytesIO()
    Image.fromarray(_scene()).save(good, "JPEG", quality=92)
    data = good.getvalue()
    # an APP1 Exif segment whose TIFF header and IFD offsets are nonsense
    bad = b"Exif\0\0MM\0*\xff\xff\xff\xf0" + os.urandom(40)
    seg = b"\xff\xe1" + (len(bad) + 2).to_bytes(2, "big") + bad
    src = tmp_path / "broken_exif.jpg"
    src.write_bytes(data[:2] + seg + data[2:])
    r = restore(face, binary, [src], tmp_path / "o")
    assert r.returncode == 0, r.stderr
    side = json.load(open(tmp_path / "o" / "broken_exif.json"))
    assert side["metadata"]["exif_tags_carried"] == 0
    ifd0, exif, _, size, xmp = exif_of(tmp_path / "o" / "broken_exif.jpg")
    assert ifd0.get(0x0112) == 1 and record(xmp)[b"WaterType"].decode() == side["water_type"]


@pytest.mark.skipif(not IMAGES_DIR.is_dir(), reason="../shared/data is not here")
@pytest.mark.parametrize("face", FACES)
def test_a_shared_camera_jpeg_keeps_its_exif(face, binary, tmp_path):
    src = IMAGES_DIR / "udc_hazed2.jpg"
    assert restore(face, binary, [src], tmp_path).returncode == 0
    ifd0_in, exif_in, _, _, _ = exif_of(src)
    ifd0, exif, _, size, _ = exif_of(tmp_path / "udc_hazed2.jpg")
    for k in IFD0_CARRIED:
        if k in ifd0_in:
            assert ifd0[k] == ifd0_in[k], hex(k)
    for k, v in exif_in.items():
        if k not in REWRITTEN:
            assert exif.get(k) == v, hex(k)
    assert ifd0[0x010F] == "OLYMPUS IMAGING CORP." and exif[0x9003] == "2012:12:14 19:04:06"


@pytest.mark.skipif(not RAW_DIR.is_dir(), reason="../shared/data is not here")
@pytest.mark.parametrize("name, make, model", [("Nikon_uncompressed.nef", "Nikon", "Nikon COOLSCAN IV ED"),
                                              ("canon_eos_6d.dng", "Canon", "Canon EOS 6D")])
def test_raw_files_keep_their_exif_and_xmp(name, make, model, tmp_path):
    r = restore("python", None, [RAW_DIR / name], tmp_path, "--half-size")
    assert r.returncode == 0, r.stderr
    out = tmp_path / (os.path.splitext(name)[0] + ".jpg")
    ifd0, exif, _, size, xmp = exif_of(out)
    assert (ifd0[0x010F], ifd0[0x0110]) == (make, model) and ifd0[0x0112] == 1
    assert (exif[0xA002], exif[0xA003]) == size
    if name.endswith(".dng"):
        # the DNG's own XMP (lens, camera serial) stays beside the record
        assert b'aux:Lens="EF24-105mm f/4L IS USM"' in xmp and NS in xmp


def test_restoring_a_restored_photo_keeps_one_record(binary, gps_jpeg, tmp_path):
    assert restore("rust", binary, [gps_jpeg], tmp_path / "a").returncode == 0
    assert restore("rust", binary, [tmp_path / "a" / "dive_0001.jpg"], tmp_path / "b", "--water-type", "II").returncode == 0
    xmp = xmp_of(tmp_path / "b" / "dive_0001.jpg")
    assert xmp.count(NS) == 1 and record(xmp)[b"WaterType"] == b"II" and record(xmp)[b"WaterTypes"] == b"II"
    assert exif_of(tmp_path / "b" / "dive_0001.jpg")[2] == exif_of(gps_jpeg)[2]
