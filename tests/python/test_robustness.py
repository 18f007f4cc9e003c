"""Randomised robustness: odd sizes, degenerate values and random masks and
parameters give either finite outputs in [0, 1] or a documented exception,
never a crash or a PanicException (a BaseException outside Exception)."""

import numpy as np
import pytest

import uwhl_rs


def _case(rng, k):
    h, w = (int(v) for v in rng.integers(4, 40, 2))
    kind = k % 6
    if kind == 0:
        img = rng.random((h, w, 3))
    elif kind == 1:  # a single bright pixel on black
        img = np.zeros((h, w, 3))
        img[rng.integers(h), rng.integers(w)] = 1
    elif kind == 2:  # exactly equal channels
        img = np.repeat(rng.random((h, w, 1)), 3, 2)
    elif kind == 3:  # only 0 and 1
        img = np.where(rng.random((h, w, 3)) < 0.5, 0.0, 1.0)
    elif kind == 4:  # subnormal-scale values
        img = rng.random((h, w, 3)) * 1e-38
    else:  # two values one float32 step apart
        img = np.full((h, w, 3), 0.5)
        img[:, : w // 2] = np.nextafter(np.float32(0.5), np.float32(1))
    kw = {}
    if rng.random() < 0.3:
        kw["mask"] = rng.random((h, w)) < 0.7
    if rng.random() < 0.3:
        kw["water_mask"] = rng.random((h, w)) < 0.2
    if rng.random() < 0.2:
        kw["guided_radius"] = int(rng.integers(0, max(h, w)))
    if rng.random() < 0.2:
        kw["sphere_points"] = int(rng.integers(1, 50))
    if rng.random() < 0.2:
        kw["veiling_light"] = tuple(float(v) for v in rng.random(3) * 0.9 + 0.05)
    return img.astype(np.float32), kw


@pytest.mark.parametrize("block", range(4))
def test_random_inputs_give_results_in_range_or_documented_errors(block):
    """100 seeded random cases per block: Ok -> finite image/radiance/transmission in [0, 1]
    (transmission > 0); else ImageError/ParameterError/MemoryError only."""
    rng = np.random.default_rng(1000 + block)
    ok = 0
    for k in range(100):
        img, kw = _case(rng, k)
        try:
            r = uwhl_rs.restore(img, **kw)
        except (uwhl_rs.UwhlError, MemoryError):
            continue
        ok += 1
        for a in (r.image, r.radiance, r.transmission):
            assert np.isfinite(a).all() and a.min() >= 0 and a.max() <= 1, (k, kw.keys())
        assert r.transmission.min() > 0
        assert r.water_type in r.scores
    assert ok > 50  # most cases are valid input
