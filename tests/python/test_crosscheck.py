"""Cross-check of every Rust stage (uwhl_rs._core._stage_*) and of the whole
uwhl_rs.restore against the independent NumPy/SciPy reference
(tests/python/reference.py), which follows docs/METHOD.md. The `_stage_*`
entry points run the code `restore` runs (the same row kernels); they exist
in wheels built with the `internals` feature (the test command of the
README builds it).

Inputs are small scenes rendered with uwhl_rs.synth and seeded random
images, always float32 and C-contiguous; the reference gets the very same
float32 values (it computes in float64). Every tolerance is a named constant
below with the reason it is not zero.
"""

import math
import os
import sys
from functools import lru_cache

import numpy as np
import pytest

sys.path.insert(0, os.path.dirname(__file__))
try:
    import uwhl_rs
except ImportError:  # not installed: use the in-tree package with the built .so
    sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "python"))
    import uwhl_rs

import reference as ref
from uwhl_rs import _core, synth

pytestmark = pytest.mark.skipif(
    not hasattr(_core, "_stage_stretch"),
    reason='the wheel was built without the internals feature (MATURIN_PEP517_ARGS="--features python,pyo3/extension-module,internals")',
)

# ---------------------------------------------------------------------------
# Tolerances (Rust stores f32 and often computes in f32; the reference is f64)
# ---------------------------------------------------------------------------

#: values in [0, 1] after a few f32 roundings (ulp(1) = 1.2e-7, a handful of them).
F32_ATOL = 1e-6
#: the per-channel stretch divides by the 1%-99% range (>= ~0.1 on these
#: inputs), amplifying the f32 rounding of the global min-max by up to ~10x.
STRETCH_ATOL = 2e-6
#: error of an f32 value in [0, 1] fed to a power x**p: the power itself is
#: compared with the exact bound (x + d)**p - (x - d)**p (see _power_bound),
#: so steep powers near 0 (x**(1/2.2), x**0.11) get what f32 input rounding implies.
POW_INPUT_ATOL = 3e-7
#: edge strength: blur and Sobel accumulate in f64 in both, on an f32
#: normalised copy (Rust) vs f64 (reference); stored as f32.
EDGE_ATOL = 1e-6
#: tau = 0.6 * noise sigma; Rust forms the Laplacian response in f32
#: (9 terms of size <= 1, error <= ~1e-6), / (6 * 0.3186) * 0.6.
TAU_ATOL = 1e-6
#: the fallback A is a mean of a blurred image (f32 storage in Rust).
A_FALLBACK_ATOL = 1e-6
#: sphere points: Rust stores the f64 lattice as f32 (half an f32 ulp of 1 = 3e-8).
SPHERE_POINT_ATOL = 6e-8
#: two nearest-point candidates are "equally near" if their squared
#: distances (f64) differ by less than this: the query and points are f32.
SPHERE_TIE_TOL = 1e-6
#: t~ in [0.009, 0.9]: r and r / r_max are computed in f32 in Rust.
HAZE_ATOL = 1e-6
#: fraction of pixels allowed to differ by more than HAZE_ATOL: a pixel whose
#: u lies within f32 rounding of a boundary between two sphere cells may join
#: the other cluster (a near-tie in the nearest-neighbour assignment); if it
#: held a cluster's r_max, every pixel of that cluster moves too.
HAZE_MISMATCH_FRACTION = 0.01
#: squared Mahalanobis distance: f64 statistics in both, Rust output is f32
#: (relative rounding 6e-8).
MAHAL_RTOL = 1e-6
MAHAL_ATOL = 1e-9
#: matting weights: a ramp of width thr_notwater - thr_water over d values
#: that carry the f32 rounding above.
MATTING_ATOL = 1e-5
#: guided filter: Rust stores window means and (Sigma + eps U)^-1 as f32;
#: the rounding of Sigma (~1e-7) is multiplied by the inverse, whose size is
#: ~1/eps, so the tolerance is GUIDED_ATOL + GUIDED_ATOL_X_EPS / eps.
GUIDED_ATOL = 1e-6
GUIDED_ATOL_X_EPS = 3e-9
#: recovery: J = A + (I - A) / t in f32 with t >= 0.1 (10x amplification)
#: then divided by max(J) <= 1.6.
RECOVER_ATOL = 2e-6
#: display stretch: global min-max in f32, then division by hi - lo >= 0.6.
DISPLAY_ATOL = 1e-6
#: chart fill: a mean (f64) of f32 values, stored as f32.
CHART_ATOL = 1e-6
#: whole pipeline: the sum of the stage errors (guided filter at eps = 1e-3
#: ~4e-6, haze lines, bounds, recovery ~2e-6), with margin.
RESTORE_T_ATOL = 1e-5
RESTORE_IMAGE_ATOL = 2e-5
#: gray-world scores are std devs of three channel means of the stretched
#: image (each within RESTORE_IMAGE_ATOL, averaged over pixels).
SCORE_ATOL = 1e-6

WATER_TYPES = ref.WATER_TYPES


# ---------------------------------------------------------------------------
# Inputs
# ---------------------------------------------------------------------------

def _f32(a):
    return np.ascontiguousarray(a, dtype=np.float32)


@lru_cache(maxsize=None)
def _scene(h, w, kind, seed):
    return synth.scene(h, w, kind=kind, seed=seed)


@lru_cache(maxsize=None)
def _render(h, w, kind="open_water", seed=0, water="III", noise=0.003):
    sc = _scene(h, w, kind, seed)
    img = synth.render(sc.clean, sc.distance, water, noise=noise, seed=seed)
    img = _f32(img)
    img.setflags(write=False)
    return img


def rendered(h=48, w=64, kind="open_water", seed=0, water="III", noise=0.003):
    """A rendered scene (float32, C-contiguous, read-only: copy to modify)."""
    return _render(h, w, kind, seed, water, noise)


def random_image(h, w, seed, lo=0.0, hi=1.0):
    return _f32(np.random.default_rng(seed).uniform(lo, hi, size=(h, w, 3)))


def chart_mask(h, w):
    """Estimation mask with two masked-out 'charts' (False = not used)."""
    m = np.ones((h, w), dtype=bool)
    m[h * 5 // 8:h * 5 // 8 + 8, w // 6:w // 6 + 10] = False
    m[2:6, w - 9:w - 3] = False
    return m


def ref_a(img):
    """A as detected by the reference, as the float32 triple Rust takes."""
    return tuple(np.float32(v) for v in ref.detect_veiling(img)["A"])


def _power_bound(x, p, d):
    """Largest change of clip(x, 0, 1)**p when x moves by at most d."""
    x = np.asarray(x, dtype=np.float64)
    return np.clip(x + d, 0, 1) ** p - np.clip(x - d, 0, 1) ** p


def _assert_close(got, exp, atol, what, rtol=0.0):
    got = np.asarray(got, dtype=np.float64)
    exp = np.asarray(exp, dtype=np.float64)
    assert got.shape == exp.shape, f"{what}: shape {got.shape} vs {exp.shape}"
    err = np.abs(got - exp)
    lim = atol + rtol * np.abs(exp)
    bad = err > lim
    if bad.any():
        i = np.unravel_index(np.argmax(err - lim), err.shape)
        raise AssertionError(
            f"{what}: {bad.sum()} of {bad.size} values off; worst at {i}: "
            f"rust {got[i]!r} vs reference {exp[i]!r} (|diff| {err[i]:.3g}, tol {lim[i]:.3g})")


# ---------------------------------------------------------------------------
# S3.1 / S6 contrast stretch and guide
# ---------------------------------------------------------------------------

def _stretch_inputs():
    flat_b = random_image(30, 40, 11).copy()
    flat_b[..., 2] = 0.5  # a constant channel: hi - lo <= 1e-12, left unchanged
    return [
        ("open_water", rendered(48, 64, "open_water", 0)),
        ("looking_down", rendered(64, 80, "looking_down", 1, water="1C")),
        ("random", random_image(40, 56, 0)),
        ("constant_channel", _f32(flat_b)),
        ("constant", _f32(np.full((8, 9, 3), 0.3))),
    ]


@pytest.mark.parametrize("name,img", _stretch_inputs(), ids=lambda v: v if isinstance(v, str) else "")
def test_stretch(name, img):
    """_stage_stretch equals stretch_image (global min-max, then per-channel
    1%/99% stretch; constant channel and constant image cases) within STRETCH_ATOL."""
    _assert_close(_core._stage_stretch(img), ref.stretch_image(img), STRETCH_ATOL, f"stretch {name}")


@pytest.mark.parametrize("with_mask", [False, True])
@pytest.mark.parametrize("name,img", _stretch_inputs()[:4], ids=lambda v: v if isinstance(v, str) else "")
def test_guide(name, img, with_mask):
    """_stage_guide equals guide_image (stretch ** (1/2.2), masked-out pixels
    0): masked-out pixels exactly 0, elsewhere within the change of x**(1/2.2)
    implied by an input error of STRETCH_ATOL (_power_bound) plus F32_ATOL."""
    h, w = img.shape[:2]
    mask = chart_mask(h, w) if with_mask else None
    got = _core._stage_guide(img, mask)
    exp = ref.guide_image(img, mask)
    if mask is not None:
        assert np.all(got[~mask] == 0.0)
    x = ref.stretch_image(img)
    tol = _power_bound(x, 1.0 / 2.2, STRETCH_ATOL) + F32_ATOL
    err = np.abs(got - exp)
    assert np.all(err <= tol), (
        f"guide {name}: max excess {np.max(err - tol):.3g} at {np.unravel_index(np.argmax(err - tol), err.shape)}")


# ---------------------------------------------------------------------------
# S3 edge map
# ---------------------------------------------------------------------------

def _edge_inputs():
    return [
        ("open_water_48x64", lambda: rendered(48, 64, "open_water", 1)),
        ("looking_down_64x80", lambda: rendered(64, 80, "looking_down", 2, water="II")),
        ("random_40x56", lambda: random_image(40, 56, 1)),
        ("open_water_600x700", lambda: rendered(600, 700, "open_water", 2, noise=0.005)),
        ("random_517x1030", lambda: random_image(517, 1030, 2, 0.3, 0.5)),
    ]


@pytest.mark.parametrize("name,make", _edge_inputs(), ids=[n for n, _ in _edge_inputs()])
def test_edge_map(name, make):
    """_stage_edge_map equals edge_map: same downscale factor and working size
    (600x700 -> s = 2; 517x1030 -> s = 3 with partial border blocks), E within
    EDGE_ATOL, tau within TAU_ATOL, and sigma consistent with tau."""
    img = make()
    e, tau, s, sigma = _core._stage_edge_map(img)
    e_ref, tau_ref, s_ref = ref.edge_map(img)
    assert s == s_ref
    h, w = img.shape[:2]
    assert e.shape == e_ref.shape == (math.ceil(h / s), math.ceil(w / s))
    if max(h, w) > 512:
        assert s > 1
    _assert_close(e, e_ref, EDGE_ATOL, f"edge E {name}")
    assert abs(tau - tau_ref) <= TAU_ATOL, f"tau {tau} vs {tau_ref}"
    assert abs(tau - min(max(ref.EDGE_TAU_MIN, ref.K_NOISE * sigma), 0.02)) <= 1e-12


# ---------------------------------------------------------------------------
# S3 veiling light and water region
# ---------------------------------------------------------------------------

def _check_veiling(img, what, a_atol=0.0, **kw):
    a, vl, flags = _core._stage_veiling(img, **kw)
    r = ref.detect_veiling(img, **kw)
    np.testing.assert_array_equal(vl, r["vl"], err_msg=f"{what}: VL differs")
    assert list(flags) == list(r["flags"]), f"{what}: flags {flags} vs {r['flags']}"
    a_exp = np.asarray(r["A"], dtype=np.float64)
    if a_atol == 0.0:
        # A is one pixel's color (or a given/clamped value): equal as float32
        np.testing.assert_array_equal(np.float32(a), a_exp.astype(np.float32), err_msg=f"{what}: A")
    else:
        _assert_close(a, a_exp, a_atol, f"{what}: A")
    return a, vl, flags


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_veiling_detection(seed):
    """Detected VL identical, A identical (the same median-luminance pixel),
    same flags, on open-water scenes; VL is non-empty and mostly true water."""
    img = rendered(48, 64, "open_water", seed)
    a, vl, flags = _check_veiling(img, f"detect seed {seed}")
    assert vl.sum() > 0 and flags == []
    assert (vl & _scene(48, 64, "open_water", seed).water).sum() >= 0.9 * vl.sum()


@pytest.mark.parametrize("with_mask", [False, True])
def test_veiling_given_water_mask(with_mask):
    """A given water_mask replaces detection: VL = water_mask & mask in both,
    A identical."""
    img = rendered(48, 64, "open_water", 1)
    water = _scene(48, 64, "open_water", 1).water
    mask = chart_mask(48, 64) if with_mask else None
    _, vl, _ = _check_veiling(img, "water_mask", mask=mask, water_mask=water)
    np.testing.assert_array_equal(vl, water & (mask if mask is not None else True))


def test_veiling_given_veiling_light():
    """A given veiling_light replaces A (VL still detected); values exactly
    representable in float32 so both sides hold the same number."""
    img = rendered(48, 64, "open_water", 2)
    given = (0.125, 0.25, 0.375)
    a, vl, _ = _check_veiling(img, "given A", veiling_light=given)
    assert tuple(a) == given and vl.sum() > 0


def test_veiling_estimation_mask():
    """An estimation mask that cuts into the water: VL is detected the same
    way, masked-out pixels are never water, A identical."""
    img = rendered(48, 64, "open_water", 0)
    mask = np.ones((48, 64), dtype=bool)
    mask[0:6, 10:40] = False
    mask[30:40, 5:20] = False
    _, vl, _ = _check_veiling(img, "estimation mask", mask=mask)
    assert vl.sum() > 0 and not vl[~mask].any()


@pytest.mark.parametrize("seed", [0, 1])
def test_veiling_textured_falls_back(seed):
    """A textured image without water (seeded uniform noise): no region in
    either, flags no_water_region + veiling_fallback, A from the fallback
    within A_FALLBACK_ATOL, and veiling_light_not_water when that A (noise's
    gray) has red at least its green and blue; with a given A of water's
    colour, only no_water_region, and of air's, that flag beside it."""
    img = random_image(40, 56, seed)
    a, vl, flags = _check_veiling(img, "textured", a_atol=A_FALLBACK_ATOL)
    not_water = ["veiling_light_not_water"] if a[0] >= max(a[1], a[2]) else []
    assert not vl.any() and flags == ["no_water_region", "veiling_fallback"] + not_water
    _, _, flags = _check_veiling(img, "textured, given A", veiling_light=(0.125, 0.25, 0.5))
    assert flags == ["no_water_region"]
    _, _, flags = _check_veiling(img, "textured, given A", veiling_light=(0.5, 0.25, 0.125))
    assert flags == ["no_water_region", "veiling_light_not_water"]


def test_veiling_tiny_water_mask_falls_back():
    """A given water_mask smaller than max(2, 0.1% of the pixels) counts as
    empty: no_water_region + veiling_fallback in both."""
    img = rendered(48, 64, "open_water", 0)
    wm = np.zeros((48, 64), dtype=bool)
    wm[0, :3] = True  # 3 < 0.001 * 3072 -> 4 needed
    _, vl, flags = _check_veiling(img, "tiny water_mask", a_atol=A_FALLBACK_ATOL, water_mask=wm)
    assert not vl.any() and flags == ["no_water_region", "veiling_fallback"]


def test_veiling_dark_region_is_a_shadow():
    """METHOD §3 step 9: a detected flat region darker than 0.2 x the
    median luminance is rejected (both), while the same region given as a
    water_mask is kept (both)."""
    img = np.array(rendered(48, 64, "open_water", 1))
    water = _scene(48, 64, "open_water", 1).water
    img[water] *= np.float32(0.03)
    img = _f32(img)
    _, vl, flags = _check_veiling(img, "shadow", a_atol=A_FALLBACK_ATOL)
    assert not vl.any() and "no_water_region" in flags
    _, vl, flags = _check_veiling(img, "shadow as water_mask", water_mask=water)
    assert vl.sum() == water.sum() and flags == []


def test_veiling_light_clamped():
    """Water with an empty red channel: A_R = 0 is raised to 1e-4 with flag
    veiling_light_clamped in both."""
    img = np.array(rendered(48, 64, "open_water", 1))
    img[_scene(48, 64, "open_water", 1).water, 0] = 0.0
    a, _, flags = _check_veiling(_f32(img), "clamp")
    assert a[0] == np.float32(1e-4) and flags == ["veiling_light_clamped"]


# ---------------------------------------------------------------------------
# S4 sphere points and nearest neighbour
# ---------------------------------------------------------------------------

def _check_nearest(n, u, what):
    pts, near = _core._stage_sphere(n, _f32(u))
    near = np.asarray(near)
    p64 = ref.sphere_points(n)
    u64 = _f32(u).astype(np.float64)
    exp = ref.nearest_point(p64, u64)
    d_got = np.sum((u64 - p64[near]) ** 2, axis=1)
    d_exp = np.sum((u64 - p64[exp]) ** 2, axis=1)
    differ = near != exp
    assert np.all(np.abs(d_got - d_exp)[differ] <= SPHERE_TIE_TOL), (
        f"{what}: {np.sum(np.abs(d_got - d_exp)[differ] > SPHERE_TIE_TOL)} nearest "
        f"indices differ without a tie")
    return pts, differ


@pytest.mark.parametrize("n", [1, 37, 500, 2000])
def test_sphere_points_and_nearest(n):
    """Sphere points equal to f32 precision (SPHERE_POINT_ATOL); nearest index
    identical for random unit vectors and for the points themselves, or an
    equally near point (squared distances within SPHERE_TIE_TOL)."""
    rng = np.random.default_rng(n)
    u = rng.normal(size=(5000, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    pts, _ = _check_nearest(n, u, f"random n={n}")
    assert pts.shape == (n, 3) and pts.dtype == np.float32
    _assert_close(pts, ref.sphere_points(n), SPHERE_POINT_ATOL, f"points n={n}")
    _, near = _core._stage_sphere(n, _f32(ref.sphere_points(n)))
    np.testing.assert_array_equal(near, np.arange(n))


def test_sphere_nearest_on_ties():
    """Queries half-way between each point and its nearest neighbour (exact
    ties up to rounding): the two sides may pick different points, but only
    equally near ones (SPHERE_TIE_TOL)."""
    p = ref.sphere_points(500)
    d = np.sum((p[:, None] - p[None]) ** 2, axis=-1)
    np.fill_diagonal(d, np.inf)
    mid = p + p[np.argmin(d, axis=1)]
    mid /= np.linalg.norm(mid, axis=1, keepdims=True)
    _check_nearest(500, mid, "midpoints")


# ---------------------------------------------------------------------------
# S4 haze-lines
# ---------------------------------------------------------------------------

def _check_haze(img, a, br, bg, mask, what):
    got = _core._stage_haze_lines(img, a, br, bg, 500, mask)
    exp = ref.haze_lines(img, np.array(a, dtype=np.float64), br, bg, 500, mask)
    assert got.shape == exp.shape
    off = np.abs(got - exp) > HAZE_ATOL
    assert off.mean() <= HAZE_MISMATCH_FRACTION, (
        f"{what}: {off.sum()} of {off.size} pixels differ by > {HAZE_ATOL} "
        f"(max {np.abs(got - exp).max():.3g})")
    return got, exp


@pytest.mark.parametrize("with_mask", [False, True])
@pytest.mark.parametrize("kind,seed", [("open_water", 0), ("looking_down", 3)])
def test_haze_lines_scenes(kind, seed, with_mask):
    """t~ (clusters, r / r_max, fill of masked-out pixels, x0.9) within
    HAZE_ATOL on all but HAZE_MISMATCH_FRACTION of the pixels, for four
    water types, with and without an estimation mask."""
    img = rendered(48, 64, kind, seed)
    a = ref_a(img)
    mask = chart_mask(48, 64) if with_mask else None
    for name, br, bg in WATER_TYPES[::3]:
        _check_haze(img, a, br, bg, mask, f"{kind} {name} mask={with_mask}")


def test_haze_lines_random_and_r_zero():
    """Random images (many clusters, near-ties most likely) and pixels equal
    to A (r = 0 -> t~ = 0.9 exactly in both)."""
    a = (np.float32(0.3), np.float32(0.5), np.float32(0.6))
    for seed in (0, 1):
        img = np.array(random_image(40, 56, seed))
        img[5, 5:15] = a
        img = _f32(img)
        for name, br, bg in WATER_TYPES[1::4]:
            got, exp = _check_haze(img, a, br, bg, chart_mask(40, 56) if seed else None,
                                   f"random {seed} {name}")
            assert np.all(got[5, 5:15] == np.float32(0.9)) and np.all(exp[5, 5:15] == 0.9)


# ---------------------------------------------------------------------------
# S5 lower bound and matting
# ---------------------------------------------------------------------------

def _lb_tolerance(img, a, br, bg):
    """Change of t_LB implied by an f32 rounding (POW_INPUT_ATOL) of each 1 - I/A."""
    img = img.astype(np.float64)
    a = np.asarray(a, dtype=np.float64)
    x = 1.0 - img / a
    b = [_power_bound(x[..., 0], br, POW_INPUT_ATOL),
         _power_bound(x[..., 1], bg, POW_INPUT_ATOL),
         _power_bound(x[..., 2], 1.0, POW_INPUT_ATOL)]
    return np.maximum(np.maximum(b[0], b[1]), b[2]) + F32_ATOL


@pytest.mark.parametrize("src", ["open_water", "random"])
def test_lower_bound(src):
    """t_LB for all ten water types within the change that f32 rounding of
    1 - I/A implies through x**beta (steep near 0 for beta_BR = 0.11)."""
    if src == "open_water":
        img = rendered(48, 64, "open_water", 2)
        a = ref_a(img)
    else:
        img = random_image(40, 56, 4)
        a = (np.float32(0.4), np.float32(0.6), np.float32(0.7))
    for name, br, bg in WATER_TYPES:
        got = _core._stage_lower_bound(img, a, br, bg)
        exp = ref.lower_bound(img, np.array(a, dtype=np.float64), br, bg)
        tol = _lb_tolerance(img, a, br, bg)
        err = np.abs(got - exp)
        assert np.all(err <= tol), f"t_LB {src} {name}: max excess {np.max(err - tol):.3g}"


def _matting_cases():
    img0 = rendered(48, 64, "open_water", 0)
    rnd = random_image(40, 50, 1)
    vl_block = np.zeros((40, 50), dtype=bool)
    vl_block[:10] = True
    same = np.array(random_image(40, 50, 2))
    same[:6, :20] = (0.1, 0.3, 0.4)  # identical VL colors: covariance singular
    vl_same = np.zeros((40, 50), dtype=bool)
    vl_same[:6, :20] = True
    return [
        ("scene water", img0, _scene(48, 64, "open_water", 0).water),
        ("scene detected", img0, ref.detect_veiling(img0)["vl"]),
        ("random block", rnd, vl_block),
        ("singular covariance", _f32(same), vl_same),
    ]


@pytest.mark.parametrize("name,img,vl", _matting_cases(), ids=lambda v: v if isinstance(v, str) else "")
def test_matting(name, img, vl):
    """Squared Mahalanobis distances within MAHAL_RTOL (relative), matting
    weights within MATTING_ATOL; includes a singular (regularised) VL covariance."""
    res = _core._stage_matting(img, vl)
    assert res is not None
    d, w = res
    _assert_close(d, ref.mahalanobis_sq(img, vl), MAHAL_ATOL, f"mahal {name}", rtol=MAHAL_RTOL)
    _assert_close(w, ref.matting_weights(img, vl), MATTING_ATOL, f"weights {name}")


def test_matting_too_few_pixels():
    """Fewer than 2 VL pixels: both skip (None)."""
    img = random_image(20, 20, 3)
    for k in (0, 1):
        vl = np.zeros((20, 20), dtype=bool)
        vl.flat[:k] = True
        assert _core._stage_matting(img, vl) is None
        assert ref.mahalanobis_sq(img, vl) is None


# ---------------------------------------------------------------------------
# S6 guided filter and chart fill
# ---------------------------------------------------------------------------

@pytest.mark.parametrize("src", ["scene", "random"])
def test_guided_filter(src):
    """Color guided filter for r in {0, 1, 3, 8, 16, 100 (> image)} and eps in
    {1e-4, 1e-3, 1e-2}, within GUIDED_ATOL + GUIDED_ATOL_X_EPS / eps."""
    if src == "scene":
        img = rendered(48, 64, "open_water", 1)
        guide = _core._stage_guide(img)
        p = _f32(ref.haze_lines(img, np.array(ref_a(img), dtype=np.float64), 0.4051, 0.9539))
    else:
        guide = random_image(40, 56, 5)
        p = random_image(40, 56, 6)[..., 0].copy()
    for r in (0, 1, 3, 8, 16, 100):
        for eps in (1e-4, 1e-3, 1e-2):
            got = _core._stage_guided(guide, p, r, eps)
            exp = ref.guided_filter(guide, p, r, eps)
            _assert_close(got, exp, GUIDED_ATOL + GUIDED_ATOL_X_EPS / eps, f"guided {src} r={r} eps={eps}")


def _check_chart(q, mask, what):
    got = _core._stage_chart_fill(_f32(q), mask)
    exp = ref.chart_fill(_f32(q), mask)
    np.testing.assert_array_equal(got[mask], _f32(q)[mask], err_msg=f"{what}: masked-in pixels changed")
    _assert_close(got, exp, CHART_ATOL, f"chart fill {what}")


def test_chart_fill_below_and_above():
    """Masked-out regions get the mean of q over the masked-in pixels directly
    below them (interior, top-border regions), or directly above (a region on
    the bottom border); several regions at once."""
    h, w = 20, 24
    q = random_image(h, w, 7)[..., 0]
    m = np.ones((h, w), dtype=bool)
    m[3:7, 4:9] = False
    m[0:2, 12:14] = False
    m[h - 3:, 15:20] = False
    m[10, 2] = False
    _check_chart(q, m, "below/above")


def test_chart_fill_neighbours_single_band():
    """A region spanning the full height (nothing below or above) gets the
    mean over its masked-in 8-neighbours."""
    h, w = 20, 24
    q = random_image(h, w, 8)[..., 0]
    m = np.ones((h, w), dtype=bool)
    m[:, 5:7] = False
    _check_chart(q, m, "full-height band")


def test_chart_fill_neighbours_shared_by_two_regions():
    """Two full-height regions separated by one masked-in column: each gets the
    mean over the SET of its masked-in 8-neighbours (METHOD §6), so the
    shared column counts once per pixel for each region."""
    h, w = 20, 24
    q = random_image(h, w, 0)[..., 0]
    m = np.ones((h, w), dtype=bool)
    m[:, 0] = False
    m[:, 2] = False
    q = _f32(q)
    # by hand: column 0's neighbour set is column 1; column 2's is columns 1 and 3
    hand0 = float(np.mean(q[:, 1], dtype=np.float64))
    hand2 = float(np.mean(np.concatenate([q[:, 1], q[:, 3]]), dtype=np.float64))
    exp = ref.chart_fill(q, m)
    assert abs(exp[0, 0] - hand0) <= 1e-12 and abs(exp[0, 2] - hand2) <= 1e-12
    got = _core._stage_chart_fill(q, m)
    assert abs(float(got[0, 0]) - hand0) <= CHART_ATOL and abs(float(got[0, 2]) - hand2) <= CHART_ATOL, (
        f"rust gives column 0 -> {got[0, 0]}, column 2 -> {got[0, 2]}; "
        f"the neighbour-set means are {hand0}, {hand2}")
    _check_chart(q, m, "two bands sharing a neighbour column")


# ---------------------------------------------------------------------------
# S7 recovery, S8 display stretch
# ---------------------------------------------------------------------------

def test_recover():
    """J (with the artifact clamp) and clamped t_B within RECOVER_ATOL /
    F32_ATOL for four water types, on a refined t and on a t with values
    outside [0, 1] (clamps of t_B, t_R, t_G and of J < -0.08)."""
    img = rendered(48, 64, "open_water", 0)
    a = ref_a(img)
    a64 = np.array(a, dtype=np.float64)
    guide = _core._stage_guide(img)
    t0 = ref.haze_lines(img, a64, 0.4051, 0.9539)
    ts = [("refined", _f32(ref.guided_filter(guide, t0, 12, 1e-3))),
          ("wild", _f32(np.random.default_rng(9).uniform(-0.2, 1.3, size=(48, 64))))]
    for tname, t in ts:
        for name, br, bg in WATER_TYPES[::3]:
            j, tb = _core._stage_recover(img, a, t, br, bg)
            r = ref.recover(img, a64, t, br, bg)
            _assert_close(tb, r["t_B"], F32_ATOL, f"t_B {tname} {name}")
            _assert_close(j, r["J"], RECOVER_ATOL, f"J {tname} {name}")


def test_display_stretch():
    """Display stretch (global min-max, per-channel 0.1%/99.9% limits forced
    to <= 0.2 and >= 0.8/0.9) within DISPLAY_ATOL; a constant J gives 0."""
    img = rendered(48, 64, "open_water", 2)
    a64 = np.array(ref_a(img), dtype=np.float64)
    t = ref.guided_filter(_core._stage_guide(img), ref.haze_lines(img, a64, 0.2773, 0.7937), 12, 1e-3)
    cases = [("recovered", _f32(ref.recover(img, a64, t, 0.2773, 0.7937)["J"])),
             ("random", random_image(40, 56, 10, 0.2, 0.7)),
             ("constant", _f32(np.full((10, 12, 3), 0.4)))]
    for name, j in cases:
        _assert_close(_core._stage_display_stretch(j), ref.display_stretch(j), DISPLAY_ATOL, f"display {name}")


# ---------------------------------------------------------------------------
# The whole method
# ---------------------------------------------------------------------------

def _check_restore(img, what, **kw):
    got = uwhl_rs.restore(img, method="paper", **kw)
    exp = ref.restore(img, **kw)
    assert tuple(np.float32(got.veiling_light)) == tuple(np.float32(exp["veiling_light"])), (
        f"{what}: A {got.veiling_light} vs {exp['veiling_light']}")
    np.testing.assert_array_equal(got.veiling_mask, exp["veiling_mask"], err_msg=f"{what}: VL")
    assert list(got.flags) == list(exp["flags"]), f"{what}: flags {got.flags} vs {exp['flags']}"
    assert list(got.excluded) == list(exp["excluded"]), f"{what}: excluded"
    assert list(got.scores) == list(exp["scores"])
    for name in exp["scores"]:
        assert abs(got.scores[name] - exp["scores"][name]) <= SCORE_ATOL, (
            f"{what}: score {name} {got.scores[name]} vs {exp['scores'][name]}")
    # the choice is meaningful only if it is not a near-tie
    alive = sorted(s for n, s in exp["scores"].items() if n not in exp["excluded"])
    assert len(alive) < 2 or alive[1] - alive[0] > 4 * SCORE_ATOL, f"{what}: near-tie in the scores"
    assert got.water_type == exp["water_type"], f"{what}: {got.water_type} vs {exp['water_type']}"
    _assert_close(got.transmission, exp["transmission"], RESTORE_T_ATOL, f"{what}: t_B")
    _assert_close(got.radiance, exp["radiance"], RESTORE_IMAGE_ATOL, f"{what}: radiance")
    _assert_close(got.image, exp["image"], RESTORE_IMAGE_ATOL, f"{what}: image")
    return got, exp


@pytest.mark.parametrize("seed,water", [(3, "III"), (4, "1C")])
def test_restore_given_water_mask(seed, water):
    """uwhl_rs.restore vs reference.restore on a 48x64 rendered open-water
    scene with water_mask=scene.water: same A, VL, flags, exclusions, scores
    within SCORE_ATOL, same water type, t_B and images within tolerance."""
    img = rendered(48, 64, "open_water", seed, water=water)
    sc = _scene(48, 64, "open_water", seed)
    _check_restore(img, f"water_mask seed {seed}", water_mask=sc.water)


def test_restore_detection():
    """The same comparison with VL detected (no water_mask)."""
    img = rendered(48, 64, "open_water", 3)
    got, _ = _check_restore(img, "detection")
    assert got.veiling_mask.any()


def test_restore_with_chart_mask():
    """The same comparison with an estimation mask (two masked-out charts,
    neither spanning the full height): haze-line fill and chart fill in the
    pipeline."""
    img = rendered(48, 64, "open_water", 4, water="II")
    sc = _scene(48, 64, "open_water", 4)
    _check_restore(img, "chart mask", water_mask=sc.water, mask=chart_mask(48, 64))


def test_restore_without_water():
    """A looking-down scene: the pipeline's VL, flags and choice agree also
    when the region is small or absent."""
    img = rendered(48, 64, "looking_down", 5, water="3C")
    _check_restore(img, "looking down")
