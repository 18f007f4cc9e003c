"""restore(distance=) on renders of METHOD §0 with a known water (METHOD
§13): the fitted attenuation near the truth, the colours nearer the true
radiance than without the distance and than the input, a map of another
scene rejected, and water= carrying a fit to another photo."""

import numpy as np
import pytest

import uwhl_rs
from uwhl_rs import synth, truth

TYPES = ["I", "IA", "IB", "II", "III", "1C", "3C", "5C", "7C", "9C"]


def _render(wt: str, beta_b: float, seed: int):
    """A seabed receding from 1 m (bottom row) to 20 m (top row), lit by
    white light, through water of type ``wt`` with blue attenuation
    ``beta_b`` (1/m): I = J e^(-beta z) + A (1 - e^(-beta z)) + noise."""
    h, w = 180, 240
    sc = synth.scene(h, w, kind="looking_down", seed=seed)
    j = np.nan_to_num(sc.clean).astype(np.float64)
    f = np.linspace(0, 1, h)[:, None] * np.ones((1, w))
    z = 1.0 / (1 / 20.0 + (1.0 - 1 / 20.0) * f)
    br, bg = synth.JERLOV[wt]
    beta = np.array([beta_b / br, beta_b / bg, beta_b])
    a = np.array(synth.default_veiling_light(wt))
    t = np.exp(-beta[None, None, :] * z[:, :, None])
    img = j * t + a * (1 - t) + np.random.default_rng(seed).normal(0, 0.003, j.shape)
    return np.clip(img, 0, 1).astype(np.float32), j, z.astype(np.float32), beta, a


@pytest.mark.parametrize("wt,beta_b", [("3C", 0.23), ("7C", 0.47)])
def test_the_fit_finds_the_water_and_the_colours_beat_the_guess(wt, beta_b):
    img, j, z, beta, a = _render(wt, beta_b, seed=4)
    obj = np.ones(z.shape, bool)
    res = uwhl_rs.restore(img, distance=z)
    assert res.distance["used"] and "distance_rejected" not in res.flags, res.distance
    fitted = np.array(res.water["beta"])
    assert np.all(np.abs(fitted / beta - 1) < 0.35), (fitted, beta)
    assert abs(TYPES.index(res.water["nearest_type"]) - TYPES.index(wt)) <= 1, res.water
    assert res.water_type == res.water["nearest_type"]
    # the distance proxy is the distance: -ln t_B = beta_B_fitted z
    assert np.allclose(-np.log(res.transmission), fitted[2] * z, rtol=1e-4, atol=1e-5)
    with_d = truth.score(res.image, j, obj)["median"]
    without = truth.score(uwhl_rs.restore(img).image, j, obj)["median"]
    raw = truth.score(img, j, obj)["median"]
    assert with_d < without and with_d < raw, (with_d, without, raw)
    assert 0 <= res.image.min() and res.image.max() <= 1 and 0 <= res.radiance.min() and res.radiance.max() <= 1
    assert res.confidence is not None and res.confidence.shape == z.shape
    # with the distance known nothing is blended toward the input's balance (§13.4)
    assert res.fallback_share is None and res.veil_excess is not None


@pytest.mark.parametrize("wt,beta_b", [("3C", 0.23), ("7C", 0.47)])
def test_the_plausible_waters_hold_the_true_one_and_the_fit(wt, beta_b):
    """METHOD §13.2 step 6: the range of each attenuation holds the fit
    and, on a render of known water, the truth; the true type and the fit's
    nearest type are among the plausible ones; more noise, a wider range."""
    spans = []
    for noise in (0.003, 0.03):
        img, j, z, beta, a = _render(wt, beta_b, seed=4)
        img = np.clip(img + np.random.default_rng(7).normal(0, noise, img.shape), 0, 1).astype(np.float32)
        res = uwhl_rs.restore(img, distance=z)
        rng = np.array(res.water["beta_range"])
        fitted = np.array(res.water["beta"])
        assert rng.shape == (3, 2) and np.all(rng[:, 0] <= fitted) and np.all(fitted <= rng[:, 1]), res.water
        assert np.all(rng[:, 0] <= beta) and np.all(beta <= rng[:, 1]), (beta, rng)
        types = res.water["plausible_types"]
        assert wt in types and res.water["nearest_type"] in types, res.water
        assert types == [t for t in TYPES if t in types]  # the table's order
        assert res.distance["water"]["beta_range"] == res.water["beta_range"]
        spans.append(rng[2, 1] / rng[2, 0])
    assert spans[0] < spans[1], spans


def test_another_scenes_map_is_rejected_and_the_photo_restored_without_it():
    img, _, z, _, _ = _render("3C", 0.23, seed=4)
    res = uwhl_rs.restore(img, distance=np.ascontiguousarray(z[::-1]))  # near and far swapped
    assert "distance_rejected" in res.flags and res.distance["used"] is False
    plain = uwhl_rs.restore(img)
    assert np.array_equal(res.image, plain.image)


def test_a_map_that_orders_near_and_far_against_the_haze_is_rejected():
    # type III over 1-20 m: the fit alone accepts disparity given as distance
    # (20 / z, near and far swapped but smooth), the photo's haze does not
    img, _, z, _, _ = _render("III", 0.10, seed=4)
    right = uwhl_rs.restore(img, distance=z)
    assert right.distance["used"] and right.distance["haze_order"] > 0.5, right.distance
    disparity = np.ascontiguousarray((20.0 / z).astype(np.float32))
    res = uwhl_rs.restore(img, distance=disparity)
    assert "distance_rejected" in res.flags and res.distance["used"] is False
    assert res.distance["haze_order"] < -0.5
    assert "orders near and far against the photo's own haze" in res.distance["rejected"]
    assert res.distance["water"] is not None  # the fit that was refused is kept for the record
    assert np.array_equal(res.image, uwhl_rs.restore(img).image)


def test_the_haze_check_keeps_the_true_map_in_clear_water():
    # in type I the haze-lines barely see the water (their order of near and
    # far is poor, rank correlation about -0.2 here): the check's threshold
    # leaves the true map in use
    img, _, z, _, _ = _render("I", 0.02, seed=4)
    res = uwhl_rs.restore(img, distance=z)
    assert res.distance["used"], res.distance
    assert res.distance["haze_order"] > -0.5


def test_the_photo_and_parameters_are_refused_with_a_distance_as_without():
    # the map would be used (and its haze check done on a copy): the photo's
    # own faults and bad parameters are still refused, as without a distance
    img, _, z, _, _ = _render("III", 0.10, seed=4)
    bad = img.copy()
    bad[0, 0, 0] = np.nan
    for kw in ({}, {"distance": z}):
        with pytest.raises(uwhl_rs.ImageError, match="non-finite"):
            uwhl_rs.restore(bad, **kw)
        with pytest.raises(uwhl_rs.ParameterError, match="t_scale"):
            uwhl_rs.restore(img, t_scale=5.0, **kw)
        with pytest.raises(uwhl_rs.ParameterError, match="guided_eps"):
            uwhl_rs.restore(img, guided_eps=-1.0, **kw)
        with pytest.raises(ValueError, match="water_mask"):
            uwhl_rs.restore(img, water_mask=np.ones(z.shape, bool), **kw)
    # A is fitted with the attenuation: a given one does not go with a map
    with pytest.raises(uwhl_rs.ParameterError, match="fitted from the distance map"):
        uwhl_rs.restore(img, distance=z, veiling_light=(0.1, 0.3, 0.4))


def test_a_wrong_water_mask_does_not_turn_the_haze_check_against_the_true_map():
    # the bottom rows (the nearest floor) given as water: the check runs the
    # method without that mask and leaves those rows out
    img, _, z, _, _ = _render("III", 0.10, seed=4)
    wm = np.zeros(z.shape, bool)
    wm[-54:] = True
    res = uwhl_rs.restore(img, distance=z, water_mask=wm)
    assert res.distance["haze_order"] > 0.5, res.distance
    assert res.distance["used"], res.distance


def test_holes_and_a_smaller_map_of_the_same_aspect_are_used():
    img, j, z, beta, _ = _render("3C", 0.23, seed=6)
    holed = z.copy()
    holed[40:90, 60:160] = np.nan
    holed[:, :10] = 0.0
    res = uwhl_rs.restore(img, distance=holed[::2, ::2])
    assert res.distance["used"], res.distance
    known = np.isfinite(holed) & (holed > 0)
    assert abs(res.distance["coverage"] - known.mean()) < 0.02
    assert np.all(np.abs(np.array(res.water["beta"]) / beta - 1) < 0.4)


def test_water_from_one_photo_restores_another_with_its_type():
    a_img, _, z, _, _ = _render("3C", 0.23, seed=4)
    b_img, _, _, _, _ = _render("3C", 0.23, seed=9)
    fit = uwhl_rs.restore(a_img, distance=z).water
    res = uwhl_rs.restore(b_img, water=fit)
    bb, br, bg = fit["beta"][2], fit["beta"][0], fit["beta"][1]
    assert res.water_type == fit["nearest_type"]
    assert res.beta_ratios == pytest.approx((bb / br, bb / bg), rel=1e-6)
    with pytest.raises(uwhl_rs.ParameterError):
        uwhl_rs.restore(b_img, water=fit, water_types=["3C"])
    with pytest.raises(uwhl_rs.ParameterError):
        uwhl_rs.restore(b_img, water={"beta": [0, 1, 1]})
