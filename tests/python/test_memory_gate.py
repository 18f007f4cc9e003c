"""The memory a batch's inputs hold at once (uwhl_rs.tasks.MemoryGate,
docs/SCALE.md): an input restored while the previous one is written, or
the inputs of --jobs, wait until the others' plans leave room for theirs;
an input alone always goes."""

from __future__ import annotations

import threading

import pytest

from uwhl_rs import batch, images, synth, tasks


def test_a_reservation_waits_for_room_and_an_input_alone_always_goes():
    gate = tasks.MemoryGate(100)
    assert gate.reserve(60) == 60 and gate.held == 60
    got = threading.Event()
    t = threading.Thread(target=lambda: (gate.reserve(50), got.set()), daemon=True)
    t.start()
    # 60 + 50 > 100: it waits (a gate that did not would have set the event by now)
    assert not got.wait(0.5)
    gate.release(60)
    assert got.wait(10) and gate.held == 50
    t.join(10)
    gate.release(50)
    # over the whole budget but alone: it goes (its own plan was checked against the budget)
    assert gate.reserve(500) == 500 and gate.held == 500
    gate.release(500)
    assert gate.held == 0


@pytest.mark.parametrize("jobs", [1, 3])
def test_a_batch_holds_one_inputs_plan_at_a_time_when_two_do_not_fit(tmp_path, monkeypatch, jobs):
    """With room for one input's plan only, no input is restored while
    another is restored or written: the most held at once is one plan."""
    for k in range(4):
        img, _ = synth.demo_input(60, 80, water_type="3C", seed=k)
        images.write_image(tmp_path / f"p{k}.png", img, bits=8, encoding="linear")
    most, lock = [0], threading.Lock()
    init, reserve = tasks.MemoryGate.__init__, tasks.MemoryGate.reserve

    def small(self, budget):
        init(self, 1)  # no two plans fit

    def watched(self, need):
        n = reserve(self, need)
        with lock:
            most[0] = max(most[0], self.held)
            assert self.held == need, "an input was restored beside another's plan"
        return n

    monkeypatch.setattr(tasks.MemoryGate, "__init__", small)
    monkeypatch.setattr(tasks.MemoryGate, "reserve", watched)
    res = batch.run_batch([str(tmp_path / f"p{k}.png") for k in range(4)], str(tmp_path / "out"), jobs=jobs)
    assert [r["status"] for r in res.rows] == ["done"] * 4, res.rows
    assert most[0] > 0


def test_the_sphere_index_is_in_the_memory_plan():
    """--sphere-points up to a million: some 60 MB of index and haze-line
    state whatever the image's size, counted in restore's own check (64
    bytes a point) and in the commands' plan of an input."""
    import uwhl_rs
    from uwhl_rs import _core

    img, _ = synth.demo_input(64, 64, water_type="3C", seed=1)
    uwhl_rs.restore(img, sphere_points=500, max_memory=10 << 20)
    with pytest.raises(MemoryError):
        uwhl_rs.restore(img, sphere_points=1_000_000, max_memory=10 << 20)
    small = _core.input_plan(64, 64, 3, True, False, 1, False, 0, 0, sphere_points=500)
    big = _core.input_plan(64, 64, 3, True, False, 1, False, 0, 0, sphere_points=1_000_000)
    assert big - small == (1_000_000 - 500) * 64


def test_another_inputs_error_line_is_not_taken_for_the_raw_decoders(capfd):
    """A raw file decodes with the process's stderr collected (LibRaw's
    lines say whether it was cut short); with --jobs another input's error
    line, written meanwhile, said "truncated" and failed the raw file.
    The command's own lines are passed on, never the decoder's."""
    import os

    from uwhl_rs import images

    with images._decoder_messages() as said:
        os.write(2, b"uwhl: d.jpg: JPEG: cannot decode: truncated JPEG\n")
        os.write(2, b'{"error": "unreadable_input", "message": "truncated"}\n')
        os.write(2, b"e.dng: Unexpected end of file\n")
    assert said == ["e.dng: Unexpected end of file"]
    err = capfd.readouterr().err
    assert "uwhl: d.jpg: JPEG: cannot decode: truncated JPEG" in err and '"error": "unreadable_input"' in err


def test_an_input_waiting_for_room_does_not_start_after_an_interrupt():
    stop = threading.Event()
    gate = tasks.MemoryGate(100, stop=stop)
    gate.reserve(80)
    raised = []

    def wait():
        try:
            gate.reserve(50)
        except KeyboardInterrupt:
            raised.append(True)

    t = threading.Thread(target=wait, daemon=True)
    t.start()
    stop.set()
    t.join(10)
    assert raised == [True] and gate.held == 80


@pytest.mark.parametrize("jobs", [1, 3])
def test_a_video_beside_photos_holds_its_frame_plan_in_the_same_gate(tmp_path, monkeypatch, jobs):
    """A video restored beside photos holds one frame's plan
    (videofiles.frame_need) for as long as it is restored: with room for one
    plan only, no photo is restored while the video is, nor the video while
    a photo is."""
    pytest.importorskip("av")
    from uwhl_rs import clip, video, videofiles

    c = clip.clip(frames=6, height=48, width=64, seed=5)
    clip.write_clip(tmp_path / "v.mkv", c, codec="ffv1")
    for k in range(3):
        img, _ = synth.demo_input(60, 80, water_type="3C", seed=k)
        images.write_image(tmp_path / f"p{k}.png", img, bits=8, encoding="linear")
    frame = videofiles.frame_need(video.probe(str(tmp_path / "v.mkv")))
    needs, lock = [], threading.Lock()
    init, reserve = tasks.MemoryGate.__init__, tasks.MemoryGate.reserve

    def small(self, budget, stop=None):
        init(self, 1, stop)  # no two plans fit

    def watched(self, need):
        n = reserve(self, need)
        with lock:
            needs.append(need)
            assert self.held == need, "an input was restored beside another's plan"
        return n

    monkeypatch.setattr(tasks.MemoryGate, "__init__", small)
    monkeypatch.setattr(tasks.MemoryGate, "reserve", watched)
    names = [str(tmp_path / "v.mkv")] + [str(tmp_path / f"p{k}.png") for k in range(3)]
    res = batch.run_batch(names, str(tmp_path / "out"), jobs=jobs)
    assert [r["status"] for r in res.rows] == ["done"] * 4, res.rows
    assert frame in needs, (frame, needs)
