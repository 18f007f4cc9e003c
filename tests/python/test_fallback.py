"""The trust step of METHOD §12.5 on renders whose truth is known:
the veil-excess flag, the fallback toward the input's balance, the
confidence map, and the profiles (the paper profile has none of it)."""

import numpy as np
import pytest

import uwhl_rs
from uwhl_rs import synth, truth


@pytest.fixture(scope="module")
def seabed():
    sc = synth.scene(120, 160, kind="looking_down", seed=5)
    return sc, np.isfinite(sc.distance)


def _render(sc, wt, noise):
    return synth.render(sc.clean, sc.distance, wt, beta_b=0.4, noise=noise, seed=1)


def test_a_veil_brighter_than_the_light_is_flagged_and_the_fallback_is_nearer_the_truth(seabed):
    """Type II told a veiling light four times too red: (1 - t_R) A_R is then
    more than the observed red at almost every object pixel, which the
    model cannot produce. The photo is flagged, and the colours fall back
    to the input's balance, which is nearer the true radiance than the
    restoration without the fallback."""
    sc, obj = seabed
    img = _render(sc, "II", 0.005)
    a = np.array(synth.default_veiling_light("II"))
    wrong = tuple(float(x) for x in a * [4.0, 1.0, 1.0])
    fb = uwhl_rs.restore(img, water_types=["II"], veiling_light=wrong)
    plain = uwhl_rs.restore(img, water_types=["II"], veiling_light=wrong, fallback="none")
    assert "unreliable" in fb.flags and fb.veil_excess > 0.9
    assert "unreliable" not in plain.flags and plain.veil_excess is None
    got = truth.score(fb.image, sc.clean, obj, gains=False)["median"]
    without = truth.score(plain.image, sc.clean, obj, gains=False)["median"]
    assert got < 0.6 * without, (got, without)
    # the photo's weight is 1: no pixel is trusted, all of the colour is the balance's
    assert float(fb.confidence.max()) == 0.0
    assert fb.fallback_share == 1.0 and plain.fallback_share is None


@pytest.mark.parametrize("wt", ["3C", "7C"])
def test_the_true_veiling_light_leaves_no_veil_excess(seabed, wt):
    sc, _ = seabed
    img = _render(sc, wt, 0.005)
    a = tuple(float(x) for x in synth.default_veiling_light(wt))
    res = uwhl_rs.restore(img, water_types=[wt], veiling_light=a)
    assert res.veil_excess < 0.02 and "unreliable" not in res.flags


def test_confidence_falls_with_noise_and_distance(seabed):
    """The confidence is the noise angle (noise / t_c against the colour):
    more noise lowers it everywhere, and at low noise it is higher where
    the true transmission is higher (nearer seabed)."""
    sc, obj = seabed
    quiet = uwhl_rs.restore(_render(sc, "3C", 0.002), water_types=["3C"])
    noisy = uwhl_rs.restore(_render(sc, "3C", 0.03), water_types=["3C"])
    assert quiet.confidence.shape == obj.shape and quiet.confidence.dtype == np.float32
    assert 0.0 <= float(noisy.confidence.min()) and float(quiet.confidence.max()) <= 1.0
    assert float(noisy.confidence[obj].mean()) < 0.5 * float(quiet.confidence[obj].mean())
    t_r = synth.transmissions(sc.distance, "3C", 0.4)[0]
    near, far = t_r >= np.percentile(t_r[obj], 67), t_r <= np.percentile(t_r[obj], 33)
    assert float(quiet.confidence[near & obj].mean()) > float(quiet.confidence[far & obj].mean())


@pytest.mark.parametrize("wt, noise", [("3C", 0.002), ("3C", 0.03), ("7C", 0.01), ("I", 0.01)])
def test_the_share_of_colour_from_the_balance_follows_from_the_confidence(seabed, wt, noise):
    """METHOD §12.5: the map is c (1 - w_p) and each pixel's blend weight
    w = 1 - (1 - w_p)(1 - 0.3 (1 - c)), so its mean is
    w_p + 0.3 (1 - w_p) - 0.3 mean(map), with w_p from veil_excess: the
    reported share against what the map and the veil excess imply."""
    sc, _ = seabed
    res = uwhl_rs.restore(_render(sc, wt, noise), water_types=[wt])
    w_p = min(max((res.veil_excess - 0.02) / 0.18, 0.0), 1.0)
    want = w_p + 0.3 * (1 - w_p) - 0.3 * float(res.confidence.astype(np.float64).mean())
    assert 0.0 <= res.fallback_share <= 1.0
    assert res.fallback_share == pytest.approx(want, abs=2e-6), (res.veil_excess, res.fallback_share, want)


def test_the_paper_profile_has_no_trust_step_and_none_leaves_the_display(seabed):
    sc, _ = seabed
    img = _render(sc, "3C", 0.005)
    paper = uwhl_rs.restore(img, method="paper")
    assert paper.confidence is None and paper.veil_excess is None and "unreliable" not in paper.flags
    assert paper.fallback_share is None
    assert uwhl_rs.method_steps(method="paper")["fallback"] == "none"
    # the revised profile with fallback="none" is the revised display unblended:
    # with a trusted photo (w_p = 0) the blend moves each pixel by at most
    # 0.3 of the way to the input's balance
    rev = uwhl_rs.restore(img, water_types=["3C"])
    none = uwhl_rs.restore(img, water_types=["3C"], fallback="none")
    assert np.array_equal(rev.radiance, none.radiance) and np.array_equal(rev.transmission, none.transmission)
    assert not np.array_equal(rev.image, none.image)
    with pytest.raises(ValueError, match="fallback"):
        uwhl_rs.restore(img, fallback="blend")
