"""What a user-journey review of 2026-12-06 found where the program and its
docs disagreed: each case says what must happen independently of the code."""

from __future__ import annotations

import csv
import io
import json

import numpy as np
import pytest
from PIL import Image

import uwhl_rs
from bothcmds import cmds, run_restore
from uwhl_rs import outdir


def _photo(path, seed=0):
    rng = np.random.default_rng(seed)
    img = np.clip(rng.normal((40, 110, 150), 25, (48, 64, 3)), 0, 255).astype(np.uint8)
    Image.fromarray(img).save(path)


def _rows(out):
    text = (out / "summary.csv").read_text(encoding="utf-8")
    return [{k: outdir.summary_cell(v) for k, v in r.items()} for r in csv.DictReader(io.StringIO(text))]


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_a_later_run_into_the_folder_keeps_the_earlier_failures(impl, binary, tmp_path):
    # a dive restored camera by camera: the first run's failure must still be
    # listed after the second run, until a run is given that input again
    cmd = cmds(binary)[impl]
    _photo(tmp_path / "a.jpg")
    _photo(tmp_path / "b.jpg", 1)
    (tmp_path / "broken.jpg").write_bytes(b"\xff\xd8\xff\xe0 not a photo")
    out = tmp_path / "out"
    r = run_restore(cmd, tmp_path / "a.jpg", tmp_path / "broken.jpg", "-o", out)
    assert r.returncode == 3, r.stderr
    r = run_restore(cmd, tmp_path / "b.jpg", "-o", out)
    assert r.returncode == 0, r.stderr
    rows = _rows(out)
    assert [(r["input"], r["status"]) for r in rows] == [(str(tmp_path / "broken.jpg"), "failed"),
                                                        (str(tmp_path / "b.jpg"), "done")]
    page = uwhl_rs_report(out)
    assert "2 photos restored, 0 flagged, 1 failed" in page and "broken.jpg" in page
    # given again (and now sound): its failure is gone, one row for it
    _photo(tmp_path / "broken.jpg", 2)
    r = run_restore(cmd, tmp_path / "broken.jpg", "-o", out)
    assert r.returncode == 0, r.stderr
    assert [(r["input"], r["status"]) for r in _rows(out)] == [(str(tmp_path / "broken.jpg"), "done")]


def uwhl_rs_report(out):
    from uwhl_rs import report
    report.write_report(str(out))
    return (out / "report" / "index.html").read_text(encoding="utf-8")


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_a_navigation_log_of_names_without_extensions_gives_each_photo_its_altitude(impl, binary, tmp_path):
    # docs/OUTPUTS.md: the file column's stem also matches (IMG_0001 for IMG_0001.jpg)
    _photo(tmp_path / "IMG_0001.jpg")
    (tmp_path / "nav.csv").write_text("image,altitude\nIMG_0001,3.5\n")
    out = tmp_path / "out"
    r = run_restore(cmds(binary)[impl], tmp_path / "IMG_0001.jpg", "-o", out, "--altitude", tmp_path / "nav.csv",
                    "--fov", "80")
    assert r.returncode == 0, r.stderr
    side = json.loads((out / "IMG_0001.json").read_text())
    assert "distance_missing" not in side["flags"], side["flags"]
    assert side["distance"]["floor"]["altitude"] == 3.5 and side["distance"]["floor"]["pose_from"]["line"] == 2


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_table_water_types_are_read_in_any_case(impl, binary, tmp_path):
    # --haze-floor 9c was taken, --water-type 3c refused: one rule, canonical names recorded
    _photo(tmp_path / "a.png")
    out = tmp_path / "out"
    r = run_restore(cmds(binary)[impl], tmp_path / "a.png", "-o", out, "--water-type", "3c", "--haze-floor", "ib")
    assert r.returncode == 0, r.stderr
    side = json.loads((out / "a.json").read_text())
    assert side["water_type"] == "3C" and side["parameters"]["haze_floor"] == "IB"


def test_the_api_reads_table_names_in_any_case_and_read_distance_names_its_file(tmp_path):
    from uwhl_rs import synth
    img, _ = synth.demo_input(60, 80)
    assert uwhl_rs.restore(img, water_types=["3c"], haze_floor="9c").water_type == "3C"
    with pytest.raises(uwhl_rs.ImageError, match="nope.npy: no such file"):
        uwhl_rs.read_distance(tmp_path / "nope.npy")
    (tmp_path / "bad.npy").write_bytes(b"xx")
    with pytest.raises(uwhl_rs.ImageError, match="bad.npy: not a distance map"):
        uwhl_rs.read_distance(tmp_path / "bad.npy")


def test_evaluate_rows_name_only_the_water_type_each_method_had(tmp_path):
    # results.csv: a baseline has no water type, a type:NAME row the type it was
    # given; a restoration given the distance has no rho (its t is the map's own)
    from uwhl_rs import synth
    img, truth = synth.demo_input(60, 80)
    Image.fromarray((np.clip(img, 0, 1) ** (1 / 2.2) * 255).astype(np.uint8)).save(tmp_path / "s.png")
    z = np.linspace(1, 8, 60 * 80, dtype=np.float32).reshape(60, 80)
    np.save(tmp_path / "s.npy", z)
    (tmp_path / "m.json").write_text(json.dumps(
        {"images": [{"path": "s.png", "distance": "s.npy", "water_type": "III"}]}))
    import subprocess
    import sys
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "evaluate", str(tmp_path / "m.json"), "-o", str(tmp_path / "ev"),
                        "-q"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    doc = json.loads((tmp_path / "ev" / "results.json").read_text())
    rows = list(csv.DictReader(open(tmp_path / "ev" / "results.csv", encoding="utf-8")))
    by = {r["method"]: r for r in rows}
    for base in ("input", "stretch", "gray_world"):
        if base in by:
            assert by[base]["water_type"] == "", by[base]
    types = [m for m in by if m.startswith("type:")]
    assert types and all(by[m]["water_type"] == m[5:] for m in types)
    assert by["revised"]["water_type"] == doc["images"][0]["water_type"]
    dist = [m for m in doc["images"][0]["rho"] if m.endswith("+distance")]
    assert dist == [] and "revised" in doc["images"][0]["rho"]


def test_the_score_panel_states_its_scale_as_the_a_panel_does():
    # the review found the A panel labelled "0 to 0.3" and the score panel without a range
    from uwhl_rs.outdir import Photo
    from uwhl_rs.report_series import series_axis, series_svg
    docs = [{"water_type": "II", "scores": {"II": 0.0412}, "veiling_light": [0.1, 0.3, 0.4]},
            {"water_type": "3C", "scores": {"3C": 0.2875}, "veiling_light": [0.1, 0.3, 0.4]}]
    svg = series_svg(series_axis([Photo(f"p{k}.json", d) for k, d in enumerate(docs)]), ["II", "3C"])
    assert "score of the chosen type (lower is better), 0.041 to 0.287" in svg
