"""Hostile inputs found by the reviews of 2026-12-05 (third session):
each case says what must happen independently of the code."""

from __future__ import annotations

import numpy as np
import pytest

from uwhl_rs import video, videofiles
from uwhl_rs.errors import ImageTooLargeError


def _video(path, h, w, n=2):
    av = pytest.importorskip("av")
    rng = np.random.default_rng(0)
    with av.open(str(path), "w") as out:
        st = out.add_stream("ffv1", rate=24)
        st.width, st.height, st.pix_fmt = w, h, "bgr0"
        for _ in range(n):
            f = av.VideoFrame.from_ndarray(rng.integers(0, 255, (h, w, 3), dtype=np.uint8), format="rgb24")
            for p in st.encode(f):
                out.mux(p)
        for p in st.encode():
            out.mux(p)


def test_a_video_over_the_memory_budget_is_refused_before_a_frame_is_decoded(tmp_path, monkeypatch):
    # The frame size comes from the stream's header; decoding a frame of a
    # 16000 x 16000 stream to read its rotation would take a gigabyte before
    # --max-memory was asked. Any decode before the refusal fails this test.
    src = tmp_path / "big.mkv"
    _video(src, 96, 128)
    decoded = []
    monkeypatch.setattr(video, "display_rotation", lambda p: decoded.append(p) or 0)
    need = videofiles.frame_need(video.probe(src, rotation=False), None)
    with pytest.raises(ImageTooLargeError, match="over max_memory"):
        videofiles.restore_video(src, tmp_path / "out", max_memory=need - 1)
    assert decoded == []
    # within the budget the rotation is read, once
    videofiles.restore_video(src, tmp_path / "out2", max_memory=need * 4)
    assert decoded == [str(src)]


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_a_usage_error_is_named_before_a_bad_water_folder_in_both_commands(impl, binary, tmp_path):
    # --water-from naming a folder with no fits, given with --water-type:
    # the combination is a usage error whatever the folder holds, and both
    # commands name it (the binary read the folder first and named that)
    from bothcmds import cmds, run_restore
    from PIL import Image

    Image.new("RGB", (32, 24), (20, 80, 120)).save(tmp_path / "a.png")
    empty = tmp_path / "nofits"
    empty.mkdir()
    r = run_restore(cmds(binary)[impl], tmp_path / "a.png", "-o", tmp_path / "o", "--water-from", empty,
                    "--water-type", "I")
    assert r.returncode == 2, r.stderr
    assert "--water-from gives the water type: it does not go with --water-type" in r.stderr, r.stderr
    # alone, the folder's own problem is named
    r = run_restore(cmds(binary)[impl], tmp_path / "a.png", "-o", tmp_path / "o", "--water-from", empty)
    assert r.returncode == 2 and "nofits" in r.stderr, r.stderr
    assert not (tmp_path / "o").exists()
