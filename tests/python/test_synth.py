"""Tests of uwhl_rs.synth: the model renderer (METHOD §0) and scenes.

Expected values are computed here independently (hand formulas, the SPEC
table typed in again), never by calling the code under test twice.
"""

from __future__ import annotations

import ast
import math
import pathlib
import time

import numpy as np
import pytest

_SYNTH_PATH = pathlib.Path(__file__).resolve().parents[2] / "python" / "uwhl_rs" / "synth.py"

from uwhl_rs import synth

import reference

# METHOD §1 as typed in, independently of the core, by tests/python/reference.py.
SPEC_TABLE = list(reference.WATER_TYPES)
TYPES = [row[0] for row in SPEC_TABLE]


# --------------------------------------------------------------------------
# Module hygiene and the table
# --------------------------------------------------------------------------


def test_module_imports_only_numpy_stdlib_and_its_package():
    """synth needs no scipy: numpy, the standard library and the package's table."""
    tree = ast.parse(_SYNTH_PATH.read_text())
    top = set()
    for node in tree.body:
        if isinstance(node, ast.Import):
            top.update(a.name.split(".")[0] for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            top.add((node.module or "").split(".")[0])
    assert top <= {"__future__", "math", "dataclasses", "typing", "numpy", ""}, top


def test_jerlov_table_matches_spec_in_order():
    assert list(synth.JERLOV) == TYPES
    for name, br, bg in SPEC_TABLE:
        assert synth.JERLOV[name] == (br, bg)


# --------------------------------------------------------------------------
# render / transmissions (METHOD §0)
# --------------------------------------------------------------------------


def test_render_one_pixel_hand_computed():
    j = np.array([[[0.5, 0.4, 0.3]]], dtype=np.float32)
    z = np.array([[2.0]])
    a = (0.03, 0.25, 0.35)
    out = synth.render(j, z, "II", veiling_light=a, beta_b=0.2)
    assert out.shape == (1, 1, 3) and out.dtype == np.float32
    # type II: beta_BR = 0.2773, beta_BG = 0.7937
    t_b = math.exp(-0.2 * 2.0)
    t_r = t_b ** (1.0 / 0.2773)
    t_g = t_b ** (1.0 / 0.7937)
    expected = [t * jj + (1 - t) * aa for t, jj, aa in zip((t_r, t_g, t_b), (0.5, 0.4, 0.3), a)]
    np.testing.assert_allclose(out[0, 0], expected, atol=1e-6)
    # the same numbers written out (checked with a calculator)
    np.testing.assert_allclose(out[0, 0], [0.14108, 0.34062, 0.31648], atol=1e-5)


def test_render_default_veiling_light_is_used():
    j = np.full((2, 3, 3), 0.4, dtype=np.float32)
    z = np.full((2, 3), np.inf)
    out = synth.render(j, z, "7C")
    np.testing.assert_allclose(out[1, 2], synth.default_veiling_light("7C"), atol=1e-7)


@pytest.mark.parametrize("water_type", ["I", "III", "5C", "9C", ("mine", 0.5, 0.9), (1.3, 0.7)])
def test_zero_distance_returns_clean_and_inf_returns_veiling_light(water_type):
    rng = np.random.default_rng(1)
    j = rng.uniform(0.02, 0.95, size=(5, 4, 3)).astype(np.float32)
    a = (0.05, 0.3, 0.45)
    out0 = synth.render(j, np.zeros((5, 4)), water_type, veiling_light=a)
    np.testing.assert_array_equal(out0, j)
    outinf = synth.render(j, np.full((5, 4), np.inf), water_type, veiling_light=a)
    np.testing.assert_allclose(outinf, np.broadcast_to(np.float32(a), j.shape), atol=1e-7)


def test_transmission_values_and_ordering_for_every_type():
    z = np.array([0.0, 0.3, 1.0, 4.0, 12.0, np.inf])
    pos = (z > 0) & np.isfinite(z)
    for name, br, bg in SPEC_TABLE:
        t_r, t_g, t_b = synth.transmissions(z, name, beta_b=0.2)
        np.testing.assert_allclose(t_b, np.exp(-0.2 * z), rtol=1e-12)
        np.testing.assert_allclose(t_r, np.exp(-0.2 * z / br), rtol=1e-12)
        np.testing.assert_allclose(t_g, np.exp(-0.2 * z / bg), rtol=1e-12)
        for t in (t_r, t_g, t_b):
            assert t[0] == 1.0 and t[-1] == 0.0
            assert np.all(np.diff(t) < 0)  # decreasing with distance
        r, g, b = t_r[pos], t_g[pos], t_b[pos]
        # a ratio below 1 means the channel attenuates faster than blue
        if br < 1:
            assert np.all(r < b), name
        elif br > 1:
            assert np.all(r > b), name
        else:
            np.testing.assert_allclose(r, b, rtol=1e-12)
        if bg < 1:
            assert np.all(g < b), name
        else:
            assert np.all(g > b), name
        if br < bg:  # red attenuates faster than green (all but 7C and 9C)
            assert np.all(r < g), name
        else:
            assert np.all(r > g), name
    # the table makes I..III satisfy the classic t_R <= t_G <= t_B
    for name in ("I", "IA", "IB", "II", "III"):
        t_r, t_g, t_b = synth.transmissions(z, name)
        assert np.all(t_r <= t_g) and np.all(t_g <= t_b)


def test_transmissions_accepts_custom_types_and_scalars():
    t_r, t_g, t_b = synth.transmissions(3.0, ("x", 0.5, 0.8), beta_b=0.1)
    assert float(t_b) == pytest.approx(math.exp(-0.3))
    assert float(t_r) == pytest.approx(math.exp(-0.6))
    t_r2, _, _ = synth.transmissions(3.0, (0.5, 0.8), beta_b=0.1)
    assert float(t_r2) == float(t_r)
    # names are case-insensitive
    np.testing.assert_array_equal(synth.transmissions(2.0, "iii")[0], synth.transmissions(2.0, "III")[0])


def test_noise_std_matches_request_and_is_seeded():
    j = np.full((200, 200, 3), 0.5, dtype=np.float32)
    z = np.full((200, 200), 1.5)
    base = synth.render(j, z, "III").astype(np.float64)
    noisy = synth.render(j, z, "III", noise=0.02, seed=3).astype(np.float64)
    diff = noisy - base
    assert abs(diff.std() - 0.02) < 0.02 * 0.03
    assert abs(diff.mean()) < 0.001
    again = synth.render(j, z, "III", noise=0.02, seed=3)
    np.testing.assert_array_equal(again, noisy.astype(np.float32))
    other = synth.render(j, z, "III", noise=0.02, seed=4)
    assert not np.array_equal(other, again)


def test_render_clips_to_unit_interval():
    j = np.full((50, 50, 3), 0.99, dtype=np.float32)
    j[25:] = 0.01
    out = synth.render(j, np.zeros((50, 50)), "II", noise=0.2, seed=0)
    assert out.min() >= 0.0 and out.max() <= 1.0
    assert (out[:25] == 1.0).any() and (out[25:] == 0.0).any()


# --------------------------------------------------------------------------
# default_veiling_light
# --------------------------------------------------------------------------


def test_default_veiling_light_blue_to_green_and_smooth():
    cols = np.array([synth.default_veiling_light(n) for n in TYPES])
    assert cols.shape == (10, 3)
    assert np.all(cols > 0) and np.all(cols < 1)
    assert np.all(cols[:, 0] < 0.1)  # a small red component
    for k, name in enumerate(TYPES):
        if name in ("I", "IA", "IB", "II", "III"):
            assert cols[k, 2] > cols[k, 1], name  # blue
        if name in ("7C", "9C"):
            assert cols[k, 1] > cols[k, 2], name  # green
    assert np.max(np.abs(np.diff(cols, axis=0))) < 0.05  # no jumps along the table
    np.testing.assert_allclose(cols[0], (0.02, 0.20, 0.40), atol=0.03)
    np.testing.assert_allclose(cols[-1], (0.04, 0.30, 0.18), atol=0.03)
    # custom types are accepted
    assert all(v > 0 for v in synth.default_veiling_light((0.3, 0.8)))


# --------------------------------------------------------------------------
# scene
# --------------------------------------------------------------------------


def _check_common(sc, h, w):
    assert sc.clean.shape == (h, w, 3) and sc.clean.dtype == np.float32
    assert sc.distance.shape == (h, w) and sc.distance.dtype == np.float32
    assert sc.water.shape == (h, w) and sc.water.dtype == bool
    np.testing.assert_array_equal(sc.water, np.isinf(sc.distance))
    assert not np.isnan(sc.distance).any()
    assert np.all(sc.distance[~sc.water] > 0)
    assert sc.clean.min() >= 0.02 and sc.clean.max() <= 0.95
    means = sc.clean[~sc.water].mean(axis=0, dtype=np.float64)
    assert means.max() / means.min() < 1.10, means  # gray world within 10 %


@pytest.mark.parametrize("size", [(24, 32), (120, 160), (360, 480)])
@pytest.mark.parametrize("seed", [0, 5])
def test_scene_open_water_properties(size, seed):
    h, w = size
    sc = synth.scene(h, w, kind="open_water", seed=seed)
    _check_common(sc, h, w)
    frac = sc.water.mean()
    assert 0.30 <= frac <= 0.50, frac
    assert sc.water[0].all()  # the top row is open water
    assert not sc.water[-1].any()  # the bottom row is seabed
    # the seabed recedes upwards: mean over rows of the per-row median
    # distance, bottom third < middle third < top third of non-water rows
    d = np.where(sc.water, np.nan, sc.distance.astype(np.float64))
    rows = np.where((~sc.water).any(axis=1))[0]
    med = np.array([np.median(d[r][np.isfinite(d[r])]) for r in rows])
    k = len(rows) // 3
    top, mid, bot = med[:k].mean(), med[k : 2 * k].mean(), med[2 * k :].mean()
    assert top > mid > bot, (top, mid, bot)
    assert 1.0 <= np.median(sc.distance[-1]) <= 2.0
    finite = sc.distance[~sc.water]
    assert 7.0 <= finite.max() <= 13.0


def test_scene_objects_are_nearer_than_the_floor_behind():
    # an object pixel is nearer than the seabed just above the object, so
    # some pixels have a finite distance larger than the pixel right below
    # them by a jump (an occluding edge), not only smooth recession
    sc = synth.scene(360, 480, kind="open_water", seed=2)
    d = np.where(sc.water, np.nan, sc.distance.astype(np.float64))
    jump = d[:-1] - d[1:]  # row above minus row below
    assert np.nanmax(jump) > 0.5  # far floor above a near object
    # and the scene contains several distinct objects: many such edge pixels
    assert np.count_nonzero(jump > 0.3) > 50


@pytest.mark.parametrize("size", [(24, 32), (240, 320)])
def test_scene_looking_down_properties(size):
    h, w = size
    sc = synth.scene(h, w, kind="looking_down", seed=1)
    _check_common(sc, h, w)
    assert not sc.water.any()
    assert sc.distance.min() >= 1.5 and sc.distance.max() <= 4.0
    assert sc.distance.max() - sc.distance.min() > 0.5  # gentle but real variation


def test_scene_is_colorful():
    sc = synth.scene(240, 320, kind="open_water", seed=0)
    c = sc.clean[~sc.water].astype(np.float64)
    sat = (c.max(axis=1) - c.min(axis=1)) / c.max(axis=1)
    dom = np.argmax(c, axis=1)
    for ch in range(3):  # reddish, greenish and bluish saturated pixels exist
        assert np.mean((dom == ch) & (sat > 0.3)) > 0.02, ch
    assert c.std(axis=0).min() > 0.05  # textured, not flat
    # yellow-ish (R and G high, B low) and dark pixels exist too
    assert np.mean((c[:, 0] > 1.3 * c[:, 2]) & (c[:, 1] > 1.3 * c[:, 2])) > 0.005
    assert np.mean(c.max(axis=1) < 0.15) > 0.01


def test_scene_is_deterministic():
    a = synth.scene(64, 80, seed=11)
    b = synth.scene(64, 80, seed=11)
    c = synth.scene(64, 80, seed=12)
    np.testing.assert_array_equal(a.clean, b.clean)
    np.testing.assert_array_equal(a.distance, b.distance)
    assert not np.array_equal(a.clean, c.clean)


def test_scene_one_megapixel_is_fast_enough():
    t0 = time.perf_counter()
    synth.scene(1000, 1000, kind="open_water", seed=0)
    # the target is < 0.5 s; the bound is loose so a busy machine passes
    assert time.perf_counter() - t0 < 3.0


# --------------------------------------------------------------------------
# demo_input
# --------------------------------------------------------------------------


def test_demo_input():
    img, truth = synth.demo_input(120, 160)
    assert img.shape == (120, 160, 3) and img.dtype == np.float32
    assert img.min() >= 0 and img.max() <= 1
    assert set(truth) == {
        "water_type", "beta_BR", "beta_BG", "veiling_light", "distance", "water", "clean", "beta_b"
    }
    assert truth["water_type"] == "III"
    assert (truth["beta_BR"], truth["beta_BG"]) == (0.4051, 0.9539)
    assert truth["beta_b"] == 0.2
    a = np.array(truth["veiling_light"])
    # open water shows the veiling light plus noise of std 0.003
    water_px = img[truth["water"]].astype(np.float64)
    np.testing.assert_allclose(water_px.mean(axis=0), a, atol=0.002)
    assert 0.002 < water_px.std(axis=0).mean() < 0.004
    again, _ = synth.demo_input(120, 160)
    np.testing.assert_array_equal(img, again)
    # haze grows with distance: bottom rows differ more from A than rows
    # just below the horizon
    floor = ~truth["water"]
    dev = np.abs(img.astype(np.float64) - a).sum(axis=2)
    near = dev[-10:][floor[-10:]].mean()
    far_rows = np.where(floor.any(axis=1))[0][:5]
    far = dev[far_rows][floor[far_rows]].mean()
    assert near > 2 * far


# --------------------------------------------------------------------------
# Error paths
# --------------------------------------------------------------------------

_J = np.full((4, 5, 3), 0.5, dtype=np.float32)
_Z = np.ones((4, 5))


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(clean=np.zeros((4, 5))), "clean must have shape"),
        (dict(clean=np.zeros((4, 5, 4))), "clean must have shape"),
        (dict(distance=np.ones((5, 4))), "distance must have shape"),
        (dict(distance=np.ones((4, 5, 1))), "distance must have shape"),
        (dict(distance=np.where(np.eye(4, 5) > 0, np.nan, 1.0)), "NaN"),
        (dict(distance=-_Z), "negative"),
        (dict(distance=np.full((4, 5), -np.inf)), "negative"),
        (dict(clean=np.where(_J > 0, np.nan, 0)), "clean contains NaN"),
        (dict(clean=-_J), "clean must be non-negative"),
        (dict(water_type="XII"), "unknown water type"),
        (dict(water_type=42), "unknown water type"),
        (dict(water_type=(0.0, 0.5)), "beta_BR"),
        (dict(water_type=("x", 0.5, -1.0)), "beta_BG"),
        (dict(water_type=(0.5, float("nan"))), "beta_BG"),
        (dict(water_type=(0.5,)), "water type tuple"),
        (dict(beta_b=0.0), "beta_b"),
        (dict(beta_b=-0.2), "beta_b"),
        (dict(veiling_light=(0.1, 0.2)), "veiling_light"),
        (dict(veiling_light=(0.1, 0.2, 1.5)), "veiling_light"),
        (dict(noise=-0.01), "noise"),
    ],
)
def test_render_rejects_bad_input(kwargs, match):
    args = dict(clean=_J, distance=_Z, water_type="II")
    args.update(kwargs)
    clean, distance = args.pop("clean"), args.pop("distance")
    with pytest.raises(ValueError, match=match):
        synth.render(clean, distance, **args)


def test_other_functions_reject_bad_input():
    with pytest.raises(ValueError, match="NaN"):
        synth.transmissions(np.array([1.0, np.nan]), "II")
    with pytest.raises(ValueError, match="negative"):
        synth.transmissions(np.array([-1.0]), "II")
    with pytest.raises(ValueError, match="unknown water type"):
        synth.default_veiling_light("IV")
    with pytest.raises(ValueError, match="unknown scene kind"):
        synth.scene(32, 32, kind="cave")
    with pytest.raises(ValueError, match="height"):
        synth.scene(4, 32)
    with pytest.raises(ValueError, match="width"):
        synth.scene(32, 2.5)
    with pytest.raises(ValueError, match="unknown water type"):
        synth.demo_input(32, 32, water_type="blue")
