"""`uwhl evaluate` (docs/EVALUATE.md): the metrics against hand-computed
values, the distance readers, the manifest checks, and a run end to end on
a rendered scene whose truth is known."""

from __future__ import annotations

import csv
import json
import math
import subprocess
import sys

import numpy as np
import pytest

import uwhl_rs
from uwhl_rs import evaluate as ev
from uwhl_rs import synth


def test_angle_of_known_rgb():
    assert ev.angle_deg([0.3, 0.3, 0.3]) == pytest.approx(0, abs=1e-6)
    # (1, 0, 0): cos = 1 / sqrt(3)
    assert ev.angle_deg([1, 0, 0]) == pytest.approx(54.7356, abs=1e-4)
    # (1, 1, 0): cos = 2 / (sqrt(2) sqrt(3))
    assert ev.angle_deg([2, 2, 0]) == pytest.approx(35.2644, abs=1e-4)
    assert math.isnan(ev.angle_deg([0, 0, 0]))


def test_rho_of_known_relations():
    x = np.arange(1, 50, dtype=float)
    assert ev.pearson(x, 3 * x + 2) == pytest.approx(1.0)
    assert ev.pearson(x, -x) == pytest.approx(-1.0)
    # x = 1..4 against x^2: sum dx dy = 25, sum dx^2 = 5, sum dy^2 = 129
    assert ev.pearson([1, 2, 3, 4], [1, 4, 9, 16]) == pytest.approx(25 / math.sqrt(5 * 129))
    assert math.isnan(ev.pearson([1, 2, 3], [5, 5, 5]))


def test_distance_maps_in_every_format(tmp_path):
    from PIL import Image
    from scipy.io import savemat

    mm = np.array([[1500, 0], [2500, 65535]], np.uint16)
    Image.fromarray(mm).save(tmp_path / "d.png")
    d = ev.read_distance(str(tmp_path / "d.png"), 2, 2)
    assert d[0, 0] == pytest.approx(1.5) and math.isnan(d[0, 1]) and d[1, 0] == pytest.approx(2.5)
    # any size, nearest neighbour: a 2x2 map onto 4x6 pixels
    big = ev.read_distance(str(tmp_path / "d.png"), 4, 6)
    assert big.shape == (4, 6) and big[3, 0] == pytest.approx(2.5) and math.isnan(big[0, 5])
    savemat(tmp_path / "d.mat", {"depth": np.array([[1.0, -1.0], [np.nan, 4.0]])})
    d = ev.read_distance(str(tmp_path / "d.mat"), 2, 2)
    assert d[0, 0] == 1.0 and math.isnan(d[0, 1]) and math.isnan(d[1, 0]) and d[1, 1] == 4.0
    np.save(tmp_path / "d.npy", np.full((3, 3), 2.0))
    assert np.all(ev.read_distance(str(tmp_path / "d.npy"), 3, 3) == 2.0)
    savemat(tmp_path / "two.mat", {"a": np.ones((2, 2)), "b": np.ones((2, 2))})
    with pytest.raises(ev.ManifestError, match="exactly one 2-D"):
        ev.read_distance(str(tmp_path / "two.mat"), 2, 2)
    Image.fromarray(np.zeros((2, 2), np.uint8)).save(tmp_path / "d8.png")
    with pytest.raises(ev.ManifestError, match="16-bit"):
        ev.read_distance(str(tmp_path / "d8.png"), 2, 2)
    (tmp_path / "bad.npy").write_bytes(b"not numpy")
    with pytest.raises(ev.ManifestError, match="not a distance map"):
        ev.read_distance(str(tmp_path / "bad.npy"), 2, 2)
    # OpenEXR (a file written from the format's specification): the Z channel
    # in metres; NaN and beyond 1000 m are unknown
    from exrfile import exr_bytes

    z = np.array([[1.5, np.nan], [2.5, 2000.0]], np.float32)
    (tmp_path / "d.exr").write_bytes(exr_bytes({"Z": z, "R": np.zeros((2, 2))}))
    d = ev.read_distance(str(tmp_path / "d.exr"), 2, 2)
    assert d[0, 0] == 1.5 and d[1, 0] == 2.5 and math.isnan(d[0, 1]) and math.isnan(d[1, 1])


def _scene(tmp_path, name="scene.png", h=120, w=160, water_type="3C", seed=1):
    """A rendered scene, its distance map (.npy; water has no value), its
    true type, and three boxes on the seabed annotated as a chart."""
    img, truth = synth.demo_input(h, w, water_type=water_type, seed=seed)
    uwhl_rs.images.write_image(tmp_path / name, img, bits=8, encoding="linear")
    d = truth["distance"].copy()
    d[~np.isfinite(d)] = 0  # water: no value
    np.save(tmp_path / (name + ".npy"), d)
    patches = [[10 + 12 * k, h - 30, 20 + 12 * k, h - 20] for k in range(3)]
    return {"path": name, "distance": name + ".npy", "water_type": water_type,
            "charts": [{"name": "chart 1", "gray_patches": patches, "region": [[8, h - 32, 50, h - 18]]}]}


def test_boxes_at_the_edge_and_outside(tmp_path):
    e = _scene(tmp_path, h=60, w=80)
    e["charts"][0]["gray_patches"] = [[70, 50, 80, 60]]  # ends exactly at the edge: fine
    (tmp_path / "m.json").write_text(json.dumps({"images": [e]}))
    entries, problems = ev.load_manifest(str(tmp_path / "m.json"))
    assert not problems
    r = ev.evaluate_entry(entries[0], water_types=["3C", "II"])
    assert r["charts"][0]["psi_deg"] is not None
    e["charts"][0]["gray_patches"] = [[70, 50, 81, 60]]
    (tmp_path / "m.json").write_text(json.dumps({"images": [e]}))
    entries, _ = ev.load_manifest(str(tmp_path / "m.json"))
    with pytest.raises(ev.ManifestError, match=r"outside the 80x60 image"):
        ev.evaluate_entry(entries[0], water_types=["3C"])


def test_boxes_refer_to_the_displayed_pixels_of_a_rotated_photo(tmp_path):
    """EXIF orientation 6: the stored pixels are turned; a box on the
    displayed top-left corner (gray) gives 0 degrees, on its stored place
    (red) it would not."""
    from PIL import Image

    shown = np.zeros((40, 60, 3), np.uint8)
    shown[:] = (200, 40, 40)
    shown[:10, :10] = (128, 128, 128)
    stored = np.rot90(shown, k=1)  # orientation 6 turns it back clockwise
    im = Image.fromarray(np.ascontiguousarray(stored))
    exif = im.getexif()
    exif[0x0112] = 6
    im.save(tmp_path / "rot.png", exif=exif)
    img, meta = uwhl_rs.images.read_image(tmp_path / "rot.png")
    assert img.shape[:2] == (40, 60) and meta.orientation == 6
    chart = ev.Chart("gray", [(1, 1, 9, 9)])
    assert ev.chart_angles(img, chart)[0] == pytest.approx(0, abs=0.01)
    assert ev.chart_angles(img, ev.Chart("red", [(40, 30, 50, 38)]))[0] > 30


def test_every_bad_manifest_entry_is_named_and_the_rest_evaluated(tmp_path):
    good = _scene(tmp_path)
    (tmp_path / "junk.npy").write_bytes(b"junk")
    bad = [
        {"path": "missing.png"},
        {"path": good["path"], "colour": "x"},
        {"path": good["path"], "water_type": "XI"},
        {"path": good["path"], "charts": [{"gray_patches": [[1, 2, 3]]}]},
        {"path": good["path"], "charts": [{"gray_patches": [[5, 5, 4, 9]]}]},
        {"path": good["path"], "restore": {"speed": 3}},
        {"path": good["path"], "distance": "nowhere.tif"},
        "just a string",
        {"distance": "x.npy"},
    ]
    (tmp_path / "m.json").write_text(json.dumps({"images": [good] + bad, "notes": 1}))
    entries, problems = ev.load_manifest(str(tmp_path / "m.json"))
    assert len(entries) == 1 and len(problems) == len(bad) + 1, problems
    for k, needle in enumerate(["no such image", "unknown key", "XI", "a box is", "empty", "speed", "no such distance",
                                "an entry is an object", "'path'"], start=1):
        assert any(f"images[{k}]" in p and needle in p for p in problems), (k, needle, problems)
    assert "unknown top-level key" in problems[0]
    # an unreadable distance map fails at evaluation, that entry alone
    junk = dict(good, distance="junk.npy")
    (tmp_path / "m2.json").write_text(json.dumps({"images": [junk, good]}))
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "evaluate", str(tmp_path / "m2.json"), "-o", str(out),
                        "--water-type", "3C,II,7C"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 3, r.stderr
    assert "images[0]" in r.stderr and "junk.npy: not a distance map" in r.stderr
    doc = json.load(open(out / "results.json"))
    assert len(doc["images"]) == 1 and doc["images"][0]["image"].startswith("images[1]")
    for m in ([], {"images": 3}):
        (tmp_path / "m3.json").write_text(json.dumps(m))
        r = subprocess.run([sys.executable, "-m", "uwhl_rs", "evaluate", str(tmp_path / "m3.json"), "-o", str(out)],
                           capture_output=True, text=True, timeout=60)
        assert r.returncode == 3 and "'images' list" in r.stderr, r.stderr


def test_end_to_end_on_a_rendered_scene(tmp_path):
    """A render with known type and distances: the restored image's t_B
    follows the distance, every baseline and candidate type is measured,
    and the three outputs are written."""
    entries = [_scene(tmp_path, "a.png", water_type="3C", seed=1), _scene(tmp_path, "b.png", water_type="II", seed=2)]
    (tmp_path / "m.json").write_text(json.dumps({"images": entries}))
    out = tmp_path / "out"
    types = ["II", "3C", "7C"]
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "evaluate", str(tmp_path / "m.json"), "-o", str(out),
                        "--water-type", ",".join(types), "--mask-charts"], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    # the summary table is plain lines: a blank one, then its header (no escaped newline)
    lines = r.stdout.splitlines()
    assert "\\x0a" not in r.stdout
    head = next(i for i, ln in enumerate(lines) if ln.startswith("method"))
    assert lines[head - 1] == "" and lines[head].split()[:2] == ["method", "psi-bar"]
    doc = json.load(open(out / "results.json"))
    assert doc["parameters"]["method"] == "revised" and doc["parameters"]["mask_charts"] is True
    assert doc["parameters"]["profiles"]["paper"]["white_balance"] == "stretch"
    for img in doc["images"]:
        methods = {row["method"] for row in img["charts"]}
        # the scenes have distance maps: the method told the distance too (METHOD §13)
        assert methods == {"input", "stretch", "grayworld", "revised", "paper", "revised+distance"} | \
            {f"type:{t}" for t in types}
        for m in ("revised", "paper"):
            assert img["rho"][m]["rho_B"] > 0.5  # -ln t_B grows with the rendered distance
            assert img["profiles"][m]["truth"]["true"] == img["water_type_truth"]["true"] in types
            assert img["profiles"][m]["steps"]["method"] == m
    summ = doc["summary"]
    # the distance fit's type is judged where its map was used, with whether the true type was plausible
    used = [img for img in doc["images"] if img["distance_use"]["used"]]
    assert used, "the rendered scenes' maps are used"
    assert set(summ["water_type"]) == {"revised", "paper", "revised+distance"}
    assert all(0 <= v["exact"] <= v["within_one"] <= 1 for v in summ["water_type"].values())
    assert "plausible" not in summ["water_type"]["revised"]
    for img in used:
        t = img["profiles"]["revised+distance"]["truth"]
        water = img["distance_use"]["water"]
        assert t["chosen"] == water["nearest_type"] and t["true"] == img["water_type_truth"]["true"]
        assert t["plausible"] == (t["true"] in water["plausible_types"])
    wt = summ["water_type"]["revised+distance"]
    assert wt["images"] == len(used)
    assert wt["plausible"] == pytest.approx(np.mean([img["profiles"]["revised+distance"]["truth"]["plausible"]
                                                     for img in used]))
    assert "the true one plausible in" in r.stdout
    assert summ["paper"]["charts"] == summ["revised"]["charts"] == 2
    rows = list(csv.DictReader(open(out / "results.csv")))
    assert {"image", "chart", "method", "psi_deg", "rho_B"} <= set(rows[0])
    assert {r["method"] for r in rows} >= {"input", "stretch", "grayworld", "revised", "paper", "type:3C"}
    page = open(out / "report.html").read()
    assert "http://" not in page and "https://" not in page  # self-contained
    for e in doc["images"]:
        assert e["image"] in page
    assert page.count("chart 1") >= 2 and page.count("<section") == 2


def test_results_csv_joins_to_the_manifest_by_path(tmp_path):
    """results.csv's ``image`` is each entry's ``path`` exactly as the
    manifest writes it (relative, with ``./``, absolute), so the table joins
    to the manifest on it; ``label`` tells apart an image listed twice."""
    (tmp_path / "sub").mkdir()
    a = _scene(tmp_path, "a.png", h=60, w=80, water_type="3C", seed=1)
    b = _scene(tmp_path, "sub/b.png", h=60, w=80, water_type="II", seed=2)
    b["path"] = "./sub/b.png"
    c = _scene(tmp_path, "c.png", h=60, w=80, water_type="II", seed=3)
    c["path"] = str(tmp_path / "c.png")
    again = dict(a, restore={"guided_radius": 5})
    manifest = [a, b, c, again]
    (tmp_path / "m.json").write_text(json.dumps({"images": manifest}))
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "evaluate", str(tmp_path / "m.json"), "-o", str(out),
                        "--water-type", "3C,II"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    rows = list(csv.DictReader(open(out / "results.csv", newline="", encoding="utf-8")))
    assert list(rows[0])[:2] == ["image", "label"]
    by_path: dict[str, list[dict]] = {}
    for row in rows:
        by_path.setdefault(row["image"], []).append(row)
    assert set(by_path) == {"a.png", "./sub/b.png", str(tmp_path / "c.png")}
    for k, entry in enumerate(manifest):
        joined = [row for row in by_path[entry["path"]] if row["label"] == f"images[{k}] ({entry['path']})"]
        # one row per method and baseline on the entry's one chart
        assert {row["method"] for row in joined} == {"input", "stretch", "grayworld", "revised", "paper",
                                                     "revised+distance", "type:3C", "type:II"}, (k, joined)
        assert all(row["true_water_type"] == entry["water_type"] and row["chart"] == "chart 1" for row in joined)
    # the twice-listed image: two entries under one path, told apart by label
    assert {row["label"] for row in by_path["a.png"]} == {"images[0] (a.png)", "images[3] (a.png)"}


def test_a_depth_map_along_the_axis_is_evaluated_as_its_ranges(tmp_path):
    """An entry whose map holds depth along the axis, with its lens
    (distance_depth), restores with distance exactly as the entry with the
    ranges: the same fitted water."""
    e = _scene(tmp_path, "a.png", water_type="3C", seed=1)
    z = np.load(tmp_path / "a.png.npy").astype(np.float32)
    z[z <= 0] = np.nan
    ones = np.ones_like(z)
    cos = ones / uwhl_rs.depth_to_range(ones, 80.0, port="dome")
    np.save(tmp_path / "depth.npy", np.nan_to_num(z * cos, nan=0.0).astype(np.float32))
    depth = dict(e, distance="depth.npy", distance_depth={"fov": 80, "port": "dome"})
    (tmp_path / "m.json").write_text(json.dumps({"images": [e, depth]}))
    entries, problems = ev.load_manifest(str(tmp_path / "m.json"))
    assert problems == [] and entries[1].distance_depth == (80.0, "dome")
    got = [ev.evaluate_entry(x)["distance_use"] for x in entries]
    assert got[0]["used"] and got[1]["used"]
    assert got[1]["water"]["beta"] == pytest.approx(got[0]["water"]["beta"], rel=1e-4)
