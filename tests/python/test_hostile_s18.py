"""What a hostile review of distance inputs, raw-frame pipes and JPEG
files found on 2026-12-06, in both commands: each case states its answer
independently of the code (a disc drawn by hand, a file cut at a known
place, a map in known wrong units, a lock held by the test itself)."""

from __future__ import annotations

import fcntl
import io
import json
import subprocess

import numpy as np
import pytest
from PIL import Image

from bothcmds import cmds, run_restore, sidecar
from exrfile import exr_bytes
from uwhl_rs import files, synth

IMPLS = ["python", "rust"]
H, W = 90, 120


@pytest.fixture(scope="module")
def seabed(tmp_path_factory):
    """A render in 3C water (open water above a seabed from 1 to 10 m) and
    its true distance in metres (NaN in the open water)."""
    d = tmp_path_factory.mktemp("seabed")
    sc = synth.scene(H, W, kind="open_water", seed=3)
    img = synth.render(sc.clean, sc.distance, "3C", beta_b=0.3, noise=0.004, seed=1)
    Image.fromarray((np.clip(img, 0, 1) ** (1 / 2.2) * 255).round().astype(np.uint8)).save(d / "sea.png")
    z = np.where(np.isfinite(sc.distance), sc.distance, np.nan).astype(np.float32)
    return d, z


def test_a_jpeg_mask_is_read_as_drawn_not_as_its_ringing(tmp_path):
    """A disc drawn 0/255 and saved by Pillow at quality 75: the mask read
    is the disc to within its edge, where nonzero codes ring well beyond it."""
    yy, xx = np.mgrid[:60, :80]
    disc = (yy - 29.3) ** 2 + (xx - 37.6) ** 2 <= 19.5 ** 2
    p = tmp_path / "mask.jpg"
    Image.fromarray(np.where(disc, 255, 0).astype(np.uint8)).save(p, quality=75)
    codes = np.asarray(Image.open(p))
    assert ((codes != 0) != disc).sum() > 100  # what the nonzero rule would have read
    m = files.read_mask(str(p), (60, 80), "--mask")
    assert (m != disc).sum() <= 12


def _cut_with_end_kept(jpg: bytes, keep: float) -> bytes:
    sos = jpg.index(b"\xff\xda")
    cut = jpg[: sos + int((len(jpg) - sos) * keep)].rstrip(b"\xff")
    return cut + b"\xff\xd9"


@pytest.mark.parametrize("impl", IMPLS)
def test_a_jpeg_cut_inside_its_scan_with_its_end_marker_is_refused(impl, binary, tmp_path):
    rng = np.random.default_rng(4)
    px = np.clip(rng.normal((60, 120, 150), 40, (160, 240, 3)), 0, 255).astype(np.uint8)
    buf = io.BytesIO()
    Image.fromarray(px).save(buf, format="JPEG", quality=90)
    whole = tmp_path / "whole.jpg"
    whole.write_bytes(buf.getvalue())
    cut = tmp_path / "cut.jpg"
    cut.write_bytes(_cut_with_end_kept(buf.getvalue(), 0.5))
    # Pillow itself decodes the cut file without an error: the gray below the cut is made up
    Image.open(cut).load()
    r = run_restore(cmds(binary)[impl], whole, "-o", tmp_path / "o1")
    assert r.returncode == 0, r.stderr
    r = run_restore(cmds(binary)[impl], cut, "-o", tmp_path / "o2")
    assert r.returncode == 3, r.stderr
    assert "a damaged JPEG: its scan data ends after" in r.stderr and "Traceback" not in r.stderr


@pytest.mark.parametrize("impl", IMPLS)
def test_distances_in_other_units_are_not_used(impl, binary, seabed, tmp_path):
    """The true map in hundredths of metres: blue would be 30 1/m, beyond
    the fit's search (5); the photo is restored without it and says why."""
    d, z = seabed
    np.save(tmp_path / "sea.npy", z * 0.01)
    r = run_restore(cmds(binary)[impl], d / "sea.png", "-o", tmp_path / "o", "--distance", tmp_path / "{stem}.npy")
    assert r.returncode == 0, r.stderr
    dist = sidecar(tmp_path / "o", "sea")["distance"]
    assert dist["used"] is False and "other units than metres" in dist["rejected"]
    # the same map in metres is used
    np.save(tmp_path / "sea.npy", z)
    r = run_restore(cmds(binary)[impl], d / "sea.png", "-o", tmp_path / "o2", "--distance", tmp_path / "{stem}.npy")
    assert sidecar(tmp_path / "o2", "sea")["distance"]["used"] is True


@pytest.mark.parametrize("impl", IMPLS)
def test_an_exr_map_cropped_inside_its_frame_or_with_two_depths_is_not_used(impl, binary, seabed, tmp_path):
    d, z = seabed
    crop = z[10:80, 10:110]
    cases = {
        "cropped": (exr_bytes({"Z": crop}, display=(-10, -10, W - 11, H - 11)), "data window"),
        "stereo": (exr_bytes({"left.Z": z, "right.Z": z * 1.1}), "two depth channels"),
        "attributes": (exr_bytes({"Z": z}, extra=20_000), "16384 attributes"),
    }
    for name, (data, why) in cases.items():
        (tmp_path / "sea.exr").write_bytes(data)
        out = tmp_path / name
        r = run_restore(cmds(binary)[impl], d / "sea.png", "-o", out, "--distance", tmp_path / "{stem}.exr")
        assert r.returncode == 0, r.stderr
        dist = sidecar(out, "sea")["distance"]
        assert dist["used"] is False and why in dist["rejected"], (name, dist["rejected"])


@pytest.mark.parametrize("impl", IMPLS)
def test_a_navigation_line_of_thousands_of_fields_is_refused_by_its_line(impl, binary, seabed, tmp_path):
    d, _ = seabed
    log = tmp_path / "nav.csv"
    log.write_text("file,altitude\nsea.png,2.0" + "," * 100_000 + "\n")
    r = run_restore(cmds(binary)[impl], d / "sea.png", "-o", tmp_path / "o", "--altitude", log, "--fov", "70")
    assert r.returncode == 2 and "line 2: more than 4096 fields" in r.stderr, r.stderr


@pytest.mark.parametrize("impl", IMPLS)
def test_a_rerun_with_another_altitude_field_of_view_or_window_says_so(impl, binary, seabed, tmp_path):
    d, _ = seabed
    cmd = cmds(binary)[impl]
    out = tmp_path / "o"
    assert run_restore(cmd, d / "sea.png", "-o", out, "--altitude", "2.5", "--fov", "70").returncode == 0
    for extra, flag in [(["--altitude", "3", "--fov", "70"], "--altitude"), (["--altitude", "2.5", "--fov", "60"], "--fov"),
                        (["--altitude", "2.5", "--fov", "70", "--port", "dome"], "--port")]:
        r = subprocess.run([*cmd, "restore", d / "sea.png", "-o", out, *extra], capture_output=True, text=True, timeout=300)
        assert f"restored with another {flag}" in r.stdout + r.stderr, (extra, r.stdout, r.stderr)
    r = subprocess.run([*cmd, "restore", d / "sea.png", "-o", out, "--altitude", "2.5", "--fov", "70"],
                       capture_output=True, text=True, timeout=300)
    assert "skipped" in r.stdout + r.stderr and "restored with another" not in r.stdout + r.stderr


def _frames(n, h=48, w=64, seed=0):
    rng = np.random.default_rng(seed)
    return np.clip(rng.normal((40, 110, 150), 30, (n, h, w, 3)), 0, 255).astype(np.uint8).tobytes()


def test_raw_frames_never_replace_another_inputs_outputs(binary, seabed, tmp_path):
    d, _ = seabed
    out = tmp_path / "o"
    photo = tmp_path / "frame_000000.png"
    photo.write_bytes((d / "sea.png").read_bytes())
    assert run_restore([binary], photo, "-o", out).returncode == 0
    before = (out / "frame_000000.jpg").read_bytes()
    r = subprocess.run([binary, "restore", "--raw-frames", "64x48", "-o", out, "-q"], input=_frames(2),
                       capture_output=True, timeout=300)
    lines = [json.loads(x) for x in r.stdout.decode().splitlines()]
    assert lines[0]["error"] == "write_failed" and "not replaced" in lines[0]["message"]
    assert lines[1]["input"] == "stdin#1" and "error" not in lines[1]
    assert (out / "frame_000000.jpg").read_bytes() == before
    assert sidecar(out, "frame_000000")["input"].endswith("frame_000000.png")


def test_a_second_pipe_into_a_folder_is_refused_and_max_side_with_frames(binary, tmp_path):
    out = tmp_path / "o"
    out.mkdir()
    with open(out / ".uwhl-frames.lock", "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)  # another pipe, as the test holds it
        r = subprocess.run([binary, "restore", "--raw-frames", "64x48", "-o", out], input=_frames(1),
                           capture_output=True, timeout=300)
    assert r.returncode == 5 and b"another --raw-frames run is writing to" in r.stderr
    assert not (out / "frame_000000.jpg").exists()
    r = subprocess.run([binary, "restore", "--raw-frames", "64x48", "-o", out], input=_frames(1),
                       capture_output=True, timeout=300)
    assert r.returncode == 0 and (out / "frame_000000.jpg").exists()
    for o in (out, "-"):
        r = subprocess.run([binary, "restore", "--raw-frames", "64x48", "--max-side", "32", "-o", o], input=_frames(1),
                           capture_output=True, timeout=300)
        assert r.returncode == 2 and b"--max-side with --raw-frames" in r.stderr


@pytest.mark.parametrize("impl", IMPLS)
def test_a_white_is_zero_tiff_map_is_refused_not_turned_over(impl, binary, seabed, tmp_path):
    tifffile = pytest.importorskip("tifffile")
    d, z = seabed
    mm = np.where(np.isfinite(z), np.round(z * 1000), 0).astype(np.uint16)
    tifffile.imwrite(tmp_path / "sea.tif", mm, photometric="miniswhite")
    r = run_restore(cmds(binary)[impl], d / "sea.png", "-o", tmp_path / "o", "--distance", tmp_path / "{stem}.tif")
    assert r.returncode == 0, r.stderr
    dist = sidecar(tmp_path / "o", "sea")["distance"]
    assert dist["used"] is False and "WhiteIsZero" in dist["rejected"]


@pytest.mark.parametrize("impl", IMPLS)
def test_a_log_whose_lines_end_in_cr_alone_is_read(impl, binary, seabed, tmp_path):
    d, _ = seabed
    log = tmp_path / "nav.csv"
    log.write_bytes(b"file,altitude\rsea.png,2.5\r")
    r = run_restore(cmds(binary)[impl], d / "sea.png", "-o", tmp_path / "o", "--altitude", log, "--fov", "70")
    assert r.returncode == 0, r.stderr
    assert sidecar(tmp_path / "o", "sea")["distance"]["floor"]["altitude"] == 2.5


def test_water_and_distance_given_in_python_take_what_the_commands_take():
    import uwhl_rs
    from uwhl_rs.errors import ParameterError
    img = synth.demo_input()[0][:64, :64]
    # bytes iterate as their codes (97, 98, 99) and a set has no order: neither is three attenuations
    for beta in (b"abc", {0.1, 0.2, 0.3}, [0.1, 0.2], "0.1,0.2,0.3"):
        with pytest.raises(ParameterError, match="three attenuations"):
            uwhl_rs.restore(img, water={"beta": beta})
    # blue 10 1/m (its ratios 0.5 and 0.83 are on the table's stretch) is no water --water-from takes
    with pytest.raises(ParameterError, match="no water a fit gives"):
        uwhl_rs.restore(img, water={"beta": [20.0, 12.0, 10.0]})
    assert uwhl_rs.restore(img, water={"beta": (0.35, 0.2, 0.23)}).water_type == "fitted"
    # a masked array's masked pixels are unknown, whatever lies under the mask
    z = np.ma.masked_array(np.full((64, 64), 0.5), mask=np.zeros((64, 64), bool))
    z.mask[:32] = True
    got = uwhl_rs.distances.distance_map(z, "distance")
    assert np.isnan(got[:32]).all() and (got[32:] == 0.5).all()
    with pytest.raises(ParameterError, match="dtype uint16"):
        uwhl_rs.distances.distance_map(np.ma.masked_array(np.ones((4, 4), np.uint16)), "distance")


def test_a_stream_whose_stdin_cannot_be_read_says_so_in_its_exit_code(binary, tmp_path):
    import os
    fd = os.open(tmp_path, os.O_RDONLY)  # a folder as stdin: reading it fails with EISDIR
    try:
        r = subprocess.run([binary, "restore", "--stream", "-o", tmp_path / "o"], stdin=fd, capture_output=True,
                           timeout=120)
    finally:
        os.close(fd)
    assert r.returncode == 3 and b"cannot read stdin" in r.stderr


@pytest.mark.parametrize("ext, codec", [("flv", "flv1"), ("ogv", "libtheora"), ("h264", "libx264"), ("asf", "wmv2")])
def test_videos_of_the_containers_read_are_taken_by_their_extension(ext, codec, binary, tmp_path):
    pytest.importorskip("av")
    from systools import installed
    src = tmp_path / f"clip.{ext}"
    r = subprocess.run([installed("ffmpeg", "ffmpeg"), "-v", "error", "-y", "-f", "lavfi", "-i",
                        "testsrc2=size=64x48:rate=10:duration=0.5", "-c:v", codec, "-pix_fmt", "yuv420p", src],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    r = run_restore(cmds(binary)["python"], src, "-o", tmp_path / "o")
    assert r.returncode == 0, r.stderr
    assert sidecar(tmp_path / "o", "clip")["video"]["frames"]["decoded"] == 5
    # the binary restores piped frames, not videos: it points at uwhl
    r = run_restore(cmds(binary)["rust"], src, "-o", tmp_path / "o2")
    assert r.returncode == 3 and "uwhl" in r.stderr


def test_a_pipe_of_which_no_frame_could_be_restored_says_why_even_quiet(binary):
    black = bytes(64 * 48 * 3)
    r = subprocess.run([binary, "restore", "--raw-frames", "64x48", "-o", "-", "-q"], input=black,
                       capture_output=True, timeout=120)
    assert r.returncode == 3 and r.stdout == black
    assert b"no frame could be restored (all 1 read from stdin); frame 0: image is constant" in r.stderr
    r = subprocess.run([binary, "restore", "--raw-frames", "64x48", "-o", "-", "--json-errors"], input=black,
                       capture_output=True, timeout=120)
    errors = [json.loads(x) for x in r.stderr.decode().splitlines() if x.startswith("{")]
    assert [e["message"].split(":")[0] for e in errors] == ["frame 0", "no frame could be restored (all 1 read from stdin); frame 0"]


def _png16(a: np.ndarray, extra: list[tuple[bytes, bytes]]) -> bytes:
    """A 16-bit grayscale PNG of ``a`` with ``extra`` chunks (type, data) before its pixels."""
    import struct
    import zlib

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)
    h, w = a.shape
    raw = b"".join(b"\0" + a[y].astype(">u2").tobytes() for y in range(h))
    return (b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, 16, 0, 0, 0, 0))
            + b"".join(chunk(k, d) for k, d in extra) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


@pytest.mark.parametrize("impl", IMPLS)
def test_a_png_maps_other_chunks_are_not_read_into_memory(impl, binary, seabed, tmp_path):
    import zlib
    d, z = seabed
    mm = np.where(np.isfinite(z), np.round(z * 1000), 0).astype(np.uint16)
    # a profile of 300 MB compressed to 300 KB: passed over, the map is used
    iccp = b"icc\0\0" + zlib.compress(bytes(300 << 20), 9)
    (tmp_path / "sea.png").write_bytes(_png16(mm, [(b"iCCP", iccp)]))
    r = run_restore(cmds(binary)[impl], d / "sea.png", "-o", tmp_path / "o", "--distance", tmp_path / "{stem}.png",
                    "--max-memory", "200M")
    assert r.returncode == 0, r.stderr
    assert sidecar(tmp_path / "o", "sea")["distance"]["used"] is True
    # 40 MB of EXIF beside a map: refused by name, not held
    (tmp_path / "sea.png").write_bytes(_png16(mm, [(b"eXIf", b"MM\0*" + bytes(40 << 20))]))
    r = run_restore(cmds(binary)[impl], d / "sea.png", "-o", tmp_path / "o2", "--distance", tmp_path / "{stem}.png")
    dist = sidecar(tmp_path / "o2", "sea")["distance"]
    assert dist["used"] is False and "a PNG distance map cannot be read" in dist["rejected"]


@pytest.mark.parametrize("impl", IMPLS)
def test_transfer_given_to_photos_only_is_said_to_do_nothing(impl, binary, seabed, tmp_path):
    d, _ = seabed
    r = subprocess.run([*cmds(binary)[impl], "restore", d / "sea.png", "-o", tmp_path / "o", "--transfer", "linear"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert "note: --transfer is the curve of video and raw-frame samples" in r.stderr
    # without it, no such note
    r = subprocess.run([*cmds(binary)[impl], "restore", d / "sea.png", "-o", tmp_path / "o2"],
                       capture_output=True, text=True, timeout=300)
    assert "--transfer" not in r.stderr


def test_the_api_names_its_own_keywords_and_numbers_compactly(seabed, tmp_path):
    import uwhl_rs
    from uwhl_rs.errors import ParameterError
    d, z = seabed
    for kw, said in [({"altitude": 2.5, "fov": 10 ** 400}, r"fov 1e\+400 is out of range"),
                     ({"altitude": 10 ** 400, "fov": 70}, r"altitude 1e\+400 is out of range")]:
        with pytest.raises(ParameterError, match=said):
            uwhl_rs.restore_file(d / "sea.png", tmp_path / "o", **kw)
    np.save(tmp_path / "z.npy", z)
    with pytest.raises(MemoryError, match="over max_pixels 10"):
        uwhl_rs.read_distance(tmp_path / "z.npy", max_pixels=10)


def test_a_video_rerun_with_other_video_options_says_which(tmp_path):
    pytest.importorskip("av")
    import sys
    from systools import installed
    src = tmp_path / "clip.mp4"
    r = subprocess.run([installed("ffmpeg", "ffmpeg"), "-v", "error", "-y", "-f", "lavfi", "-i",
                        "testsrc2=size=64x48:rate=10:duration=1", "-c:v", "libx264", "-pix_fmt", "yuv420p", src],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr

    def rerun(*extra):
        r = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", src, "-o", tmp_path / "o", *extra],
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stderr
        return r.stdout
    rerun("--every", "5")
    assert "restored with another" not in rerun("--every", "5")
    assert "restored with another --every" in rerun()
    assert "restored with another --every, --video-codec" in rerun("--video-codec", "ffv1")
