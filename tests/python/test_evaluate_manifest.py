"""uwhl evaluate's manifest from a hostile or careless hand (issue 30):
what is not a manifest is one line naming it (exit 3, no traceback, no
hang), and what the docs promise of an entry's ``restore`` holds."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

import uwhl_rs
from uwhl_rs import evaluate as ev
from uwhl_rs import synth


def _evaluate(tmp_path, manifest, *args, timeout=120):
    """``uwhl evaluate MANIFEST`` in a subprocess (the timeout only guards a hang)."""
    return subprocess.run([sys.executable, "-m", "uwhl_rs", "evaluate", str(manifest), "-o", str(tmp_path / "out"),
                           *args], capture_output=True, text=True, timeout=timeout)


def _one_line_about(r, manifest, needle):
    assert r.returncode == 3, (r.returncode, r.stderr)
    assert "Traceback" not in r.stderr and "Error:" not in r.stderr, r.stderr
    lines = [x for x in r.stderr.splitlines() if x.strip()]
    assert len(lines) == 1, r.stderr
    assert lines[0].startswith(f"uwhl: {manifest}: ") and lines[0].count(str(manifest)) == 1, lines
    assert needle in lines[0], lines


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_a_fifo_manifest_is_refused_not_waited_on(tmp_path):
    fifo = tmp_path / "m.json"
    os.mkfifo(fifo)
    _one_line_about(_evaluate(tmp_path, fifo, timeout=60), fifo, "regular file")


@pytest.mark.skipif(not os.path.exists("/dev/zero"), reason="no /dev/zero")
def test_a_device_manifest_is_refused_not_read_to_the_end(tmp_path):
    _one_line_about(_evaluate(tmp_path, "/dev/zero", timeout=60), "/dev/zero", "regular file")


def test_a_manifest_over_the_size_limit_is_refused_unread(tmp_path):
    big = tmp_path / "m.json"
    with open(big, "wb") as f:  # sparse: costs no disk; far over any manifest of boxes
        f.truncate(64 << 20)
    _one_line_about(_evaluate(tmp_path, big, timeout=60), big, "over the limit")


@pytest.mark.parametrize("content, needle", [
    (b'{"images": [], "note": "caf\xe9"}', "not UTF-8"),
    (b"[" * 100_000 + b"]" * 100_000, "nested too deeply"),
    (b'{"images": [' + b"1" * 5000 + b"]}", "not a manifest"),  # more digits than Python turns into an int
    (b'{"images": [}', "not JSON"),
], ids=["latin-1", "deep", "long-int", "broken"])
def test_a_manifest_that_is_not_json_text_is_one_line(tmp_path, content, needle):
    m = tmp_path / "m.json"
    m.write_bytes(content)
    _one_line_about(_evaluate(tmp_path, m, timeout=60), m, needle)


def _scene(tmp_path, name="scene.png", h=60, w=80, water_type="3C", seed=1):
    img, _ = synth.demo_input(h, w, water_type=water_type, seed=seed)
    uwhl_rs.images.write_image(tmp_path / name, img, bits=8, encoding="linear")
    return {"path": name, "charts": [{"gray_patches": [[10, h - 20, 20, h - 10]]}]}


@pytest.mark.parametrize("field, value, needle", [
    ("charts", 5, "'charts' is a list"),
    ("charts", "chart", "'charts' is a list"),
    ("restore", {"water_types": "3C"}, "restore.water_types"),
    ("restore", {"water_types": [["x", "a", 1]]}, "restore.water_types[0]"),
    ("restore", {"method": "fastest"}, "restore.method"),
    ("restore", {"guided_radius": -3}, "guided_radius"),
], ids=["charts-int", "charts-str", "types-str", "types-bad-custom", "method", "radius"])
def test_a_malformed_entry_is_named_and_not_a_traceback(tmp_path, field, value, needle):
    e = _scene(tmp_path)
    e[field] = value
    (tmp_path / "m.json").write_text(json.dumps({"images": [e]}))
    entries, problems = ev.load_manifest(str(tmp_path / "m.json"))
    assert entries == [] and len(problems) == 1, problems
    assert problems[0].startswith("images[0] (scene.png): ") and needle in problems[0], problems


@pytest.mark.parametrize("depth, with_map, needle", [
    ({"fov": 70}, False, "'distance' map, which is missing"),
    ({"fov": "wide"}, True, "fov (the lens's"),
    ({"fov": 0}, True, "(0, 170]"),
    ({"fov": True}, True, "(0, 170]"),
    ({"fov": 70, "port": "round"}, True, "port is"),
    ({"fov": 70, "lens": 1}, True, "distance_depth is"),
    ([70], True, "distance_depth is"),
], ids=["no-map", "fov-str", "fov-0", "fov-bool", "port", "extra-key", "list"])
def test_a_malformed_distance_depth_is_named(tmp_path, depth, with_map, needle):
    e = _scene(tmp_path)
    if with_map:
        np.save(tmp_path / "d.npy", np.full((8, 8), 2.0, np.float32))
        e["distance"] = "d.npy"
    e["distance_depth"] = depth
    (tmp_path / "m.json").write_text(json.dumps({"images": [e]}))
    entries, problems = ev.load_manifest(str(tmp_path / "m.json"))
    assert entries == [] and len(problems) == 1, problems
    assert problems[0].startswith("images[0] (scene.png): distance_depth") and needle in problems[0], problems


def test_an_unknown_restore_water_type_is_a_bad_entry_exit_3(tmp_path):
    """docs/EVALUATE.md: an unknown water type in an entry is a bad entry,
    exit 3 (not 2, a bad command-line argument)."""
    e = _scene(tmp_path)
    e["restore"] = {"water_types": ["3C", "XI"]}
    (tmp_path / "m.json").write_text(json.dumps({"images": [e]}))
    r = _evaluate(tmp_path, tmp_path / "m.json")
    assert r.returncode == 3, r.stderr
    assert "images[0] (scene.png)" in r.stderr and "'XI'" in r.stderr and "Traceback" not in r.stderr


def test_a_restore_value_only_the_image_checks_is_a_bad_entry_exit_3(tmp_path):
    e = _scene(tmp_path)
    e["restore"] = {"guided_eps": -1.0, "water_types": ["3C"]}
    (tmp_path / "m.json").write_text(json.dumps({"images": [e]}))
    r = _evaluate(tmp_path, tmp_path / "m.json")
    assert r.returncode == 3, r.stderr
    assert "images[0] (scene.png)" in r.stderr and "guided_eps" in r.stderr


def test_custom_water_types_can_be_written_in_json(tmp_path):
    """restore() takes a custom type as a (name, beta_BR, beta_BG) tuple;
    JSON has no tuples, so the manifest takes a list or an object."""
    e = _scene(tmp_path)
    e["restore"] = {"water_types": ["3C", ["deep", 1.6, 1.3], {"name": "murky", "beta_br": 0.9, "beta_bg": 1.05}]}
    (tmp_path / "m.json").write_text(json.dumps({"images": [e]}))
    entries, problems = ev.load_manifest(str(tmp_path / "m.json"))
    assert not problems, problems
    r = ev.evaluate_entry(entries[0])
    assert set(r["types"]) == {"3C", "deep", "murky"}
    img, _ = uwhl_rs.images.read_image(tmp_path / "scene.png")
    want = uwhl_rs.restore(img, water_types=["3C", ("deep", 1.6, 1.3), ("murky", 0.9, 1.05)])
    assert r["water_type"] == want.water_type


def test_an_entrys_restore_method_is_the_method_evaluated(tmp_path):
    """docs/EVALUATE.md: an entry's ``restore`` keywords override the
    command's options, ``method`` too (it used to be dropped silently)."""
    e = _scene(tmp_path)
    e["restore"] = {"method": "paper", "water_types": ["3C", "II", "7C"]}
    (tmp_path / "m.json").write_text(json.dumps({"images": [e]}))
    entries, problems = ev.load_manifest(str(tmp_path / "m.json"))
    assert not problems, problems
    r = ev.evaluate_entry(entries[0], method="revised")
    img, _ = uwhl_rs.images.read_image(tmp_path / "scene.png")
    paper = uwhl_rs.restore(img, method="paper", water_types=["3C", "II", "7C"])
    revised = uwhl_rs.restore(img, method="revised", water_types=["3C", "II", "7C"])
    assert not np.array_equal(paper.image, revised.image)  # else the test could not tell them apart
    assert r["method"] == "paper"
    assert r["veiling_light"] == [float(v) for v in paper.veiling_light]
    np.testing.assert_array_equal(r["_images"]["paper"], paper.image)
    # and the command's progress line reports that method's numbers
    out = _evaluate(tmp_path, tmp_path / "m.json")
    assert out.returncode == 0, out.stderr
    assert json.load(open(tmp_path / "out" / "results.json"))["images"][0]["method"] == "paper"


def test_an_unknown_top_level_key_is_an_error_and_says_so(tmp_path):
    """The line and the exit code agree: an unknown key is refused (exit
    3), as an entry's unknown key is; the line does not call it ignored."""
    (tmp_path / "m.json").write_text(json.dumps({"images": [], "imges": []}))
    r = _evaluate(tmp_path, tmp_path / "m.json", timeout=60)
    assert r.returncode == 3, r.stderr
    assert "'imges'" in r.stderr and "ignored" not in r.stderr, r.stderr


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
@pytest.mark.parametrize("field", ["path", "distance", "water_mask"])
def test_an_entry_naming_a_fifo_says_so_and_the_others_are_evaluated(tmp_path, field):
    good = _scene(tmp_path)
    bad = _scene(tmp_path, "other.png", seed=2)
    os.mkfifo(tmp_path / "pipe.png")
    bad[field] = "pipe.png"
    (tmp_path / "m.json").write_text(json.dumps({"images": [good, bad]}))
    entries, problems = ev.load_manifest(str(tmp_path / "m.json"))
    assert [e.path for e in entries] == [str(tmp_path / "scene.png")], problems
    assert len(problems) == 1 and "pipe.png is a FIFO, not a regular file" in problems[0], problems


def test_a_box_outside_the_image_names_its_entry_once(tmp_path):
    e = _scene(tmp_path)
    e["charts"] = [{"gray_patches": [[0, 0, 10**12, 10**12]]}]
    (tmp_path / "m.json").write_text(json.dumps({"images": [e]}))
    r = _evaluate(tmp_path, tmp_path / "m.json")
    assert r.returncode == 3 and "Traceback" not in r.stderr, r.stderr
    line = [x for x in r.stderr.splitlines() if "outside" in x]
    assert len(line) == 1 and line[0].count("images[0] (scene.png)") == 1, r.stderr


@pytest.mark.parametrize("key, value", [("max_memory", 100_000_000_000), ("threads", 1024)])
def test_an_entry_cannot_set_the_machines_limits(tmp_path, key, value):
    """--max-memory and --threads are the user's, for every entry: a
    manifest that lifts the memory limit or asks for 1024 threads on a
    small machine is a bad entry, named, not obeyed."""
    e = _scene(tmp_path)
    e["restore"] = {key: value}
    (tmp_path / "m.json").write_text(json.dumps({"images": [e]}))
    entries, problems = ev.load_manifest(str(tmp_path / "m.json"))
    assert entries == [] and len(problems) == 1, problems
    assert f"restore.{key} is the machine's" in problems[0] and f"--{key.replace('_', '-')}" in problems[0]


def test_a_long_value_is_quoted_short(tmp_path):
    """A message quotes a value of the manifest cut short: three values of
    5 MB once made 15 MB of stderr."""
    e = _scene(tmp_path)
    e["water_type"] = "x" * 100_000
    e["charts"] = [{"gray_patches": [[int("9" * 4000), 0, 1, 1]]}]
    (tmp_path / "m.json").write_text(json.dumps({"images": [e, {**_scene(tmp_path), "charts": ["c" * 100_000]}]}))
    entries, problems = ev.load_manifest(str(tmp_path / "m.json"))
    assert len(problems) == 2 and all(len(p) < 600 for p in problems), [len(p) for p in problems]


def test_a_truth_far_larger_than_its_photo_is_not_read(tmp_path):
    """A small compressed file can hold a huge truth: one with more than 64
    times the photo's pixels (and 4 Mpx) is refused from its header."""
    tifffile = pytest.importorskip("tifffile")
    e = _scene(tmp_path)
    tifffile.imwrite(tmp_path / "t.tif", np.zeros((2100, 2100), np.float32), compression="zlib")
    assert (tmp_path / "t.tif").stat().st_size < 200_000
    e["truth"] = "t.tif"
    (tmp_path / "m.json").write_text(json.dumps({"images": [e]}))
    r = _evaluate(tmp_path, tmp_path / "m.json")
    assert r.returncode == 3 and "Traceback" not in r.stderr, r.stderr
    assert "t.tif: the truth is 4410000 pixels, more than 64 times the photo's 80x60" in r.stderr, r.stderr


def test_the_memory_of_an_evaluation_is_planned_against_max_memory(tmp_path):
    """Every profile's and type's restoration is kept to be scored: an
    image whose evaluation cannot fit --max-memory is refused before its
    first restore (exit 4, the entry named), the others evaluated."""
    big = _scene(tmp_path, "big.png", h=1000, w=1500)
    small = _scene(tmp_path, "small.png")
    (tmp_path / "m.json").write_text(json.dumps({"images": [big, small]}))
    # two profiles and the ten types kept: 48 + 12 x 36 bytes a pixel
    need = 1000 * 1500 * (ev.EVALUATE_BASE_PER_PIXEL + 12 * ev.EVALUATE_PER_RESTORATION)
    r = _evaluate(tmp_path, tmp_path / "m.json", "--max-memory", str(need - 1))
    assert r.returncode == 4 and "Traceback" not in r.stderr, r.stderr
    assert "images[0] (big.png): over the memory budget: evaluating 1500x1000 pixels keeps the restorations" in r.stderr
    assert f"about {need} bytes, more than the {need - 1} of --max-memory" in r.stderr
    doc = json.loads((tmp_path / "out" / "results.json").read_text())
    assert [i["image"] for i in doc["images"]] == ["images[1] (small.png)"]
    # told one type, it keeps three restorations (two profiles, the type): it fits
    r = _evaluate(tmp_path, tmp_path / "m.json", "--max-memory", str(need - 1), "--water-type", "3C")
    assert r.returncode == 0, r.stderr
