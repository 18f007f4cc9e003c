"""Sequence mode, ``uwhl_rs.Sequence``: frames of a rendered "video" (a camera
panning over a scene of known water type, veiling light and distances,
METHOD §0), the equality of a reused frame with ``restore`` given the same
estimates, the refresh schedule, threads, and every error path.
"""

from __future__ import annotations

import threading

import numpy as np
import pytest

import uwhl_rs
from uwhl_rs import synth

from test_api import _same

H, W, PAN = 72, 96, 4


@pytest.fixture(scope="module")
def video():
    """Five frames of a type-III scene seen by a camera panning PAN columns a
    frame, each rendered with its own noise; and the truth of each frame."""
    sc = synth.scene(H, W + 5 * PAN, kind="open_water", seed=11)
    br, bg = uwhl_rs.WATER_TYPES["III"]
    a = synth.default_veiling_light((br, bg))
    frames, truths = [], []
    for k in range(5):
        cols = slice(k * PAN, k * PAN + W)
        clean = np.ascontiguousarray(sc.clean[:, cols])
        dist = np.ascontiguousarray(sc.distance[:, cols])
        frames.append(synth.render(clean, dist, (br, bg), veiling_light=a, beta_b=0.2, noise=0.003, seed=100 + k))
        truths.append(dist)
    return frames, truths, a


def _rho(dist, t):
    ok = np.isfinite(dist)
    return np.corrcoef(dist[ok], -np.log(t[ok].astype(np.float64)))[0, 1]


def test_video_frames_reuse_the_first_estimates_and_match_the_truth(video):
    frames, truths, a_true = video
    seq = uwhl_rs.Sequence(guided_subsample="auto")
    assert seq.water_type is None and seq.veiling_light is None and seq.estimates_next
    first = seq.restore(frames[0])
    assert len(first.scores) == 10 and "estimates_reused" not in first.flags
    assert seq.water_type == first.water_type and seq.veiling_light == first.veiling_light
    assert not seq.estimates_next
    assert seq.buffer_bytes == 32 * H * W
    np.testing.assert_allclose(first.veiling_light, a_true, atol=0.02)
    for f, dist in zip(frames[1:], truths[1:]):
        r = seq.restore(f)
        assert r.water_type == first.water_type and r.veiling_light == first.veiling_light
        assert list(r.scores) == [first.water_type] and "estimates_reused" in r.flags
        # known truth: -ln t_B tracks the rendered distance on every frame
        assert _rho(dist, r.transmission) > 0.7


@pytest.mark.parametrize("reuse_water_mask", [False, True])
@pytest.mark.parametrize("subsample", [1, "auto"])
def test_reused_frame_equals_restore_with_the_estimates(video, reuse_water_mask, subsample):
    frames = video[0]
    seq = uwhl_rs.Sequence(reuse_water_mask=reuse_water_mask, guided_subsample=subsample, threads=2)
    first = seq.restore(frames[0])
    _same(first, uwhl_rs.restore(frames[0], guided_subsample=subsample))
    for f in frames[1:3]:
        got = seq.restore(f.astype(np.float64))  # float64 converted as by restore
        want = uwhl_rs.restore(
            f,
            water_types=[first.water_type],
            veiling_light=first.veiling_light,
            water_mask=first.veiling_mask if reuse_water_mask else None,
            guided_subsample=subsample,
        )
        assert got.flags == want.flags + ["estimates_reused"]
        for field in ("image", "radiance", "transmission", "veiling_mask"):
            assert np.array_equal(getattr(got, field).view(np.uint8), getattr(want, field).view(np.uint8)), field
        assert got.scores == want.scores and got.veiling_light == want.veiling_light


def test_refresh_every(video):
    frames = video[0]
    seq = uwhl_rs.Sequence(refresh_every=3, water_types=["I", "III", "7C"])
    got = [(len(r.scores), "estimates_reused" in r.flags) for r in map(seq.restore, frames)]
    assert got == [(3, False), (1, True), (1, True), (3, False), (1, True)]


def test_given_water_mask_and_mask_are_used_on_their_frame(video):
    frames = video[0]
    seq = uwhl_rs.Sequence(reuse_water_mask=True)
    first = seq.restore(frames[0])
    wm = np.zeros((H, W), bool)
    wm[:6] = True
    mask = np.ones((H, W), bool)
    mask[50:60, 10:30] = False
    got = seq.restore(frames[1], water_mask=wm, mask=mask)
    assert np.array_equal(got.veiling_mask, wm)
    want = uwhl_rs.restore(
        frames[1], water_types=[first.water_type], veiling_light=first.veiling_light, water_mask=wm, mask=mask
    )
    assert np.array_equal(got.image, want.image) and np.array_equal(got.transmission, want.transmission)
    # the next frame reuses the first frame's region again, not the given one
    nxt = seq.restore(frames[2])
    assert np.array_equal(nxt.veiling_mask, first.veiling_mask)


def test_reset_and_new_size(video):
    frames = video[0]
    seq = uwhl_rs.Sequence(reuse_water_mask=True)
    first = seq.restore(frames[0])
    small = np.ascontiguousarray(frames[1][:48, :64])
    r = seq.restore(small)  # another size: reused type and A, its own water region
    assert r.image.shape == (48, 64, 3) and r.water_type == first.water_type
    assert seq.buffer_bytes == 32 * 48 * 64
    seq.reset()
    assert seq.water_type is None and seq.estimates_next and seq.buffer_bytes == 0
    _same(seq.restore(frames[0]), first)
    assert "Sequence(water_type=" in repr(seq)


def test_threads_take_turns(video):
    """Two Python threads restoring through one Sequence get the results of
    calls made one after the other (the GIL is released and the core locks)."""
    frames = video[0]
    seq = uwhl_rs.Sequence()
    seq.restore(frames[0])
    want = [seq.restore(f) for f in frames[1:3]]
    out = {}

    def run(i):
        out[i] = seq.restore(frames[1 + i])

    ths = [threading.Thread(target=run, args=(i,)) for i in range(2)]
    for t in ths:
        t.start()
    for t in ths:
        t.join()
    for i in range(2):
        _same(out[i], want[i])


# ---------------------------------------------------------------------------
# Errors: each names the problem; a failed frame changes nothing
# ---------------------------------------------------------------------------


@pytest.mark.parametrize(
    "kwargs, match",
    [
        ({"refresh_every": -1}, "refresh_every"),
        ({"refresh_every": 1.5}, "refresh_every"),
        ({"refresh_every": True}, "refresh_every"),
        ({"reuse_water_mask": "yes"}, "reuse_water_mask"),
        ({"selection": "quick"}, "selection"),
        ({"guided_subsample": "fast"}, "guided_subsample"),
        ({"water_types": "III"}, "water_types"),
        ({"water_types": ["XI"]}, "XI"),
        ({"veiling_light": (0.1, 0.2)}, "veiling_light"),
        ({"guided_eps": 0.0}, "guided_eps"),
        ({"threads": -2}, "threads"),
    ],
)
def test_bad_parameters(kwargs, match):
    with pytest.raises(uwhl_rs.ParameterError, match=match):
        seq = uwhl_rs.Sequence(**kwargs)
        # some values are only checked by the core, on the first frame
        seq.restore(synth.demo_input(16, 16)[0])


def test_unknown_keyword_is_a_type_error():
    with pytest.raises(TypeError, match="radius"):
        uwhl_rs.Sequence(radius=3)


@pytest.mark.parametrize(
    "image, match",
    [
        (np.zeros((20, 20, 3), np.uint8), "dtype"),
        (np.zeros((20, 20), np.float32), "shape"),
        (np.zeros((20, 20, 4), np.float32), "shape"),
        (np.zeros((0, 20, 3), np.float32), "empty"),
        (np.full((1, 1, 3), 0.5, np.float32), "small"),
        (np.full((20, 20, 3), np.nan, np.float32), "non-finite"),
        (np.full((20, 20, 3), np.inf, np.float64), "non-finite"),
        (np.full((20, 20, 3), 1.5, np.float32), r"outside \[0, 1\]"),
    ],
)
def test_bad_frames_change_nothing(video, image, match):
    frames = video[0]
    seq = uwhl_rs.Sequence()
    with pytest.raises(uwhl_rs.ImageError, match=match):
        seq.restore(image)  # as the first frame: nothing estimated
    assert seq.water_type is None and seq.estimates_next
    first = seq.restore(frames[0])
    with pytest.raises(uwhl_rs.ImageError, match=match):
        seq.restore(image)  # as a later frame: the estimates are kept
    assert seq.water_type == first.water_type and seq.veiling_light == first.veiling_light
    assert "estimates_reused" in seq.restore(frames[1]).flags


def test_bad_masks(video):
    frames = video[0]
    seq = uwhl_rs.Sequence()
    with pytest.raises(uwhl_rs.ParameterError, match="water_mask has shape"):
        seq.restore(frames[0], water_mask=np.zeros((H, W + 1), bool))
    with pytest.raises(uwhl_rs.ParameterError, match="mask has dtype"):
        seq.restore(frames[0], mask=np.ones((H, W), np.uint8))
    with pytest.raises(uwhl_rs.ParameterError, match="no object pixels"):
        seq.restore(frames[0], water_mask=np.ones((H, W), bool))
    assert seq.water_type is None


def test_memory_budget_is_checked_per_frame(video):
    frames = video[0]
    seq = uwhl_rs.Sequence(max_memory=1000)
    with pytest.raises(MemoryError):
        seq.restore(frames[0])
    assert seq.water_type is None and seq.buffer_bytes == 0
