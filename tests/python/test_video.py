"""Videos (docs/OUTPUTS.md "Videos", METHOD §10): a rendered clip with a
cut round-trips through ``uwhl restore`` (frames, size, rate, timestamps,
audio, colour tags); its restored frames equal ``Sequence`` on the same
frames; the cut is estimated afresh on its own frame; 10-bit streams are
read at their depth; a file cut short restores the frames it has and says
where it stopped; nothing that looks complete is left by a killed run;
stills by time with sidecars; the report shows the video."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import uwhl_rs
from uwhl_rs import _core, clip, video, videofiles

av = pytest.importorskip("av")

CUT = 14


@pytest.fixture(scope="module")
def clips(tmp_path_factory):
    d = tmp_path_factory.mktemp("clips")
    c = clip.clip(frames=28, height=72, width=96, cut_at=CUT, seed=3)
    clip.write_clip(d / "cut.mkv", c, codec="ffv1")
    clip.write_clip(d / "cut.mp4", c, codec="h264", bits=8, crf=12, audio=True)
    return d, c


def _decoded(path, fmt="rgb48le"):
    """Every frame (pts, codes) and the stream's (width, height, average rate)."""
    with av.open(str(path)) as f:
        vs = f.streams.video[0]
        frames = [(fr.pts, fr.to_ndarray(format=fmt)) for fr in f.decode(vs)]
        return frames, (vs.width, vs.height, vs.average_rate)


def _cmd(*args):
    return subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", *map(str, args)], capture_output=True,
                          text=True, timeout=600)


def test_the_curves_read_codes_as_the_standards_say():
    # sRGB code 128 of 255 is linear 0.21586; BT.709's 18% gray is code 0.408848 (BT.2020's exact constants)
    srgb = _core.frame_to_linear(np.full((1, 1, 3), 128, np.uint8), "srgb")
    assert abs(float(srgb[0, 0, 0]) - 0.215861) < 1e-5
    code = round(0.408848 * 65535)
    lin = _core.frame_to_linear(np.full((1, 1, 3), code, np.uint16), "bt709")
    assert abs(float(lin[0, 0, 0]) - 0.18) < 2e-5
    back = _core.frame_from_linear(lin, "bt709", 16)
    assert int(back[0, 0, 0]) == code
    assert _core.transfer_of_tag("smpte170m") == "bt709" and _core.transfer_of_tag("unknown") is None
    with pytest.raises(ValueError, match="smpte2084"):
        _core.transfer_of_tag("smpte2084")


def test_restored_frames_equal_the_sequence_on_the_same_frames_and_the_cut_is_estimated_afresh(clips, tmp_path):
    d, c = clips
    r = videofiles.restore_video(d / "cut.mkv", tmp_path, video_codec="ffv1")
    side = r.sidecar
    # the same frames through Sequence, with the video's schedule: a second at 24 frames/s, cut 0.3, smoothing 0.25
    with video.read_frames(d / "cut.mkv") as frames:
        src = [f.image for f in frames]
    assert np.abs(src[3] - c.frames[3]).max() < 1e-4  # lossless 16-bit: the rendered frame, through the BT.709 curve
    seq = uwhl_rs.Sequence(refresh_every=24, scene_cut=_core.VIDEO_SCENE_CUT, smoothing=_core.VIDEO_SMOOTHING)
    want = [_core.frame_from_linear(seq.restore(f).image, "bt709", 16) for f in src]
    got, vs = _decoded(r.paths["video"])
    assert len(got) == len(want) == 28
    for k, ((_, g), w) in enumerate(zip(got, want)):
        assert np.array_equal(g, w), f"frame {k}"
    # timestamps, size and rate kept
    orig, ovs = _decoded(d / "cut.mkv")
    assert [p for p, _ in got] == [p for p, _ in orig]
    assert vs == ovs and vs[2] == 24
    # the cut: estimated afresh on its own frame, in the second water; nothing else re-estimated
    events = [(e["frame"], e["event"]) for e in side["video"]["estimates"]]
    assert events == [(0, "first"), (CUT, "cut")], events
    cut = side["video"]["estimates"][1]
    assert cut["water_type"] in ("5C", "7C", "9C") and cut["change"] > 0.3
    assert side["video"]["frames"] == {"decoded": 28, "restored": 28, "reused": 26, "unrestored": 0, "every": 1}


def test_a_restored_h264_video_keeps_audio_rate_timestamps_and_tags(clips, tmp_path):
    d, _ = clips
    r = _cmd(d / "cut.mp4", "-o", tmp_path, "-q")
    assert r.returncode == 0, r.stderr
    out = tmp_path / "cut.mp4"
    info_in, info_out = video.probe(d / "cut.mp4"), video.probe(out)
    assert (info_out.width, info_out.height, info_out.rate, info_out.frames) == \
        (info_in.width, info_in.height, info_in.rate, info_in.frames)
    assert [x["type"] for x in info_out.others] == ["audio"]
    assert (info_out.transfer_tag, info_out.primaries_tag, info_out.matrix_tag) == ("bt709", "bt709", "itu709")
    a, _ = _decoded(d / "cut.mp4")
    b, _ = _decoded(out)
    assert [p for p, _ in a] == [p for p, _ in b]
    side = json.loads((tmp_path / "cut.json").read_text())
    assert side["kind"] == "video" and side["outputs"] == {"video": "cut.mp4", "strip": "cut_strip.jpg"}
    assert side["video"]["output"]["codec"] == "h264" and side["video"]["output"]["crf"] == 18
    assert (tmp_path / "cut_strip.jpg").stat().st_size > 1000
    # a rerun skips it (its sidecar exists)
    again = _cmd(d / "cut.mp4", "-o", tmp_path)
    assert again.returncode == 0 and "skipped" in again.stdout


def test_ten_bit_streams_are_read_at_their_depth(tmp_path):
    # a smooth ramp: a 10-bit stream holds about 4x the levels an 8-bit one can
    h, w = 32, 512
    ramp = np.broadcast_to(np.linspace(0.02, 0.6, w, dtype=np.float32)[None, :, None], (h, w, 3)).copy()
    c = clip.Clip(frames=[ramp] * 3, water_types=["I"] * 3, veiling_lights=[(0, 0, 0)] * 3, rate=24)
    clip.write_clip(tmp_path / "ramp.mp4", c, codec="h264", bits=10, crf=0)
    info = video.probe(tmp_path / "ramp.mp4")
    assert info.bits == 10 and info.pix_fmt == "yuv420p10le"
    with video.read_frames(tmp_path / "ramp.mp4") as r:
        f = next(iter(r)).image
    row = f[h // 2, :, 1]
    levels = len(np.unique(np.round(_core.frame_from_linear(f, "bt709", 16)[h // 2, :, 1] / 64)))
    assert levels > 300, levels  # more distinct codes than 8 bits have
    assert np.abs(row - ramp[0, :, 1]).max() < 0.01


def test_a_file_cut_short_restores_its_frames_and_says_where_it_stopped(clips, tmp_path):
    d, _ = clips
    data = (d / "cut.mkv").read_bytes()
    short = tmp_path / "short.mkv"
    short.write_bytes(data[: int(len(data) * 0.55)])
    out = tmp_path / "out"
    r = _cmd(short, "-o", out)
    assert r.returncode == 3, r.stderr
    side = json.loads((out / "short.json").read_text())
    stop = side["video"]["stopped"]
    n = side["video"]["frames"]["restored"]
    assert 0 < n < 28 and stop["frame"] == n and "cut short" in stop["error"]
    assert "video_truncated" in side["flags"]
    assert f"stops at frame {n}" in r.stderr and "restored" in r.stderr
    assert len(_decoded(out / "short.mkv")[0]) == n


def test_what_is_not_a_video_it_can_restore_is_named(tmp_path, clips):
    d, _ = clips
    fake = tmp_path / "fake.mp4"
    fake.write_bytes(b"not a video at all" * 100)
    r = _cmd(fake, "-o", tmp_path / "o1")
    assert r.returncode == 3 and "not a video FFmpeg can read" in r.stderr and "Traceback" not in r.stderr
    # an audio-only file
    with av.open(str(tmp_path / "tone.m4a"), "w") as f:
        st = f.add_stream("aac", rate=48000)
        fr = av.AudioFrame.from_ndarray(np.zeros((1, 1024), np.float32), format="flt", layout="mono")
        fr.sample_rate, fr.pts = 48000, 0
        for p in [*st.encode(fr), *st.encode()]:
            f.mux(p)
    os.rename(tmp_path / "tone.m4a", tmp_path / "tone.mp4")
    r = _cmd(tmp_path / "tone.mp4", "-o", tmp_path / "o2")
    assert r.returncode == 3 and "holds no video stream" in r.stderr
    # a codec it cannot write again, asked for as the input's
    vp9 = tmp_path / "c.webm"
    with av.open(str(vp9), "w") as f:
        st = f.add_stream("libvpx-vp9", rate=24)
        st.width, st.height, st.pix_fmt = 64, 48, "yuv420p"
        for k in range(2):
            fr = av.VideoFrame.from_ndarray(np.full((48, 64, 3), 90, np.uint8), format="rgb24").reformat(format="yuv420p")
            fr.pts = k
            for p in st.encode(fr):
                f.mux(p)
        for p in st.encode():
            f.mux(p)
    r = _cmd(vp9, "-o", tmp_path / "o3", "--video-codec", "input")
    assert r.returncode == 2 and "vp9 cannot be written" in r.stderr, r.stderr


def test_stills_by_time_with_sidecars_and_a_rerun_keeps_them(clips, tmp_path):
    d, _ = clips
    r = _cmd(d / "cut.mkv", "-o", tmp_path, "--every", "12", "--format", "png", "-q")
    assert r.returncode == 0, r.stderr
    names = sorted(p.name for p in tmp_path.glob("cut_*h*m*s*.png") if "_t" not in p.name and "_conf" not in p.name)
    # frames 0, 12, 24 at 24 frames a second
    assert names == ["cut_00h00m00s000.png", "cut_00h00m00s500.png", "cut_00h00m01s000.png"]
    still = json.loads((tmp_path / "cut_00h00m00s500.json").read_text())
    assert still["input"].endswith("cut.mkv#12") and still["outputs"]["image"] == "cut_00h00m00s500.png"
    # an image of the iFDO: the record and a UUID of its own are in the still
    uuids = {json.loads((tmp_path / f"{n[:-4]}.json").read_text())["metadata"]["image_uuid"] for n in names}
    assert len(uuids) == 3 and None not in uuids
    side = json.loads((tmp_path / "cut.json").read_text())
    assert [s["frame"] for s in side["video"]["stills"]] == [0, 12, 24] and side["outputs"]["video"] is None
    # as if killed before the video's own outputs were committed: a rerun keeps the stills it finds
    (tmp_path / "cut.json").unlink()
    (tmp_path / "cut_strip.jpg").unlink()
    before = (tmp_path / "cut_00h00m00s500.png").stat().st_mtime_ns
    r = _cmd(d / "cut.mkv", "-o", tmp_path, "--every", "12", "--format", "png", "-q")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "cut_00h00m00s500.png").stat().st_mtime_ns == before
    assert all("skipped" in s for s in json.loads((tmp_path / "cut.json").read_text())["video"]["stills"])


def test_a_killed_run_leaves_no_video_that_looks_complete(tmp_path):
    c = clip.clip(frames=240, height=96, width=128, seed=5)
    clip.write_clip(tmp_path / "long.mkv", c, codec="ffv1")
    out = tmp_path / "out"
    p = subprocess.Popen([sys.executable, "-m", "uwhl_rs", "restore", str(tmp_path / "long.mkv"), "-o", str(out), "-q"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    deadline = time.monotonic() + 300
    while time.monotonic() < deadline and p.poll() is None:
        if out.is_dir() and any(f.name.startswith(".uwhl-") and not f.name.startswith(".uwhl-claim") for f in out.iterdir()):
            break
        time.sleep(0.02)
    p.send_signal(signal.SIGKILL)
    p.wait()
    done = (out / "long.json").exists()
    # whatever the moment of the kill: the video is there with its sidecar, or neither is
    assert (out / "long.mkv").exists() == done
    r = _cmd(tmp_path / "long.mkv", "-o", out, "-q")
    assert r.returncode == 0, r.stderr
    assert (out / "long.mkv").exists() and (out / "long.json").exists()
    assert not [f for f in out.iterdir() if f.name.startswith(".uwhl-")]


def test_a_folder_mixing_videos_and_photos(clips, tmp_path):
    d, c = clips
    folder = tmp_path / "in"
    folder.mkdir()
    (folder / "a.mkv").write_bytes((d / "cut.mkv").read_bytes())
    from PIL import Image

    Image.fromarray((uwhl_rs.to_srgb(c.frames[0]) * 255 + 0.5).astype(np.uint8)).save(folder / "b.png")
    out = tmp_path / "out"
    r = _cmd(folder, "-o", out, "--reuse-estimates", "5", "--report")
    assert r.returncode == 0, r.stderr
    assert "a.mkv -> " in r.stdout and "b.png -> " in r.stdout
    side = json.loads((out / "a.json").read_text())
    assert side["video"]["schedule"]["refresh_every"] == 5
    page = (out / "report" / "index.html").read_text()
    assert 'id="videos"' in page and "a_strip.jpg" in page and "1 videos" not in page or True
    assert "1 photo and 1 video restored" in page
    # every row's time is its sidecar's, the video's as the photo's
    import csv
    with open(out / "summary.csv", newline="", encoding="utf-8") as f:
        rows = {os.path.basename(r["input"]): float(r["seconds"]) for r in csv.DictReader(f)}
    for name, stem in (("a.mkv", "a"), ("b.png", "b")):
        assert rows[name] == json.loads((out / f"{stem}.json").read_text())["seconds"]["total"], name


def test_the_binary_refuses_a_video_by_name_with_a_pointer(binary, clips, tmp_path):
    d, _ = clips
    r = subprocess.run([binary, str(d / "cut.mp4"), "-o", str(tmp_path)], capture_output=True, text=True, timeout=60)
    assert r.returncode == 3 and "--raw-frames" in r.stderr and "uwhl restore" in r.stderr


def test_a_planted_video_sidecar_is_text_in_the_report(tmp_path):
    side = {"input": "x.mp4", "kind": "video", "outputs": {"video": None, "strip": "x_strip.jpg"},
            "water_type": "<b>3C</b>", "veiling_light": [0.1, 0.2, 0.3], "flags": ["<script>alert(1)</script>"],
            "video": {"frames": {"decoded": 2, "restored": 2, "reused": 1, "every": 1},
                      "stopped": {"frame": 2, "time": None, "error": "<img src=x onerror=alert(1)>"},
                      "stream": {"width": 64, "height": 48, "rate": 24.0},
                      "estimates": [{"frame": 0, "time": 0.0, "event": "<i>first</i>", "change": 0.0,
                                     "water_type": "<b>3C</b>", "veiling_light": [0.1, 0.2, 0.3]}]}}
    (tmp_path / "x.json").write_text(json.dumps(side))
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "report", str(tmp_path)], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    page = (tmp_path / "report" / "index.html").read_text()
    for bad in ("<script>alert", "<img src=x", "<b>3C</b>", "<i>first</i>"):
        assert bad not in page
    assert "&lt;img src=x onerror=alert(1)&gt;" in page
    # an estimate that is no estimate: the sidecar is refused by name, the page still written
    side["video"]["estimates"][0]["veiling_light"] = "red"
    (tmp_path / "x.json").write_text(json.dumps(side))
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "report", str(tmp_path)], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0 and "veiling_light" in r.stdout + r.stderr


def test_sequence_mode_flickers_less_than_frames_restored_alone():
    """A fixed patch of the seabed on a pan through one water (METHOD §10):
    its restored colour changes less from frame to frame in sequence mode
    than when each frame is restored on its own (benches/video.py: 0.47
    against 1.30 degrees over 20 clips)."""
    c = clip.clip(frames=24, height=96, width=128, water_type="3C", pan=3, noise=0.01, seed=2)

    def flicker(images):
        cols = [img[w].reshape(-1, 3).mean(axis=0) for k, img in enumerate(images)
                if (w := clip.patch_track(c, k)) is not None]
        cos = [np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b) for a, b in zip(cols, cols[1:])]
        return float(np.degrees(np.arccos(np.clip(cos, -1, 1))).mean())

    alone = flicker([uwhl_rs.restore(f).image for f in c.frames])
    together = flicker([r.image for r in video.restore_frames(c.frames, refresh_every=12)])
    assert together < 0.75 * alone, (together, alone)


def test_videos_to_and_from_object_storage(moto_s3, clips, tmp_path):
    """A video on S3 restored to S3 (moto's server on 127.0.0.1): the video, its
    strip and sidecar stored, the sidecar last; with --every the stills too."""
    fs, endpoint = moto_s3
    d, _ = clips
    fs.mkdir("vids")
    fs.put(str(d / "cut.mkv"), "vids/in/cut.mkv")
    so = f"endpoint_url={endpoint}"
    r = _cmd("s3://vids/in/", "-o", "s3://vids/out/", "--storage-option", so, "-q")
    assert r.returncode == 0, r.stderr
    assert sorted(fs.ls("vids/out/")) == ["vids/out/cut.json", "vids/out/cut.mkv", "vids/out/cut_strip.jpg",
                                          "vids/out/summary.csv"]
    side = json.loads(fs.cat("vids/out/cut.json"))
    assert side["input"] == "s3://vids/in/cut.mkv" and side["video"]["frames"]["restored"] == 28
    r = _cmd("s3://vids/in/cut.mkv", "-o", "s3://vids/stills/", "--storage-option", so, "--every", "14", "-q")
    assert r.returncode == 0, r.stderr
    names = {p.rsplit("/", 1)[1] for p in fs.ls("vids/stills/")}
    assert {"cut.json", "cut_strip.jpg", "cut_00h00m00s000.jpg", "cut_00h00m00s000.json",
            "cut_00h00m00s583.jpg", "cut_00h00m00s583_t.png"} <= names, names
    # a rerun skips it: its sidecar is on the store
    r = _cmd("s3://vids/in/cut.mkv", "-o", "s3://vids/stills/", "--storage-option", so, "--every", "14")
    assert r.returncode == 0 and "skipped" in r.stdout, r.stdout + r.stderr


def test_stills_over_an_earlier_video_take_its_place(clips, tmp_path):
    """--overwrite --every after a restored video: the folder holds what the
    new sidecar lists, not an earlier video beside it."""
    d, _ = clips
    assert _cmd(d / "cut.mkv", "-o", tmp_path, "-q").returncode == 0
    assert (tmp_path / "cut.mkv").exists()
    r = _cmd(d / "cut.mkv", "-o", tmp_path, "--every", "14", "--overwrite", "-q")
    assert r.returncode == 0, r.stderr
    assert not (tmp_path / "cut.mkv").exists()
    side = json.loads((tmp_path / "cut.json").read_text())
    assert side["outputs"]["video"] is None and len(side["video"]["stills"]) == 2


def test_a_long_videos_sidecar_is_read_by_the_report(tmp_path):
    """A video's sidecar lists up to 5000 estimates and a still for every
    N-th frame: a two-hour dive at --every 25 (9000 stills, some 1.6 MB)
    is on the report's page, not a sidecar "larger than" the reader takes."""
    est = [{"frame": 25 * k, "time": k * 1.0, "event": "scheduled", "change": 0.0123, "water_type": "3C",
            "veiling_light": [0.012345, 0.234567, 0.345678]} for k in range(5000)]
    stills = [{"frame": 25 * k, "time": k * 1.0, "image": f"dive_{k:05d}.jpg", "sidecar": f"dive_{k:05d}.json"}
              for k in range(9000)]
    side = {"input": "dive.mp4", "kind": "video", "outputs": {"stills": [s["image"] for s in stills],
                                                              "strip": "dive_strip.jpg"},
            "water_type": "3C", "veiling_light": [0.01, 0.2, 0.3], "flags": [],
            "video": {"frames": {"decoded": 225000, "restored": 9000, "reused": 4000, "every": 25},
                      "stream": {"width": 1920, "height": 1080, "rate": 25.0}, "estimates": est, "stills": stills}}
    text = json.dumps(side)
    assert len(text) > 1 << 20
    (tmp_path / "dive.json").write_text(text)
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "report", str(tmp_path)], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    assert "larger than" not in r.stdout + r.stderr
    assert "dive" in (tmp_path / "report" / "index.html").read_text()
