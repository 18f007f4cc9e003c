"""The second hostile pass over issue 30's surfaces (both commands): what
it found broken, each a case built here. EXIF times and GPS positions
that cannot exist (the sidecar's readers refused the whole photo, so the
report and the iFDO lost it), TIFF layouts the decoder cannot read and
BigTIFF named in words, an input named ``ifdo`` (its sidecar was the
iFDO's own ``ifdo.json``), a water type listed twice (one usage error,
not a failure per input), the iFDO's message when every sidecar is left
out, the report opening files no batch takes as inputs, and the metadata
of a TIFF read again only within what its pixels took.

Expected values are hand-made (calendar dates, degrees, the documented
naming rule), not copied from either command's output."""

from __future__ import annotations

import hashlib
import io
import json
import os
import struct

import numpy as np
import pytest
import yaml
from PIL import Image

from test_hostile_outdir import FACES, _run
from test_hostile_report import uwhl
from test_ifdo import HEADER, POSITION


def _pixels(h=48, w=64, seed=3):
    rng = np.random.default_rng(seed)
    base = np.linspace(20, 200, h * w * 3).reshape(h, w, 3)
    return np.clip(base + rng.normal(0, 12, base.shape), 0, 255).astype(np.uint8)


def _gps_jpeg(path, lat_deg, lon_deg=10, when="2026:01:02 03:04:05", seed=3):
    """A JPEG whose EXIF holds GPS degrees (whole, north/east) and a
    DateTimeOriginal, as a camera writes them (rationals)."""
    from PIL.TiffImagePlugin import IFDRational as R

    ex = Image.Exif()
    g = ex.get_ifd(0x8825)
    g[1], g[2] = "N", (R(lat_deg, 1), R(0, 1), R(0, 1))
    g[3], g[4] = "E", (R(lon_deg, 1), R(0, 1), R(0, 1))
    ex.get_ifd(0x8769)[0x9003] = when
    Image.fromarray(_pixels(seed=seed)).save(path, quality=90, exif=ex)


def _error_lines(r) -> list[str]:
    return [x for x in r.stderr.splitlines() if x.strip()]


def _header(path):
    path.write_text(yaml.safe_dump({**HEADER, **POSITION}))
    return path


# ------------------------------------------------------------------ times and positions that cannot exist


@pytest.mark.parametrize("face", FACES)
def test_an_impossible_exif_time_or_position_is_dropped_and_the_photo_stays_in_the_report(binary, tmp_path, face):
    """Latitude 1000 and 9999:99:99 99:99:99 used to reach the sidecar as
    they were; the sidecar's readers then refused it whole, so the report
    showed 0 photos and the iFDO said no sidecar was found."""
    d = tmp_path / "in"
    d.mkdir()
    _gps_jpeg(d / "a.jpg", lat_deg=1000, when="9999:99:99 99:99:99")
    out = tmp_path / "out"
    r = _run(face, binary, [d, "-o", out, "-q"])
    assert r.returncode == 0, r.stderr
    md = json.loads((out / "a.json").read_text())["metadata"]
    assert md["taken_at"] is None and md["gps"] is None
    notes = " ".join(md["notes"])
    assert "time" in notes and "position" in notes, notes
    page = uwhl("report", out)
    assert page.returncode == 0 and "(1 photo," in page.stdout, page.stdout + page.stderr


@pytest.mark.parametrize("when, expected", [
    ("2024:02:29 23:59:59", "2024-02-29T23:59:59"),  # a leap day
    ("2023:02:29 12:00:00", None),  # no 29 February in 2023
    ("2026:04:31 12:00:00", None),  # April has 30 days
    ("2026:13:01 12:00:00", None),
    ("2026:01:01 24:00:00", None),
    ("0000:00:00 00:00:00", None),  # a camera whose clock was never set
    ("1900:02:29 00:00:00", None),  # 1900 is no leap year
    ("2000:02:29 00:00:00", "2000-02-29T00:00:00"),  # 2000 is
])
def test_exif_times_are_recorded_only_when_the_date_exists(binary, tmp_path, when, expected):
    _gps_jpeg(tmp_path / "a.jpg", lat_deg=10, when=when)
    r = _run("rust", binary, [tmp_path / "a.jpg", "-o", tmp_path / "out", "-q"])
    assert r.returncode == 0, r.stderr
    md = json.loads((tmp_path / "out" / "a.json").read_text())["metadata"]
    assert md["taken_at"] == expected
    assert md["gps"]["latitude"] == 10.0 and md["gps"]["longitude"] == 10.0


@pytest.mark.parametrize("lat, lon, kept", [(90, 180, True), (91, 10, False), (10, 181, False)])
def test_positions_off_the_globe_are_none(binary, tmp_path, lat, lon, kept):
    _gps_jpeg(tmp_path / "a.jpg", lat_deg=lat, lon_deg=lon)
    r = _run("rust", binary, [tmp_path / "a.jpg", "-o", tmp_path / "out", "-q"])
    assert r.returncode == 0, r.stderr
    gps = json.loads((tmp_path / "out" / "a.json").read_text())["metadata"]["gps"]
    assert (gps == {"latitude": float(lat), "longitude": float(lon), "altitude": None}) if kept else gps is None


# ------------------------------------------------------------------ TIFF layouts named in words


@pytest.mark.parametrize("face", FACES)
@pytest.mark.parametrize("bits", [8, 16])
def test_a_gray_alpha_tiff_names_what_it_holds(binary, tmp_path, face, bits):
    """It said "unsupported color type Unknown(16)", the decoder's own name."""
    tifffile = pytest.importorskip("tifffile")
    g = (np.random.default_rng(1).random((40, 50)) * 200).astype(np.uint8 if bits == 8 else np.uint16)
    tifffile.imwrite(tmp_path / "ga.tif", np.stack([g, g], -1), photometric="minisblack",
                     extrasamples=["unassalpha"], planarconfig="contig")
    r = _run(face, binary, [tmp_path / "ga.tif", "-o", tmp_path / "out"])
    assert r.returncode == 3, r.stderr
    assert any("ga.tif" in x and f"2 samples per pixel (gray + alpha), {bits} bits each" in x
               and "gray, RGB, RGBA and CMYK" in x for x in _error_lines(r)), r.stderr


@pytest.mark.parametrize("face", FACES)
def test_a_half_float_tiff_says_floating_point(binary, tmp_path, face):
    tifffile = pytest.importorskip("tifffile")
    rgb = np.random.default_rng(1).random((40, 50, 3)).astype(np.float16)
    tifffile.imwrite(tmp_path / "h.tif", rgb, photometric="rgb")
    r = _run(face, binary, [tmp_path / "h.tif", "-o", tmp_path / "out"])
    assert r.returncode == 3, r.stderr
    assert any("h.tif" in x and "3 samples per pixel (RGB), 16 bits each, floating point" in x
               for x in _error_lines(r)), r.stderr


@pytest.mark.parametrize("face", FACES)
def test_a_bigtiff_is_named_not_unrecognised(binary, tmp_path, face):
    tifffile = pytest.importorskip("tifffile")
    tifffile.imwrite(tmp_path / "b.tif", _pixels(), photometric="rgb", bigtiff=True)
    assert (tmp_path / "b.tif").read_bytes()[:4] == b"II+\0"
    r = _run(face, binary, [tmp_path / "b.tif", "-o", tmp_path / "out"])
    assert r.returncode == 3, r.stderr
    assert any("b.tif" in x and "BigTIFF" in x for x in _error_lines(r)), r.stderr
    assert "unrecognised signature" not in r.stderr


# ------------------------------------------------------------------ an input named ifdo


@pytest.mark.parametrize("face", FACES)
def test_an_input_named_ifdo_never_has_the_ifdos_file_as_its_sidecar(binary, tmp_path, face):
    """Its sidecar was ifdo.json, which the report and the iFDO take as the
    iFDO's own file (left out: 0 photos) and ``uwhl ifdo --format json``
    replaces. docs/OUTPUTS.md: the name ifdo goes to ifdo_2."""
    d = tmp_path / "in"
    d.mkdir()
    _gps_jpeg(d / "ifdo.jpg", lat_deg=10)
    out = tmp_path / "out"
    r = _run(face, binary, [d, "-o", out, "-q"])
    assert r.returncode == 0, r.stderr
    assert not (out / "ifdo.json").exists()
    side = json.loads((out / "ifdo_2.json").read_text())
    assert side["outputs"]["image"] == "ifdo_2.jpg"
    page = uwhl("report", out)
    assert "(1 photo," in page.stdout, page.stdout + page.stderr
    r = uwhl("ifdo", out, "--header", _header(tmp_path / "h.yaml"), "--format", "json")
    assert r.returncode == 0, r.stderr
    assert "image-set-header" in json.loads((out / "ifdo.json").read_text())
    assert json.loads((out / "ifdo_2.json").read_text()) == side
    # a rerun recognises it as done
    r = _run(face, binary, [d, "-o", out, "-q"])
    assert r.returncode == 0 and not (out / "ifdo_3.json").exists(), r.stderr


# ------------------------------------------------------------------ water types


def test_a_water_type_listed_twice_is_one_usage_error_before_any_input(binary, tmp_path):
    """``uwhl restore`` failed each input with it (three lines, "3 input(s)
    failed"); the binary refuses it once, at parsing: both do now."""
    d = tmp_path / "in"
    d.mkdir()
    for k in range(3):
        Image.fromarray(_pixels(seed=k)).save(d / f"f{k}.png")
    for face in FACES:
        r = _run(face, binary, [d, "-o", tmp_path / f"out_{face}", "--water-type", "3C,II,3C"])
        assert r.returncode == 2, (face, r.stderr)
        lines = [x for x in _error_lines(r) if "listed twice" in x]
        assert len(lines) == 1 and "--water-type" in lines[0] and '"3C"' in lines[0], (face, r.stderr)
        assert "input(s) failed" not in r.stderr, (face, r.stderr)
        assert not (tmp_path / f"out_{face}" / "f0.json").exists()


def test_the_api_refuses_a_water_type_listed_twice_when_the_parameters_are_made():
    from uwhl_rs import _core
    from uwhl_rs.errors import UwhlError

    with pytest.raises(UwhlError, match='"3C" is listed twice'):
        _core.Params(water_types=["3C", "II", "3C"])
    with pytest.raises(UwhlError, match='"X" is listed twice'):
        _core.Params(water_types=[("X", 0.7, 1.1), ("X", 0.8, 1.2)])


# ------------------------------------------------------------------ the iFDO says why it has no photo


def test_an_ifdo_whose_sidecars_are_all_left_out_names_them(binary, tmp_path):
    """It said "no sidecar of uwhl restore found" with a usable-looking
    sidecar in the folder; the notes that said why were dropped."""
    _gps_jpeg(tmp_path / "a.jpg", lat_deg=10)
    out = tmp_path / "out"
    assert _run("rust", binary, [tmp_path / "a.jpg", "-o", out, "-q"]).returncode == 0
    side = json.loads((out / "a.json").read_text())
    side["veiling_light"] = "bright"
    (out / "a.json").write_text(json.dumps(side))
    r = uwhl("ifdo", out, "--header", _header(tmp_path / "h.yaml"))
    assert r.returncode == 2, r.stderr
    assert "a.json" in r.stderr and "veiling_light" in r.stderr, r.stderr
    assert "no sidecar of uwhl restore found" not in r.stderr


# ------------------------------------------------------------------ the report opens only what a batch takes


def test_the_report_does_not_open_a_file_no_batch_takes_as_an_input(binary, tmp_path):
    """A planted sidecar naming a file outside the batch with that file's
    true hash had the report hash it and thumbnail it (here a PNG saved
    as ``notes.txt``): a name a batch never takes is refused unopened."""
    _gps_jpeg(tmp_path / "a.jpg", lat_deg=10)
    out = tmp_path / "out"
    assert _run("rust", binary, [tmp_path / "a.jpg", "-o", out, "-q"]).returncode == 0
    secret = tmp_path / "elsewhere" / "notes.txt"
    secret.parent.mkdir()
    Image.fromarray(_pixels(seed=9)).save(secret, format="PNG")
    side = json.loads((out / "a.json").read_text())
    side["input"] = str(secret)
    side["metadata"]["input_sha256"] = hashlib.sha256(secret.read_bytes()).hexdigest()
    (out / "a.json").write_text(json.dumps(side))
    r = uwhl("report", out)
    assert r.returncode == 0, r.stderr
    text = r.stdout + r.stderr
    assert "notes.txt" in text and "not opened" in text, text
    thumbs = os.listdir(out / "report" / "thumbs")
    assert not [t for t in thumbs if t.endswith("_in.jpeg")], thumbs


# ------------------------------------------------------------------ metadata read again, bounded


def _tiff_with_tail(path, tail: int):
    """An 8-bit RGB TIFF with a Make tag and `tail` bytes after its IFD
    that nothing points at: a file far larger than its pixels."""
    tifffile = pytest.importorskip("tifffile")
    buf = io.BytesIO()
    tifffile.imwrite(buf, _pixels(), photometric="rgb", extratags=[(0x010F, "s", 0, "SeaCam", True)])
    path.write_bytes(buf.getvalue() + bytes(tail))


def test_a_tiff_far_larger_than_its_pixels_is_not_read_whole_again(binary, tmp_path):
    """The metadata of a TIFF was carried by reading the whole file again,
    whatever its size. Now at most what its pixels took when decoded (RGBA
    at its bits) and a 16 MiB block of tags: this one's 48x64 pixels are
    12 KiB, the file 17 MiB; its EXIF is not carried, with a note."""
    _tiff_with_tail(tmp_path / "big.tif", 17 << 20)
    _tiff_with_tail(tmp_path / "small.tif", 0)
    r = _run("rust", binary, [tmp_path / "big.tif", tmp_path / "small.tif", "-o", tmp_path / "out", "-q"])
    assert r.returncode == 0, r.stderr
    big = json.loads((tmp_path / "out" / "big.json").read_text())["metadata"]
    small = json.loads((tmp_path / "out" / "small.json").read_text())["metadata"]
    assert small["exif_tags_carried"] > 0 and not small["notes"], small
    assert big["exif_tags_carried"] == 0 and any("not carried" in n for n in big["notes"]), big
    # the hash is still of the whole file
    assert big["input_sha256"] == hashlib.sha256((tmp_path / "big.tif").read_bytes()).hexdigest()


def test_a_jpeg_is_hashed_whole_and_its_metadata_found_without_reading_it_all(binary, tmp_path):
    """What the streamed reading must keep: the hash of every byte, and the
    EXIF of a JPEG followed by 17 MiB of bytes after its end."""
    _gps_jpeg(tmp_path / "a.jpg", lat_deg=10)
    with open(tmp_path / "a.jpg", "ab") as f:
        f.write(b"\x5a" * (17 << 20))
    r = _run("rust", binary, [tmp_path / "a.jpg", "-o", tmp_path / "out", "-q"])
    assert r.returncode == 0, r.stderr
    md = json.loads((tmp_path / "out" / "a.json").read_text())["metadata"]
    assert md["input_sha256"] == hashlib.sha256((tmp_path / "a.jpg").read_bytes()).hexdigest()
    assert md["gps"]["latitude"] == 10.0 and md["taken_at"] == "2026-01-02T03:04:05"
    assert struct.unpack(">H", (tmp_path / "out" / "a.jpg").read_bytes()[:2])[0] == 0xFFD8


# ------------------------------------------------------------------ bytes after a JPEG's end


@pytest.mark.parametrize("face", FACES)
def test_a_jpeg_with_a_video_appended_after_its_end_is_restored(binary, tmp_path, face):
    """Phones append a video after the end-of-image marker (Motion Photos).
    A start-of-scan marker in those bytes with no end marker after it made
    the photo "truncated"; completeness is the segments' walk to the end
    marker now, whatever follows it."""
    _gps_jpeg(tmp_path / "m.jpg", lat_deg=10)
    with open(tmp_path / "m.jpg", "ab") as f:
        f.write(b"\0\0\0\x18ftypmp42" + b"\xff\xda\x00\x08" + b"\x11" * 1000)
    r = _run(face, binary, [tmp_path / "m.jpg", "-o", tmp_path / "out", "-q"])
    assert r.returncode == 0, r.stderr
    side = json.loads((tmp_path / "out" / "m.json").read_text())
    assert (side["source"]["height"], side["source"]["width"]) == (48, 64)


@pytest.mark.parametrize("face", FACES)
def test_a_jpeg_cut_inside_its_scan_is_still_truncated(binary, tmp_path, face):
    _gps_jpeg(tmp_path / "c.jpg", lat_deg=10)
    data = (tmp_path / "c.jpg").read_bytes()
    (tmp_path / "c.jpg").write_bytes(data[:data.index(b"\xff\xda") + 200])
    r = _run(face, binary, [tmp_path / "c.jpg", "-o", tmp_path / "out"])
    assert r.returncode == 3 and "truncated" in r.stderr, r.stderr


# ------------------------------------------------------------------ the memory plan holds for a tagged photo


def _peak_rss_of(argv) -> tuple[int, str]:
    """Peak resident bytes of one run of ``argv``, measured by a fresh
    Python parent (so no earlier child of the test session counts)."""
    import subprocess
    import sys

    code = ("import resource, subprocess, sys; r = subprocess.run(sys.argv[1:], capture_output=True, text=True); "
            "print(resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss); print(r.returncode); print(r.stderr)")
    out = subprocess.run([sys.executable, "-c", code, *map(str, argv)], capture_output=True, text=True, timeout=600)
    kib, rc, err = out.stdout.split("\n", 2)
    return int(kib) * 1024, f"{rc}: {err}"


def test_a_large_tagged_jpeg_with_max_side_stays_within_its_memory_plan(binary, tmp_path):
    """A 12 MP JPEG in Adobe RGB restored with --max-side 1024 peaked far
    over the plan the binary checks (docs/PERFORMANCE.md): the ICC
    conversion copied the whole image (24 bytes a pixel against the plan's
    18) and the full-size values stayed alive through the restoration of
    the small copy. The plan is the binary's own number (its refusal at a
    budget too small names it); the run must peak within it, above what the
    same binary holds when it refuses the file before decoding."""
    from test_icc import ADOBE_PHOTO

    if not ADOBE_PHOTO.exists():
        pytest.skip("../shared/data is not here")
    with Image.open(ADOBE_PHOTO) as im:
        icc = im.info["icc_profile"]
    h, w = 3000, 4000
    y, x = np.mgrid[0:h, 0:w]
    rgb = np.stack([40 + 60 * x / w, 90 + 80 * y / h, 150 + 40 * (x + y) / (w + h)], -1)
    rgb += np.random.default_rng(4).normal(0, 6, rgb.shape)
    photo = tmp_path / "big.jpg"
    Image.fromarray(np.clip(rgb, 0, 255).astype(np.uint8)).save(photo, quality=85, icc_profile=icc)
    args = [binary, "restore", photo, "-q", "--threads", "1", "--max-side", "1024"]
    # the plan, as the binary states it when refusing
    _, said = _peak_rss_of([*args, "-o", tmp_path / "o1", "--max-memory", str(photo.stat().st_size + (1 << 20))])
    import re

    m = re.search(r"need about (\d+) bytes", said)
    assert m, said
    plan = int(m.group(1))
    # what the process holds with nothing decoded (the file refused by its size)
    base, said = _peak_rss_of([*args, "-o", tmp_path / "o2", "--max-memory", "1M"])
    assert "over --max-memory" in said, said
    peak, said = _peak_rss_of([*args, "-o", tmp_path / "o3", "--max-memory", str(2 * plan)])
    assert said.startswith("0:"), said
    assert peak - base <= plan, f"peak {peak - base} bytes over the process's own, plan {plan}"


@pytest.mark.parametrize("face", FACES)
def test_a_tiff_cut_short_says_so(binary, tmp_path, face):
    """It said "cannot decode: failed to fill whole buffer"."""
    tifffile = pytest.importorskip("tifffile")
    buf = io.BytesIO()
    tifffile.imwrite(buf, _pixels(), photometric="rgb")
    data = buf.getvalue()
    (tmp_path / "cut.tif").write_bytes(data[:len(data) // 2])
    r = _run(face, binary, [tmp_path / "cut.tif", "-o", tmp_path / "out"])
    assert r.returncode == 3, r.stderr
    assert any("cut.tif" in x and "ends before its image data" in x for x in _error_lines(r)), r.stderr


# ------------------------------------------------------------------ an output name the file system cannot hold


@pytest.mark.parametrize("face", FACES)
def test_an_input_whose_output_names_are_too_long_fails_before_it_is_decoded(tmp_path, binary, face):
    """A 250-byte stem fits as an input name (254 bytes with .png) but its
    outputs (``_t_color.png``: 262 bytes) do not fit the 255 bytes a file
    name may have. The input is refused when its names are claimed, before
    it is decoded: its bytes are no image at all, and the error is the
    name's, not the decoder's. The other input is restored."""
    d = tmp_path / "in"
    d.mkdir()
    (d / ("a" * 250 + ".png")).write_bytes(b"not an image")
    Image.fromarray(_pixels()).save(d / "ok.png")
    r = _run(face, binary, [str(d), "-o", str(tmp_path / "out"), "-q"])
    assert r.returncode == 5, (r.returncode, r.stderr)
    assert "more than the 255 a file name may have" in r.stderr and "decode" not in r.stderr.lower(), r.stderr
    assert (tmp_path / "out" / "ok.json").exists()
    assert not [p for p in os.listdir(tmp_path / "out") if p.startswith("a" * 20)]
