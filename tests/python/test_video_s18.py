"""Videos, a hostile review's findings (stop 18): an output folder whose
name reads as a URL (``tcp:``, ``file:zz``, ``dive:2``) is that folder and
nothing else is opened; an MP4 trimmed with an edit list is whole, while
one cut short still says so; stills of a rotated phone video are upright
and a display matrix that is no quarter turn is said not applied; FFV1 is
tagged with the RGB matrix it holds; ``--max-memory`` counts the
process's own memory for a video as for a photo.

Every expected value comes from FFmpeg's own tools (ffprobe's frame and
packet counts, its colour tags, ffmpeg's autorotated frame) or from the
budget's arithmetic, not from the code under test."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys

import numpy as np
import pytest

from systools import installed
from uwhl_rs import video, videofiles
from uwhl_rs.errors import ImageTooLargeError

av = pytest.importorskip("av")


def _ffmpeg(*args) -> None:
    r = subprocess.run([installed("ffmpeg", "ffmpeg"), "-v", "error", "-y", *map(str, args)], capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0, r.stderr


def _probe(*args) -> str:
    ffprobe = installed("ffprobe", "ffmpeg")
    r = subprocess.run([ffprobe, "-v", "error", *map(str, args)], capture_output=True, text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    return r.stdout


def _counts(path) -> tuple[int, int]:
    """(the frame count the header states, the frames FFmpeg decodes) of ``path``'s video, by ffprobe."""
    out = _probe("-count_frames", "-select_streams", "v:0", "-show_entries", "stream=nb_frames,nb_read_frames",
                 "-of", "json", path)
    s = json.loads(out)["streams"][0]
    return int(s["nb_frames"]), int(s["nb_read_frames"])


def _clip(path, seconds=0.5, size="64x48", extra=()) -> None:
    """A test card (H.264, 10 frames/s): parts unlike each other in every corner, so that its turn shows."""
    _ffmpeg("-f", "lavfi", "-i", f"testsrc2=size={size}:rate=10:duration={seconds}", "-c:v", "libx264",
            "-pix_fmt", "yuv420p", *extra, path)


def _restore(*args, cwd=None):
    # the package the tests import (installed, or on the PYTHONPATH a developer set), from any folder
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", *map(str, args)], capture_output=True,
                       text=True, timeout=300, cwd=cwd)
    assert "Traceback" not in r.stderr, r.stderr
    return r


def _frames_of(path) -> int:
    with av.open(str(path)) as c:
        return sum(1 for _ in c.decode(c.streams.video[0]))


@pytest.fixture(scope="module")
def card(tmp_path_factory):
    d = tmp_path_factory.mktemp("card")
    _clip(d / "card.mp4")
    return d / "card.mp4"


# ------------------------------------------------------------------ 1. output folders that read as URLs


@pytest.mark.parametrize("folder", ["tcp:", "dive:2", "file:zz", "2024-05-01T10:30:00", "tcp:/127.0.0.1:{port}"])
def test_an_output_folder_that_reads_as_a_url_is_that_folder(card, tmp_path, folder):
    # FFmpeg read the temporary's relative name as a URL: tcp:/127.0.0.1:9999 sent the video to a listener
    # and left a 0-byte file, file:zz wrote ./zz/, dive:2 was "Protocol not found"
    listener = socket.socket()
    listener.bind(("127.0.0.1", 0))
    listener.listen(4)
    try:
        folder = folder.format(port=listener.getsockname()[1])
        r = _restore(card, "-o", folder, "-q", cwd=tmp_path)
        assert r.returncode == 0, r.stderr
        out = tmp_path / folder / "card.mp4"
        assert _frames_of(out) == _counts(card)[1] == 5
        assert sorted(os.listdir(tmp_path / folder)) == ["card.json", "card.mp4", "card_strip.jpg", "summary.csv"]
        # nothing beside the folder asked for: its first part is all the run made here
        assert os.listdir(tmp_path) == [folder.split("/")[0]]
        # a connection the run made would wait in the backlog now that it is over
        listener.setblocking(False)
        with pytest.raises(BlockingIOError):
            listener.accept()
    finally:
        listener.close()


def test_the_api_writes_into_a_relative_folder_called_like_a_protocol(card, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    r = videofiles.restore_video(card, "dive:2")
    assert os.path.samefile(r.paths["video"], tmp_path / "dive:2" / "card.mp4")
    assert _frames_of(tmp_path / "dive:2" / "card.mp4") == 5


# ------------------------------------------------------------------ 2. edit lists


def test_an_mp4_trimmed_with_an_edit_list_is_whole(tmp_path):
    # a cut without re-encoding keeps the samples from the key frame before the cut and an edit list that
    # leaves them out: the header counts them, FFmpeg never decodes them
    whole = tmp_path / "whole.mp4"
    _clip(whole, seconds=3)
    trimmed = tmp_path / "trimmed.mp4"
    _ffmpeg("-ss", "1.05", "-i", whole, "-c", "copy", trimmed)
    stated, decodes = _counts(trimmed)
    assert stated > decodes + 1, (stated, decodes)  # the file is such a case
    r = _restore(trimmed, "-o", tmp_path / "out")
    assert r.returncode == 0, r.stderr
    side = json.loads((tmp_path / "out" / "trimmed.json").read_text())
    assert side["video"]["stopped"] is None and "video_truncated" not in side["flags"], side["video"]["stopped"]
    assert side["video"]["frames"]["decoded"] == decodes
    assert side["video"]["stream"]["frames"] == stated
    assert side["video"]["stream"]["frames_edited_out"] == stated - decodes
    assert _frames_of(tmp_path / "out" / "trimmed.mp4") == decodes


def test_a_trimmed_mp4_cut_short_is_still_cut_short(tmp_path):
    whole = tmp_path / "whole.mp4"
    _clip(whole, seconds=3, extra=("-g", "10", "-bf", "0"))
    trimmed = tmp_path / "trimmed.mp4"
    # the index first, so that a file cut short keeps it (the usual recording ends with it)
    _ffmpeg("-ss", "0.95", "-i", whole, "-c", "copy", "-movflags", "+faststart", trimmed)
    stated, decodes = _counts(trimmed)
    assert stated > decodes + 1, (stated, decodes)
    rows = [ln.split(",") for ln in _probe("-select_streams", "v:0", "-show_entries", "packet=pos,flags",
                                           "-of", "csv=p=0", trimmed).split()]
    discarded = sum("D" in flags for _, flags in rows)
    assert discarded == stated - decodes, rows
    # cut where a packet starts, four packets before the end: the demuxer ends there without an error
    keep = len(rows) - 4
    short = tmp_path / "short.mp4"
    short.write_bytes(trimmed.read_bytes()[: int(rows[keep][0])])
    left = keep - discarded
    r = _restore(short, "-o", tmp_path / "out")
    assert r.returncode == 3, r.stderr
    side = json.loads((tmp_path / "out" / "short.json").read_text())
    assert "video_truncated" in side["flags"]
    stop = side["video"]["stopped"]
    assert stop["frame"] == left == side["video"]["frames"]["decoded"], stop
    assert "cut short" in stop["error"] and f"states {stated} ({discarded} of them left out" in stop["error"], stop


# ------------------------------------------------------------------ 3. rotation


def _gray(path) -> np.ndarray:
    from PIL import Image

    with Image.open(path) as im:
        assert im.getexif().get(0x0112, 1) == 1  # upright in its pixels: no EXIF turn on top
        return np.asarray(im.convert("L"), dtype=np.float64)


def _corr(a, b) -> float:
    return float(np.corrcoef(a.ravel(), b.ravel())[0, 1])


@pytest.mark.parametrize("rotate", [90, 180, 270])
def test_stills_of_a_rotated_video_are_upright_as_ffmpeg_shows_it(card, tmp_path, rotate):
    turned = tmp_path / f"rot{rotate}.mp4"
    _ffmpeg("-i", card, "-c", "copy", "-metadata:s:v:0", f"rotate={rotate}", turned)
    shown = tmp_path / "shown.png"
    _ffmpeg("-i", turned, "-frames:v", "1", shown)  # FFmpeg turns a frame as a player does
    want = _gray(shown)
    r = _restore(turned, "-o", tmp_path / "out", "--every", "2", "-q")
    assert r.returncode == 0, r.stderr
    name = f"rot{rotate}_00h00m00s000"
    got = _gray(tmp_path / "out" / f"{name}.jpg")
    assert got.shape == want.shape
    # the restoration changes the colours, not where things are: the frame FFmpeg shows, not its half turn
    assert _corr(got, want) > 0.8 > _corr(got, np.rot90(want, 2)), (_corr(got, want), _corr(got, np.rot90(want, 2)))
    for m in ("_t.png", "_confidence.png"):
        assert _gray(tmp_path / "out" / f"{name}{m}").shape == want.shape
    source = json.loads((tmp_path / "out" / f"{name}.json").read_text())["source"]
    assert (source["height"], source["width"]) == want.shape
    # the orientation recorded is the EXIF code that shows the stored frame as FFmpeg does: Pillow's reading
    # of that code, applied to the frame as stored, gives the frame shown
    from PIL import Image, ImageOps

    stored = tmp_path / "stored.png"
    _ffmpeg("-noautorotate", "-i", turned, "-frames:v", "1", stored)
    with Image.open(stored) as im:
        exif = im.getexif()
        exif[0x0112] = source["orientation"]
        im.info["exif"] = exif.tobytes()
        upright = np.asarray(ImageOps.exif_transpose(im.convert("L")), dtype=np.float64)
    assert upright.shape == want.shape and np.abs(upright - want).max() < 1e-9


def test_a_display_matrix_that_is_no_quarter_turn_is_said_not_applied(card, tmp_path):
    tilted = tmp_path / "tilt.mp4"
    _ffmpeg("-i", card, "-c", "copy", "-metadata:s:v:0", "rotate=45", tilted)
    assert "rotation=-45" in _probe("-show_entries", "stream_side_data=rotation", "-of", "compact", tilted) or \
        "rotation=45" in _probe("-show_entries", "stream_side_data=rotation", "-of", "compact", tilted)
    for every, out in ((["--every", "2"], "o1"), ([], "o2")):
        r = _restore(tilted, "-o", tmp_path / out, "-q", *every)
        assert r.returncode == 0, r.stderr
        side = json.loads((tmp_path / out / "tilt.json").read_text())
        assert side["video"]["stream"]["rotation"] == 0
        assert any("45 degrees" in n and "not applied" in n for n in side["video"]["notes"]), side["video"]["notes"]
    assert _gray(tmp_path / "o1" / "tilt_00h00m00s000.jpg").shape == (48, 64)


# ------------------------------------------------------------------ 4. FFV1's matrix


def test_ffv1_is_tagged_with_the_rgb_matrix_its_pixels_have(card, tmp_path):
    r = _restore(card, "-o", tmp_path / "out", "--video-codec", "ffv1", "-q")
    assert r.returncode == 0, r.stderr
    out = json.loads(_probe("-select_streams", "v:0", "-show_entries", "stream=pix_fmt,color_space,color_range",
                            "-of", "json", tmp_path / "out" / "card.mkv"))["streams"][0]
    # AVCOL_SPC_RGB (H.273 matrix 0, the identity) is what ffprobe calls "gbr"; RGB samples are full range
    assert out["pix_fmt"].startswith(("gbrp", "rgb", "bgr")) and out["color_space"] == "gbr", out
    assert out["color_range"] == "pc", out
    side = json.loads((tmp_path / "out" / "card.json").read_text())
    assert side["video"]["output"]["matrix"] == "rgb"
    # H.264's 4:2:0 stays BT.709 and limited range
    r = _restore(card, "-o", tmp_path / "o2", "-q")
    assert r.returncode == 0, r.stderr
    out = json.loads(_probe("-select_streams", "v:0", "-show_entries", "stream=color_space,color_range",
                            "-of", "json", tmp_path / "o2" / "card.mp4"))["streams"][0]
    assert (out["color_space"], out["color_range"]) == ("bt709", "tv"), out


# ------------------------------------------------------------------ 5. --max-memory


def test_a_videos_memory_check_adds_what_the_process_holds(card, tmp_path):
    need = videofiles.frame_need(video.probe(card, rotation=False), None)
    base = 48 << 20
    with pytest.raises(ImageTooLargeError, match=f"need about {need + base} bytes, over max_memory {need + base - 1}"):
        videofiles.restore_video(card, tmp_path / "o1", max_memory=need + base - 1, _base=base)
    assert not (tmp_path / "o1" / "card.json").exists()
    r = videofiles.restore_video(card, tmp_path / "o2", max_memory=need + base, _base=base)
    assert r.sidecar["video"]["frames"]["restored"] == 5


def test_the_command_counts_the_process_in_a_videos_budget(card, tmp_path):
    # the process holds its interpreter, numpy and the codecs, and its base has 10 MiB of slack and 4 MiB for
    # the writer threads: a budget 1 MiB over the frames' plan leaves no room for it, as for a photo
    need = videofiles.frame_need(video.probe(card, rotation=False), None)
    r = _restore(card, "-o", tmp_path / "o1", "--max-memory", need + (1 << 20))
    assert r.returncode == 4, r.stderr
    assert f"over --max-memory {need + (1 << 20)} (use --max-side or raise --max-memory)" in r.stderr, r.stderr
    assert not (tmp_path / "o1" / "card.json").exists()
    r = _restore(card, "-o", tmp_path / "o2", "--max-memory", need + (1 << 30), "-q")
    assert r.returncode == 0, r.stderr
