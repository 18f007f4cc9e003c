"""``OUTDIR/summary.csv`` (uwhl_rs.outdir): one row per input, done,
skipped or failed, with what its sidecar says and the EXIF time and GPS
position; written as the batch goes, so an interrupted run keeps its rows."""

import csv
import json
import os
import signal
import subprocess
import sys
import time

import pytest
from PIL import Image

from test_metadata import _gps_exif, _scene
from uwhl_rs import synth
from uwhl_rs.images import write_image


def rows(out):
    with open(os.path.join(out, "summary.csv"), newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def run(*args, **kw):
    return subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", *map(str, args)], capture_output=True,
                          text=True, timeout=600, **kw)


@pytest.fixture()
def batch_in(tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    Image.fromarray(_scene()).save(src / "a_gps.jpg", quality=92, exif=_gps_exif())
    for k in range(3):
        img, _ = synth.demo_input(90, 120, water_type="II", seed=k)
        write_image(src / f"b{k}.png", img, encoding="linear")
    (src / "c_bad.jpg").write_bytes(b"\xff\xd8\xff not a jpeg")
    return src


def test_every_input_has_its_row(batch_in, tmp_path):
    out = tmp_path / "out"
    assert run(batch_in, "-o", out, "-q").returncode == 3
    got = {os.path.basename(r["input"]): r for r in rows(out)}
    assert set(got) == {"a_gps.jpg", "b0.png", "b1.png", "b2.png", "c_bad.jpg"}
    bad = got.pop("c_bad.jpg")
    assert bad["status"] == "failed" and bad["error_kind"] == "unreadable_input" and bad["exit_code"] == "3"
    assert "cannot decode" in bad["error"]
    for name, r in got.items():
        side = json.load(open(r["sidecar"]))
        assert r["status"] == "done" and r["water_type"] == side["water_type"]
        assert [float(r[c]) for c in ("A_R", "A_G", "A_B")] == side["veiling_light"]
        assert {t: float(r[f"score_{t}"]) for t in side["scores"]} == side["scores"]
        assert os.path.exists(r["image"]) and float(r["seconds"]) > 0
    a = got["a_gps.jpg"]
    assert a["taken_at"] == "2026-11-30T10:15:42.437"
    assert float(a["latitude"]) == pytest.approx(-(33 + 51 / 60 + 35.9 / 3600), abs=1e-9)
    assert float(a["longitude"]) == pytest.approx(151 + 12 / 60 + 40.5 / 3600, abs=1e-9)
    assert float(a["altitude"]) == -18.5
    assert got["b0.png"]["taken_at"] == "" and got["b0.png"]["latitude"] == ""
    # the rerun's summary covers every input too: skipped rows from their sidecars
    assert run(batch_in, "-o", out, "-q").returncode == 3
    again = {os.path.basename(r["input"]): r for r in rows(out)}
    assert again["a_gps.jpg"]["status"] == "skipped" and again["a_gps.jpg"]["water_type"] == a["water_type"]
    assert again["a_gps.jpg"]["taken_at"] == a["taken_at"] and again["a_gps.jpg"]["image"] == a["image"]


def test_an_interrupted_run_keeps_its_rows(tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    for k in range(40):
        img, _ = synth.demo_input(360, 480, water_type="3C", seed=k)
        write_image(src / f"f{k:02d}.png", img, encoding="linear")
    out = tmp_path / "out"
    # SIGINT back to its default in the child: a parent that ignores it (a
    # pytest-xdist worker, a shell's background job) would have the child
    # ignore it too, and Python then installs no KeyboardInterrupt
    p = subprocess.Popen([sys.executable, "-m", "uwhl_rs", "restore", str(src), "-o", str(out)],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                         preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.time() + 120
    while time.time() < deadline and (not (out / "summary.csv").exists() or len(rows(out)) < 3):
        time.sleep(0.05)
    p.send_signal(signal.SIGINT)
    p.communicate(timeout=120)
    assert p.returncode == 130
    kept = rows(out)
    assert 3 <= len(kept) < 40
    done = {r["input"] for r in kept if r["status"] == "done"}
    sidecars = {json.load(open(os.path.join(out, f)))["input"] for f in os.listdir(out) if f.endswith(".json")}
    assert done == sidecars  # every done row's input is done, and every done input has its row


def test_both_batch_paths_write_it(batch_in, tmp_path):
    from uwhl_rs import batch

    out = tmp_path / "dask"
    df = batch.restore_many(str(batch_in), str(out))
    kept = {r["input"]: r for r in rows(out)}
    assert len(kept) == 5
    for _, row in df.iterrows():
        assert kept[row.input]["status"] == row.status
        if row.status == "done":
            assert kept[row.input]["water_type"] == row.water_type
