"""Scores against a true radiance (uwhl_rs.truth) and the ``truth`` key of
``uwhl evaluate`` (docs/EVALUATE.md): angles computed by hand, gains that
are known because the test applied them, a render whose truth is known, and
the truth files a user can get wrong."""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys

import numpy as np
import pytest

from uwhl_rs import evaluate as ev
from uwhl_rs import synth, truth
from uwhl_rs.errors import ManifestError


def _deg(a, b):
    """The angle between two RGB vectors, written out (not through the module)."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    return math.degrees(math.acos(float(a @ b) / (np.linalg.norm(a) * np.linalg.norm(b))))


def test_angles_computed_by_hand():
    out = np.array([[1, 0, 0], [1, 0, 0], [2, 2, 2], [1, 2, 3], [0, 0, 0]], float)
    tru = np.array([[1, 1, 0], [0, 1, 0], [1, 1, 1], [1, 2, 3], [1, 1, 1]], float)
    ang = truth.pixel_angles(out, tru)
    # (1,0,0).(1,1,0) = 1 = 1 * sqrt(2) cos -> 45; orthogonal -> 90; brightness alone -> 0; black output -> 90
    assert ang == pytest.approx([45.0, 90.0, 0.0, 0.0, 90.0], abs=1e-6)
    # (1,0,0) against gray: cos = 1/sqrt(3)
    assert truth.pixel_angles([[1, 0, 0]], [[1, 1, 1]])[0] == pytest.approx(54.7356, abs=1e-4)
    st = truth.angle_stats(np.arange(0.0, 101.0, 10.0))  # 0, 10, ..., 100: median 50, 90th percentile 90
    assert st == pytest.approx({"median": 50.0, "p90": 90.0})
    assert all(math.isnan(v) for v in truth.angle_stats(np.array([])).values())


def _colourful(h=40, w=50, seed=0):
    rng = np.random.default_rng(seed)
    return rng.uniform(0.05, 1.0, (h, w, 3))


def test_best_gains_undo_a_known_per_channel_cast():
    tru = _colourful()
    cast = np.array([2.0, 1.0, 0.4])
    out = tru * cast
    s = truth.score(out, tru)
    # a gray pixel under this cast: cos = 3.4 / (sqrt(3) sqrt(4 + 1 + 0.16)) = 0.8641 -> 30.2 degrees
    assert _deg(cast, [1, 1, 1]) == pytest.approx(30.22, abs=0.01)
    assert s["median"] > 15
    assert s["gain_median"] < 0.2 and s["gain_p90"] < 0.5
    g = truth.best_gains(out, tru, np.ones(tru.shape[:2], bool))
    assert g == pytest.approx(1 / cast, rel=0.02)


def test_dark_truth_pixels_are_not_scored():
    tru = _colourful(10, 10)
    tru[:, :5] = 0.004  # R + G + B = 0.012 < MIN_TRUTH_SUM: no colour worth scoring
    out = tru.copy()
    out[:, :5] = (1, 0, 0)  # as wrong as an output can be, where it does not count
    s = truth.score(out, tru, gains=False)
    assert s["median"] == pytest.approx(0, abs=1e-4) and s["p90"] == pytest.approx(0, abs=1e-4)
    dark = np.full((4, 4, 3), 0.001)
    assert math.isnan(truth.score(dark * 3, dark, gains=False)["median"])


def test_median_interval_matches_the_medians_known_spread():
    # the median of n draws of N(0, 1) has standard error sqrt(pi / 2) / sqrt(n)
    # (1.2533 / 20 at n = 400): a 95% interval about 2 x 1.96 x that wide,
    # holding the true median 0 about 95 times in 100
    widths, held = [], 0
    for seed in range(30):
        v = np.random.default_rng(seed).normal(size=400)
        lo, hi = truth.median_interval(v, resamples=2000, seed=seed)
        widths.append(hi - lo)
        held += lo <= 0.0 <= hi
    expected = 2 * 1.96 * math.sqrt(math.pi / 2) / 20
    assert abs(np.mean(widths) / expected - 1) < 0.15
    assert held >= 25


def test_median_interval_edges():
    assert truth.median_interval([3.0, 3.0, 3.0]) == (3.0, 3.0)
    assert truth.median_interval([None, float("nan"), 2.0]) == (2.0, 2.0)
    assert all(math.isnan(x) for x in truth.median_interval([]))
    v = np.random.default_rng(5).normal(size=50)
    assert truth.median_interval(v, seed=7) == truth.median_interval(v, seed=7)
    with pytest.raises(ValueError):
        truth.median_interval(v, level=1.0)


def test_paired_medians_of_a_known_shift():
    rng = np.random.default_rng(3)
    b = rng.uniform(5, 25, size=60)
    # a is b moved down by exactly 2 on every image: the difference is -2 whatever the resample
    p = truth.paired_medians(b - 2.0, b)
    assert p["difference"] == pytest.approx(-2.0)
    assert p["low"] == pytest.approx(-2.0) and p["high"] == pytest.approx(-2.0)
    assert (p["better"], p["worse"], p["images"]) == (60, 0, 60)
    # one missing value on either side drops that pair only
    a2 = list(b - 2.0)
    a2[0] = None
    b2 = list(b)
    b2[1] = float("nan")
    q = truth.paired_medians(a2, b2)
    assert q["images"] == 58 and q["better"] == 58


def test_paired_medians_of_unrelated_noise_straddle_zero():
    # two methods whose per-image values are the same distribution: the
    # difference of medians is noise, and its interval holds 0
    rng = np.random.default_rng(11)
    a, b = rng.normal(10, 3, size=40), rng.normal(10, 3, size=40)
    p = truth.paired_medians(a, b)
    assert p["low"] < 0 < p["high"]
    assert p["better"] + p["worse"] == 40
    with pytest.raises(ValueError, match="different lengths"):
        truth.paired_medians([1.0, 2.0], [1.0])


def test_truth_files_of_every_form(tmp_path, monkeypatch):
    import tifffile
    from PIL import Image

    from uwhl_rs.images import write_image

    codes = np.array([[[65535, 0, 32768], [1000, 2000, 3000]]], np.uint16)  # 1 x 2
    write_image(tmp_path / "t.png", codes)
    img, ok = truth.read_truth(str(tmp_path / "t.png"), 2, 4)
    # read as linear / 65535 (no sRGB curve), resized by nearest neighbour to 2 x 4
    assert img.shape == (2, 4, 3) and ok.all()
    assert img[1, 0] == pytest.approx([1.0, 0.0, 32768 / 65535], abs=1e-6)
    assert img[0, 3] == pytest.approx([1000 / 65535, 2000 / 65535, 3000 / 65535], abs=1e-6)
    f = np.array([[[0.5, 0.25, 0.125], [np.nan, 0.1, 0.1]], [[0.2, -0.1, 0.3], [np.inf, 1, 1]]], np.float32)
    tifffile.imwrite(tmp_path / "t.tif", f, photometric="rgb")
    np.save(tmp_path / "t.npy", f.astype(np.float64))
    for name in ("t.tif", "t.npy"):
        img, ok = truth.read_truth(str(tmp_path / name), 2, 2)
        assert ok.tolist() == [[True, False], [False, False]]  # non-finite or negative: not scored
        assert img[0, 0] == pytest.approx([0.5, 0.25, 0.125]) and np.all(img[~ok] == 0)
    Image.fromarray(np.zeros((2, 2, 3), np.uint8)).save(tmp_path / "t8.png")
    with pytest.raises(ManifestError, match="16-bit"):
        truth.read_truth(str(tmp_path / "t8.png"), 2, 2)
    np.save(tmp_path / "flat.npy", np.ones((2, 2, 5)))
    with pytest.raises(ManifestError, match="H x W x 3"):
        truth.read_truth(str(tmp_path / "flat.npy"), 2, 2)
    # a file claiming more pixels than a photo may have is not read (the limit lowered to see it)
    monkeypatch.setattr(truth, "MAX_TRUTH_PIXELS", 1)
    for name in ("t.tif", "t.npy", "t.png"):
        with pytest.raises(ManifestError, match="over the limit"):
            truth.read_truth(str(tmp_path / name), 2, 2)
    monkeypatch.undo()
    Image.fromarray(np.array([[0, 255], [255, 0]], np.uint8)).save(tmp_path / "m.png")
    assert truth.read_truth_mask(str(tmp_path / "m.png"), 4, 4)[2:, :2].all()
    assert not truth.read_truth_mask(str(tmp_path / "m.png"), 4, 4)[:2, :2].any()


def test_a_file_that_is_no_npy_is_called_so(tmp_path):
    """numpy's own message for it suggests unpickling the file; the reader says what it is."""
    (tmp_path / "junk.npy").write_bytes(b"these are not the bytes of a .npy file")
    # the distance map goes through the commands' reader, which names the formats it reads
    for read, says in ((lambda p: truth.read_truth(p, 2, 2), "not a .npy file"),
                       (lambda p: ev.read_distance(p, 2, 2), "not a distance map: expected a .npy array"),
                       (lambda p: truth.read_truth_mask(p, 2, 2), "not a .npy file")):
        with pytest.raises(ManifestError, match=says) as e:
            read(str(tmp_path / "junk.npy"))
        assert "pickle" not in str(e.value)


def _write_float(path, a):
    import tifffile

    tifffile.imwrite(path, np.ascontiguousarray(a, np.float32), photometric="rgb")


def test_evaluate_scores_a_render_against_its_truth(tmp_path):
    """A synth render (no noise) with its true radiance: the input's angles
    are those computed here; the radiance recovered with the true t and A
    (the floor) scores near 0; the water region given as water_mask is not
    scored; the numbers reach the JSON, the CSV, the summary and the page."""
    from PIL import Image

    img, tr = synth.demo_input(48, 64, water_type="3C", seed=4, noise=0.0)
    clean, water = tr["clean"].astype(np.float64), tr["water"]
    _write_float(tmp_path / "scene.tif", img)  # a float TIFF is read as linear, as it is
    # the truth at twice the size: resized (nearest) back onto the photo's pixels
    _write_float(tmp_path / "truth.tif", np.repeat(np.repeat(clean, 2, axis=0), 2, axis=1))
    Image.fromarray(water.astype(np.uint8) * 255).save(tmp_path / "water.png")
    t = np.stack(synth.transmissions(np.where(water, 0, tr["distance"]), "3C", tr["beta_b"]), axis=-1)
    a = np.array(tr["veiling_light"])
    floor = np.where(water[:, :, None], 0, (img - a * (1 - t)) / t)
    _write_float(tmp_path / "floor.tif", np.clip(floor, 0, None))
    np.save(tmp_path / "nan.npy", np.full((4, 4, 3), np.nan))
    (tmp_path / "junk.npy").write_bytes(b"\x93NUMPY but not really")
    np.save(tmp_path / "dark.npy", np.full((4, 4, 3), 0.001))
    base = {"path": "scene.tif", "truth": "truth.tif", "water_mask": "water.png", "water_type": "3C"}
    entries = [
        base,
        {"path": "floor.tif", "truth": "truth.tif", "water_mask": "water.png"},
        dict(base, truth="nan.npy"),  # 2: nothing finite
        dict(base, truth="junk.npy"),  # 3: not a .npy
        dict(base, truth="missing.tif"),  # 4
        dict(base, truth=7),  # 5: not a path
        {"path": "scene.tif", "truth_mask": "water.png"},  # 6: a mask of nothing
        dict(base, truth="dark.npy"),  # 7: too dark to have a colour
    ]
    (tmp_path / "m.json").write_text(json.dumps({"images": entries}))
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "evaluate", str(tmp_path / "m.json"), "-o", str(out),
                        "--water-type", "3C,7C"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 3, r.stderr
    err = r.stderr
    for k, needle in [(2, "no pixel of the truth can be scored"), (3, "cannot read the truth"),
                      (4, "no such truth file"), (5, "'truth' is a file path"), (6, "which is missing"),
                      (7, "no pixel of the truth can be scored")]:
        assert any(f"images[{k}]" in line and needle in line for line in err.splitlines()), (k, needle, err)
    assert "Traceback" not in err
    doc = json.load(open(out / "results.json"))
    assert [e["image"] for e in doc["images"]] == ["images[0] (scene.tif)", "images[1] (floor.tif)"]
    scene, fl = doc["images"]
    scored = ~water & (clean.sum(axis=2) > truth.MIN_TRUTH_SUM)
    assert scene["truth_pixels"] == fl["truth_pixels"] == int(scored.sum()) < water.size
    o, c = img[scored].astype(np.float64), clean[scored]
    by_hand = np.degrees(np.arccos(np.clip((o * c).sum(1) / np.linalg.norm(o, axis=1) / np.linalg.norm(c, axis=1),
                                           -1, 1)))
    got = scene["truth_angles"]["input"]
    assert got["median_deg"] == pytest.approx(float(np.median(by_hand)), abs=1e-3)
    assert got["p90_deg"] == pytest.approx(float(np.percentile(by_hand, 90)), abs=1e-3)
    assert got["median_deg"] > 10  # the water's cast is there to be measured
    assert got["gain_median_deg"] < got["median_deg"]
    assert fl["truth_angles"]["input"]["median_deg"] < 0.05 and fl["truth_angles"]["input"]["p90_deg"] < 0.1
    assert set(scene["truth_angles"]) == {"input", "stretch", "grayworld", "revised", "paper", "type:3C", "type:7C"}
    summ = doc["summary"]
    assert summ["input"]["images_with_truth"] == 2
    assert summ["input"]["truth_median_deg"] == pytest.approx(
        np.median([scene["truth_angles"]["input"]["median_deg"], fl["truth_angles"]["input"]["median_deg"]]))
    # each profile against each baseline, image by image, from the per-image angles
    for m in ("revised", "paper"):
        for b in ("input", "grayworld", "stretch"):
            mine = [e["truth_angles"][m]["median_deg"] for e in (scene, fl)]
            base = [e["truth_angles"][b]["median_deg"] for e in (scene, fl)]
            p = summ["paired"][m][b]
            assert p["difference_deg"] == pytest.approx(np.median(mine) - np.median(base), abs=1e-9)
            assert p["images"] == 2
            assert (p["better"], p["worse"]) == (sum(x < y for x, y in zip(mine, base)),
                                                 sum(x > y for x, y in zip(mine, base)))
            # a resample of two images is one of them twice or both: its difference lies between these
            pairs = [mine[0] - base[0], mine[1] - base[1], p["difference_deg"]]
            assert min(pairs) - 1e-9 <= p["low_deg"] <= p["high_deg"] <= max(pairs) + 1e-9
        lo, hi = summ[m]["truth_median_deg_ci95"]
        per = [e["truth_angles"][m]["median_deg"] for e in (scene, fl)]
        assert min(per) - 1e-9 <= lo <= hi <= max(per) + 1e-9
    assert "type:3C" not in summ["paired"]  # a forced type is not a profile
    assert f"revised - grayworld: {summ['paired']['revised']['grayworld']['difference_deg']:+.2f} deg" in r.stdout
    rows = list(csv.DictReader(open(out / "results.csv", newline="", encoding="utf-8")))
    row = next(x for x in rows if x["label"] == scene["image"] and x["method"] == "input")
    assert float(row["truth_median_deg"]) == pytest.approx(got["median_deg"], abs=1e-4)
    assert float(row["truth_gain_p90_deg"]) == pytest.approx(got["gain_p90_deg"], abs=1e-4)
    page = open(out / "report.html").read()
    assert "angle to truth" in page and "class='truth'" in page and f"{scene['truth_pixels']} pixels scored" in page
    assert '<table id="paired">' in page
    assert "angle to truth" in r.stdout


def test_truth_mask_chooses_the_pixels(tmp_path):
    """With truth_mask, exactly its pixels are scored (the water mask does not
    narrow them further); a truth of another size is resized."""
    from PIL import Image

    img, tr = synth.demo_input(32, 40, water_type="II", seed=5, noise=0.0)
    _write_float(tmp_path / "s.tif", img)
    np.save(tmp_path / "t.npy", tr["clean"][::2, ::2].astype(np.float64))  # half size
    keep = np.zeros((32, 40), bool)
    keep[20:, :10] = True
    Image.fromarray(keep.astype(np.uint8) * 255).save(tmp_path / "k.png")
    (tmp_path / "m.json").write_text(json.dumps({"images": [{"path": "s.tif", "truth": "t.npy",
                                                             "truth_mask": "k.png"}]}))
    entries, problems = ev.load_manifest(str(tmp_path / "m.json"))
    assert not problems
    r = ev.evaluate_entry(entries[0], water_types=["II"])
    assert r["truth_pixels"] == int(keep.sum())
    assert r["_truth"][1, 1] == pytest.approx(tr["clean"][0, 0].astype(np.float64))
