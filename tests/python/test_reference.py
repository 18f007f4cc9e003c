"""Self-checks of tests/python/reference.py against independently known answers."""

import math

import numpy as np
import pytest

import reference as ref


def test_water_types_table():
    assert len(ref.WATER_TYPES) == 10
    assert [t[0] for t in ref.WATER_TYPES] == [
        "I", "IA", "IB", "II", "III", "1C", "3C", "5C", "7C", "9C"]
    assert ref.WATER_TYPES[3] == ("II", 0.2773, 0.7937)
    assert ref.WATER_TYPES[9] == ("9C", 2.0708, 1.5942)


@pytest.mark.parametrize("r", [0, 1, 3, 10])
def test_box_sum_brute_force(r):
    rng = np.random.default_rng(1)
    x = rng.random((7, 9))
    expect = np.zeros_like(x)
    count = np.zeros_like(x)
    for y in range(7):
        for xx in range(9):
            for yy in range(max(0, y - r), min(7, y + r + 1)):
                for xc in range(max(0, xx - r), min(9, xx + r + 1)):
                    expect[y, xx] += x[yy, xc]
                    count[y, xx] += 1
    np.testing.assert_allclose(ref.box_sum(x, r), expect, rtol=0, atol=1e-12)
    np.testing.assert_allclose(ref.box_mean(x, r), expect / count, rtol=0, atol=1e-12)


def test_pct_matches_numpy_quantile():
    rng = np.random.default_rng(2)
    for n in [1, 2, 3, 10, 101, 1000]:
        v = rng.normal(size=n)
        for q in [0.0, 0.001, 0.01, 0.25, 0.5, 0.99, 0.999, 1.0]:
            assert ref.pct(v, q) == pytest.approx(float(np.quantile(v, q)), abs=1e-12)
    # hand case: positions 0..4, q = 0.3 -> h = 1.2 -> 1 + 0.2 * (4 - 1)
    assert ref.pct([4.0, 1.0, 9.0, 16.0, 0.0], 0.3) == pytest.approx(1.6)


def test_sphere_points_unit_and_uniform():
    p = ref.sphere_points(500)
    assert p.shape == (500, 3) and p.dtype == np.float64
    np.testing.assert_allclose(np.linalg.norm(p, axis=1), 1.0, atol=1e-12)
    cosang = np.clip(p @ p.T, -1, 1)
    np.fill_diagonal(cosang, -2)
    nn = np.arccos(cosang.max(axis=1))
    assert 0.14 < nn.mean() < 0.18
    assert nn.min() > 0.08
    # near-uniform: every octant holds about 1/8 of the points
    octant = (p[:, 0] > 0) * 4 + (p[:, 1] > 0) * 2 + (p[:, 2] > 0)
    counts = np.bincount(octant, minlength=8)
    assert counts.min() > 45 and counts.max() < 80


def test_nearest_point_matches_argmin():
    rng = np.random.default_rng(3)
    p = ref.sphere_points(500)
    u = rng.normal(size=(3000, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    expect = np.argmin(np.linalg.norm(u[:, None, :] - p[None, :, :], axis=2), axis=1)
    np.testing.assert_array_equal(ref.nearest_point(p, u), expect)
    # exact hits and a tie -> lowest index
    pts = np.array([[1.0, 0, 0], [0, 1.0, 0], [-1.0, 0, 0]])
    uu = np.array([[0, 1.0, 0], [0, 0, 1.0], [-1.0, 0, 0]])
    np.testing.assert_array_equal(ref.nearest_point(pts, uu), [1, 0, 2])


def test_guided_filter_constant():
    rng = np.random.default_rng(4)
    g = rng.random((20, 30, 3))
    for r in [1, 4, 50]:
        q = ref.guided_filter(g, np.full((20, 30), 0.37), r, 1e-3)
        np.testing.assert_allclose(q, 0.37, atol=1e-12)


def test_guided_filter_reproduces_linear_function_of_guide():
    # with eps -> 0, p = a . I + b is reproduced exactly
    rng = np.random.default_rng(5)
    g = rng.random((15, 17, 3))
    p = 0.3 * g[..., 0] - 0.2 * g[..., 1] + 0.5 * g[..., 2] + 0.1
    np.testing.assert_allclose(ref.guided_filter(g, p, 2, 1e-12), p, atol=1e-6)


def test_lower_bound_hand_pixel():
    img = np.array([[[0.2, 0.3, 0.4], [0.6, 0.6, 0.6]]])
    a = (0.1, 0.5, 0.6)
    lb = ref.lower_bound(img, a, 0.5, 0.8)
    # pixel 0: R: 1 - 0.2/0.1 < 0 -> 0; G: (1 - 0.3/0.5)^0.8 = 0.4^0.8;
    # B: 1 - 0.4/0.6 = 1/3; floor 0.1
    g = math.exp(0.8 * math.log(0.4))
    assert g == pytest.approx(0.4804498, abs=1e-6)
    assert lb[0, 0] == pytest.approx(max(0.0, g, 1.0 / 3.0, 0.1), abs=1e-12)
    # pixel 1 brighter than A everywhere -> floor 0.1
    assert lb[0, 1] == pytest.approx(0.1, abs=1e-12)


def test_recover_hand_pixels():
    img = np.array([[[0.2, 0.3, 0.4], [0.1, 0.5, 0.6]]])
    a = (0.1, 0.5, 0.6)
    t = np.array([[0.5, 0.5]])
    out = ref.recover(img, a, t, 0.5, 0.8)
    tR = 0.5 ** 2.0          # 0.25
    tG = 0.5 ** 1.25         # 0.4204482
    assert out["t_B"][0, 0] == pytest.approx(0.5)
    assert out["t_R"][0, 0] == pytest.approx(tR)
    assert out["t_G"][0, 0] == pytest.approx(tG)
    raw0 = [0.1 + 0.1 / tR, 0.5 - 0.2 / tG, 0.6 - 0.2 / 0.5]   # 0.5, 0.02432, 0.2
    raw1 = [0.1, 0.5, 0.6]                                      # I == A -> J == A
    lo = min(raw0 + raw1)                    # 0.02432 > -0.08: subtract it
    hi = max(raw0 + raw1) - lo               # <= 1.6: divide by it
    np.testing.assert_allclose(out["J"][0, 0], [(v - lo) / hi for v in raw0], atol=1e-12)
    np.testing.assert_allclose(out["J"][0, 1], [(v - lo) / hi for v in raw1], atol=1e-12)

    # clamps: t_B floored at 0.1^beta_BR, t_R at 0.1; strongly negative J
    img2 = np.array([[[0.05, 0.3, 0.4], [0.9, 0.9, 0.9]]])
    out2 = ref.recover(img2, a, np.array([[0.2, 1.0]]), 0.5, 0.8)
    tb = math.sqrt(0.1)
    assert out2["t_B"][0, 0] == pytest.approx(tb)
    assert out2["t_R"][0, 0] == pytest.approx(0.1)
    tg = tb ** 1.25
    raw0 = [0.1 - 0.05 / 0.1, 0.5 - 0.2 / tg, 0.6 - 0.2 / tb]   # -0.4, ...
    raw1 = [0.9, 0.9, 0.9]
    shifted = [max(v + 0.08, 0.0) for v in raw0 + raw1]     # min < -0.08 -> +0.08
    top = min(max(shifted), 1.6)
    expect = [min(v / top, 1.0) for v in shifted]
    np.testing.assert_allclose(out2["J"].reshape(-1), expect, atol=1e-12)


def test_mahalanobis_diagonal_hand():
    mu = np.array([0.3, 0.4, 0.5])
    a, b, c = 0.05, 0.02, 0.1
    offs = [(a, 0, 0), (-a, 0, 0), (0, b, 0), (0, -b, 0), (0, 0, c), (0, 0, -c)]
    pix = [mu + np.array(o) for o in offs]
    q1 = mu + np.array([0.1, 0.0, 0.0])
    q2 = mu + np.array([0.01, -0.02, 0.03])
    img = np.array(pix + [q1, q2]).reshape(2, 4, 3)
    vl = np.array([True] * 6 + [False] * 2).reshape(2, 4)
    d = ref.mahalanobis_sq(img, vl)
    # covariance (n - 1 = 5): diag(2a^2, 2b^2, 2c^2) / 5, zero off-diagonal
    var = np.array([2 * a * a, 2 * b * b, 2 * c * c]) / 5.0
    lam = 1e-6 * var.sum() / 3.0 + 1e-12
    var = var + lam

    def md(x):
        return float(np.sum((x - mu) ** 2 / var))

    for i, x in enumerate(pix + [q1, q2]):
        assert d.reshape(-1)[i] == pytest.approx(md(x), rel=1e-9)
    assert d.reshape(-1)[6] == pytest.approx(0.01 / (0.005 / 5.0), rel=1e-5)   # ~10
    # without VL: None
    assert ref.mahalanobis_sq(img, np.zeros((2, 4), bool)) is None
    assert ref.matting_weights(img, np.zeros((2, 4), bool)) is None


def test_largest_component_shape():
    b = np.zeros((8, 10), bool)
    # a diagonal chain of 5 pixels: one component only with 8-connectivity
    for i in range(5):
        b[i, i] = True
    # a 2x2 block (4 pixels) far away
    b[6:8, 7:9] = True
    got = ref.largest_component(b)
    expect = np.zeros_like(b)
    for i in range(5):
        expect[i, i] = True
    np.testing.assert_array_equal(got, expect)
    # tie: two 2x2 blocks -> the one whose first pixel comes first in raster order
    t = np.zeros((6, 6), bool)
    t[4:6, 0:2] = True
    t[1:3, 4:6] = True
    got = ref.largest_component(t)
    assert got[1, 4] and not got[4, 0] and got.sum() == 4
    assert not ref.largest_component(np.zeros((3, 3), bool)).any()


def test_downscale_and_blur():
    x = np.arange(5 * 7, dtype=float).reshape(5, 7)
    d = ref.downscale(x, 3)
    assert d.shape == (2, 3)
    assert d[0, 0] == pytest.approx(x[0:3, 0:3].mean())
    assert d[1, 2] == pytest.approx(x[3:5, 6:7].mean())
    k = ref.gaussian_kernel(1.0, 3)
    assert k.sum() == pytest.approx(1.0) and len(k) == 7
    c = np.full((6, 6), 0.4)
    np.testing.assert_allclose(ref.gaussian_blur(c, 1.0, 3), 0.4, atol=1e-14)
    np.testing.assert_allclose(ref.sobel_magnitude(c), 0.0, atol=1e-14)
    # a horizontal ramp of slope 1: gx = 8 everywhere inside -> E = 1
    ramp = np.tile(np.arange(6.0), (6, 1))
    assert ref.sobel_magnitude(ramp)[2, 2] == pytest.approx(1.0)


def test_noise_sigma_gaussian():
    rng = np.random.default_rng(6)
    x = 0.5 + 0.01 * rng.normal(size=(200, 200, 3))
    # for pure noise the Laplacian response has std 6 sigma
    assert ref.noise_sigma(x) == pytest.approx(0.01, rel=0.1)
    assert ref.noise_sigma(np.zeros((2, 5, 3))) == 0.0


def test_fill_and_chart_fill():
    t = np.arange(20, dtype=float).reshape(4, 5)
    m = np.ones((4, 5), bool)
    m[1:3, 1:3] = False
    f = ref.fill_masked(t, m)
    np.testing.assert_array_equal(f[m], t[m])
    # radius 1: (1, 1) sees the 5 masked-in pixels (0,0),(0,1),(0,2),(1,0),(2,0)
    assert f[1, 1] == pytest.approx((0 + 1 + 2 + 5 + 10) / 5.0)
    q = np.arange(20, dtype=float).reshape(4, 5)
    g = ref.chart_fill(q, m)
    # region rows 1-2, cols 1-2: pixels directly below are (3,1), (3,2) -> 16, 17
    np.testing.assert_allclose(g[1:3, 1:3], 16.5)
    np.testing.assert_array_equal(g[m], q[m])
    # region on the bottom row: use pixels directly above
    m2 = np.ones((4, 5), bool)
    m2[3, 0:2] = False
    g2 = ref.chart_fill(q, m2)
    np.testing.assert_allclose(g2[3, 0:2], (10 + 11) / 2.0)


def test_display_stretch_and_stretch_image_range():
    rng = np.random.default_rng(7)
    j = rng.random((30, 20, 3)) * np.array([0.2, 0.6, 1.0])
    s = ref.display_stretch(j)
    assert s.min() >= 0 and s.max() <= 1
    x = ref.stretch_image(j)
    assert x.min() >= 0 and x.max() <= 1
    for c in range(3):
        assert np.quantile(x[..., c], 0.995) == pytest.approx(1.0)


def _render_scene(h=40, w=50, beta=(0.2773, 0.7937), a=(0.05, 0.35, 0.45), noise=0.002):
    rng = np.random.default_rng(8)
    yy, xx = np.mgrid[0:h, 0:w]
    # colourful textured object
    j = np.stack([
        0.25 + 0.2 * np.sin(xx / 3.0) * np.cos(yy / 4.0),
        0.35 + 0.2 * ((xx // 5 + yy // 5) % 2),
        0.3 + 0.25 * (xx / w),
    ], axis=-1)
    j = np.clip(j + 0.05 * rng.random((h, w, 3)), 0, 1)
    z = 1.0 + 4.0 * (1.0 - yy / h)                 # farther at the top
    t_b = np.exp(-0.3 * z)
    t_b[: h // 5] = 0.0                               # open water at the top
    br, bg = beta
    t = np.stack([t_b ** (1 / br), t_b ** (1 / bg), t_b], axis=-1)
    img = j * t + np.array(a) * (1 - t)
    img = img + noise * rng.normal(size=img.shape)
    return np.clip(img, 0, 1).astype(np.float32)


def test_restore_end_to_end():
    img = _render_scene()
    out = ref.restore(img)
    for key in ["image", "radiance", "transmission", "transmission_red"]:
        v = out[key]
        assert v.shape[:2] == (40, 50)
        assert np.all(np.isfinite(v))
        assert v.min() >= 0 and v.max() <= 1
    assert out["water_type"] in [t[0] for t in ref.WATER_TYPES]
    assert set(out["scores"]) == {t[0] for t in ref.WATER_TYPES}
    assert all(np.isfinite(s) for s in out["scores"].values())
    assert out["veiling_mask"].dtype == bool
    # the top rows are pure water: VL found there, A close to the water colour
    assert out["veiling_mask"][:4].mean() > 0.5
    assert not out["veiling_mask"][10:].any()
    np.testing.assert_allclose(out["veiling_light"], [0.05, 0.35, 0.45], atol=0.01)


def test_restore_with_mask_and_given_light():
    img = _render_scene()
    m = np.ones((40, 50), bool)
    m[20:28, 10:20] = False
    out = ref.restore(img, water_types=["II", ("custom", 0.5, 1.0)], mask=m,
                      veiling_light=(0.05, 0.35, 0.45))
    assert set(out["scores"]) == {"II", "custom"}
    assert np.all(np.isfinite(out["image"]))
    # a chart region gets one transmission value
    tb = out["transmission"][20:28, 10:20]
    assert np.ptp(tb) < 1e-12
    assert out["veiling_light"] == pytest.approx([0.05, 0.35, 0.45])
    with pytest.raises(ValueError):
        ref.restore(img, veiling_light=(0.0, 0.3, 0.4))
    bad = img.copy()
    bad[0, 0, 0] = np.nan
    with pytest.raises(ValueError):
        ref.restore(bad)
