"""End-to-end quality checks of ``uwhl_rs.restore`` (METHOD §11).

Rendered scenes (``uwhl_rs.synth``, METHOD §0) give known truth: distance z,
clean radiance, water region, water type and veiling light. Every threshold
below comes from measurements of exactly these runs (200 x 260 px, scene
seeds 0-3, noise 0.002, noise seed 100 * seed + type index), quoted next to
the assertion, with a margin. ``benches/quality.py`` prints the same figures
at 360 x 480 with noise 0.002 and 0.01.

Real photos (../shared/data/images, described in
../shared/data/PROVENANCE.md) are checked for VL placement only; those
tests skip when the folder is absent.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

uwhl_rs = pytest.importorskip("uwhl_rs")
from uwhl_rs import synth  # noqa: E402
from datapaths import IMAGES_DIR as DATA_DIR  # noqa: E402

TYPES = list(synth.JERLOV)
H, W = 200, 260
SEEDS = (0, 1, 2, 3)
NOISE = 0.002


def _pearson(x, y) -> float:
    x = np.asarray(x, np.float64).ravel()
    y = np.asarray(y, np.float64).ravel()
    x = x - x.mean()
    y = y - y.mean()
    return float(x @ y / math.sqrt((x @ x) * (y @ y)))


def _iou(a, b) -> float:
    return np.count_nonzero(a & b) / max(1, np.count_nonzero(a | b))


def _vl_row_limit(h: int, w: int) -> int:
    """Rows y < this may hold VL (METHOD §3.4, as pinned in METHOD §3)."""
    s = max(1, math.ceil(max(h, w) / 512))
    return min(h, s * math.ceil(math.ceil(h / s) / 4))


def _mean_angle_deg(a, b, sel) -> float:
    x = np.asarray(a, np.float64)[sel]
    y = np.asarray(b, np.float64)[sel]
    cos = np.einsum("ij,ij->i", x, y) / np.maximum(
        np.linalg.norm(x, axis=1) * np.linalg.norm(y, axis=1), 1e-12)
    return float(np.degrees(np.arccos(np.clip(cos, -1, 1))).mean())


def _rank(scores: dict, name: str) -> int:
    names = list(scores)
    order = sorted(names, key=lambda n: (scores[n], names.index(n)))
    return order.index(name) + 1


def _run(kind: str, seed: int, ti: int, wt: str, sc, given: bool) -> dict:
    img = synth.render(sc.clean, sc.distance, wt, noise=NOISE, seed=100 * seed + ti)
    res = uwhl_rs.restore(img, water_mask=sc.water if given else None, method="paper")
    nonwater = ~sc.water
    top = sc.water.copy()
    top[_vl_row_limit(H, W):] = False
    vm = np.asarray(res.veiling_mask)
    return dict(
        kind=kind, seed=seed, type=wt, given=given,
        rho=_pearson(sc.distance[nonwater], -np.log(res.transmission[nonwater])),
        rank=_rank(res.scores, wt),
        chosen=res.water_type,
        a_err=float(np.abs(np.asarray(res.veiling_light)
                           - np.asarray(synth.default_veiling_light(wt))).max()),
        fallback="veiling_fallback" in res.flags,
        vl_frac=float(vm.mean()),
        iou_top=_iou(vm, top) if top.any() else float("nan"),
        vl_in_water=np.count_nonzero(vm & sc.water) / max(1, np.count_nonzero(vm)),
        ang_in=_mean_angle_deg(img, sc.clean, nonwater),
        ang_out=_mean_angle_deg(res.image, sc.clean, nonwater),
    )


@pytest.fixture(scope="module")
def open_runs():
    """open_water scenes: 4 seeds x 10 types x (water_mask given, detected)."""
    out = []
    for seed in SEEDS:
        sc = synth.scene(H, W, kind="open_water", seed=seed)
        for ti, wt in enumerate(TYPES):
            for given in (True, False):
                out.append(_run("open_water", seed, ti, wt, sc, given))
    return out


@pytest.fixture(scope="module")
def down_runs():
    """looking_down scenes (no water at all): 4 seeds x 10 types, detected."""
    out = []
    for seed in SEEDS:
        sc = synth.scene(H, W, kind="looking_down", seed=seed)
        for ti, wt in enumerate(TYPES):
            out.append(_run("looking_down", seed, ti, wt, sc, False))
    return out


def _sel(runs, given=None, wt=None):
    return [r for r in runs if (given is None or r["given"] == given)
            and (wt is None or r["type"] == wt)]


# --------------------------------------------------------------------------
# Transmission vs distance (METHOD §11)
# --------------------------------------------------------------------------


@pytest.mark.parametrize("wt", TYPES)
def test_rho_with_given_water_mask_every_type(open_runs, wt):
    # Measured (water_mask given, 4 seeds): per-type minimum 0.589 (7C,
    # seed 1), next lowest 0.683 (9C), 0.697 (IB); per-type medians
    # 0.79-0.89. The paper reports 0.66-0.93 per real image. Every run must
    # exceed 0.5 (margin 0.09 over the worst run) and each type's median
    # 0.7 (margin >= 0.09 over the lowest median, 0.793 for 1C).
    rhos = [r["rho"] for r in _sel(open_runs, True, wt)]
    assert len(rhos) == len(SEEDS)
    assert min(rhos) > 0.5, rhos
    assert np.median(rhos) > 0.7, rhos


def test_rho_with_detected_vl(open_runs):
    # Measured (VL detected, 40 runs): min 0.619 (7C seed 1), median 0.83.
    rhos = [r["rho"] for r in _sel(open_runs, False)]
    assert min(rhos) > 0.5, sorted(rhos)[:5]
    assert np.median(rhos) > 0.75


# --------------------------------------------------------------------------
# VL detection and the veiling light (METHOD §3)
# --------------------------------------------------------------------------


def test_detected_vl_matches_water_in_the_top_quarter(open_runs):
    # Measured: IoU with the true water restricted to the rows VL may
    # occupy = 1.000 in all 40 runs (360x480 in the bench: min 0.999 at
    # noise 0.01). The full water region reaches ~40% of the rows, so the
    # IoU with all of it is ~0.62 by construction; instead check that
    # VL lies in the water (precision).
    runs = _sel(open_runs, False)
    assert not any(r["fallback"] for r in runs)
    assert min(r["iou_top"] for r in runs) > 0.95
    assert min(r["vl_in_water"] for r in runs) > 0.98


@pytest.mark.parametrize("given", [True, False], ids=["water_mask", "detected"])
def test_veiling_light_error_when_water_is_visible(open_runs, given):
    # Measured max |A - A_true| (max over channels, linear): 0.006 with the
    # mask given, 0.004 detected (bench, 360x480 incl. noise 0.01: 0.029).
    errs = [r["a_err"] for r in _sel(open_runs, given)]
    assert max(errs) < 0.02, max(errs)


def test_looking_down_vl_is_tiny_or_absent(down_runs):
    # Measured at 200x260: 'veiling_fallback' in 19/40 runs; otherwise VL
    # is a speck of 0.10-0.86% of the pixels (max 1.34% at 360x480, noise
    # 0.01, where the bench sees the fallback in 0/40 runs). Assert what
    # holds: VL never above 2% of the image.
    fr = [r["vl_frac"] for r in down_runs]
    assert max(fr) < 0.02, max(fr)
    assert sum(r["fallback"] for r in down_runs) >= 10


@pytest.mark.xfail(strict=True, reason=(
    "known gap: on looking_down renders, uniform seabed patches in the top quarter "
    "(green algae, dark rubble: clean-radiance std < 0.03) are textureless to the "
    "edge map (METHOD §3) and exceed the 0.1% minimum, so "
    "'veiling_fallback' is raised in only 19/40 runs at 200x260 and 0/40 at 360x480"))
def test_looking_down_always_raises_veiling_fallback(down_runs):
    missing = [(r["seed"], r["type"], round(100 * r["vl_frac"], 2))
               for r in down_runs if not r["fallback"]]
    assert not missing, missing


# --------------------------------------------------------------------------
# Color (METHOD §11: error of J against the clean image)
# --------------------------------------------------------------------------


@pytest.mark.parametrize("wt", ["II", "III", "1C", "3C", "7C"])
def test_restored_colors_closer_to_clean_than_input(open_runs, wt):
    # Mean per-pixel angle between RGB and the clean radiance over non-water
    # pixels, VL detected. Measured ratio restored/input (worst of 4 seeds):
    # II 0.67, III 0.55, 1C 0.57, 3C 0.59, 7C 0.62 (e.g. II 25.7 -> 15.6
    # degrees). Not asserted: I/IA/IB (ratio up to 1.05: with beta_b = 0.2
    # the red of every object is attenuated below the noise, nothing to
    # recover), 5C (0.93 on seed 0, when a wrong type 3C is chosen) and 9C
    # (0.76, the input is already within ~9 degrees).
    for r in _sel(open_runs, False, wt):
        assert r["ang_out"] < 0.8 * r["ang_in"], (r["seed"], r["ang_in"], r["ang_out"])


def test_restored_colors_improve_on_average(open_runs):
    runs = _sel(open_runs, False)
    assert np.mean([r["ang_out"] for r in runs]) < 0.8 * np.mean([r["ang_in"] for r in runs])


# --------------------------------------------------------------------------
# Water-type choice (METHOD §9, gray world)
# --------------------------------------------------------------------------
#
# Ranks are by gray-world score over all ten types (1 = lowest score), so
# they ignore the t_R exclusion rule. Measured ranks of the true type over
# seeds 0-3, water_mask given / detected:
#   I   1,5,1,2 / 1,10,1,3    II  4,4,4,4 / 4,4,4,4    3C 1,2,1,2 / 3,4,1,3
#   IA  3,4,2,3 / 2,5,2,3     III 4,4,2,5 / 5,5,4,6    5C 2,2,1,1 / 3,3,1,2
#   IB  2,3,3,3 / 3,4,2,3     1C  1,2,1,2 / 2,6,3,6    7C 1,1,1,1 / 1,1,1,3
#                                                      9C 1,1,1,1 / 1,1,1,2
# Top-3 rate: 31/40 = 78% (given), 26/40 = 65% (detected).
#
# Where gray world misses, and why:
# - II and III rank 4-5 in every run; the lowest scores go to types with a
#   SMALLER beta_BR (I, IA, IB), i.e. more red gain. With beta_b = 0.2 the
#   true t_R of the far seabed is far below 0.1, but METHOD §7 clamps t_R at
#   0.1 and the far pixels' red is at the noise level anyway, so under the
#   true type the restored red mean is too low and gray world prefers a type
#   that over-amplifies the red of the near pixels.
# - I, IA, IB rank well by score but are (almost) never CHOSEN: the METHOD §9
#   exclusion removes them. t_R = t_B^(1/beta_BR) with 1/beta_BR = 5.7-8.9,
#   so any t_B below ~0.7-0.77 gives t_R at its 0.1 clamp, the value it also
#   has on water; the estimated t_B is at most 0.9 (METHOD §4.6) and the seabed
#   lies 1.5-11 m away, so the mean t_R difference stays under 0.1. The
#   bench: true type excluded in 4/4 runs for each of I, IA, IB. This is not
#   an artifact of the renders' strong attenuation: with beta_b = 0.05
#   instead of 0.2 (seeds 0, 1, mask given) I and IA were still excluded in
#   2/2 runs and IB in 1/2, and the true type's rank got worse (5-9).
# - Detection (vs the given mask) costs little in VL (IoU 1.0) but the
#   scores are computed over non-VL pixels, which then include the lower
#   water rows below the top quarter; 1C and 3C drop in rank.


def test_true_type_among_three_best_scores_with_given_mask(open_runs):
    runs = _sel(open_runs, True)
    rate = np.mean([r["rank"] <= 3 for r in runs])
    assert rate >= 0.65, rate  # measured 0.78
    # coastal types 1C-9C: top-3 in every one of the 16 measured runs
    for wt in ("1C", "3C", "5C", "7C", "9C"):
        ranks = [r["rank"] for r in _sel(open_runs, True, wt)]
        assert sum(k <= 3 for k in ranks) >= 3, (wt, ranks)


def test_true_type_among_three_best_scores_with_detected_vl(open_runs):
    runs = _sel(open_runs, False)
    rate = np.mean([r["rank"] <= 3 for r in runs])
    assert rate >= 0.5, rate  # measured 0.65
    for wt in ("5C", "7C", "9C"):  # measured ranks <= 3 in all 12 runs
        ranks = [r["rank"] for r in _sel(open_runs, False, wt)]
        assert sum(k <= 3 for k in ranks) >= 3, (wt, ranks)


def test_chosen_type_is_a_known_type(open_runs, down_runs):
    for r in open_runs + down_runs:
        assert r["chosen"] in TYPES


# --------------------------------------------------------------------------
# Real photos (../shared/data/images), VL placement only
# --------------------------------------------------------------------------
#
# Photos are reduced by block averaging (linear data) by the integer factor
# s = ceil(max(H, W) / 512): the same reduction the detector applies
# (METHOD §3 step 2), so VL matches the full-size run closely (fractions
# within ~2 points, same fallbacks; uieb_880 7.3% full size vs 1.8% here) at
# a tenth of the time.

# PROVENANCE.md: open water with a visible water background.
OPEN_WATER = [
    "uwhl_galdran1_input.jpg",  # VL 14.6% (full size), the water band under the surface
    "uwhl_ship_highres_input.jpg",  # 4.0%, blue water top-left
    "uwhl_shipwreck_input.jpg",  # 5.0%, water top-left
    "uieb_616.png",  # 3.2%, blue water between fish
    "lcm_sample_1.jpg",  # 24%, the whole top quarter is water
    "lcm_sample_5.jpg",  # 0.6%, a corner of the water band only
    "udc_5-2.jpg",  # 15.4%, same scene as galdran1
    "udc_10.jpg",  # 0.8%, a gap between sharks
    "euvp_7.jpg",  # 12.9%
    "euvp_17.jpg",  # 10.9%
]
# Not listed: udc_hazed3.jpg ("fish school, open water"): the frame is filled
# by the school; VL (1.5%) lands on out-of-focus fish bodies, not on water
# (seen in the bench's overlay), so asserting "found" would enshrine a miss.

# PROVENANCE.md: looking down, no water background.
LOOKING_DOWN = [
    "uieb_866.png",
    "euvp_13.jpg",
    "euvp_22.jpg",
    "chart_calib_3_under.jpg",
    pytest.param("uieb_880.png", marks=pytest.mark.xfail(strict=True, reason=(
        "known miss: camera at sand level; the defocused far seabed at the top is "
        "textureless and VL (7.3% full size, 1.8% here) lands on it"))),
]
# PROVENANCE.md calls these looking down, but the overlays show a band of
# water at the top: lcm_sample_7 ("sand + coral, looking down-ish") has open
# water above a sand horizon over the whole top quarter; udc_hazed2 ("looking
# down at sand") has turbid green water above the sand slope in its top
# ~20%. VL covers those bands (24.8% and 12.5% full size), which is right.
WATER_ON_TOP_DESPITE_LABEL = ["lcm_sample_7.jpg", "udc_hazed2.jpg"]


def _srgb_to_linear(x):
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def _load(name: str) -> np.ndarray:
    iio = pytest.importorskip("imageio.v3")
    p = DATA_DIR / name
    if not p.is_file():
        pytest.skip(f"{p} absent")
    a = iio.imread(p)[..., :3]
    lin = _srgb_to_linear(a.astype(np.float64) / np.iinfo(a.dtype).max)
    h, w = lin.shape[:2]
    k = max(1, math.ceil(max(h, w) / 512))
    if k > 1:
        hp, wp = math.ceil(h / k) * k, math.ceil(w / k) * k
        pad = ((0, hp - h), (0, wp - w))
        s = np.pad(lin, pad + ((0, 0),)).reshape(hp // k, k, wp // k, k, 3).sum((1, 3))
        n = np.pad(np.ones((h, w)), pad).reshape(hp // k, k, wp // k, k).sum((1, 3))
        lin = s / n[..., None]
    return np.ascontiguousarray(lin, dtype=np.float32)


needs_photos = pytest.mark.skipif(not DATA_DIR.is_dir(), reason=f"{DATA_DIR} absent")


@needs_photos
@pytest.mark.parametrize("name", OPEN_WATER)
def test_photo_open_water_vl_found_in_upper_part(name):
    img = _load(name)
    res = uwhl_rs.restore(img)
    vm = np.asarray(res.veiling_mask)
    h = vm.shape[0]
    assert "veiling_fallback" not in res.flags
    # measured (at this size) 0.6% (lcm_sample_5) .. 24% of the pixels
    assert vm.mean() > 0.003, vm.mean()
    rows = np.flatnonzero(vm.any(axis=1))
    assert rows[-1] < 0.3 * h  # METHOD §3.4: the top quarter only
    # water color: red is the weakest component of A in every measured photo
    a = np.asarray(res.veiling_light)
    assert a[0] < a[1] and a[0] < a[2], a


@needs_photos
@pytest.mark.parametrize("name", LOOKING_DOWN)
def test_photo_looking_down_falls_back(name):
    # Measured: uieb_866, euvp_13, euvp_22 and chart_calib_3_under raise
    # 'veiling_fallback' (full size and at this size); uieb_880 does not.
    res = uwhl_rs.restore(_load(name))
    assert "veiling_fallback" in res.flags, (name, float(np.mean(res.veiling_mask)))
    assert not np.asarray(res.veiling_mask).any()


@needs_photos
@pytest.mark.parametrize("name", WATER_ON_TOP_DESPITE_LABEL)
def test_photo_water_band_above_the_bottom_is_found(name):
    # measured at this size: 24.75% (lcm_sample_7), 12.4% (udc_hazed2)
    res = uwhl_rs.restore(_load(name))
    vm = np.asarray(res.veiling_mask)
    assert "veiling_fallback" not in res.flags
    assert vm.mean() > 0.05, vm.mean()
    assert np.flatnonzero(vm.any(axis=1))[-1] < 0.3 * vm.shape[0]


# PROVENANCE.md: the same charts photographed above water (in air), and
# photos taken under water whose water region is found (the list above)
IN_AIR = ["chart_calib_2_above.jpg", "chart_calib_3_above.jpg"]


@needs_photos
@pytest.mark.parametrize("name", IN_AIR + OPEN_WATER)
def test_a_photo_taken_in_air_is_flagged_and_one_under_water_is_not(name):
    """METHOD §3 "Not water's colour": no water leaves its veil as red as
    it is green or blue; air's haze is neutral to warm."""
    res = uwhl_rs.restore(_load(name))
    a = res.veiling_light
    assert ("veiling_light_not_water" in res.flags) == (name in IN_AIR), (a, res.flags)
    assert (a[0] >= max(a[1], a[2])) == (name in IN_AIR)
