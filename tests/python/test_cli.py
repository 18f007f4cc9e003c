"""The ``uwhl`` command end to end, through a real subprocess: outputs exist
and decode, the sidecar is complete, bad files fail alone with one clear
line, interrupted runs resume, and the help is complete."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys

import numpy as np
import pytest

from datapaths import IMAGES_DIR, RAW_DIR

import uwhl_rs
from uwhl_rs import images, synth

SIDECAR_KEYS = {
    "input", "outputs", "uwhl_version", "implementation", "source", "water_type", "scores",
    "excluded", "veiling_light", "vl_pixels", "vl_fraction", "flags", "veil_excess", "fallback_share", "guided_radius",
    "guided_subsample", "beta_ratios", "parameters", "seconds",
}


def _env() -> dict:
    """The environment of the tests' own interpreter: the package the tests
    import (installed, or the source tree when it holds a built extension)."""
    env = dict(os.environ)
    pkg = os.path.dirname(os.path.dirname(os.path.abspath(uwhl_rs.__file__)))
    env["PYTHONPATH"] = os.pathsep.join(p for p in [pkg, env.get("PYTHONPATH", "")] if p)
    return env


def uwhl(*args, timeout=600) -> subprocess.CompletedProcess:
    """Run the command as users do (``python -m uwhl_rs`` runs the console script's code)."""
    return subprocess.run([sys.executable, "-m", "uwhl_rs", *map(str, args)], capture_output=True, text=True,
                          timeout=timeout, env=_env())


@pytest.fixture(scope="module")
def scenes(tmp_path_factory):
    """Three small rendered underwater scenes saved as 8-bit sRGB files."""
    d = tmp_path_factory.mktemp("scenes")
    for k, wt in enumerate(["II", "3C", "7C"]):
        img, _ = synth.demo_input(96, 128, water_type=wt, seed=k)
        images.write_image(d / f"scene_{wt}.png", img, encoding="linear")
    return d


def _check_outputs(out, name, fmt="jpg"):
    ext = {"jpg": ".jpg", "tiff": ".tif", "png": ".png"}[fmt]
    side = json.loads((out / f"{name}.json").read_text())
    assert SIDECAR_KEYS <= set(side), SIDECAR_KEYS - set(side)
    assert side["water_type"] in side["scores"] and len(side["scores"]) == 10
    assert set(side["excluded"]) <= set(side["scores"])
    assert all(0 < v <= 1 for v in side["veiling_light"])
    assert side["implementation"] == "python" and side["uwhl_version"] == uwhl_rs.__version__
    assert {"preprocess", "format", "guided_eps", "guided_subsample", "sphere_points", "max_side"} <= set(side["parameters"])
    assert side["seconds"]["total"] >= side["seconds"]["restore"] > 0
    img, meta = images.read_image(out / f"{name}{ext}")
    h, w = side["source"]["processed_height"], side["source"]["processed_width"]
    assert img.shape == (h, w, 3)
    t16 = images._core._decode_png((out / f"{name}_t.png").read_bytes(), 10**9)
    assert t16.dtype == np.uint16 and t16.shape == (h, w, 3)
    tc, _ = images.read_image(out / f"{name}_t_color.png")
    assert tc.shape == (h, w, 3)
    for role, fname in side["outputs"].items():
        assert (out / fname).is_file(), role
    return side


def test_restore_writes_every_output_and_a_complete_sidecar(scenes, tmp_path):
    r = uwhl("restore", scenes, "-o", tmp_path)
    assert r.returncode == 0, r.stderr
    for wt in ["II", "3C", "7C"]:
        side = _check_outputs(tmp_path, f"scene_{wt}")
        assert side["source"]["kind"] == "srgb" and side["source"]["bits"] == 8
    assert "3 done, 0 skipped, 0 failed" in r.stdout
    assert not [f for f in os.listdir(tmp_path) if f.startswith(".")]  # no temporaries


def test_outputs_equal_the_python_api(scenes, tmp_path):
    """The command's files hold exactly what restore() returns."""
    r = uwhl("restore", scenes / "scene_3C.png", "-o", tmp_path, "--format", "tiff")
    assert r.returncode == 0, r.stderr
    img, _ = images.read_image(scenes / "scene_3C.png")
    res = uwhl_rs.restore(img)
    side = json.loads((tmp_path / "scene_3C.json").read_text())
    assert side["water_type"] == res.water_type
    assert side["scores"] == pytest.approx(res.scores, rel=1e-12)
    import tifffile

    tif = tifffile.imread(tmp_path / "scene_3C.tif")
    assert tif.dtype == np.uint16
    # 16-bit sRGB codes of the restored image: floor(srgb(v) * 65535 + 0.5)
    want = np.floor(images.linear_to_srgb(res.image) * 65535 + 0.5)
    assert np.array_equal(tif, want)
    t16 = images._core._decode_png((tmp_path / "scene_3C_t.png").read_bytes(), 10**9)[..., 0]
    assert np.array_equal(t16, np.floor(np.clip(res.transmission, 0, 1).astype(np.float64) * 65535 + 0.5))


def test_bad_files_fail_alone_with_one_clear_line(scenes, tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    good = (scenes / "scene_II.png").read_bytes()
    (src / "a_good.png").write_bytes(good)
    img = (np.random.default_rng(0).random((80, 80, 3)) * 255).astype(np.uint8)
    images.write_image(src / "b_full.jpg", img)
    data = (src / "b_full.jpg").read_bytes()
    (src / "b_full.jpg").unlink()
    (src / "c_truncated.jpg").write_bytes(data[: len(data) // 2])
    (src / "d_random.NEF").write_bytes(np.random.default_rng(1).bytes(4096))
    (src / "e_good.png").write_bytes(good)
    out = tmp_path / "out"
    r = uwhl("restore", src, "-o", out)
    assert r.returncode == 3  # unreadable input (docs/CLI.md)
    lines = [ln for ln in r.stderr.splitlines() if ln.startswith("uwhl: ") and "input(s) failed" not in ln]
    assert len(lines) == 2, r.stderr
    assert any("c_truncated.jpg" in ln and "truncated" in ln.lower() for ln in lines)
    assert any("d_random.NEF" in ln and "LibRaw" in ln for ln in lines)
    assert "2 done, 0 skipped, 2 failed" in r.stdout
    # progress lines on stdout, errors on stderr, as uwhl-rs writes them
    assert [os.path.basename(ln.split(" ")[1]) for ln in r.stdout.splitlines() if ln.startswith("[")] == \
        ["a_good.png", "e_good.png"], r.stdout
    assert not any(ln.startswith("[") for ln in r.stderr.splitlines()), r.stderr
    # one input is written while the next is restored: the lines, on both
    # streams read as one, stay in input order
    both = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", str(src), "-o", str(tmp_path / "again")],
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, timeout=600, env=_env()).stdout
    order = [n for ln in both.splitlines() for n in ("a_good", "c_truncated", "d_random", "e_good") if n in ln]
    assert order == ["a_good", "c_truncated", "d_random", "e_good"], both
    assert [ln[:5] for ln in both.splitlines() if ln.startswith("[")] == ["[1/4]", "[4/4]"], both
    names = sorted(os.listdir(out))
    assert not [n for n in names if n.startswith(("c_truncated", "d_random", "."))], names  # nothing partial
    assert {"a_good.json", "e_good.json"} <= set(names)


def test_staged_restore_writes_nothing_until_asked(scenes, tmp_path):
    # the command's --jobs 1 loop restores one input while writing the previous
    from uwhl_rs import files

    out = tmp_path / "out"
    write = files.restore_staged(scenes / "scene_3C.png", out, format="png")
    # only the claim of the name (docs/OUTPUTS.md) is there until the outputs are written
    assert [p.name[:12] for p in out.iterdir()] == [".uwhl-claim-"]
    r = write()
    assert sorted(os.listdir(out)) == ["scene_3C.json", "scene_3C.png", "scene_3C_confidence.png", "scene_3C_t.png",
                                       "scene_3C_t_color.png"]
    want = uwhl_rs.restore_file(scenes / "scene_3C.png", tmp_path / "again", format="png")
    assert np.array_equal(r.restoration.image, want.restoration.image)
    with pytest.raises(Exception, match="truncated|decode"):
        (tmp_path / "cut.png").write_bytes((scenes / "scene_3C.png").read_bytes()[:300])
        files.restore_staged(tmp_path / "cut.png", out)


def test_something_foreign_at_the_sidecars_name_is_kept(scenes, tmp_path):
    # a folder where the sidecar would go is not this input's: kept, even
    # with --overwrite, and the outputs go under the next free name
    (tmp_path / "scene_II.json").mkdir()
    r = uwhl("restore", scenes / "scene_II.png", "-o", tmp_path, "--overwrite")
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "scene_II.json").is_dir()
    assert sorted(os.listdir(tmp_path)) == ["scene_II.json", "scene_II_2.jpg", "scene_II_2.json",
                                            "scene_II_2_confidence.png", "scene_II_2_t.png", "scene_II_2_t_color.png", "summary.csv"]


def test_options_reach_restore(scenes, tmp_path):
    mask = np.ones((96, 128), np.uint8) * 255
    mask[60:80, 10:40] = 0  # a "chart" to ignore
    images.write_image(tmp_path / "mask.png", mask)
    r = uwhl("restore", scenes / "scene_3C.png", "-o", tmp_path / "o", "--water-type", "II,3C", "--water-type", "x:1.2:1.1",
             "--veiling-light", "0.05,0.3,0.4", "--mask", tmp_path / "mask.png", "--guided-radius", "9",
             "--guided-eps", "0.01", "--sphere-points", "300", "--format", "png", "--bits", "16",
             "--max-side", "64", "--contact-sheet", "--jobs", "2", "--guided-subsample", "2")
    assert r.returncode == 0, r.stderr
    side = json.loads((tmp_path / "o" / "scene_3C.json").read_text())
    assert list(side["scores"]) == ["II", "3C", "x"]
    assert side["veiling_light"] == pytest.approx([0.05, 0.3, 0.4], abs=1e-7)
    assert side["guided_radius"] == 9 and side["guided_subsample"] == 2
    p = side["parameters"]
    assert p["guided_subsample"] == 2
    assert p["guided_eps"] == 0.01 and p["sphere_points"] == 300 and p["max_side"] == 64 and p["bits"] == 16
    assert p["mask"].endswith("mask.png")
    # 128 wide, max side 64: blocks of 2
    assert (side["source"]["processed_height"], side["source"]["processed_width"]) == (48, 64)
    assert (side["source"]["height"], side["source"]["width"]) == (96, 128)
    img, meta = images.read_image(tmp_path / "o" / "scene_3C.png")
    assert meta.bits == 16 and img.shape == (48, 64, 3)
    sheet, _ = images.read_image(tmp_path / "o" / "scene_3C_sheet.png")
    assert sheet.shape[1] > 4 * 64  # four columns of cells


@pytest.mark.parametrize(
    "args,needle",
    [
        (["--water-type", "XX"], "unknown"),
        (["--veiling-light", "0.1,0.2"], "R,G,B"),
        (["--veiling-light", "0,0.2,0.3"], "(0, 1]"),
        (["--max-side", "0"], ">= 4"),
        (["--max-side", "3"], ">= 4"),
        (["--quality", "0"], "1..100"),
        (["--quality", "101"], "1..100"),
        (["--quality", "-5"], "1..100"),
        (["--threads", "0"], "1..1024"),
        (["--bits", "12"], "one of 8, 16"),
        (["--format", "bmp"], "one of jpg, png, tiff"),
        (["--bits", "16"], "--bits 16 needs"),
        (["--mask", "/nonexistent/m.png"], "no such file"),
        (["--max-memory", "lots"], "not a byte count"),
        (["--guided-subsample", "fast"], "--guided-subsample"),
        (["--guided-subsample", "-1"], "--guided-subsample"),
        (["--guided-subsample", "1.5"], "--guided-subsample"),
        (["--reuse-estimates", "0"], "--reuse-estimates"),
        (["--reuse-estimates", "2", "--jobs", "2"], "needs --jobs 1"),
        (["--reuse-water-mask"], "needs --reuse-estimates"),
    ],
)
def test_bad_arguments_exit_2_with_a_message(scenes, tmp_path, args, needle):
    r = uwhl("restore", scenes / "scene_II.png", "-o", tmp_path, *args)
    assert r.returncode == 2 and needle in r.stderr, r.stderr
    assert not any(tmp_path.iterdir())


def test_reuse_estimates_restores_a_folder_as_a_sequence(tmp_path):
    """--reuse-estimates 2 on four frames of one rendered scene (different
    noise): frames 0 and 2 (in name order) choose the type and estimate A,
    1 and 3 reuse the previous estimate; every file equals the Python
    Sequence's result, and the reused frames equal restore() given the
    estimates."""
    d = tmp_path / "frames"
    d.mkdir()
    sc = synth.scene(80, 112, kind="open_water", seed=4)
    br, bg = uwhl_rs.WATER_TYPES["5C"]
    for k in range(4):
        img = synth.render(sc.clean, sc.distance, (br, bg), noise=0.004, seed=k)
        images.write_image(d / f"frame_{k:03d}.png", img, encoding="linear")
    r = uwhl("restore", d, "-o", tmp_path / "out", "--reuse-estimates", "2", "--format", "tiff",
             "--guided-subsample", "auto")
    assert r.returncode == 0, r.stderr
    sides = [json.loads((tmp_path / "out" / f"frame_{k:03d}.json").read_text()) for k in range(4)]
    assert [s["reused_estimates"] for s in sides] == [False, True, False, True]
    assert [len(s["scores"]) for s in sides] == [10, 1, 10, 1]
    assert sides[1]["water_type"] == sides[0]["water_type"] and sides[1]["veiling_light"] == sides[0]["veiling_light"]
    assert "estimates_reused" in sides[1]["flags"] and "estimates_reused" not in sides[2]["flags"]
    import tifffile

    seq = uwhl_rs.Sequence(refresh_every=2, guided_subsample="auto")
    for k, side in enumerate(sides):
        img, _ = images.read_image(d / f"frame_{k:03d}.png")
        res = seq.restore(img)
        assert side["water_type"] == res.water_type and side["scores"] == pytest.approx(res.scores, rel=1e-12)
        tif = tifffile.imread(tmp_path / "out" / f"frame_{k:03d}.tif")
        assert np.array_equal(tif, np.floor(images.linear_to_srgb(res.image) * 65535 + 0.5))
        if side["reused_estimates"]:
            want = uwhl_rs.restore(img, water_types=[res.water_type], veiling_light=res.veiling_light,
                                   guided_subsample="auto")
            assert np.array_equal(want.image, res.image)


def test_reuse_water_mask_keeps_the_first_region(scenes, tmp_path):
    """--reuse-estimates 5 --reuse-water-mask: the second input (another
    scene, in name order) is restored with the first one's water type, A and
    water region, exactly as the Python Sequence does."""
    r = uwhl("restore", scenes / "scene_3C.png", scenes / "scene_7C.png", "-o", tmp_path, "--reuse-estimates", "5",
             "--reuse-water-mask", "--format", "tiff")
    assert r.returncode == 0, r.stderr
    first, second = (json.loads((tmp_path / f"scene_{t}.json").read_text()) for t in ("3C", "7C"))
    assert second["reused_estimates"] and second["vl_pixels"] == first["vl_pixels"]
    seq = uwhl_rs.Sequence(refresh_every=5, reuse_water_mask=True)
    a, _ = images.read_image(scenes / "scene_3C.png")
    b, _ = images.read_image(scenes / "scene_7C.png")
    ra = seq.restore(a)
    rb = seq.restore(b)
    assert np.array_equal(rb.veiling_mask, ra.veiling_mask)
    import tifffile

    tif = tifffile.imread(tmp_path / "scene_7C.tif")
    assert np.array_equal(tif, np.floor(images.linear_to_srgb(rb.image) * 65535 + 0.5))


def test_guided_subsample_in_the_sidecar(scenes, tmp_path):
    """--guided-subsample auto is recorded as 0 (asked for) and the factor
    used, max(1, 24 // 32) = 1 at 96x128, and gives restore(guided_subsample=0);
    the default records 1 and 1; a factor larger than the image fails that
    input (exit 2, a parameter error) with the parameter named."""
    r = uwhl("restore", scenes / "scene_II.png", "-o", tmp_path / "a", "--guided-subsample", "auto",
             "--water-type", "II,3C", "--format", "png")
    assert r.returncode == 0, r.stderr
    side = json.loads((tmp_path / "a" / "scene_II.json").read_text())
    assert side["parameters"]["guided_subsample"] == 0 and side["guided_subsample"] == 1
    img, _ = images.read_image(scenes / "scene_II.png")
    res = uwhl_rs.restore(img, water_types=["II", "3C"], guided_subsample=0)
    assert side["water_type"] == res.water_type and side["scores"] == pytest.approx(res.scores, rel=1e-12)
    r = uwhl("restore", scenes / "scene_II.png", "-o", tmp_path / "b", "--guided-subsample", "500", "-q")
    assert r.returncode == 2 and "guided_subsample" in r.stderr, r.stderr  # a parameter error
    assert not (tmp_path / "b" / "scene_II.json").exists()


def test_memory_budget_and_missing_inputs_are_reported(scenes, tmp_path):
    r = uwhl("restore", scenes / "scene_II.png", tmp_path / "nope.jpg", str(tmp_path / "*.tif"), "-o", tmp_path / "o",
             "--max-memory", "100K")
    assert r.returncode == 4  # over budget outranks the missing inputs (3)
    assert "nope.jpg: no such file" in r.stderr and "matches no image file" in r.stderr
    assert "over --max-memory 102400" in r.stderr  # refused from the header, before decoding


def test_glob_and_name_collisions(scenes, tmp_path):
    src = tmp_path / "in"
    (src / "sub").mkdir(parents=True)
    img, _ = synth.demo_input(64, 80, water_type="II", seed=3)
    images.write_image(src / "x.png", img, encoding="linear")
    images.write_image(src / "x.jpg", img, encoding="linear")
    images.write_image(src / "sub" / "x.png", img, encoding="linear")
    r = uwhl("restore", str(src / "*.*"), src / "sub", "-o", tmp_path / "o")
    assert r.returncode == 0, r.stderr
    names = set(os.listdir(tmp_path / "o"))
    # the folder argument's own files land in the root too: three x's
    assert {"x_png.json", "x_jpg.json", "x_png_2.json"} <= names
    r = uwhl("restore", src, "-o", tmp_path / "o2")
    assert (tmp_path / "o2" / "sub" / "x.json").is_file()  # folder inputs mirror sub-folders


def test_a_recursive_glob_does_not_follow_links_to_folders(tmp_path):
    """``**`` goes down folders, not links to them, as a folder walk does:
    two links back to a parent once made the search grow without end (the
    run hung), and a link out of the tree took files the walk does not.
    A hidden name is matched only when the pattern spells its dot."""
    from uwhl_rs.inputs import _glob

    (tmp_path / "in" / "sub").mkdir(parents=True)
    (tmp_path / "outside").mkdir()
    for p in ("in/a.jpg", "in/sub/b.jpg", "outside/c.jpg", "in/.h.jpg"):
        (tmp_path / p).write_bytes(b"")
    os.symlink("..", tmp_path / "in" / "sub" / "up")
    os.symlink("..", tmp_path / "in" / "sub" / "up2")
    os.symlink("../outside", tmp_path / "in" / "out")
    root = str(tmp_path)
    assert sorted(_glob(f"{root}/in/**/*.jpg")) == [f"{root}/in/a.jpg", f"{root}/in/sub/b.jpg"]
    assert _glob(f"{root}/in/.*.jpg") == [f"{root}/in/.h.jpg"]
    assert sorted(_glob(f"{root}/i?/*.jpg")) == [f"{root}/in/a.jpg"]
    # a trailing ** takes the files too, as glob.glob's does; the pattern's own ./ is kept
    assert [p for p in sorted(_glob(f"{root}/in/**")) if p.endswith(".jpg")] == [f"{root}/in/a.jpg", f"{root}/in/sub/b.jpg"]
    assert _glob(f"{root}/in/./*.jpg") == [f"{root}/in/./a.jpg"]
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", "in/**/*.jpg", "-o", "o", "-q"], cwd=tmp_path,
                       capture_output=True, text=True, timeout=60)
    assert "Traceback" not in r.stderr and "outside" not in r.stderr and "c.jpg" not in r.stderr, r.stderr


def test_help_and_version():
    r = uwhl("--help")
    assert r.returncode == 0 and "restore" in r.stdout and "demo" in r.stdout
    r = uwhl("restore", "--help")
    assert r.returncode == 0
    for opt in ["--water-type", "--veiling-light", "--mask", "--water-mask", "--guided-radius", "--guided-eps",
                "--guided-subsample", "--sphere-points", "--selection", "--max-side", "--jobs", "--overwrite", "--contact-sheet", "--format", "--threads",
                "--max-memory", "--preprocess", "--half-size", "exit codes"]:
        assert opt in r.stdout, opt
    assert uwhl("demo", "--help").returncode == 0
    r = uwhl("--version")
    assert r.returncode == 0 and uwhl_rs.__version__ in r.stdout


def test_demo_reports_true_and_estimated_type(tmp_path):
    r = uwhl("demo", "-o", tmp_path, "--size", "120x160")
    assert r.returncode == 0, r.stderr
    assert "true water type:      III" in r.stdout and "estimated water type:" in r.stdout
    for f in ["input.png", "restored.png", "transmission.png", "clean_truth.png"]:
        img, _ = images.read_image(tmp_path / f)
        assert img.shape == (120, 160, 3)


# --------------------------------------------------- the shared real data


@pytest.mark.skipif(not RAW_DIR.is_dir(), reason=f"{RAW_DIR} absent")
def test_shared_raw_files_end_to_end(tmp_path):
    r = uwhl("restore", RAW_DIR, "-o", tmp_path, "--max-side", "600", "--jobs", "2")
    assert r.returncode == 0, r.stderr
    for f in sorted(RAW_DIR.iterdir()):
        name = f.stem
        side = _check_outputs(tmp_path, name)
        src = side["source"]
        assert src["kind"] == "raw" and src["orientation"] == 1
        img, meta = images.read_image(f)
        assert (src["height"], src["width"]) == img.shape[:2]
        assert max(src["processed_height"], src["processed_width"]) <= 600


@pytest.mark.skipif(not IMAGES_DIR.is_dir(), reason=f"{IMAGES_DIR} absent")
def test_shared_images_end_to_end(tmp_path):
    r = uwhl("restore", IMAGES_DIR, "-o", tmp_path, "--max-side", "384", "--jobs", "2")
    assert r.returncode == 0, r.stderr
    inputs = sorted(p for p in IMAGES_DIR.iterdir() if p.suffix.lower() in (".jpg", ".png"))
    assert len(inputs) >= 20
    for p in inputs:
        side = _check_outputs(tmp_path, p.stem)
        assert side["source"]["kind"] == "srgb"
    assert f"{len(inputs)} done, 0 skipped, 0 failed" in r.stdout


def test_the_binary_says_what_its_demo_takes_and_that_it_does_not_expand_patterns(binary, tmp_path):
    r = subprocess.run([binary, "demo", "--help"], capture_output=True, text=True, timeout=60)
    assert r.returncode == 0 and r.stdout.startswith("usage: uwhl-rs demo") and "--water-type" in r.stdout
    # a quoted pattern reaches the binary as it is: it names what to do
    r = subprocess.run([binary, str(tmp_path / "nothere" / "*.jpg"), "-o", str(tmp_path / "out")],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 3 and "uwhl-rs does not expand patterns" in r.stderr, r.stderr


def test_a_rows_seconds_are_its_sidecars_in_both_commands(scenes, binary, tmp_path):
    src = tmp_path / "in"
    src.mkdir()
    (src / "a.png").write_bytes((scenes / "scene_II.png").read_bytes())
    for face, cmd in (("py", [sys.executable, "-m", "uwhl_rs", "restore"]), ("rs", [binary])):
        out = tmp_path / face
        assert subprocess.run([*cmd, str(src), "-o", str(out), "-q"], capture_output=True, timeout=300).returncode == 0
        with open(out / "summary.csv", newline="", encoding="utf-8") as f:
            (row,) = list(csv.DictReader(f))
        side = json.loads((out / "a.json").read_text())
        assert float(row["seconds"]) == side["seconds"]["total"], face


def test_an_option_of_the_other_command_is_a_usage_error_in_both_commands_words(binary, tmp_path):
    r = uwhl("restore", tmp_path / "x.png", "--linear", "-o", tmp_path / "out")
    assert r.returncode == 2
    assert r.stderr.splitlines() == ["uwhl restore: error: --linear is an option of the binary only: run "
                                     "'uwhl-rs restore' (docs/CLI.md)", "Try 'uwhl restore --help'."]
    r = subprocess.run([binary, str(tmp_path / "x.png"), "--ifdo", "h.yaml", "-o", str(tmp_path / "out")],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2 and r.stderr.splitlines()[-1] == "Try 'uwhl-rs --help'."
    # with --json-errors, one JSON object, as every other usage error
    r = uwhl("restore", "--json-errors", "--linear", tmp_path / "x.png", "-o", tmp_path / "out")
    got = json.loads(r.stderr)
    assert r.returncode == 2 and got["error"] == "bad_arguments" and "--linear" in got["message"], r.stderr
