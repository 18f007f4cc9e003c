"""What the distance templates, ``--water-from``, the navigation log and the
report read from names and files someone else chose (both commands where
both read it): a file name cannot move a map out of its template's folder
or be expanded twice, a name that is not UTF-8 finds its map, fits no photo
gives are refused and every sidecar not used is named, a log's bad times
and doubled columns are refused, and the report shows every photo
``restore`` wrote, with no lone surrogate on its page and no unbounded
table of failures."""

import csv
import json
import os
import shutil
import subprocess
import sys

import numpy as np
import pytest
from bothcmds import cmds as _cmds
from bothcmds import run_restore, sidecar

tifffile = pytest.importorskip("tifffile")

BOTH = ["python", "rust"]


@pytest.fixture(scope="module")
def photos(tmp_path_factory):
    """Photos named as a hostile folder may name them, and one map that
    sits outside the maps' folder."""
    d = tmp_path_factory.mktemp("names")
    img = np.random.default_rng(5).random((40, 60, 3)).astype(np.float32) * 0.6 + 0.2
    ind = d / "in"
    ind.mkdir()
    for name in (b"...tif", b"{name}.tif", b"q\xff.tif", b"a\nb.tif", b"plain.tif"):
        tifffile.imwrite(os.fsdecode(os.path.join(os.fsencode(ind), name)), img, photometric="rgb")
    z = np.full((40, 60), 3.0, np.float32)
    (d / "maps" / "x").mkdir(parents=True)
    np.save(d / "maps" / "depth.npy", z)  # what maps/{stem}/../depth.npy would reach
    np.save(d / "maps" / "x" / "{name}.npy", z)  # what a second expansion would miss
    np.save(os.fsdecode(os.path.join(os.fsencode(d / "maps" / "x"), b"q\xff.npy")), z)
    np.save(d / "maps" / "x" / "plain.npy", z)
    return d


@pytest.mark.parametrize("impl", BOTH)
def test_a_name_cannot_move_or_rename_its_distance_map(impl, binary, photos, tmp_path):
    out = tmp_path / impl
    # the stem of "...tif" is "..": maps/../depth.npy is outside maps/
    r = run_restore(_cmds(binary)[impl], photos / "in" / "...tif", "-o", out, "--distance", photos / "maps" / "{stem}" / "depth.npy")
    assert r.returncode == 0, r.stderr
    side = sidecar(out, "..")
    assert "distance_missing" in side["flags"], side["flags"]
    assert "would leave the template's folder" in side["distance"]["rejected"], side["distance"]
    # "{name}.tif" has the stem "{name}": its map is maps/x/{name}.npy, not expanded again
    r = run_restore(_cmds(binary)[impl], photos / "in" / "{name}.tif", "-o", out, "--distance", photos / "maps" / "x" / "{stem}.npy")
    assert r.returncode == 0, r.stderr
    side = sidecar(out, "{name}")
    assert side["distance"]["source"].endswith("maps/x/{name}.npy") and "distance_missing" not in side["flags"], side["distance"]


@pytest.mark.parametrize("impl", BOTH)
def test_a_name_that_is_not_utf8_finds_its_map(impl, binary, photos, tmp_path):
    out = tmp_path / impl
    src = os.path.join(os.fsencode(photos / "in"), b"q\xff.tif")
    tpl = str(photos / "maps" / "x" / "{stem}.npy")
    cmd = [*_cmds(binary)[impl], "restore", src, "-o", str(out), "--distance", tpl, "-q"]
    r = subprocess.run(cmd, capture_output=True, timeout=300)
    assert r.returncode == 0, r.stderr
    side = sidecar(out, "q\ufffd")  # outputs are named with the undecodable byte as U+FFFD
    assert "distance_missing" not in side["flags"], side.get("distance")
    assert side["distance"]["coverage"] == pytest.approx(1.0)


def _cal(tmp_path, docs):
    cal = tmp_path / "cal"
    cal.mkdir()
    for name, doc in docs.items():
        (cal / name).write_text(doc if isinstance(doc, str) else json.dumps(doc))
    return cal


def _fit(beta):
    return {"distance": {"used": True, "water": {"beta": beta}}}


@pytest.mark.parametrize("impl", BOTH)
def test_water_from_refuses_fits_no_photo_gives_and_names_what_it_skipped(impl, binary, photos, tmp_path):
    cal = _cal(tmp_path, {
        "good.json": _fit([0.5, 0.1, 0.05]),
        "tiny_ratio.json": _fit([99, 99, 1e-300]),  # beta_B/beta_R 1e-302: labelled Jerlov I before
        "tiny_all.json": _fit([1e-300, 1e-300, 1e-300]),
        "broken.json": "{",
        "nodistance.json": {"distance": {"used": False}},
    })
    out = tmp_path / impl
    cmd = [*_cmds(binary)[impl], "restore", str(photos / "in" / "plain.tif"), "-o", str(out), "--water-from", str(cal)]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    side = sidecar(out, "plain")
    assert side["beta_ratios"] == pytest.approx([0.1, 0.5], rel=1e-9)
    rec = side["parameters"]["water_from"]
    assert (rec["photos"], rec["skipped"]) == (1, 3), rec
    for name in ("tiny_ratio.json", "tiny_all.json", "broken.json"):
        assert any(name in line and "not used" in line for line in r.stderr.splitlines()), r.stderr
    assert "nodistance.json" not in r.stderr
    # only hostile fits: a usage error that says some files could not be used
    os.remove(cal / "good.json")
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=300)
    assert r.returncode == 2 and "3 of its *.json files could not be used" in r.stderr, r.stderr


@pytest.mark.parametrize("impl", BOTH)
@pytest.mark.parametrize("log, want", [
    ("time,altitude\n1e300,2\n", 'line 2, column 1 (time): "1e300" is not an ISO 8601 time'),
    ("time,altitude\n2026-11-30T10:15:40+99:00,2\n", "line 2, column 1 (time)"),
    ("time,altitude\n100,2\n100,9\n", "line 3: the time of line 2 again"),
    ("file,altitude,alt\nplain.tif,2,3\n", 'two altitude columns, "altitude" (column 2) and "alt" (column 3)'),
    ("file,altitude\nplain.tif,1e300\n", "1.000000e300 is not in"),
])
def test_a_navigation_log_with_bad_times_or_doubled_columns_is_refused(impl, binary, photos, tmp_path, log, want):
    nav = tmp_path / "nav.csv"
    nav.write_text(log)
    r = run_restore(_cmds(binary)[impl], photos / "in" / "plain.tif", "-o", tmp_path / "o", "--altitude", nav, "--fov", "80")
    assert r.returncode == 2 and want in r.stderr, r.stderr
    assert len(r.stderr) < 600, r.stderr  # no 300-digit number


def test_the_report_shows_every_photo_restore_wrote_and_no_lone_surrogate(binary, photos, tmp_path):
    out = tmp_path / "out"
    for name in (b"a\nb.tif", b"q\xff.tif", b"plain.tif"):
        src = os.path.join(os.fsencode(photos / "in"), name)
        r = subprocess.run([binary, "restore", src, "-o", str(out), "-q"], capture_output=True, timeout=300)
        assert r.returncode == 0, r.stderr
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "report", str(out)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "not a usable sidecar" not in r.stdout, r.stdout
    page = (out / "report" / "index.html").read_text(encoding="utf-8")
    start = page.index('<script id="data" type="application/json">') + len('<script id="data" type="application/json">')
    data = json.loads(page[start:page.index("</script>", start)])
    names = sorted(p["name"] for p in data["photos"])
    # as the console shows them: the newline as \x0a, the undecodable byte as U+FFFD
    assert names == sorted(["a\\x0ab", "q\ufffd", "plain"]), names
    assert not any(0xD800 <= ord(c) <= 0xDFFF for p in data["photos"] for c in json.dumps(p, ensure_ascii=False))
    assert "\\udc" not in page.lower()


def test_the_reports_table_of_failures_is_bounded(binary, photos, tmp_path):
    """250,000 failed rows with 300-character errors: the page shows 200 of
    them, each cut, and says how many more summary.csv holds."""
    out = tmp_path / "out"
    r = subprocess.run([binary, "restore", str(photos / "in" / "plain.tif"), "-o", str(out), "-q"], capture_output=True, timeout=300)
    assert r.returncode == 0, r.stderr
    with open(out / "summary.csv", newline="") as f:
        head = next(csv.reader(f))
    with open(out / "summary.csv", "a", newline="") as f:
        w = csv.writer(f)
        for k in range(250_000):
            row = {"input": f"x{k}.jpg", "status": "failed", "error_kind": "unreadable_input", "error": "e" * 1000, "exit_code": "3"}
            w.writerow([row.get(c, "") for c in head])
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "report", str(out)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    page = (out / "report" / "index.html").read_text()
    assert "Failed: 250000" in page and "and 249800 more: see summary.csv" in page
    assert page.count("<tr>") <= 200 + 50
    assert len(page) < 2_000_000, len(page)
    assert "e" * 400 not in page


def test_report_of_a_file_says_it_is_not_a_folder(tmp_path):
    f = tmp_path / "f.json"
    f.write_text("{}")
    os.mkfifo(tmp_path / "pipe")
    for p, want in ((f, "not a folder"), (tmp_path / "pipe", "not a folder"), (tmp_path / "nope", "no such folder")):
        r = subprocess.run([sys.executable, "-m", "uwhl_rs", "report", str(p)], capture_output=True, text=True, timeout=60)
        assert r.returncode != 0 and want in r.stderr, (p, r.stderr)
    shutil.rmtree(tmp_path / "out", ignore_errors=True)


@pytest.mark.parametrize("impl", BOTH)
def test_a_map_far_larger_than_its_photo_is_not_read(impl, binary, photos, tmp_path):
    """A 4096 x 4096 16-bit PNG of zeros (a few kB compressed, 32 MB of
    samples) for a photo of 60 x 40: refused from its header (more than 16
    times the photo's pixels, and over the 4 Mpx floor of that cap)."""
    from PIL import Image

    big = tmp_path / "big.png"
    Image.fromarray(np.zeros((4096, 4096), np.uint16)).save(big)
    assert big.stat().st_size < 1_000_000
    out = tmp_path / impl
    r = run_restore(_cmds(binary)[impl], photos / "in" / "plain.tif", "-o", out, "--distance", big)
    assert r.returncode == 0, r.stderr
    side = sidecar(out, "plain")
    assert "distance_missing" in side["flags"]
    assert "4096x4096 pixels, more than 16 times the photo's 60x40" in side["distance"]["rejected"], side["distance"]


def test_both_commands_write_the_same_json_error_line_and_a_short_usage_error(binary, tmp_path):
    lines = {}
    for impl, cmd in _cmds(binary).items():
        r = subprocess.run([*cmd, "restore", str(tmp_path / "nope.jpg"), "-o", str(tmp_path / impl), "--json-errors", "-q"],
                           capture_output=True, text=True, timeout=120)
        lines[impl] = [x for x in r.stderr.splitlines() if x.startswith("{")]
        # a usage error is its line and where to look, not the usage of thirty options
        u = subprocess.run([*cmd, "restore", "x.jpg", "-o", str(tmp_path / "u"), "--fov", "nan"], capture_output=True,
                           text=True, timeout=120)
        assert u.returncode == 2 and len(u.stderr.splitlines()) == 2 and "--help" in u.stderr, u.stderr
    assert lines["python"] == lines["rust"], lines
    assert lines["python"][0].startswith('{"error": "unreadable_input", "input": '), lines


# ------------------------------------------------------------------ uwhl evaluate and demo


def _evaluate(manifest, out, *extra):
    return subprocess.run([sys.executable, "-m", "uwhl_rs", "evaluate", str(manifest), "-o", str(out), *extra],
                          capture_output=True, text=True, timeout=600)


@pytest.fixture
def ev(tmp_path):
    """A folder with one small photo and a writer of manifests over it."""
    from PIL import Image

    rng = np.random.default_rng(2)
    Image.fromarray((rng.random((48, 64, 3)) * 200 + 20).astype(np.uint8)).save(tmp_path / "img.png")

    def manifest(*entries):
        p = tmp_path / "m.json"
        p.write_text(json.dumps({"images": list(entries)}))
        return p
    return tmp_path, manifest


def _sparse_npy(path, shape):
    """A .npy whose header claims ``shape`` (uint8) over a sparse file: nothing large on disk."""
    from numpy.lib import format as npf

    with open(path, "wb") as f:
        npf.write_array_header_1_0(f, {"descr": "|u1", "fortran_order": False, "shape": shape})
        f.truncate(f.tell() + int(np.prod(shape)))


def test_evaluate_refuses_shapes_that_are_no_image_from_their_header(ev):
    """A 1-D or (4, 4, 2^27) header (2 GiB each, sparse) and a 4-D animation
    as a mask: refused by name before anything is read, the good entry
    still evaluated; each refusal takes no memory worth the name."""
    d, manifest = ev
    _sparse_npy(d / "t1d.npy", (1 << 31,))
    _sparse_npy(d / "tchan.npy", (4, 4, 1 << 27))
    np.save(d / "t.npy", np.full((48, 64, 3), 0.3))
    np.save(d / "anim.npy", np.ones((5, 48, 64, 3), np.uint8))
    m = manifest({"path": "img.png", "truth": "t1d.npy"}, {"path": "img.png", "truth": "tchan.npy"},
                 {"path": "img.png", "truth": "t.npy", "truth_mask": "anim.npy"}, {"path": "img.png", "truth": "t.npy"})
    r = _evaluate(m, d / "out")
    assert r.returncode == 3, r.stdout + r.stderr
    assert "t1d.npy: the truth has shape (2147483648,), not one H x W image" in r.stderr, r.stderr
    assert "tchan.npy: the truth is 536870912 pixels, over the limit" in r.stderr, r.stderr
    assert "anim.npy: the truth mask has shape (5, 48, 64, 3)" in r.stderr, r.stderr
    doc = json.loads((d / "out" / "results.json").read_text())
    assert len(doc["images"]) == 1 and doc["images"][0]["truth_pixels"] > 0


def test_evaluate_refuses_a_truth_of_values_beyond_radiance(ev):
    d, manifest = ev
    np.save(d / "huge.npy", np.full((10, 10, 3), 1e308))
    r = _evaluate(manifest({"path": "img.png", "truth": "huge.npy"}), d / "out")
    assert r.returncode == 3 and "no pixel of the truth can be scored" in r.stderr, r.stderr
    assert "RuntimeWarning" not in r.stderr


def test_evaluate_a_mat_distance_far_larger_than_its_photo_is_not_decompressed(ev):
    scipy_io = pytest.importorskip("scipy.io")
    d, manifest = ev
    a = np.zeros((3000, 3000), np.uint8)
    a[0, 0] = 1
    scipy_io.savemat(d / "big.mat", {"z": a}, do_compression=True)
    np.save(d / "bigz.npy", np.ones((3000, 3000), np.float32))
    r = _evaluate(manifest({"path": "img.png", "distance": "big.mat"}, {"path": "img.png", "distance": "bigz.npy"}),
                  d / "out")
    assert r.returncode == 3, r.stdout + r.stderr
    assert r.stderr.count("more than 16 times the photo's 64x48") == 2, r.stderr


def test_evaluate_names_a_path_that_is_no_file_name_and_shows_undecodable_ones(ev):
    d, manifest = ev
    import shutil as _sh
    _sh.copy(d / "img.png", os.fsdecode(os.path.join(os.fsencode(d), b"q\xff.png")))
    m = manifest({"path": "a\ud800.png"}, {"path": "q\udcff.png", "charts": [{"name": "c\udcfe", "gray_patches": [[1, 1, 9, 9]]}]})
    r = _evaluate(m, d / "out")
    assert r.returncode == 3 and "not a file name (it holds a lone surrogate)" in r.stderr, r.stderr
    assert "Traceback" not in r.stderr and "UnicodeEncodeError" not in r.stderr
    text = (d / "out" / "results.csv").read_text(encoding="utf-8")
    assert "q\ufffd.png" in text and "c\ufffd" in text


def test_evaluate_caps_the_boxes_of_a_chart(ev):
    d, manifest = ev
    r = _evaluate(manifest({"path": "img.png", "charts": [{"gray_patches": [[0, 0, 8, 8]] * 65}]}), d / "out")
    assert r.returncode == 3 and "65 boxes in 'gray_patches', over the limit of 64" in r.stderr, r.stderr


@pytest.mark.parametrize("impl", BOTH)
def test_demo_into_what_cannot_be_a_folder_is_a_write_failure_said_first(impl, binary, tmp_path):
    (tmp_path / "f").write_text("x")
    r = subprocess.run([*_cmds(binary)[impl], "demo", "-o", str(tmp_path / "f")], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 5 and "cannot create" in r.stderr and "File exists" in r.stderr, r.stderr
    assert "restore took" not in r.stdout  # nothing was rendered or restored before
    r = subprocess.run([*_cmds(binary)[impl], "demo", "-o", str(tmp_path / "a\nb\x1b[31m")], capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0 and "a\\x0ab\\x1b[31m" in r.stdout and "\x1b" not in r.stdout, r.stdout


def test_evaluate_chart_regions_over_the_whole_photo_are_a_bad_entry(ev):
    d, manifest = ev
    m = manifest({"path": "img.png", "charts": [{"gray_patches": [[0, 0, 8, 8]], "region": [[0, 0, 64, 48]]}]})
    r = _evaluate(m, d / "out", "--mask-charts")
    assert r.returncode == 3 and "regions cover the whole photo" in r.stderr, r.stderr


def test_ifdo_says_a_bad_header_or_handle_base_once_and_first(tmp_path):
    (tmp_path / "out").mkdir()
    bomb = tmp_path / "bomb.yaml"
    bomb.write_text("a: &x [1, 2]\nb: *x\n")
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "ifdo", str(tmp_path / "out"), "--header", str(bomb)],
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 2 and "anchors and aliases" in r.stderr and r.stderr.count("bomb.yaml") == 1, r.stderr
    ok = tmp_path / "h.yaml"
    ok.write_text("image-set-name: x\n")
    for base in ("http://x/ y", "http://x/\ny", "no-scheme"):
        r = subprocess.run([sys.executable, "-m", "uwhl_rs", "ifdo", str(tmp_path / "out"), "--header", str(ok),
                            "--handle-base", base], capture_output=True, text=True, timeout=120)
        assert r.returncode == 2 and "--handle-base" in r.stderr and "must be a URI" in r.stderr, (base, r.stderr)


@pytest.mark.parametrize("restore, want", [({"t_scale": float("nan")}, "t_scale"),
                                           ({"sphere_points": 4294967295}, "sphere_points"),
                                           ({"veiling_light": [0.5, 0.5, 0]}, "veiling_light")])
def test_evaluate_checks_an_entrys_restore_values_before_anything_runs(ev, restore, want):
    d, manifest = ev
    (d / "m.json").write_text(json.dumps({"images": [{"path": "img.png"}, {"path": "img.png", "restore": restore}]}))
    r = _evaluate(d / "m.json", d / "out")
    assert r.returncode == 3 and f"images[1] (img.png): restore: bad parameter {want}" in r.stderr, r.stderr
    # said with the manifest, before the first entry ran
    assert r.stdout.count("[1/1]") == 1 and "images[1]" not in r.stdout, r.stdout


def test_a_veiling_light_beyond_single_precision_is_quoted_as_given():
    import uwhl_rs

    with pytest.raises(uwhl_rs.ParameterError, match=r"veiling_light: \[1e308, 0.5, 0.5\]"):
        uwhl_rs.Sequence(veiling_light=(1e308, 0.5, 0.5))


# ------------------------------------------------------------------ the Python API and the console


def test_the_api_refuses_from_shapes_before_copying():
    """Broadcast views of hundreds of gigabytes cost nothing until copied:
    the image's working memory and the distance map's size against the
    image are checked from their shapes, with the library's messages."""
    import uwhl_rs
    from uwhl_rs import synth

    img, _ = synth.demo_input(60, 80)
    with pytest.raises(MemoryError, match="over the limit of"):
        uwhl_rs.restore(np.broadcast_to(img[:1, :1], (200_000, 200_000, 3)))
    with pytest.raises(MemoryError, match="over the limit of"):
        uwhl_rs.Sequence(max_memory=10**8).restore(np.broadcast_to(img[:1, :1], (200_000, 200_000, 3)))
    with pytest.raises(uwhl_rs.ParameterError, match="more than 16 times the image's 60x80 pixels"):
        uwhl_rs.restore(img, distance=np.broadcast_to(np.float32(3), (100_000, 100_000)))
    with pytest.raises(uwhl_rs.ParameterError, match="over the largest input"):
        uwhl_rs.depth_to_range(np.broadcast_to(np.float32(1), (100_000, 100_000)), 60)
    # a map of the image's own size is taken as before
    z = np.where(np.isfinite(_["distance"]), _["distance"], np.nan).astype(np.float32)
    assert uwhl_rs.restore(img, distance=z).transmission.shape == (60, 80)


def test_read_image_and_restore_file_do_not_open_a_fifo(tmp_path):
    os.mkfifo(tmp_path / "f.jpg")
    code = ("import uwhl_rs, sys\n"
            "for f in (lambda: uwhl_rs.read_image(sys.argv[1]), lambda: uwhl_rs.restore_file(sys.argv[1], sys.argv[2]),\n"
            "          lambda: uwhl_rs.read_image('/dev/zero')):\n"
            "    try:\n        f()\n    except uwhl_rs.ImageReadError as e:\n        print(e)\n")
    r = subprocess.run([sys.executable, "-c", code, str(tmp_path / "f.jpg"), str(tmp_path / "o")], capture_output=True,
                       text=True, timeout=60)  # a guard against the hang this test is about
    assert r.returncode == 0, r.stderr
    assert r.stdout.count("is not a regular file (a FIFO, socket or device): not opened") == 3, r.stdout


@pytest.mark.parametrize("impl", BOTH)
def test_a_closed_or_full_stdout_or_stderr_changes_no_exit_code(impl, binary, photos, tmp_path):
    cmd = " ".join(f"'{c}'" for c in _cmds(binary)[impl])
    good, missing = photos / "in" / "plain.tif", tmp_path / "missing.tif"
    for redirect, src, want in ((">&-", good, 0), ("> /dev/full", good, 0), ("2>&-", missing, 3),
                                ("2> /dev/full", missing, 3)):
        out = tmp_path / f"o{abs(hash(redirect))}"
        r = subprocess.run(f"exec {cmd} restore '{src}' -o '{out}' {redirect}", shell=True, capture_output=True,
                           text=True, timeout=300)
        assert r.returncode == want, (redirect, r.returncode, r.stdout, r.stderr)
        assert "Traceback" not in r.stderr and "AttributeError" not in r.stderr


RAW = os.path.join(os.path.dirname(__file__), "..", "..", "..", "shared", "data", "raw")


@pytest.mark.skipif(not os.path.isfile(os.path.join(RAW, "canon_eos_6d.dng")), reason="../shared/data is not beside the repo")
def test_a_raw_file_cut_short_is_unreadable_and_its_decoder_says_nothing_on_stderr(tmp_path):
    """canon_eos_6d.dng cut at 97% of its bytes: LibRaw fills the missing
    rows and used to return a photo with garbage at its bottom, exit 0,
    and libjpeg's "Premature end of JPEG file" among the JSON error lines.
    The whole file still restores, with no decoder note."""
    data = open(os.path.join(RAW, "canon_eos_6d.dng"), "rb").read()
    cut = tmp_path / "cut.dng"
    cut.write_bytes(data[:len(data) * 97 // 100])
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", str(cut), "-o", str(tmp_path / "o"), "-q",
                        "--json-errors", "--max-side", "400"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 3, r.stderr
    lines = r.stderr.splitlines()
    assert all(x.startswith("{") for x in lines), lines  # nothing but JSON objects
    assert "the raw data ends early" in json.loads(lines[0])["message"]
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", os.path.join(RAW, "canon_eos_6d.dng"), "-o",
                        str(tmp_path / "w"), "-q", "--max-side", "400"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0 and r.stderr == "", r.stderr
    side = json.loads((tmp_path / "w" / "canon_eos_6d.json").read_text())
    assert not any(n.startswith("raw decoder") for n in side["source"]["notes"])


def test_both_commands_call_a_file_of_no_bytes_empty(binary, tmp_path):
    (tmp_path / "e.jpg").write_bytes(b"")
    lines = {}
    for impl, cmd in _cmds(binary).items():
        r = subprocess.run([*cmd, "restore", str(tmp_path / "e.jpg"), "-o", str(tmp_path / impl), "--json-errors", "-q"],
                           capture_output=True, text=True, timeout=120)
        assert r.returncode == 3, r.stderr
        lines[impl] = [x for x in r.stderr.splitlines() if x.startswith("{")]
    assert lines["python"] == lines["rust"] and '"message": "empty file"' in lines["rust"][0], lines


@pytest.mark.parametrize("kw, want", [
    ({"water_types": {"3C": (1, 1)}}, "not a dict"),
    ({"water_types": "3C"}, "not a str"),
    ({"water": {"beta": [True, True, True]}}, "water must be a dict"),
    ({"water": {"beta": ["0.1", "0.2", "0.3"]}}, "water must be a dict"),
    ({"water": {"beta": [0.3, 0.2, 0.1], "nearest_type": ["x"]}}, "water's nearest_type must be a Jerlov type"),
    ({"distance": np.ones((60, 80), complex)}, "not complex128"),
])
def test_the_api_refuses_arguments_it_would_take_quietly_in_part(kw, want):
    import uwhl_rs
    from uwhl_rs import synth

    img, _ = synth.demo_input(60, 80)
    with pytest.raises(uwhl_rs.ParameterError, match=want):
        uwhl_rs.restore(img, **kw)


def test_negative_or_fractional_sizes_are_parameter_errors_not_overflow():
    import uwhl_rs

    for f in (lambda: uwhl_rs.floor_distance((-4, 64), 3, 60), lambda: uwhl_rs.floor_distance((2.5, 4), 3, 60),
              lambda: uwhl_rs.read_distance("x.npy", max_pixels=-5)):
        with pytest.raises(uwhl_rs.ParameterError, match="positive integer"):
            f()
