"""``uwhl-rs --raw-frames WxH`` (docs/CLI.md "Raw frames"): frames piped
in as rgb24 or rgb48le come out as the Python ``Sequence`` restores them
(the video defaults: an estimate every 30 frames, cuts at 0.3, A smoothed
by 0.25) through the BT.709 curve; a cut is announced on stderr; a stream
that ends inside a frame, a closed stdout and a frame over the budget end
cleanly with their exit codes; frames to a folder get their outputs and
a JSON line each; and it sits in an FFmpeg pipeline (FFmpeg installed
from the system's packages when missing)."""

from __future__ import annotations

import json
import subprocess

import numpy as np
import pytest

import uwhl_rs
from systools import installed
from uwhl_rs import _core, clip

H, W = 48, 64


@pytest.fixture(scope="module")
def frames():
    """A pan through 3C water with a cut to 7C at frame 8: 14 frames."""
    return clip.clip(frames=14, height=H, width=W, cut_at=8, seed=11).frames


def _codes(frames, bits):
    return [_core.frame_from_linear(f, "bt709", bits) for f in frames]


def _bytes(codes, bits):
    return b"".join((c.astype("<u2") if bits == 16 else c).tobytes() for c in codes)


def _expected(codes, bits, refresh=30):
    seq = uwhl_rs.Sequence(refresh_every=refresh, scene_cut=_core.VIDEO_SCENE_CUT, smoothing=_core.VIDEO_SMOOTHING)
    return [_core.frame_from_linear(seq.restore(_core.frame_to_linear(c, "bt709")).image, "bt709", bits)
            for c in codes]


def _run(binary, *args, data=b"", **kw):
    return subprocess.run([binary, "restore", *map(str, args)], input=data, capture_output=True, timeout=300, **kw)


@pytest.mark.parametrize("bits,fmt", [(8, "rgb24"), (16, "rgb48le")])
def test_frames_out_are_the_sequence_of_the_frames_in(binary, frames, bits, fmt):
    codes = _codes(frames, bits)
    r = _run(binary, "--raw-frames", f"{W}x{H}", "--pix-fmt", fmt, "-o", "-", data=_bytes(codes, bits))
    assert r.returncode == 0, r.stderr.decode()
    dtype = "<u2" if bits == 16 else np.uint8
    got = np.frombuffer(r.stdout, dtype=dtype).reshape(-1, H, W, 3)
    want = _expected(codes, bits)
    assert len(got) == len(want) == 14
    for k, (g, w) in enumerate(zip(got, want)):
        assert np.array_equal(g, w), f"frame {k}"
    err = r.stderr.decode()
    assert "frame 0: first estimate" in err and "frame 8: cut estimate" in err and "14 frames in" in err
    assert "frame 5:" not in err  # no estimate between: reused


def test_a_stream_that_ends_inside_a_frame_keeps_the_frames_before(binary, frames):
    data = _bytes(_codes(frames[:3], 8), 8)
    r = _run(binary, "--raw-frames", f"{W}x{H}", "-o", "-", data=data[: len(data) - 100])
    assert r.returncode == 3
    assert len(r.stdout) == 2 * H * W * 3
    assert f"inside frame 2 ({H * W * 3 - 100} of its {H * W * 3} bytes)" in r.stderr.decode()
    # an empty stream is a clean end
    r = _run(binary, "--raw-frames", f"{W}x{H}", "-o", "-", "-q")
    assert r.returncode == 0 and r.stdout == b"" and r.stderr == b""


def test_a_closed_stdout_stops_with_its_exit_code(binary, frames):
    data = _bytes(_codes(frames, 8), 8) * 20
    p = subprocess.Popen([binary, "restore", "--raw-frames", f"{W}x{H}", "-o", "-", "-q"], stdin=subprocess.PIPE,
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    first = None
    try:
        p.stdin.write(data[: 2 * H * W * 3])
        p.stdin.flush()
        first = p.stdout.read(H * W * 3)
        p.stdout.close()  # the reader goes away
        p.stdin.write(data[2 * H * W * 3:])
        p.stdin.close()
    except BrokenPipeError:
        pass  # it stopped reading: what we check is how it ended
    code = p.wait(timeout=120)
    err = p.stderr.read().decode()
    assert len(first) == H * W * 3
    assert code == 5 and "cannot write frame" in err and "stdout" in err, (code, err)


def test_frames_to_a_folder_get_their_outputs_and_a_line_each(binary, frames, tmp_path):
    codes = _codes(frames[:3], 8)
    r = _run(binary, "--raw-frames", f"{W}x{H}", "-o", tmp_path, "--format", "png", "-q", data=_bytes(codes, 8))
    assert r.returncode == 0, r.stderr.decode()
    lines = [json.loads(x) for x in r.stdout.decode().splitlines()]
    assert [x["input"] for x in lines] == ["stdin#0", "stdin#1", "stdin#2"]
    assert [x["reused_estimates"] for x in lines] == [False, True, True]
    for k in range(3):
        side = json.loads((tmp_path / f"frame_{k:06d}.json").read_text())
        assert side["outputs"]["image"] == f"frame_{k:06d}.png" and (tmp_path / f"frame_{k:06d}_t.png").exists()
        # no file to carry from, but the record and an image UUID of its own
        assert side["metadata"]["written"] is True and side["metadata"]["input_sha256"] is None
        assert len(side["metadata"]["image_uuid"]) == 32


@pytest.mark.parametrize("args,why", [
    (["--raw-frames", "3x9", "-o", "-"], "WIDTHxHEIGHT"),
    (["--raw-frames", "64x48", "a.png", "-o", "-"], "give no INPUT"),
    (["--raw-frames", "64x48", "-o", "-", "--max-side", "32"], "--max-side"),
    (["a.png", "-o", "-"], "-o - (stdout) is for --raw-frames"),
    (["a.png", "-o", "out", "--pix-fmt", "rgb24"], "--pix-fmt is for --raw-frames"),
])
def test_bad_combinations_are_usage_errors(binary, args, why):
    r = _run(binary, *args)
    assert r.returncode == 2 and why in r.stderr.decode(), r.stderr.decode()


def test_the_python_command_points_to_the_binary():
    import sys

    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", "--raw-frames", "64x48", "-o", "-"],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and "uwhl-rs" in r.stderr


def test_frames_over_the_budget_are_refused_before_reading(binary):
    r = _run(binary, "--raw-frames", "1920x1080", "-o", "-", "--max-memory", "20M", data=b"\0" * 100)
    assert r.returncode == 4 and "frames of 1920x1080 need about" in r.stderr.decode()


def _ffmpeg() -> str:
    return installed("ffmpeg", "ffmpeg")


def test_it_sits_in_an_ffmpeg_pipeline(binary, frames, tmp_path):
    ffmpeg = _ffmpeg()
    c = clip.Clip(frames=list(frames), rate=12)
    clip.write_clip(tmp_path / "cam.mkv", c, codec="ffv1")
    out = tmp_path / "out.mkv"
    cmd = (f"'{ffmpeg}' -v error -i '{tmp_path / 'cam.mkv'}' -f rawvideo -pix_fmt rgb48le - | "
           f"'{binary}' restore --raw-frames {W}x{H} --pix-fmt rgb48le -o - -q | "
           f"'{ffmpeg}' -v error -y -f rawvideo -pix_fmt rgb48le -s {W}x{H} -r 12 -i - -c:v ffv1 '{out}'")
    r = subprocess.run(["bash", "-o", "pipefail", "-c", cmd], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    import av

    with av.open(str(out)) as f:
        got = [fr.to_ndarray(format="rgb48le") for fr in f.decode(video=0)]
    # FFmpeg's decoding of the 16-bit RGB file is exact: the same frames as the Python sequence's
    want = _expected(_codes(frames, 16), 16)
    assert len(got) == 14 and all(np.array_equal(g, w) for g, w in zip(got, want))


def test_frames_over_max_pixels_are_refused_before_reading(binary):
    r = _run(binary, "--raw-frames", "300x200", "-o", "-", "--max-pixels", "100", data=b"\0" * 100)
    assert r.returncode == 4 and b"300x200 = 60000 pixels are over the limit of 100 pixels (--max-pixels)" in r.stderr
    assert r.stdout == b""
    # at the limit: restored
    r = _run(binary, "--raw-frames", "8x8", "--max-pixels", "64", "-o", "-", data=bytes(range(192)))
    assert r.returncode == 0, r.stderr


def test_a_frame_not_restored_leaves_no_earlier_runs_outputs_under_its_name(binary, frames, tmp_path):
    """A second run into the same folder whose frame 1 is black (no
    haze-line to read): frame_000001's files are not the first run's."""
    codes = _codes(frames[:3], 8)
    r = _run(binary, "--raw-frames", f"{W}x{H}", "-o", tmp_path, "--format", "png", "-q", data=_bytes(codes, 8))
    assert r.returncode == 0 and (tmp_path / "frame_000001.json").exists(), r.stderr.decode()
    codes[1] = np.zeros_like(codes[1])
    r = _run(binary, "--raw-frames", f"{W}x{H}", "-o", tmp_path, "--format", "png", "-q", data=_bytes(codes, 8))
    lines = [json.loads(x) for x in r.stdout.decode().splitlines()]
    assert [x.get("error") is not None for x in lines] == [False, True, False], lines
    assert sorted(p.name for p in tmp_path.glob("frame_000001*")) == []
    assert (tmp_path / "frame_000000.json").exists() and (tmp_path / "frame_000002.json").exists()
