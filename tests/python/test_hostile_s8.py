"""Hostile inputs left from the passes of 2026-12-05: what stream mode says
about lines that cannot be names, CSV cells a spreadsheet would run, and
iFDO values the schema lets through that no survey has."""

import json
import subprocess
import sys

import pytest


def test_a_stream_line_that_cannot_be_a_name_is_identified(binary, tmp_path):
    """Its error object used to have ``"input": null``: a reader could not
    tell which of its lines failed. Now the line as it can be shown (one
    U+FFFD a byte, cut after 256 characters) and its number."""
    data = b"\xff\xfe.jpg\n\n" + b"a" * 70000 + b"\nmissing.jpg\n"
    r = subprocess.run([binary, "restore", "--stream", "-o", str(tmp_path / "o")], input=data,
                       capture_output=True, timeout=120)
    assert r.returncode == 0, r.stderr
    lines = [json.loads(x) for x in r.stdout.decode().splitlines()]
    assert len(lines) == 3, lines
    bad, long, missing = lines
    assert bad["error"] == "unreadable_input" and bad["input"] == "\ufffd\ufffd.jpg"
    assert "line 1 " in bad["message"] and "UTF-8" in bad["message"]
    # the empty line 2 is not a frame, but it is counted
    assert long["input"] == "a" * 256 + "..." and "line 3 " in long["message"]
    assert "65536" in long["message"]
    assert missing["input"] == "missing.jpg"


def test_results_csv_shows_formula_names_and_gives_them_back(tmp_path):
    """``uwhl evaluate`` wrote the manifest's names verbatim into
    results.csv: a photo called ``=HYPERLINK(...).png`` or a chart called
    ``-1+1`` was a formula to a spreadsheet. Its text cells now follow
    summary.csv's rule (a quote in front); the numbers do not."""
    import csv

    import uwhl_rs
    from uwhl_rs import synth
    from uwhl_rs.outdir import summary_cell

    name = '=HYPERLINK("x";"y").png'
    img, truth = synth.demo_input(60, 80, water_type="3C", seed=1)
    uwhl_rs.images.write_image(tmp_path / name, img, bits=8, encoding="linear")
    box = [[10, 30, 20, 40], [24, 30, 34, 40], [38, 30, 48, 40]]
    entry = {"path": name, "water_type": "3C", "charts": [{"name": "-1+1", "gray_patches": box}]}
    (tmp_path / "m.json").write_text(json.dumps({"images": [entry]}))
    out = tmp_path / "out"
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "evaluate", str(tmp_path / "m.json"), "-o", str(out),
                        "--water-type", "3C"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    rows = list(csv.DictReader(open(out / "results.csv", newline="", encoding="utf-8")))
    assert rows
    for row in rows:
        assert row["image"] == "'" + name and summary_cell(row["image"]) == name
        assert row["label"] == f"images[0] ({name})"  # begins with a letter: no quote
    charted = [row for row in rows if row["chart"]]
    assert charted and all(row["chart"] == "'-1+1" for row in charted)
    # numbers stay numbers, a negative one too
    assert all(float(row["psi_deg"]) >= 0 for row in charted)
    assert not any(row[k].startswith("'") for row in rows for k in ("psi_deg", "rho_B", "rho_R"))


def test_an_ifdo_takes_no_impossible_time_place_or_structure(binary, tmp_path):
    """Values the iFDO schema lets through but no survey has: a header
    time 9999-99-99, a header that carries image-set-items of its own, and
    a sidecar's GPS altitude of 1e308 m. The first two refuse the header
    (exit 2, naming the field); the last leaves that photo without a
    position, with a note, and the photos' mean is not taken."""
    import yaml
    from PIL import Image
    from test_ifdo import HEADER, POSITION, header_file, restore, uwhl, validator
    from test_metadata import _gps_exif, _scene

    src = tmp_path / "in"
    src.mkdir()
    for k in (1, 2):
        Image.fromarray(_scene(seed=k)).save(src / f"p{k}.jpg", quality=92, exif=_gps_exif())
    out = tmp_path / "out"
    assert restore("rust", binary, [src], out).returncode == 0
    for bad, field in (({"image-datetime": "9999-99-99"}, "image-datetime must be a time"),
                       ({"image-datetime": "2026-12-05 10:00:00", "image-datetime-format": "%d.%m.%Y"},
                        "image-datetime must be a time in the form '%d.%m.%Y'"),
                       ({"image-set-items": {"../../evil.jpg": {"image-uuid": "x"}}}, "image-set-items is a part"),
                       ({"image-altitude-meters": -1e308}, "image-altitude-meters must be between")):
        r = uwhl("ifdo", out, "--header", header_file(tmp_path, {**HEADER, **bad}))
        assert r.returncode == 2 and field in r.stderr, (bad, r.stderr)
        assert not (out / "ifdo.yaml").exists()
    # a real time in either of the default's forms is taken
    for t in ("2026-12-05 10:00:00", "2026-12-05 10:00:00.250"):
        r = uwhl("ifdo", out, "--header", header_file(tmp_path, {**HEADER, "image-datetime": t}))
        assert r.returncode == 0, r.stderr
    # a format that repeats a directive, gives no time, cannot be read back, or is too long: refused
    for fmt, why in (("%d.%m.%Y %H:%M:%S (%d)", "cannot be written and read back"), ("", "gives no time"),
                     ("constant", "gives no time"), ("%-d/%m/%Y", "cannot be written and read back"),
                     ("%Y" * 150, "is longer than 200")):
        r = uwhl("ifdo", out, "--header", header_file(tmp_path, {**HEADER, "image-datetime-format": fmt}))
        assert r.returncode == 2 and f"image-datetime-format {why}" in r.stderr, (fmt, r.stderr)
        assert "Traceback" not in r.stderr
    # a number of 400 digits is no altitude (it crashed float conversion)
    r = uwhl("ifdo", out, "--header", header_file(tmp_path, {**HEADER, "image-altitude-meters": 10 ** 400}))
    assert r.returncode == 2 and "image-altitude-meters must be a finite number" in r.stderr, r.stderr
    # %z: the times are UTC, and say so
    r = uwhl("ifdo", out, "--header", header_file(tmp_path, {**HEADER, "image-datetime-format": "%Y-%m-%dT%H:%M:%S%z"}))
    assert r.returncode == 0, r.stderr
    assert yaml.safe_load((out / "ifdo.yaml").read_text())["image-set-items"]["p1.jpg"]["image-datetime"] == \
        "2026-11-30T10:15:42+0000"
    # a header with a format of its own: the photos' times are written in it, as iFDO asks
    r = uwhl("ifdo", out, "--header", header_file(tmp_path, {**HEADER, "image-datetime-format": "%d.%m.%Y %H:%M"}))
    assert r.returncode == 0, r.stderr
    ifdo = yaml.safe_load((out / "ifdo.yaml").read_text())
    assert ifdo["image-set-header"]["image-datetime"] == "30.11.2026 10:15"
    assert ifdo["image-set-items"]["p1.jpg"]["image-datetime"] == "30.11.2026 10:15"
    side = out / "p2.json"
    doc = json.loads(side.read_text())
    doc["metadata"]["gps"]["altitude"] = 1e308
    side.write_text(json.dumps(doc))
    r = uwhl("ifdo", out, "--header", header_file(tmp_path, {**HEADER, **POSITION}))
    assert r.returncode == 0, r.stderr
    assert "p2.json: GPS image-altitude-meters must be between" in r.stdout + r.stderr
    ifdo = yaml.safe_load((out / "ifdo.yaml").read_text())
    validator().validate(ifdo)
    items = ifdo["image-set-items"]
    assert "image-altitude-meters" not in items["p2.jpg"] and "image-latitude" not in items["p2.jpg"]
    assert items["p1.jpg"]["image-altitude-meters"] == -18.5
    # the header's default place, not a mean over photos of which one has none
    assert ifdo["image-set-header"]["image-altitude-meters"] == POSITION["image-altitude-meters"]


def test_the_report_says_where_each_photos_colours_come_from(tmp_path):
    """Each cell says how much of its colour is the input's own balance
    (the sidecar's fallback_share): the whole of it, a share, or nothing
    under 5%. A value that is not a share in [0, 1] makes the sidecar
    malformed: that photo is named, not drawn with a made-up number."""
    from test_batch_report import _restore
    from test_report_browser import _chromium, _run

    browser = _chromium()
    r, out = _restore(tmp_path, n=4)
    assert r.returncode == 0, r.stderr
    for name, share in (("f000", 1.0), ("f001", 0.42), ("sub/f002", 0.01), ("sub/f003", "x")):
        side = out / f"{name}.json"
        doc = json.loads(side.read_text())
        doc["fallback_share"] = share
        side.write_text(json.dumps(doc))
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "report", str(out)], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    assert "f003.json" in r.stdout + r.stderr and "fallback_share" in r.stdout + r.stderr
    dom = _run(browser, "--dump-dom", (out / "report" / "index.html").resolve().as_uri())
    assert dom.returncode == 0, dom.stderr[-2000:]
    grid = dom.stdout[dom.stdout.index('id="all-grid"'):dom.stdout.index("<script")]
    cells = {c.split("</div></div>", 1)[0].split(". ", 1)[1].split("<br>", 1)[0]: c for c in grid.split('<div class="cell')[1:]}
    assert set(cells) == {"f000", "f001", "sub/f002"}, list(cells)
    assert "colours: the input's balance (the restoration gives the brightness)" in cells["f000"]
    assert "colours: 42% the input's balance" in cells["f001"]
    assert "colours:" not in cells["sub/f002"]
    # the page's summary counts the photos whose colour is all the balance's
    assert "3 photos restored, 0 flagged, 0 failed, 1 with the input's balance for colours" in dom.stdout


def test_report_of_a_folder_that_restore_did_not_write_writes_nothing(tmp_path):
    """``uwhl report`` on the photos' own folder (a slip for the output
    folder) wrote report/index.html of "0 photos" into it. A folder with
    no sidecar and no summary.csv is now refused, and left as it was."""
    from uwhl_rs import synth
    from uwhl_rs.images import write_image

    src = tmp_path / "photos"
    src.mkdir()
    img, _ = synth.demo_input(60, 80, seed=1)
    write_image(src / "a.png", img, encoding="linear")
    (src / "notes.json").write_text('{"not": "a sidecar"}')
    before = sorted(p.name for p in src.iterdir())
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "report", str(src)], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 3, (r.returncode, r.stderr)
    assert "not an output folder" in r.stderr and "Traceback" not in r.stderr
    assert sorted(p.name for p in src.iterdir()) == before


@pytest.mark.parametrize("slip", ["--output-dir", "--watertype", "--water"])
def test_both_commands_name_an_unknown_option_first(binary, tmp_path, slip):
    """A misspelt option is what a user needs to hear about: the Python
    command said "-o is required" for ``--output-dir`` and read ``--water``
    as an abbreviation, where the binary names the option. Both now say
    ``invalid option '...'`` and exit 2, and take no abbreviation."""
    from bothcmds import cmds

    for face, cmd in cmds(binary).items():
        r = subprocess.run([*cmd, "restore", str(tmp_path / "x.jpg"), slip, "3C"], capture_output=True, text=True,
                           timeout=60)
        assert r.returncode == 2, (face, r.stderr)
        assert f"invalid option '{slip}'" in r.stderr and "--help" in r.stderr, (face, r.stderr)
        assert len(r.stderr.strip().splitlines()) == 2, (face, r.stderr)


def test_an_output_folder_that_is_a_file_is_refused_before_any_input(binary, tmp_path):
    """``-o`` naming a file failed each input ("cannot claim output names
    ...: File exists") and then summary.csv. Both commands now say once
    that a folder is needed, exit 5 and read nothing."""
    from bothcmds import cmds
    from uwhl_rs import synth
    from uwhl_rs.images import write_image

    img, _ = synth.demo_input(40, 60, seed=2)
    write_image(tmp_path / "a.png", img, encoding="linear")
    target = tmp_path / "notdir"
    target.write_text("keep me")
    for face, cmd in cmds(binary).items():
        r = subprocess.run([*cmd, "restore", str(tmp_path / "a.png"), "-o", str(target)], capture_output=True,
                           text=True, timeout=120)
        assert r.returncode == 5, (face, r.stderr)
        assert r.stderr.strip().splitlines() == [
            f"{'uwhl' if face == 'python' else 'uwhl-rs'}: {target}: not a folder (a file is there): the outputs "
            "need a folder"], (face, r.stderr)
        assert target.read_text() == "keep me"
    r = subprocess.run([binary, "restore", "--stream", "-o", str(target)], input=f"{tmp_path / 'a.png'}\n",
                       capture_output=True, text=True, timeout=120)
    assert r.returncode == 5 and "not a folder" in r.stderr and r.stdout == ""


def test_evaluate_counts_the_entries_it_could_not_evaluate(tmp_path):
    """With every entry bad the last line said "0 of 0 images evaluated":
    the manifest's bad entries are images it lists too."""
    (tmp_path / "m.json").write_text(json.dumps({"images": [{"path": "missing.png"}, {"nopath": 1}]}))
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "evaluate", str(tmp_path / "m.json"), "-o",
                        str(tmp_path / "out")], capture_output=True, text=True, timeout=120)
    assert r.returncode == 3, r.stderr
    assert "0 of 2 images evaluated" in r.stdout, r.stdout


def test_an_earlier_runs_output_folder_inside_the_input_is_not_restored_again(binary, tmp_path):
    """Restoring into photos/out_1 and then photos/ into another folder took
    out_1's restored photo and its maps as photos (and failed on the flat
    confidence map). Both commands now leave such a folder out, with a note."""
    from bothcmds import cmds
    from uwhl_rs import synth
    from uwhl_rs.images import write_image

    src = tmp_path / "photos"
    src.mkdir()
    img, _ = synth.demo_input(40, 60, seed=3)
    write_image(src / "a.png", img, encoding="linear")
    r = subprocess.run([binary, "restore", str(src), "-o", str(src / "out_1"), "-q"], capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    assert (src / "out_1" / "a_t.png").exists()
    for face, cmd in cmds(binary).items():
        out = tmp_path / f"again_{face}"
        r = subprocess.run([*cmd, "restore", str(src), "-o", str(out)], capture_output=True, text=True, timeout=120)
        assert r.returncode == 0, (face, r.stderr)
        assert f"note: {src / 'out_1'}: an output folder of an earlier restore" in r.stderr, (face, r.stderr)
        assert sorted(p.name for p in out.iterdir() if p.suffix == ".json") == ["a.json"], face
        assert not (out / "out_1").exists(), face


def test_the_line_and_summary_say_when_the_colours_are_the_inputs_balance(binary, tmp_path):
    """A photo whose veil exceeds its light everywhere (a veiling light four
    times too red) takes all its colour from the input's balance: the
    progress line of both commands says so, and summary.csv carries the
    sidecar's veil_excess and fallback_share; a photo restored as usual
    says nothing more than its type."""
    import csv

    from bothcmds import cmds
    from uwhl_rs import synth
    from uwhl_rs.images import write_image

    src = tmp_path / "in"
    src.mkdir()
    img, _ = synth.demo_input(60, 80, water_type="II", seed=4)
    write_image(src / "a.png", img, encoding="linear")
    a = synth.default_veiling_light("II")
    wrong = ",".join(f"{v:.4f}" for v in (min(1.0, 4 * a[0]), a[1], a[2]))
    for face, cmd in cmds(binary).items():
        for tag, extra in (("wrong", ["--veiling-light", wrong]), ("plain", [])):
            out = tmp_path / f"{face}_{tag}"
            r = subprocess.run([*cmd, "restore", str(src), "-o", str(out), "--water-type", "II", *extra],
                               capture_output=True, text=True, timeout=120)
            assert r.returncode == 0, (face, r.stderr)
            side = json.loads((out / "a.json").read_text())
            row = next(csv.DictReader(open(out / "summary.csv", newline="")))
            assert float(row["fallback_share"]) == pytest.approx(side["fallback_share"], rel=1e-9)
            assert float(row["veil_excess"]) == pytest.approx(side["veil_excess"], rel=1e-9)
            said = "(water type II, colours from the input's balance, " in r.stdout
            assert said == (tag == "wrong"), (face, tag, side["fallback_share"], r.stdout)
            if tag == "wrong":
                assert side["fallback_share"] == 1.0


def test_a_rerun_with_other_options_says_so_when_it_skips(binary, tmp_path):
    """A rerun that skips an input (its sidecar exists) said only
    "skipped (x.json exists)", though it was asked for another water type:
    the outputs did not follow the options and nothing told. Both commands
    now name the options that differ; the machine's (--threads) do not
    count, and an unchanged rerun says nothing more."""
    from bothcmds import cmds
    from uwhl_rs import synth
    from uwhl_rs.images import write_image

    img, _ = synth.demo_input(40, 60, seed=6)
    write_image(tmp_path / "a.png", img, encoding="linear")
    for face, cmd in cmds(binary).items():
        out = tmp_path / f"out_{face}"
        run = lambda *extra: subprocess.run([*cmd, "restore", str(tmp_path / "a.png"), "-o", str(out), *extra],  # noqa: E731
                                            capture_output=True, text=True, timeout=120)
        assert run("-q").returncode == 0
        side = out / "a.json"
        for extra, said in ((["--threads", "1"], ""),
                            (["--water-type", "3C"], "; restored with another --water-type: --overwrite redoes it"),
                            (["--water-type", "3C", "--guided-radius", "5"],
                             "; restored with another --guided-radius, --water-type: --overwrite redoes it")):
            r = run(*extra)
            assert r.returncode == 0, (face, r.stderr)
            assert f"[1/1] {tmp_path / 'a.png'}: skipped ({side} exists{said})" in r.stdout, (face, extra, r.stdout)
    # stream mode: the skipped line's other_options, only when some differ
    out = tmp_path / "out_rust"
    for extra, other in ((["--threads", "1"], None), (["--water-type", "3C"], ["--water-type"])):
        r = subprocess.run([binary, "restore", "--stream", "-o", str(out), *extra], input=f"{tmp_path / 'a.png'}\n",
                           capture_output=True, text=True, timeout=120)
        line = json.loads(r.stdout)
        assert line["skipped"] == "sidecar exists" and line.get("other_options") == other, line
