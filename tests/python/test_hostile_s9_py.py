"""Hostile inputs of the ninth pass, Python side: a video's outputs on a
full disk (a failed write, exit 5, naming the output and not its
temporary), the command's messages naming options by their flags as
uwhl-rs does, empty and foreign files given as videos, unknown
single-dash options, integer distance arrays in the API (metres or
millimetres?), numbers too large for the API's parameters, and the API's
shapes, dtypes and water-type names that ``restore`` and
``depth_to_range`` took differently.

Each case says what must happen independently of the code: the exit
code and error kind of docs/CLI.md, the flag's spelling of the binary,
the package's ParameterError with a message naming the parameter."""

from __future__ import annotations

import json
import os
import resource
import signal
import subprocess
import sys

import numpy as np
import pytest

import uwhl_rs

#: where the package this test imported lives (the repository's python/ with a built extension beside it, or
#: site-packages after `pip install`): the commands run here import the same one
PYTHON_DIR = os.path.dirname(os.path.dirname(os.path.abspath(uwhl_rs.__file__)))


def _env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = PYTHON_DIR + os.pathsep + env.get("PYTHONPATH", "")
    # a file size limit would cut the interpreter's own .pyc files short
    env["PYTHONDONTWRITEBYTECODE"] = "1"
    return env


def uwhl(*args, cwd=None, preexec_fn=None, timeout=300) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "uwhl_rs", *map(str, args)], capture_output=True, text=True,
                          env=_env(), cwd=cwd, preexec_fn=preexec_fn, timeout=timeout)


def _file_size_limit(limit: int):
    """A child whose files cannot grow past ``limit`` bytes: a write past it
    fails with EFBIG, as on a full disk with ENOSPC (SIGXFSZ ignored, so the
    write fails instead of the process being killed)."""

    def pre():
        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return pre


def _video(path, n=24, h=48, w=64):
    from test_hostile_video import _write

    _write(path, n=n, codec="ffv1", pix="bgr0", h=h, w=w)


def _error(stderr: str) -> dict:
    lines = [json.loads(x) for x in stderr.splitlines() if x.startswith("{")]
    assert len(lines) == 1, stderr
    return lines[0]


# ------------------------------------------------------------------ 1. a full disk while writing a video


@pytest.mark.parametrize("extra", [[], ["--every", "6", "--format", "png", "--bits", "16"]],
                         ids=["video", "stills"])
def test_a_video_that_cannot_be_written_is_a_failed_write_naming_its_output(tmp_path, extra):
    """The restored video (24 lossless frames, some 100 KB) and a 16-bit
    still (18 KB) cannot be written under a 10 KB file size limit. That is
    a failed write (exit 5, write_failed) naming the output, as for a
    photo; it used to be an unreadable input (exit 3) naming the
    temporary ``.uwhl-PID-0.tmp.mp4``."""
    pytest.importorskip("av")
    src = tmp_path / "clip.mkv"
    _video(src)
    out = tmp_path / "out"
    r = uwhl("restore", src, "-o", out, "--video-codec", "ffv1", "--json-errors", "-q", *extra,
             preexec_fn=_file_size_limit(10_000))
    assert r.returncode == 5, r.stderr
    e = _error(r.stderr)
    assert e["error"] == "write_failed" and e["exit_code"] == 5, e
    assert ".uwhl-" not in e["message"] and ".tmp" not in e["message"], e
    assert e["message"].startswith(f"cannot write {out}{os.sep}clip"), e
    assert "File too large" in e["message"], e
    # nothing of the video is left but the summary
    assert sorted(os.listdir(out)) == ["summary.csv"]


def test_the_encoder_closing_on_a_full_disk_is_a_failed_write():
    """The container's trailer, written when it is closed, is where a full
    disk showed first; its error was raised from a ``finally`` outside the
    handler. A container whose close fails with ENOSPC now gives
    write_failed naming the output; abandoning the video after another
    error keeps that error (the close's own is dropped)."""
    import errno

    av = pytest.importorskip("av")
    from uwhl_rs.errors import CommandError, kind_of
    from uwhl_rs.videoencode import Writer

    class Full:
        closed = 0

        def mux(self, packet):
            pass

        def close(self):
            Full.closed += 1
            raise av.error.OSError(errno.ENOSPC, "No space left on device", "/out/.uwhl-1-0.tmp.mp4")

    class Encoder:
        def encode(self, frame=None):
            return []

    w = Writer.__new__(Writer)
    w.av, w.out, w.video, w.shown = av, Full(), Encoder(), "/out/dive.mp4"
    with pytest.raises(CommandError) as got:
        w.close()
    assert kind_of(got.value) == "write_failed"
    assert str(got.value) == "cannot write /out/dive.mp4: No space left on device (os error 28)"
    w.out = Full()
    w.close(flush=False)  # no error of its own
    assert Full.closed == 2


# ------------------------------------------------------------------ 2. the command's messages name flags


def _png(path, h=48, w=64, seed=0):
    from PIL import Image

    rng = np.random.default_rng(seed)
    Image.fromarray(rng.integers(0, 256, (h, w, 3), dtype=np.uint8)).save(path)


def _said(r: subprocess.CompletedProcess, prog: str) -> str:
    """The line that reports the input, without the command's name."""
    lines = [x for x in r.stderr.splitlines() if x.startswith(prog + ": ") and "input(s) failed" not in x]
    assert len(lines) == 1, r.stderr
    return lines[0][len(prog) + 2:]


def test_the_commands_name_the_memory_and_mask_options_as_flags(binary, tmp_path):
    """``uwhl restore`` said ``over max_memory N (use max_side or raise
    max_memory)`` and ``mask is 32x24 pixels but the image is ...``, the
    API's keywords, where uwhl-rs says ``--max-memory`` and ``--mask``.
    Both commands now say the same words; the API keeps its keywords."""
    import uwhl_rs.files

    photo, small = tmp_path / "p.png", tmp_path / "m.png"
    _png(photo)
    _png(small, 24, 32)
    runs = {}
    for prog, cmd in (("uwhl", [sys.executable, "-m", "uwhl_rs"]), ("uwhl-rs", [binary])):
        for case, extra in (("memory", ["--max-memory", "1M"]), ("mask", ["--mask", small]),
                            ("water", ["--water-mask", small])):
            r = subprocess.run([*cmd, "restore", photo, "-o", tmp_path / f"{prog}-{case}", "-q", *map(str, extra)],
                               capture_output=True, text=True, env=_env(), timeout=300)
            runs[prog, case] = (r.returncode, _said(r, prog))
    for case in ("memory", "mask", "water"):
        assert runs["uwhl", case][0] == runs["uwhl-rs", case][0], (case, runs)
    tail = "over --max-memory 1048576 (use --max-side or raise --max-memory)"
    assert runs["uwhl", "memory"][1].endswith(tail) and runs["uwhl-rs", "memory"][1].endswith(tail), runs
    assert runs["uwhl", "mask"][1] == runs["uwhl-rs", "mask"][1] == \
        f"{photo}: --mask is 32x24 pixels but the input is 64x48"
    assert runs["uwhl", "water"][1] == runs["uwhl-rs", "water"][1] == \
        f"{photo}: --water-mask is 32x24 pixels but the input is 64x48"
    # the API's own words name its keywords
    # (without the interpreter's own memory, which the command counts, the photo needs some 400 KB)
    with pytest.raises(uwhl_rs.ImageTooLargeError, match=r"over max_memory 10000 \(use max_side or raise max_memory\)"):
        uwhl_rs.files.restore_file(photo, tmp_path / "api", max_memory=10000)
    with pytest.raises(uwhl_rs.ParameterError, match="^mask is 32x24 pixels but the image is 64x48$"):
        uwhl_rs.files.restore_file(photo, tmp_path / "api", mask=small)


@pytest.mark.parametrize("flag,value", [("--mask", "m.png"), ("--water-mask", "m.png"), ("--half-size", None),
                                        ("--preprocess", "reference"), ("--distance", "d.npy"), ("--altitude", "3")])
def test_a_photo_option_given_for_a_video_is_named_as_its_flag(tmp_path, flag, value):
    """``uwhl restore clip.mkv --mask m.png`` said ``mask is for photos``:
    the flag the user typed is ``--mask`` (a usage error, exit 2)."""
    pytest.importorskip("av")
    src = tmp_path / "clip.mkv"
    _video(src, n=2)
    _png(tmp_path / "m.png")
    r = uwhl("restore", src, "-o", tmp_path / "o", "-q", flag, *([value] if value else []), cwd=tmp_path)
    assert r.returncode == 2, r.stderr
    assert _said(r, "uwhl") == f"{src}: {flag} is for photos: a video is restored as a sequence of frames"


def test_a_videos_budget_is_named_as_the_flags(tmp_path):
    """The frames' memory and pixel limits of a video, said with the flags."""
    pytest.importorskip("av")
    src = tmp_path / "clip.mkv"
    _video(src, n=2)
    r = uwhl("restore", src, "-o", tmp_path / "o", "-q", "--max-memory", "1M")
    assert r.returncode == 4, r.stderr
    assert _said(r, "uwhl").endswith("over --max-memory 1048576 (use --max-side or raise --max-memory)"), r.stderr
    r = uwhl("restore", src, "-o", tmp_path / "o", "-q", "--max-pixels", "100")
    assert r.returncode == 4, r.stderr
    assert _said(r, "uwhl") == f"{src}: 64x48 frames are over --max-pixels 100"


def test_a_raw_files_pixel_limit_is_said_as_for_a_png(tmp_path):
    """A raw file (read by LibRaw, in the Python command only) over
    ``--max-pixels`` said ``WxH pixels is over the limit of N (max_pixels)``;
    a PNG, read by the core's decoder, says ``WxH = P pixels is over the
    limit of N pixels (--max-pixels)``. The raw file now says the same."""
    from datapaths import RAW_DIR

    raw = RAW_DIR / "Blackmagic.dng"
    if not raw.exists():
        pytest.skip(f"the shared raw photographs are not at {RAW_DIR}")
    png = tmp_path / "p.png"
    _png(png)
    said = {}
    for p in (raw, png):
        r = uwhl("restore", p, "-o", tmp_path / "o", "-q", "--max-pixels", "100")
        assert r.returncode == 4, r.stderr
        said[p] = _said(r, "uwhl")
    assert said[png] == f"{png}: 64x48 = 3072 pixels is over the limit of 100 pixels (--max-pixels)"
    import re

    assert re.fullmatch(rf"{re.escape(str(raw))}: (\d+)x(\d+) = (\d+) pixels is over the limit of 100 pixels "
                        r"\(--max-pixels\)", said[raw]), said[raw]


# ------------------------------------------------------------------ 3. empty and foreign files named as videos


def test_an_empty_or_foreign_video_file_is_named_for_what_it_is(tmp_path):
    """An empty ``.mp4`` was 'not a video FFmpeg can read ([Errno
    1094995529] ...); an MP4 or MOV cut short loses the index ...', and so
    was a text file called ``.mp4``. An empty file is said to be empty (a
    photo's words, exit 3); the cut-short hint is for a file whose boxes
    are an MP4's without the index (``moov``), which a recording cut short
    is, whatever its name; FFmpeg's reason comes without its error
    number."""
    av = pytest.importorskip("av")
    (tmp_path / "empty.mp4").write_bytes(b"")
    (tmp_path / "text.mp4").write_bytes(b"not a video at all\n" * 50)
    whole = tmp_path / "whole.mp4"
    with av.open(str(whole), "w") as f:
        st = f.add_stream("mpeg4", rate=24)
        st.width, st.height, st.pix_fmt = 64, 48, "yuv420p"
        rng = np.random.default_rng(3)
        for k in range(24):
            fr = av.VideoFrame.from_ndarray(rng.integers(0, 256, (48, 64, 3), dtype=np.uint8), format="rgb24")
            fr.pts = k
            for p in st.encode(fr.reformat(format="yuv420p")):
                f.mux(p)
        for p in st.encode():
            f.mux(p)
    data = whole.read_bytes()
    assert data[4:8] == b"ftyp" and data.rfind(b"moov") > len(data) // 2  # the index at the end
    (tmp_path / "cut.mp4").write_bytes(data[: len(data) // 2])
    # an MP4 cut short, named otherwise: its boxes say what it is
    (tmp_path / "cut.mkv").write_bytes(data[: len(data) // 2])
    said = {}
    for name in ("empty.mp4", "text.mp4", "cut.mp4", "cut.mkv"):
        r = uwhl("restore", name, "-o", "o", "-q", cwd=tmp_path)
        assert r.returncode == 3 and "Traceback" not in r.stderr, r.stderr
        said[name] = _said(r, "uwhl")
    assert said["empty.mp4"] == "empty.mp4: empty file"
    assert said["text.mp4"] == "text.mp4: not a video FFmpeg can read (Invalid data found when processing input)"
    for name in ("cut.mp4", "cut.mkv"):
        assert said[name].startswith(f"{name}: not a video FFmpeg can read (Invalid data found when processing "
                                     "input); it is an MP4 or MOV without its index (moov)"), said
        assert "cut short" in said[name]
    assert "Errno" not in " ".join(said.values())


# ------------------------------------------------------------------ 4. unknown single-dash options


def test_an_unknown_short_option_is_named_first_as_the_binary_names_it(binary, tmp_path):
    """``uwhl restore -x -o x`` said that INPUT was missing, and ``uwhl
    restore -dash.mp4 a.jpg -o x`` 'uwhl: error: unrecognized arguments'
    (the top-level prefix). The option is now named first (exit 2), in
    uwhl-rs's words: a word whose first letter is no option whole, with
    the two ways to give a file when it looks like a file name (a dot, or
    a file of that name); an unknown letter later in a cluster alone."""
    photo = tmp_path / "a.png"
    _png(photo)
    (tmp_path / "-dash").write_bytes(b"")
    hint = " (a file whose name starts with '-': write ./{0}, or put it after --)"
    cases = [(["-x", "-o", "x"], "invalid option '-x'"),
             (["-dash.mp4", "a.png", "-o", "x"], "invalid option '-dash.mp4'" + hint.format("-dash.mp4")),
             # a file of that name, without a dot
             (["-dash", "a.png", "-o", "x"], "invalid option '-dash'" + hint.format("-dash")),
             (["a.png", "-o", "x", "-xq"], "invalid option '-xq'"),
             (["a.png", "-qx", "-o", "x"], "invalid option '-x'"),
             (["a.png", "-o", "x", "-5"], "invalid option '-5'"),
             (["-nothere", "-o", "x"], "invalid option '-nothere'")]
    for args, said in cases:
        r = uwhl("restore", *args, cwd=tmp_path)
        assert r.returncode == 2, (args, r.stderr)
        assert r.stderr.splitlines()[0] == f"uwhl restore: error: {said}", (args, r.stderr)
        rb = subprocess.run([binary, "restore", *args], capture_output=True, text=True, cwd=tmp_path, timeout=60)
        assert rb.returncode == 2 and rb.stderr.splitlines()[0] == f"uwhl-rs: {said}", (args, rb.stderr)
    assert not (tmp_path / "x").exists()


def test_the_ways_the_hint_gives_a_dash_file_work_and_inputs_go_anywhere(binary, tmp_path):
    """The hint's two ways are taken by both commands: ``./-dash.png`` and
    ``-- -dash.png``, the latter after another input too ("a.png -o x --
    -dash.png": argparse left it unread); an input after the options
    ("a.png -o x b.png") is read, as uwhl-rs reads it. Each input is
    restored under its own name."""
    for name in ("a.png", "b.png", "-dash.png"):
        _png(tmp_path / name, seed=len(name))
    runs = [(["./-dash.png", "-o", "OUT"], {"-dash"}),
            (["a.png", "-o", "OUT", "--", "-dash.png"], {"a", "-dash"}),
            (["-o", "OUT", "--", "-dash.png", "a.png"], {"a", "-dash"}),
            (["a.png", "-o", "OUT", "b.png"], {"a", "b"}),
            (["-qo", "OUT", "a.png"], {"a"})]
    for prog, cmd in (("uwhl", [sys.executable, "-m", "uwhl_rs"]), ("uwhl-rs", [binary])):
        for k, (args, names) in enumerate(runs):
            out = tmp_path / prog / f"o{k}"
            args = [str(out) if a == "OUT" else a for a in args]
            r = subprocess.run([*cmd, "restore", "-q", *args], capture_output=True, text=True, env=_env(),
                               cwd=tmp_path, timeout=300)
            assert r.returncode == 0, (prog, args, r.stderr)
            got = {f[:-5] for f in os.listdir(out) if f.endswith(".json")}
            assert got == names, (prog, args, got)


# ------------------------------------------------------------------ 5. integer distance arrays


def test_an_integer_distance_array_is_refused_with_the_conversion(tmp_path):
    """A 16-bit file is read as millimetres (``read_distance``), but an
    integer array given to ``restore(distance=)`` was taken as metres: 3 m
    as 3000 uint16 lost every pixel ('only 0.0% of the pixels have a
    known distance') and ``depth_to_range`` gave ranges in the thousands.
    Both now refuse integers (and booleans) with a ParameterError that
    says the conversion; the conversion it says gives what the file
    reader gives for the same millimetres."""
    from PIL import Image

    from uwhl_rs import synth

    img, truth = synth.demo_input(60, 80, water_type="3C", seed=1)
    z = np.where(np.isfinite(truth["distance"]), truth["distance"], np.nan).astype(np.float32)
    mm = np.where(np.isfinite(z), np.round(z * 1000), 0).astype(np.uint16)
    for bad in (mm, mm.astype(np.int64), np.isfinite(z)):
        with pytest.raises(uwhl_rs.ParameterError, match=r"^distance has dtype .*expected float metres.*integers are "
                                                         r"refused.*distance\.astype\(np\.float32\) / 1000"):
            uwhl_rs.restore(img, distance=bad)
        with pytest.raises(uwhl_rs.ParameterError, match=r"^depth has dtype .*depth\.astype\(np\.float32\) / 1000"):
            uwhl_rs.depth_to_range(bad, 70)
    # the conversion the message gives is what the reader of a 16-bit file gives
    Image.fromarray(mm).save(tmp_path / "mm.png")
    read = uwhl_rs.read_distance(tmp_path / "mm.png")
    converted = mm.astype(np.float32) / 1000
    known = mm > 0
    assert np.array_equal(np.isnan(read), ~known)
    assert np.allclose(read[known], converted[known], rtol=0, atol=1e-6)
    # and it is the scene's distance to the millimetre: the fit uses every pixel of the seabed
    res = uwhl_rs.restore(img, distance=np.where(known, converted, np.nan))
    assert "distance_rejected" not in res.flags
    assert res.distance["coverage"] == pytest.approx(known.mean(), abs=1e-6)


# ------------------------------------------------------------------ 6. numbers too large, values of the wrong type


def _api_cases(tmp_path):
    from uwhl_rs import images, synth

    img, _ = synth.demo_input(48, 64, water_type="3C", seed=1)
    z = np.full((48, 64), 3.0, np.float32)
    np.save(tmp_path / "good.npy", z)
    good = tmp_path / "good.npy"
    return [
        ("beta of 400 digits", lambda: uwhl_rs.restore(img, water={"beta": [10**400, 1, 1]}),
         "water's beta must be three positive numbers, not [1e+400, 1, 1]"),
        ("beta of 5000 digits", lambda: uwhl_rs.restore(img, water={"beta": [10**5000, 1, 1]}),
         "water's beta must be three positive numbers, not [1e+5000, 1, 1]"),
        ("a side of 2^64", lambda: uwhl_rs.floor_distance((2**64, 1), 2, 70),
         "shape (1.84467e+19, 1) is over the largest input (300000000 pixels)"),
        ("max_pixels 2^70", lambda: uwhl_rs.read_distance(good, max_pixels=2**70),
         "max_pixels must be a positive integer up to 18446744073709551615, not 1.18059e+21"),
        ("read_image's max_pixels 2^70", lambda: images.read_image(good, max_pixels=2**70),
         "max_pixels must be a positive integer up to 18446744073709551615, not 1.18059e+21"),
        ("fov of 400 digits", lambda: uwhl_rs.depth_to_range(z, 10**400),
         "fov 1e+400 is out of range (too large for a float)"),
        ("altitude of 400 digits", lambda: uwhl_rs.floor_distance((48, 64), 10**400, 70),
         "altitude 1e+400 is out of range (too large for a float)"),
        ("port None", lambda: uwhl_rs.floor_distance((48, 64), 2, 70, port=None), "port None is not flat or dome"),
        ("port 5", lambda: uwhl_rs.depth_to_range(z, 70, port=5), "port 5 is not flat or dome"),
        ("altitude None", lambda: uwhl_rs.floor_distance((48, 64), None, 70), "altitude must be a number, not None"),
        ("altitude as text", lambda: uwhl_rs.floor_distance((48, 64), "2", 70), "altitude must be a number, not '2'"),
        ("pitch 1e308", lambda: uwhl_rs.floor_distance((48, 64), 2, 70, pitch=1e308),
         "pitch 1e+308 degrees is not within +-89"),
        ("altitude 1e308", lambda: uwhl_rs.floor_distance((48, 64), 1e308, 70),
         "altitude 1e+308 m is not in (0, 1000]"),
        ("fov 1e308", lambda: uwhl_rs.depth_to_range(z, 1e308), "field of view 1e+308 degrees is not in (0, 170]"),
        ("scene_cut of 400 digits", lambda: uwhl_rs.Sequence(scene_cut=10**400),
         "scene_cut must be a number in [0, 1]; got 1e+400"),
    ]


def test_numbers_too_large_or_of_the_wrong_type_are_parameter_errors_said_compactly(tmp_path):
    """``water={'beta': [10**400, 1, 1]}``, a side of 2^64, ``max_pixels``
    of 2^70 and a field of view or altitude of 400 digits raised a plain
    OverflowError, ``port=None`` and ``altitude=None`` a TypeError, and a
    pitch of 1e308 printed its 309 digits. Each is the package's
    ParameterError, its number shown as ``{:g}`` shows it."""
    for what, call, said in _api_cases(tmp_path):
        with pytest.raises(uwhl_rs.ParameterError) as got:
            call()
        assert str(got.value) == said, what
        assert len(str(got.value)) < 120, what
    # what was right stays right: numpy numbers, an image as the shape
    z = uwhl_rs.floor_distance(np.zeros((48, 64, 3)), np.float32(2), np.int64(70))
    assert z.shape == (48, 64) and np.nanmin(z) == pytest.approx(2.0, rel=1e-3)


# ------------------------------------------------------------------ 7. restore and depth_to_range alike


def test_depth_to_range_takes_and_refuses_what_restore_does():
    """``restore(distance=)`` takes a map of shape (H, W, 1) and refuses a
    complex one; ``depth_to_range`` refused the first and took the second
    (with a ComplexWarning, the imaginary part dropped). Both now take
    (H, W, 1) as (H, W) and refuse complex maps. On the optical axis the
    range is the depth itself; a pixel's ray at angle a gives depth /
    cos(a), so the corner is farther than the centre."""
    import warnings

    from uwhl_rs import synth

    z = np.full((48, 64), 3.0, np.float32)
    flat = uwhl_rs.depth_to_range(z, 70)
    one = uwhl_rs.depth_to_range(z[:, :, None], 70)
    assert one.shape == (48, 64) and np.array_equal(one, flat)
    assert flat[24, 32] == pytest.approx(3.0, rel=1e-3) and flat[0, 0] > flat[24, 32] * 1.05
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a ComplexWarning would be an error here
        with pytest.raises(uwhl_rs.ParameterError, match="^depth must be a 2-D array of metres, not complex128"):
            uwhl_rs.depth_to_range(z.astype(complex), 70)
    img, _ = synth.demo_input(48, 64, water_type="3C", seed=1)
    with pytest.raises(uwhl_rs.ParameterError, match="^distance must be a 2-D array of metres, not complex128"):
        uwhl_rs.restore(img, distance=z.astype(complex))
    for bad in (np.zeros((48, 64, 2), np.float32), np.zeros(64, np.float32)):
        for call, name in ((lambda: uwhl_rs.depth_to_range(bad, 70), "depth"),
                           (lambda: uwhl_rs.restore(img, distance=bad), "distance")):
            with pytest.raises(uwhl_rs.ParameterError, match=f"^{name} must be a 2-D array of metres"):
                call()


@pytest.mark.parametrize("name", [12, ["x"], "\x1b[31mEVIL\n", "x" * 10_000, "", "3c"])
def test_a_given_waters_nearest_type_is_a_jerlov_name(name):
    """``water={'beta': [...], 'nearest_type': 12}`` was told 'water must
    be a dict with beta', which it is; a name with escape codes and a line
    break became ``res.water_type`` unchecked (and the sidecar's, the
    summary's and a terminal's). A fit, and uwhl-rs's --water-from (which
    names the dive's water from its betas), only ever name it one of the
    ten Jerlov types: anything else is refused, the message saying what is
    wrong with nearest_type and showing it escaped and short."""
    from uwhl_rs import synth

    img, _ = synth.demo_input(48, 64, water_type="3C", seed=1)
    with pytest.raises(uwhl_rs.ParameterError) as got:
        uwhl_rs.restore(img, water={"beta": [0.5, 0.1, 0.1], "nearest_type": name})
    text = str(got.value)
    assert text.startswith("water's nearest_type must be a Jerlov type (I, IA, IB, II, III, 1C, 3C, 5C, 7C, 9C) "
                           "or None, not "), text
    assert "\x1b" not in text and "\n" not in text and len(text) < 200


def test_a_given_waters_jerlov_name_or_none_still_names_the_type():
    """A Jerlov name names the one candidate type; None or no name: "fitted"."""
    from uwhl_rs import synth

    img, _ = synth.demo_input(48, 64, water_type="3C", seed=1)
    beta = [0.2 / 0.6515, 0.2 / 1.1244, 0.2]  # 3C's ratios beta_B / beta_R, beta_B / beta_G
    assert uwhl_rs.restore(img, water={"beta": beta, "nearest_type": "3C"}).water_type == "3C"
    assert uwhl_rs.restore(img, water={"beta": beta, "nearest_type": None}).water_type == "fitted"
    assert uwhl_rs.restore(img, water={"beta": beta}).water_type == "fitted"
