"""Hostile videos, raw frames and video sidecars (docs/CLI.md "Videos",
"Raw frames"; docs/OUTPUTS.md "Videos"; docs/REPORT.md item 6): every
file is made here (PyAV and byte surgery, a few frames of 64x48), and
each case says what must happen independently of the code: the exit code
of docs/CLI.md, a message naming the file, frame or reason, no Python
traceback, nothing in the output folder that looks complete but is not,
no markup of a sidecar in the page."""

from __future__ import annotations

import json
import os
import signal
import struct
import subprocess
import sys
import time

import numpy as np
import pytest

av = pytest.importorskip("av")

H, W = 48, 64


# ------------------------------------------------------------------ makers


def _noise(n: int, h: int = H, w: int = W, seed: int = 0) -> list[np.ndarray]:
    """``n`` 8-bit RGB frames: a textured picture sliding one column a frame
    (so the restoration has colours to work on)."""
    rng = np.random.default_rng(seed)
    y, x = np.mgrid[0:h, 0:w]
    base = np.stack([60 + 40 * np.sin(x / 5.0), 120 + 50 * np.cos(y / 4.0), 150 + 30 * np.sin((x + y) / 7.0)], -1)
    base = np.clip(base + rng.normal(0, 12, base.shape), 0, 255).astype(np.uint8)
    return [np.roll(base, k, axis=1) for k in range(n)]


def _write(path, frames=None, *, n=6, codec="ffv1", pix="bgr0", pts=None, rate=24, audio_seconds=0.0,
           rotation=None, options=None, h=H, w=W):
    """A video of ``frames`` (8-bit RGB arrays); ``pts`` the packets'
    timestamps in frames of ``1/rate`` (written as given: repeated or
    decreasing ones too, with dts kept increasing so the muxer takes them)."""
    frames = _noise(n, h, w) if frames is None else frames
    with av.open(str(path), "w", options=options or {}) as out:
        st = out.add_stream(codec, rate=rate)
        st.width, st.height = frames[0].shape[1], frames[0].shape[0]
        st.pix_fmt = pix
        if rotation is not None:
            st.set_display_rotation(rotation)
        a = None
        if audio_seconds:
            a = out.add_stream("aac", rate=48000)
            a.layout = "mono"

        def mux(p):
            if pts is not None and p.pts is not None:
                k = p.pts
                p.pts, p.dts = pts[k], k - len(frames)
            out.mux(p)

        for k, img in enumerate(frames):
            f = av.VideoFrame.from_ndarray(img, format="rgb24").reformat(format=pix)
            f.pts = k
            for p in st.encode(f):
                mux(p)
        for p in st.encode():
            mux(p)
        if a is not None:
            n_s = int(48000 * audio_seconds)
            tone = (0.1 * np.sin(np.arange(n_s) / 9.0)).astype(np.float32)[None]
            for i in range(0, n_s, 1024):
                fr = av.AudioFrame.from_ndarray(np.ascontiguousarray(tone[:, i:i + 1024]), format="flt", layout="mono")
                fr.sample_rate, fr.pts = 48000, i
                for p in a.encode(fr):
                    out.mux(p)
            for p in a.encode():
                out.mux(p)


def _decoded(path):
    """(pts, rgb24 array, rotation) of every frame of ``path``'s first video stream."""
    with av.open(str(path)) as f:
        return [(fr.pts, fr.to_ndarray(format="rgb24"), fr.rotation) for fr in f.decode(f.streams.video[0])]


def _cmd(*args, env=None):
    return subprocess.run([sys.executable, "-m", "uwhl_rs", *map(str, args)], capture_output=True, text=True,
                          timeout=300, env=env)


def _restore(*args):
    return _cmd("restore", *args)


def _clean(r):
    """No traceback, and no temporary's name in what the user reads."""
    assert "Traceback" not in r.stderr, r.stderr
    assert ".uwhl-" not in r.stderr, r.stderr


def _listing(d) -> list[str]:
    return sorted(os.listdir(d)) if os.path.isdir(d) else []


def _video_files(d) -> list[str]:
    return [n for n in _listing(d) if n.rsplit(".", 1)[-1] in ("mp4", "mkv", "mov", "avi", "ts")]


# ------------------------------------------------------------------ timestamps


@pytest.mark.parametrize("pts", [[0, 1, 1, 2, 3, 4], [0, 3, 2, 1, 4, 5]], ids=["repeated", "decreasing"])
def test_timestamps_that_do_not_increase_are_written_increasing(tmp_path, pts):
    src = tmp_path / "ts.mkv"
    _write(src, pts=pts)
    out = tmp_path / "out"
    r = _restore(src, "-o", out, "--video-codec", "ffv1")
    _clean(r)
    assert r.returncode == 0, r.stderr
    got = [p for p, _, _ in _decoded(out / "ts.mkv")]
    # every frame decoded is written, and a container needs increasing timestamps
    assert len(got) == 6
    assert all(b > a for a, b in zip(got, got[1:])), got
    side = json.loads((out / "ts.json").read_text())
    assert any("timestamp" in n for n in side["video"]["notes"]), side["video"]["notes"]


def test_a_complete_variable_rate_file_is_not_called_cut_short(tmp_path):
    # six frames at 0, 1, 5, 6, 30 and 31 of 1/24 s: a camera that paused; nothing is missing
    src = tmp_path / "vfr.mkv"
    _write(src, pts=[0, 1, 5, 6, 30, 31])
    r = _restore(src, "-o", tmp_path / "out")
    _clean(r)
    assert r.returncode == 0, r.stderr
    side = json.loads((tmp_path / "out" / "vfr.json").read_text())
    assert side["video"]["stopped"] is None and "video_truncated" not in side["flags"]


def test_a_complete_matroska_whose_clock_starts_late_is_not_called_cut_short(tmp_path):
    """Timestamps from 10 h on (a recorder's clock) and no per-stream
    DURATION tag (GStreamer writes none): Matroska's segment duration runs
    from time 0, so it is where the file ends, not a length to add to 10 h."""
    src = tmp_path / "late.mkv"
    _write(src, pts=[864_000 + k for k in range(6)])
    data = src.read_bytes()
    assert b"DURATION" in data
    src.write_bytes(data.replace(b"DURATION", b"DURATIOX"))  # the tag's name unknown: as if none was written
    r = _restore(src, "-o", tmp_path / "out")
    _clean(r)
    assert r.returncode == 0, r.stderr
    side = json.loads((tmp_path / "out" / "late.json").read_text())
    assert side["video"]["stopped"] is None and "video_truncated" not in side["flags"], side["video"]


def test_audio_longer_than_the_video_is_not_a_file_cut_short(tmp_path):
    # a quarter second of video and a second of sound: the container's duration is the sound's
    src = tmp_path / "talk.mkv"
    _write(src, n=6, audio_seconds=1.0)
    r = _restore(src, "-o", tmp_path / "out")
    _clean(r)
    assert r.returncode == 0, r.stderr
    assert json.loads((tmp_path / "out" / "talk.json").read_text())["video"]["stopped"] is None


# ------------------------------------------------------------------ sizes and codecs


def test_odd_sizes_are_refused_by_name_for_codecs_that_cannot_hold_them(tmp_path):
    src = tmp_path / "odd.mkv"
    _write(src, _noise(4, 47, 63))
    for codec in ("h264", "hevc", "prores"):
        out = tmp_path / codec
        r = _restore(src, "-o", out, "--video-codec", codec)
        _clean(r)
        assert r.returncode == 2, (codec, r.stderr)
        assert "63x47" in r.stderr and "even" in r.stderr and "ffv1" in r.stderr, r.stderr
        assert _video_files(out) == [] and not (out / "odd.json").exists()
    # a codec that takes any size writes it
    r = _restore(src, "-o", tmp_path / "mj", "--video-codec", "mjpeg")
    assert r.returncode == 0, r.stderr
    assert _decoded(tmp_path / "mj" / "odd.mkv")[0][1].shape == (47, 63, 3)


def test_max_side_that_gives_an_odd_size_is_refused_by_name(tmp_path):
    # 64x48 with --max-side 22: blocks of 3, 22x16 frames -> fine; --max-side 13: blocks of 5, 13x10 -> odd width
    src = tmp_path / "v.mkv"
    _write(src, n=3)
    r = _restore(src, "-o", tmp_path / "a", "--max-side", "13")
    _clean(r)
    assert r.returncode == 2 and "13x10" in r.stderr, r.stderr
    r = _restore(src, "-o", tmp_path / "b", "--max-side", "22")
    assert r.returncode == 0, r.stderr
    assert _decoded(tmp_path / "b" / "v.mkv")[0][1].shape == (16, 22, 3)


def _avi_with_header(path, *, width=None, height=None, frames=None):
    """A 3-frame raw AVI whose header then states another width or frame count."""
    _write(path, n=3, codec="rawvideo", pix="bgr24")
    d = bytearray(path.read_bytes())
    avih, strh, strf = d.find(b"avih"), d.find(b"strh"), d.find(b"strf")
    if frames is not None:
        struct.pack_into("<I", d, avih + 8 + 16, frames)
        struct.pack_into("<I", d, strh + 8 + 32, frames)
    if width is not None:
        struct.pack_into("<I", d, avih + 8 + 32, width)
        struct.pack_into("<i", d, strf + 8 + 4, width)
    if height is not None:
        struct.pack_into("<I", d, avih + 8 + 36, height)
        struct.pack_into("<i", d, strf + 8 + 8, height)
    path.write_bytes(bytes(d))


def test_a_header_size_the_frames_do_not_have_is_an_unreadable_input(tmp_path):
    # the header says 65534 pixels wide; the frames hold 64: nothing can be decoded
    src = tmp_path / "wide.avi"
    _avi_with_header(src, width=65534)
    r = _restore(src, "-o", tmp_path / "out")
    _clean(r)
    assert r.returncode == 3, r.stderr
    assert "wide.avi" in r.stderr
    assert _video_files(tmp_path / "out") == []


def test_a_header_without_a_usable_size_says_so(tmp_path):
    src = tmp_path / "nosize.avi"
    _avi_with_header(src, width=1 << 20, height=1 << 20)  # FFmpeg takes no size of 2^40 pixels
    r = _restore(src, "-o", tmp_path / "out")
    _clean(r)
    assert r.returncode == 3 and "nosize.avi" in r.stderr
    assert "no usable frame size" in r.stderr, r.stderr


def test_an_mkv_cut_before_its_first_frame_is_not_blamed_on_an_mp4_index(tmp_path):
    src = tmp_path / "v.mkv"
    _write(src, n=3)
    (tmp_path / "cut.mkv").write_bytes(src.read_bytes()[:40])
    r = _restore(tmp_path / "cut.mkv", "-o", tmp_path / "out")
    _clean(r)
    assert r.returncode == 3 and "cut.mkv" in r.stderr
    assert "MP4" not in r.stderr, r.stderr


def test_video_codec_input_keeps_the_container_that_takes_the_codec(tmp_path):
    _write(tmp_path / "a.avi", n=3, codec="ffv1", pix="bgr0")
    _write(tmp_path / "m.mp4", n=3, codec="mjpeg", pix="yuvj420p")
    r = _restore(tmp_path / "a.avi", tmp_path / "m.mp4", "-o", tmp_path / "out", "--video-codec", "input")
    _clean(r)
    assert r.returncode == 0, r.stderr
    # FFV1 goes in the input's AVI; motion JPEG is not written into an MP4 but a MOV (docs/CLI.md "Videos")
    assert _video_files(tmp_path / "out") == ["a.avi", "m.mov"]
    assert json.loads((tmp_path / "out" / "a.json").read_text())["outputs"]["video"] == "a.avi"
    with av.open(str(tmp_path / "out" / "a.avi")) as f:
        assert f.streams.video[0].codec_context.name == "ffv1"


def test_a_second_video_stream_is_said_not_restored(tmp_path):
    src = tmp_path / "two.mkv"
    with av.open(str(src), "w") as out:
        sts = []
        for _ in range(2):
            st = out.add_stream("ffv1", rate=24)
            st.width, st.height, st.pix_fmt = W, H, "bgr0"
            sts.append(st)
        for k, img in enumerate(_noise(3)):
            for st in sts:
                f = av.VideoFrame.from_ndarray(img, format="rgb24").reformat(format="bgr0")
                f.pts = k
                for p in st.encode(f):
                    out.mux(p)
        for st in sts:
            for p in st.encode():
                out.mux(p)
    r = _restore(src, "-o", tmp_path / "out")
    assert r.returncode == 0, r.stderr
    notes = json.loads((tmp_path / "out" / "two.json").read_text())["video"]["notes"]
    assert any("#1 video" in n and "first video stream" in n for n in notes), notes


def test_hevc_writes_nothing_on_stderr_but_errors(tmp_path):
    src = tmp_path / "v.mkv"
    _write(src, n=3)
    r = _restore(src, "-o", tmp_path / "out", "--video-codec", "hevc", "-q")
    assert r.returncode == 0, r.stderr
    assert r.stderr == "", r.stderr


# ------------------------------------------------------------------ frames that cannot be restored


def test_black_and_flat_frames_are_written_unrestored_and_counted(tmp_path):
    frames = _noise(8)
    frames[0] = np.zeros_like(frames[0])          # a fade from black
    frames[5] = np.full_like(frames[5], 255)       # a flash
    src = tmp_path / "fade.mkv"
    _write(src, frames)
    out = tmp_path / "out"
    r = _restore(src, "-o", out, "--video-codec", "ffv1")
    _clean(r)
    assert r.returncode == 0, r.stderr
    got = _decoded(out / "fade.mkv")
    # every frame is there, in order; the two that hold nothing to restore are the input's
    assert len(got) == 8
    assert got[0][1].max() == 0 and got[5][1].min() == 255
    assert not np.array_equal(got[1][1], frames[1])  # the others are restored
    side = json.loads((out / "fade.json").read_text())
    fr = side["video"]["frames"]
    assert fr["restored"] == 6 and fr["unrestored"] == 2 and fr["decoded"] == 8
    assert [u["frame"] for u in side["video"]["unrestored"]] == [0, 5]
    assert "constant" in side["video"]["unrestored"][0]["error"]


def _ts(path, h, w, n, seed):
    """An MPEG transport stream of ``n`` frames of ``h`` x ``w`` (MPEG-2 video)."""
    frames = _noise(n, h, w, seed)
    with av.open(str(path), "w", format="mpegts") as out:
        st = out.add_stream("mpeg2video", rate=24)
        st.width, st.height, st.pix_fmt = w, h, "yuv420p"
        for f in frames:
            for p in st.encode(av.VideoFrame.from_ndarray(f, format="rgb24")):
                out.mux(p)
        for p in st.encode():
            out.mux(p)


def _joined(tmp_path, name, *parts):
    """Transport streams laid end to end, as a recorder that switches
    resolution writes them: ``parts`` are (height, width) of 6 frames each.
    Returns the file and the frame sizes its decoder gives."""
    data = b""
    for k, (h, w) in enumerate(parts):
        _ts(tmp_path / "part.ts", h, w, 6, k)
        data += (tmp_path / "part.ts").read_bytes()
    os.unlink(tmp_path / "part.ts")
    src = tmp_path / name
    src.write_bytes(data)
    with av.open(str(src)) as f:
        sizes = [(fr.height, fr.width) for fr in f.decode(video=0)]
    assert sizes[0] == parts[0] and parts[1] in sizes
    return src, sizes


def test_a_stream_that_changes_size_is_written_at_its_size_and_says_so(tmp_path):
    # 96x64 frames, then 64x48: the video is written at the stated 96x64
    src, sizes = _joined(tmp_path, "cam.ts", (64, 96), (H, W))
    small = sum(s == (H, W) for s in sizes)
    out = tmp_path / "out"
    r = _restore(src, "-o", out)
    _clean(r)
    assert r.returncode == 0, r.stderr
    got = _decoded(out / _video_files(out)[0])
    assert len(got) == len(sizes)
    assert all(g[1].shape[:2] == (64, 96) for g in got)
    notes = json.loads((out / "cam.json").read_text())["video"]["notes"]
    said = [n for n in notes if "scaled to 96x64" in n]
    assert len(said) == 1 and said[0].startswith(f"{small} frames") and "64x48" in said[0], notes
    # stills keep each frame's own size, and nothing is said
    out2 = tmp_path / "stills"
    r = _restore(src, "-o", out2, "--every", "1")
    _clean(r)
    assert r.returncode == 0, r.stderr
    side = json.loads((out2 / "cam.json").read_text())
    assert not any("scaled" in n for n in side["video"]["notes"])
    from PIL import Image
    shapes = [Image.open(out2 / s["image"]).size for s in side["video"]["stills"] if s.get("image")]
    assert (W, H) in shapes and (96, 64) in shapes


def test_a_frame_larger_than_the_stream_states_stops_it_there(tmp_path):
    # the limits were checked for 64x48 frames; a 96x64 frame part way would go past
    # --max-pixels: the frames before it are restored and kept, the stop said by frame
    src, sizes = _joined(tmp_path, "grow.ts", (H, W), (64, 96))
    first_big = sizes.index((64, 96))
    out = tmp_path / "out"
    r = _restore(src, "-o", out, "--max-pixels", str(H * W))
    _clean(r)
    assert r.returncode == 3, r.stderr
    side = json.loads((out / "grow.json").read_text())
    stop = side["video"]["stopped"]
    assert stop["frame"] == first_big and "96x64, larger than the 64x48" in stop["error"]
    assert "video_truncated" in side["flags"] and side["video"]["frames"]["restored"] == first_big
    got = _decoded(out / _video_files(out)[0])
    assert len(got) == first_big and all(g[1].shape[:2] == (H, W) for g in got)


def test_a_video_of_black_frames_only_fails_by_name(tmp_path):
    src = tmp_path / "cap.mkv"
    _write(src, [np.zeros((H, W, 3), np.uint8)] * 3)
    r = _restore(src, "-o", tmp_path / "out")
    _clean(r)
    assert r.returncode == 3 and "cap.mkv" in r.stderr and "no frame could be restored" in r.stderr, r.stderr
    assert _video_files(tmp_path / "out") == [] and not (tmp_path / "out" / "cap.json").exists()


def test_black_frames_among_stills_are_not_written_as_stills(tmp_path):
    frames = _noise(6)
    frames[3] = np.zeros_like(frames[3])
    src = tmp_path / "s.mkv"
    _write(src, frames)
    out = tmp_path / "out"
    r = _restore(src, "-o", out, "--every", "3", "--format", "png")
    assert r.returncode == 0, r.stderr
    stills = json.loads((out / "s.json").read_text())["video"]["stills"]
    assert [s["frame"] for s in stills] == [0, 3]
    assert stills[0]["image"] and stills[1]["image"] is None and "constant" in stills[1]["skipped"]
    assert not (out / "s_00h00m00s125.png").exists()


# ------------------------------------------------------------------ names


def test_a_name_that_is_not_utf8_is_restored_with_u_fffd(tmp_path):
    src = tmp_path / "v.mkv"
    _write(src, n=3)
    bad = os.fsencode(tmp_path) + b"/dive\xff\xfe.mkv"
    os.rename(src, bad)
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", bad, b"-o", os.fsencode(out)], capture_output=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr.decode("utf-8", "replace")
    sidecars = [n for n in _listing(out) if n.endswith(".json")]
    assert sidecars == ["dive\ufffd\ufffd.json"], sidecars
    side = json.loads((out / sidecars[0]).read_text(encoding="utf-8"))
    assert side["input"].endswith("dive\ufffd\ufffd.mkv") and side["outputs"]["video"] == "dive\ufffd\ufffd.mkv"


def test_stills_whose_names_another_input_holds_take_the_next_name(tmp_path):
    from PIL import Image

    folder = tmp_path / "in"
    folder.mkdir()
    _write(folder / "v.mkv", n=4)
    # a photo whose outputs are named as the video's first still would be
    Image.fromarray(_noise(1, 32, 32, seed=4)[0]).save(folder / "v_00h00m00s000.png")
    out = tmp_path / "out"
    r = _restore(folder, "-o", out, "--every", "2", "--format", "png")
    _clean(r)
    assert r.returncode == 0, r.stderr
    photo = json.loads((out / "v_00h00m00s000.json").read_text())
    assert photo["input"].endswith("v_00h00m00s000.png")  # the photo's own outputs are its own
    stills = json.loads((out / "v.json").read_text())["video"]["stills"]
    assert [s["frame"] for s in stills] == [0, 2] and all(s["image"] for s in stills), stills
    first = json.loads((out / stills[0]["sidecar"]).read_text())
    assert first["input"].endswith("v.mkv#0") and stills[0]["sidecar"] != "v_00h00m00s000.json"


def test_what_is_not_a_regular_video_file_is_named(tmp_path):
    os.mkfifo(tmp_path / "fifo.mp4")
    (tmp_path / "dir.mp4").mkdir()
    os.symlink("loop2.mp4", tmp_path / "loop1.mp4")
    os.symlink("loop1.mp4", tmp_path / "loop2.mp4")
    for name in ("fifo.mp4", "dir.mp4", "loop1.mp4"):
        r = _restore(tmp_path / name, "-o", tmp_path / "out")
        _clean(r)
        assert r.returncode == 3 and name in r.stderr, r.stderr
    assert _video_files(tmp_path / "out") == []


# ------------------------------------------------------------------ rotation


def test_a_phone_videos_rotation_is_kept(tmp_path):
    src = tmp_path / "phone.mp4"
    _write(src, n=3, codec="libx264", pix="yuv420p", rotation=-90)
    assert _decoded(src)[0][2] == -90
    out = tmp_path / "out"
    r = _restore(src, "-o", out)
    assert r.returncode == 0, r.stderr
    got = _decoded(out / "phone.mp4")
    assert got[0][1].shape == (H, W, 3) and got[0][2] == -90
    assert json.loads((out / "phone.json").read_text())["video"]["stream"]["rotation"] == -90


# ------------------------------------------------------------------ interrupts


def _long(path, n=3000):
    """A video that takes far longer to restore than the tests wait for a
    signal to act (seconds of restoring at any machine's speed)."""
    _write(path, _noise(1) * n, codec="ffv1", pix="bgr0")


def _wait_for_temporary(out, p, what=".tmp"):
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and p.poll() is None:
        if any(n.startswith(".uwhl-") and what in n for n in _listing(out)):
            return True
        time.sleep(0.02)
    return False


def _restoring_a_long_video(tmp_path):
    """(the output folder, the process) of ``uwhl restore`` on a long video,
    once the video's temporary exists (its frames are being restored)."""
    src = tmp_path / "long.mkv"
    _long(src)
    out = tmp_path / "out"
    p = subprocess.Popen([sys.executable, "-m", "uwhl_rs", "restore", str(src), "-o", str(out), "-q"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    assert _wait_for_temporary(out, p)
    return out, p


def test_sigint_stops_a_video_at_the_next_frame_and_leaves_nothing(tmp_path):
    out, p = _restoring_a_long_video(tmp_path)
    p.send_signal(signal.SIGINT)
    err = _ended(p, "SIGINT did not stop the video (it kept restoring)")
    assert p.returncode == 130, err
    assert "interrupted" in err and "Traceback" not in err
    # nothing that looks complete, and the temporaries and claim are gone
    assert [n for n in _listing(out) if n != "summary.csv"] == [], _listing(out)


def _tgkill(pid: int, tid: int, sig: int) -> None:
    """``sig`` to one thread of process ``pid`` (Linux's tgkill)."""
    import ctypes

    libc = ctypes.CDLL(None, use_errno=True)
    if libc.syscall(234, pid, tid, sig) != 0:  # SYS_tgkill on x86-64
        raise OSError(ctypes.get_errno(), "tgkill")


@pytest.mark.skipif(sys.platform != "linux" or os.uname().machine != "x86_64", reason="tgkill's number is x86-64's")
def test_sigint_that_the_kernel_gives_a_worker_thread_still_stops_the_video(tmp_path):
    """The kernel delivers a process's SIGINT to any thread that does not
    block it (a decoder's, the core's); the main thread must notice it
    though it waits for the video's write."""
    out, p = _restoring_a_long_video(tmp_path)
    time.sleep(0.3)  # the main thread is then waiting on the write
    # threads come and go (a decoder's helper may end between the listing
    # and the signal): the signal goes to the newest one still there
    sent = False
    while not sent and p.poll() is None:
        others = [int(t) for t in os.listdir(f"/proc/{p.pid}/task") if int(t) != p.pid]
        assert others
        for tid in reversed(others):
            try:
                _tgkill(p.pid, tid, signal.SIGINT)
            except ProcessLookupError:
                continue
            sent = True
            break
    assert sent, "the process ended before a thread could be signalled"
    err = _ended(p, "a SIGINT taken by a worker thread did not stop the video")
    assert p.returncode == 130, err
    assert [n for n in _listing(out) if n != "summary.csv"] == [], _listing(out)


# ------------------------------------------------------------------ the report


def _video_sidecar(**video):
    v = {"frames": {"decoded": 10, "restored": 10, "reused": 9, "every": 1},
         "stream": {"width": 64, "height": 48, "rate": 24.0},
         "estimates": [{"frame": 0, "time": 0.0, "event": "first", "change": 0.0, "water_type": "3C",
                        "veiling_light": [0.1, 0.2, 0.3]}]}
    v.update(video)
    return {"input": "x.mp4", "kind": "video", "outputs": {"video": None, "strip": "x_strip.jpg"},
            "water_type": "3C", "veiling_light": [0.1, 0.2, 0.3], "flags": [], "video": v}


@pytest.mark.parametrize("case", ["event", "frame", "water_type", "veiling_light", "stopped_error", "stopped_frame"])
def test_a_video_sidecar_missing_a_field_is_a_note_not_a_crash(tmp_path, case):
    est = {"frame": 0, "time": 0.0, "event": "first", "water_type": "3C", "veiling_light": [0.1, 0.2, 0.3]}
    if case.startswith("stopped"):
        stop = {"frame": 3, "time": 0.1, "error": "cut short"}
        del stop[case.split("_")[1]]
        side = _video_sidecar(stopped=stop)
    else:
        del est[case]
        side = _video_sidecar(estimates=[est])
    (tmp_path / "x.json").write_text(json.dumps(side))
    r = _cmd("report", tmp_path)
    _clean(r)
    assert r.returncode == 0, r.stderr
    said = r.stdout + r.stderr
    assert "x.json" in said and "not a usable sidecar" in said, said


def test_absurd_numbers_in_a_video_sidecar_draw_no_broken_series(tmp_path):
    est = [{"frame": 50, "time": 1e308, "event": "first", "water_type": "3C", "veiling_light": [1e308, 0.2, 0.3]},
           {"frame": 0, "time": -1e308, "event": "cut", "water_type": "3C", "veiling_light": [0.1, 0.2, 0.3]}]
    side = _video_sidecar(estimates=est, stream={"width": 64, "height": 48, "rate": 1e-300})
    (tmp_path / "x.json").write_text(json.dumps(side))
    r = _cmd("report", tmp_path)
    _clean(r)
    assert r.returncode == 0, r.stderr
    page = (tmp_path / "report" / "index.html").read_text()
    section = page[page.index('<section id="videos">'):]
    section = section[:section.index("</section>")]
    for bad in ("inf", "nan", "e+", "e-3"):
        assert bad not in section.lower().replace("infinity", ""), bad


def test_a_video_sidecars_strip_outside_the_folder_is_refused(tmp_path):
    for k, strip in enumerate(["../../etc/passwd", "/etc/passwd", "http://example.org/x.jpg", "a/b.jpg"]):
        side = _video_sidecar()
        side["input"] = f"v{k}.mp4"
        side["outputs"]["strip"] = strip
        (tmp_path / f"v{k}.json").write_text(json.dumps(side))
    r = _cmd("report", tmp_path)
    assert r.returncode == 0, r.stderr
    import re

    page = (tmp_path / "report" / "index.html").read_text()
    links = re.findall(r'(?:src|href)="([^"]*)"', page)
    for bad in ("passwd", "example.org", "b.jpg"):
        assert not [u for u in links if bad in u], (bad, links)
    assert (r.stdout + r.stderr).count("not a usable sidecar") == 4, r.stdout + r.stderr


# ------------------------------------------------------------------ uwhl-rs --raw-frames


def _ended(p, why: str) -> str:
    """The stderr of ``p`` once it has ended within a minute; the test fails with ``why`` if it has not."""
    try:
        return p.communicate(timeout=60)[1]
    except subprocess.TimeoutExpired:
        p.kill()
        p.communicate()
        pytest.fail(why)


def _raw(binary, *args, data=b"", **kw):
    return subprocess.run([binary, "restore", *map(str, args)], input=data, capture_output=True, timeout=120, **kw)


def test_raw_frames_refuse_a_stdout_closed_from_the_start(binary):
    frame = bytes(_noise(1, 16, 16)[0].tobytes())
    r = subprocess.run(f"exec {binary} restore --raw-frames 16x16 -o - >&-", shell=True, input=frame * 3,
                       capture_output=True, timeout=120)
    assert r.returncode == 5 and b"stdout is closed" in r.stderr, r.stderr


def test_raw_frames_out_keep_every_frame_black_ones_too(binary):
    frames = _noise(4, 16, 16)
    frames[1] = np.zeros_like(frames[1])
    data = b"".join(f.tobytes() for f in frames)
    r = _raw(binary, "--raw-frames", "16x16", "-o", "-", "-q", data=data)
    assert r.returncode == 0, r.stderr
    got = np.frombuffer(r.stdout, np.uint8).reshape(-1, 16, 16, 3)
    assert len(got) == 4 and got[1].max() == 0


def test_raw_frames_of_which_none_is_restored_fail(binary, tmp_path):
    """Every frame black: each still goes out in step (stdout) or gets its
    error line (a folder), and the run ends with exit 3 naming it, as a
    video whose frames all fail does; one restored frame is enough for 0."""
    black = bytes(16 * 16 * 3) * 3
    r = _raw(binary, "--raw-frames", "16x16", "-o", "-", "-q", data=black)
    assert r.returncode == 3 and b"no frame could be restored (all 3" in r.stderr, r.stderr
    assert r.stdout == black
    r = _raw(binary, "--raw-frames", "16x16", "-o", str(tmp_path / "f"), "-q", data=black)
    lines = [json.loads(x) for x in r.stdout.decode().splitlines()]
    assert r.returncode == 3 and len(lines) == 3 and all("error" in x for x in lines), (r.returncode, lines)
    one = black + _noise(1, 16, 16)[0].tobytes()
    r = _raw(binary, "--raw-frames", "16x16", "-o", "-", "-q", data=one)
    assert r.returncode == 0 and len(r.stdout) == len(one), r.stderr


def test_raw_frames_a_run_of_black_frames_is_two_lines_not_one_a_frame(binary):
    """A camera's black start (50 frames) and a lens cap later (20): each
    run is its first frame's line and one line for the rest, every frame
    still goes out in step (to stdout and, into a folder, one JSON line
    each)."""
    frames = _noise(75, 16, 16)
    for k in [*range(0, 50), *range(52, 72)]:
        frames[k] = np.zeros_like(frames[k])
    data = b"".join(f.tobytes() for f in frames)
    r = _raw(binary, "--raw-frames", "16x16", "-o", "-", data=data)
    assert r.returncode == 0, r.stderr
    assert len(np.frombuffer(r.stdout, np.uint8)) == 75 * 16 * 16 * 3
    err = r.stderr.decode()
    assert err.count("nothing to restore") == 2, err
    assert "frames 1-49: the same (49 frames" in err and "frames 53-71: the same (19 frames" in err, err
    assert len(err.splitlines()) < 12, err


def test_raw_frames_planted_names_are_replaced_not_followed(binary, tmp_path):
    out = tmp_path / "frames"
    out.mkdir()
    victim = tmp_path / "victim"
    victim.write_bytes(b"keep")
    os.mkfifo(out / "frame_000000.json")
    os.symlink(victim, out / "frame_000000.jpg")
    os.symlink(victim, out / "frame_000001_t.png")
    data = b"".join(f.tobytes() for f in _noise(2, 16, 16))
    r = _raw(binary, "--raw-frames", "16x16", "-o", out, "-q", data=data)
    assert r.returncode == 0, r.stderr
    assert victim.read_bytes() == b"keep"
    for n in ("frame_000000.json", "frame_000000.jpg", "frame_000001_t.png"):
        assert (out / n).is_file() and not (out / n).is_symlink(), n
    assert len(r.stdout.decode().splitlines()) == 2


def test_raw_frames_a_slow_pipe_is_waited_for_not_spun_on(binary):
    """One byte at a time with pauses: the binary sleeps in read (its CPU
    time stays far below the wall time) and restores the frame at the end."""
    frame = _noise(1, 16, 16)[0].tobytes()
    p = subprocess.Popen([binary, "restore", "--raw-frames", "16x16", "-o", "-", "-q"], stdin=subprocess.PIPE,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    for i in range(0, len(frame), 97):
        p.stdin.write(frame[i:i + 97])
        p.stdin.flush()
        time.sleep(0.05)
    with open(f"/proc/{p.pid}/stat") as f:
        fields = f.read().rsplit(")", 1)[1].split()
    cpu = (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
    assert cpu < 0.2, cpu  # about 0.4 s of wall time went by in the loop
    out, err = p.communicate(timeout=60)
    assert p.returncode == 0 and len(out) == len(frame), err


def test_raw_frame_sizes_are_digits_only(binary):
    for bad in ("+64x+48", " 64 x 48 ", "64x-48"):
        r = _raw(binary, "--raw-frames", bad, "-o", "-")
        assert r.returncode == 2 and b"WIDTHxHEIGHT" in r.stderr, (bad, r.stderr)


def test_raw_frames_a_frame_whose_files_cannot_be_written_is_its_line(binary, tmp_path):
    out = tmp_path / "frames"
    out.mkdir()
    (out / "frame_000001.jpg").mkdir()  # a folder where frame 1's photo goes
    data = b"".join(f.tobytes() for f in _noise(3, 16, 16))
    r = _raw(binary, "--raw-frames", "16x16", "-o", out, "-q", data=data)
    lines = [json.loads(x) for x in r.stdout.decode().splitlines()]
    assert r.returncode == 0 and len(lines) == 3, r.stderr
    assert lines[1]["error"] == "write_failed" and lines[1]["input"] == "stdin#1"
    assert lines[0]["outputs"]["image"] == "frame_000000.jpg" and lines[2]["outputs"]["image"] == "frame_000002.jpg"
