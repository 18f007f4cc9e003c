"""``uwhl report OUTDIR`` and ``restore --report`` (uwhl_rs.report): the
page a batch gets, opened in headless Chromium (installed by the browser
test's helper when missing). The numbers it shows are checked against the
sidecars, which the test reads itself; a screenshot is saved for a person
to look at (``target/batch-report-screenshot.png``)."""

import collections
import json
import os
import subprocess
import sys

from test_report_browser import ROOT, _chromium, _run
from uwhl_rs import report, synth
from uwhl_rs.images import write_image


def _restore(tmp_path, n=8, extra=()):
    src = tmp_path / "in"
    (src / "sub").mkdir(parents=True, exist_ok=True)
    for k in range(n):
        img, _ = synth.demo_input(90, 120, water_type=["III", "1C", "II", "7C"][k % 4], seed=k)
        write_image(src / ("sub" if k >= n - 2 else "") / f"f{k:03d}.png", img, encoding="linear")
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", str(src), "-o", str(out), "-q", *extra],
                       capture_output=True, text=True, timeout=600)
    return r, out


def _sidecars(out):
    docs = {}
    for d, dirs, files in os.walk(out):
        dirs[:] = [x for x in dirs if x != "report"]
        for f in files:
            if f.endswith(".json"):
                docs[os.path.relpath(os.path.join(d, f), out)] = json.load(open(os.path.join(d, f)))
    return docs


def test_restore_report_in_chromium(tmp_path):
    browser = _chromium()
    r, out = _restore(tmp_path, extra=("--report",))
    assert r.returncode == 0, r.stderr
    assert (out / "report" / "index.html").exists() and len(os.listdir(out / "report" / "thumbs")) == 16
    # an operator's flag on one photo: the report must list it first (the
    # pipeline raises these on scenes without water; a sidecar says so)
    side = out / "f002.json"
    doc = json.loads(side.read_text())
    doc["flags"] = ["no_water_region", "veiling_fallback"]
    side.write_text(json.dumps(doc, indent=2) + "\n")
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "report", str(out)], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0 and "8 photos, 1 flagged, 0 failed, 0 thumbnails written" in r.stdout, r.stdout + r.stderr
    page_path = out / "report" / "index.html"
    url = page_path.resolve().as_uri()
    dom = _run(browser, "--dump-dom", url)
    assert dom.returncode == 0, dom.stderr[-2000:]
    page = dom.stdout
    docs = _sidecars(out)
    counts = collections.Counter(d["water_type"] for d in docs.values())
    # the histogram's bars say what the sidecars say
    for wt, n in counts.items():
        assert f"<title>{wt}: {n}</title>" in page, wt
    assert "8 photos restored, 1 flagged, 0 failed" in page and 'id="failed"' not in page
    # the flagged section comes first and holds exactly the flagged photo
    flagged = page[page.index('id="flagged-grid"'):page.index('id="all"')]
    assert flagged.count('class="cell flagged"') == 1 and "f002" in flagged and "veiling_fallback" in flagged
    allgrid = page[page.index('id="all-grid"'):page.index('<script')]
    assert allgrid.count('<div class="cell') == 8
    # every thumbnail is a file beside the page (nothing fetched from the network), and decodes
    from PIL import Image

    thumbs = sorted(os.listdir(out / "report" / "thumbs"))
    assert len(thumbs) == 16
    for t in thumbs:
        with Image.open(out / "report" / "thumbs" / t) as im:
            assert max(im.size) <= report.THUMB_SIDE
    # the links open the full-size photo and its t map
    assert 'src="../f000.jpg"' not in allgrid  # thumbnails in the grid, not full images
    data = json.loads(page[page.index('id="data"'):].split(">", 1)[1].split("</script>", 1)[0])
    for p in data["photos"]:
        assert os.path.exists(os.path.normpath(os.path.join(out / "report", p["full"])))
        assert os.path.exists(os.path.normpath(os.path.join(out / "report", p["t"])))
    # the series has one point per photo in each of its five lines
    series = page[page.index('class="series"'):]
    assert series.count("<polyline") == 5
    first = series.split('points="', 1)[1].split('"', 1)[0]
    assert len(first.split()) == 8
    shot = os.path.join(ROOT, "target", "batch-report-screenshot.png")
    os.makedirs(os.path.dirname(shot), exist_ok=True)
    s = _run(browser, f"--screenshot={shot}", "--window-size=1280,1500", url)
    assert s.returncode == 0 and os.path.getsize(shot) > 10000, s.stderr[-2000:]


def test_report_pages_a_large_batch(tmp_path):
    browser = _chromium()
    r, out = _restore(tmp_path, n=11)
    assert r.returncode == 0, r.stderr
    done = report.write_report(str(out), page_size=4)
    assert done["photos"] == 11
    page = _run(browser, "--dump-dom", (out / "report" / "index.html").resolve().as_uri()).stdout
    allgrid = page[page.index('id="all-grid"'):page.index('<script')]
    assert "page 1 of 3" in allgrid and allgrid.count('<div class="cell') == 4
    assert 'loading="lazy"' in allgrid


def test_report_refusals_and_leftovers(tmp_path):
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "report", str(tmp_path / "missing")], capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 3 and "no such folder" in r.stderr
    # an unreadable sidecar and a missing output: a note, and the rest of the page
    r, out = _restore(tmp_path, n=3, extra=())
    # a failed input (in summary.csv, without a sidecar) is listed with its reason
    (tmp_path / "in" / "zz_bad.jpg").write_bytes(b"\xff\xd8\xff not a jpeg")
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", str(tmp_path / "in"), "-o", str(out), "-q",
                        "--report"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 3, r.stderr
    page = (out / "report" / "index.html").read_text()
    failed = page[page.index('id="failed"'):page.index('id="flagged"')]
    assert "zz_bad.jpg" in failed and "unreadable_input" in failed and "cannot decode" in failed
    assert "3 photos restored, 0 flagged, 1 failed" in page
    (out / "broken.json").write_text("{ not json")
    os.remove(out / "f000.jpg")
    done = report.write_report(str(out))
    assert done["photos"] == 3
    assert any("broken.json" in p for p in done["problems"]) and any("f000.jpg" in p for p in done["problems"])


def test_the_sequence_follows_exif_time_when_every_photo_has_it(tmp_path):
    """Frames named out of time order, with EXIF DateTimeOriginal: the
    series is drawn in time order, its axis labelled with the times."""
    from PIL import Image

    from test_metadata import _gps_exif, _scene

    src = tmp_path / "in"
    src.mkdir()
    # names in one order, times in the other
    for k, name in enumerate(["c.jpg", "b.jpg", "a.jpg"]):
        ex = _gps_exif()
        ex.get_ifd(0x8769)[0x9003] = f"2026:11:30 10:15:{10 * k:02d}"
        Image.fromarray(_scene(seed=k)).save(src / name, quality=92, exif=ex)
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", str(src), "-o", str(out), "-q"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    photos, _ = report.collect_sidecars(str(out))
    axis = report.series_axis(photos)
    assert [os.path.basename(p.sidecar) for p in axis.photos] == ["c.json", "b.json", "a.json"]
    assert axis.xs == [0.0, 10.0, 20.0] and axis.first.endswith("2026-11-30T10:15:00.437")
    assert axis.last.endswith("(+20 s)") and axis.by_time
    report.write_report(str(out))
    page = (out / "report" / "index.html").read_text()
    assert "Over the sequence (EXIF time)" in page and "2026-11-30T10:15:00.437" in page


def test_a_float_tiff_input_gets_its_thumbnail(tmp_path):
    """Pillow cannot open a float RGB TIFF at all: the input's thumbnail comes
    through the package's reader, its colours those of the linear data."""
    import numpy as np
    import tifffile
    from PIL import Image

    src = tmp_path / "in"
    src.mkdir()
    img = np.zeros((60, 80, 3), np.float32)
    img[:, :40] = (0.6, 0.1, 0.05)  # red left half, blue right half (linear)
    img[:, 40:] = (0.05, 0.1, 0.6)
    tifffile.imwrite(src / "scan.tif", img, photometric="rgb")
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", str(src), "-o", str(out), "-q"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    done = report.write_report(str(out))
    assert not [p for p in done["problems"] if "no thumbnail" in p], done["problems"]
    thumbs = [f for f in os.listdir(out / "report" / "thumbs") if f.endswith(".jpeg")]
    assert len(thumbs) == 2
    page = (out / "report" / "index.html").read_text()
    data = json.loads(page[page.index('type="application/json">') + 24:page.index("</script>")])
    ti = out / "report" / data["photos"][0]["ti"]
    th = np.asarray(Image.open(ti).convert("RGB"), float)
    left, right = th[:, : th.shape[1] // 3].mean((0, 1)), th[:, -th.shape[1] // 3:].mean((0, 1))
    assert left[0] > left[2] + 50 and right[2] > right[0] + 50, (left, right)


def test_a_float_tiff_too_large_for_a_thumbnail_is_named_without_a_temporary(tmp_path, monkeypatch):
    """A float TIFF over the thumbnail's pixel limit: a note naming the input
    and the limit, not the private copy the reader was given."""
    import numpy as np
    import tifffile

    src = tmp_path / "in"
    src.mkdir()
    img = np.random.default_rng(1).uniform(0.1, 0.6, (40, 60, 3)).astype(np.float32)
    tifffile.imwrite(src / "wide.tif", img, photometric="rgb")
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", str(src), "-o", str(out), "-q"],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    monkeypatch.setattr(report, "THUMB_MAX_PIXELS", 1000)  # 40 x 60 = 2400 pixels: over it
    done = report.write_report(str(out))
    notes = [p for p in done["problems"] if "wide.tif" in p]
    assert len(notes) == 1 and "no thumbnail" in notes[0] and "1000" in notes[0], done["problems"]
    assert "uwhl-thumb-" not in notes[0] and "source.tif" not in notes[0], notes[0]
