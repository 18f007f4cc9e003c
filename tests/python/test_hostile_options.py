"""Odd images and option values, in both commands (issue 30, "Other
cases"): a long thin image, one too thin to restore, a TIFF of 2-sample
pixels, a mask that is a FIFO or of the wrong size, an empty ``-o``, and
stream mode with stdout closed. Each is restored, or refused with a line
that says what is wrong with the user's input, with the contract's code.
The binary comes from the ``binary`` fixture of ``conftest.py``."""

from __future__ import annotations

import os
import subprocess
import sys

import numpy as np
import pytest

import uwhl_rs

CONTRACT = {"ok": 0, "bad_arguments": 2, "unreadable_input": 3, "write_failed": 5, "internal": 6}
FACES = ["python", "rust"]


def _env() -> dict:
    env = dict(os.environ)
    pkg = os.path.dirname(os.path.dirname(os.path.abspath(uwhl_rs.__file__)))
    env["PYTHONPATH"] = os.pathsep.join(p for p in [pkg, env.get("PYTHONPATH", "")] if p)
    return env


def _run(face, binary, args, timeout=120, **kw):
    """One command; the timeout only turns a hang into a failure."""
    cmd = [sys.executable, "-m", "uwhl_rs", "restore", *args] if face == "python" else [binary, "restore", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=timeout, env=_env(), **kw)


def _png(path, h, w, seed=0):
    from PIL import Image

    rng = np.random.default_rng(seed)
    # a bluish, textured scene: restorable, not constant
    base = np.array([40, 110, 150], np.float64)
    img = base * (0.5 + rng.random((h, w, 1))) + rng.normal(0, 8, (h, w, 3))
    Image.fromarray(np.clip(img, 0, 255).astype(np.uint8)).save(path)


def _error_lines(r):
    assert "Traceback" not in r.stderr, r.stderr
    return [x for x in r.stderr.splitlines() if x.startswith(("uwhl:", "uwhl-rs:", "uwhl restore:"))]


# ------------------------------------------------------------ tiny or odd images


@pytest.mark.parametrize("face", FACES)
def test_a_long_thin_image_is_restored_under_the_default_selection(binary, tmp_path, face):
    """10000x4: the fast selection's copy would be 1000x1, which used to
    fail the input as "image too small: 1x1000"; it is restored."""
    _png(tmp_path / "strip.png", 4, 10000)
    out = tmp_path / "out"
    r = _run(face, binary, [str(tmp_path / "strip.png"), "-o", str(out), "--format", "png"])
    assert r.returncode == 0, r.stderr
    from PIL import Image

    with Image.open(out / "strip.png") as im:
        assert im.size == (10000, 4)


def test_the_api_restores_a_long_thin_image():
    rng = np.random.default_rng(1)
    img = (np.array([0.1, 0.35, 0.5], np.float32) * (0.5 + rng.random((4, 10000, 1), np.float32))).astype(np.float32)
    res = uwhl_rs.restore(img, selection="fast", water_types=["II", "3C", "7C"])
    assert res.image.shape == (4, 10000, 3)
    # the same choice as scoring every type at full resolution: the copy could not be thinner than the image
    assert res.water_type == uwhl_rs.restore(img, selection="exhaustive", water_types=["II", "3C", "7C"]).water_type


@pytest.mark.parametrize("face", FACES)
def test_an_image_too_thin_names_its_width_height_and_the_minimum(binary, tmp_path, face):
    _png(tmp_path / "thin.png", 3, 5000)
    r = _run(face, binary, [str(tmp_path / "thin.png"), "-o", str(tmp_path / "out")])
    assert r.returncode == CONTRACT["unreadable_input"], r.stderr
    lines = _error_lines(r)
    assert any("thin.png" in x and "5000 pixels wide and 3 high" in x and "at least 4 pixels on each side" in x
               for x in lines), r.stderr


@pytest.mark.parametrize("face", FACES)
def test_a_tiff_of_two_sample_pixels_says_what_it_holds(binary, tmp_path, face):
    """tifffile stores a (32, 32, 2) array as 32 pages of 32x2 gray images;
    the line says the image read is 2 pixels wide and 32 high (it used to
    say "32x2 pixels", read as 32 wide), and the minimum."""
    tifffile = pytest.importorskip("tifffile")
    rng = np.random.default_rng(2)
    tifffile.imwrite(tmp_path / "two.tif", (rng.random((32, 32, 2)) * 200).astype(np.uint8))
    r = _run(face, binary, [str(tmp_path / "two.tif"), "-o", str(tmp_path / "out")])
    assert r.returncode == CONTRACT["unreadable_input"], r.stderr
    assert any("two.tif" in x and "2 pixels wide and 32 high" in x and "at least 4" in x for x in _error_lines(r)), \
        r.stderr


# ------------------------------------------------------------------ masks


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
@pytest.mark.parametrize("flag", ["--mask", "--water-mask"])
@pytest.mark.parametrize("face", ["python",
                                  "rust"])
def test_a_mask_that_is_a_fifo_is_refused_not_waited_on(binary, tmp_path, face, flag):
    _png(tmp_path / "a.png", 40, 60)
    os.mkfifo(tmp_path / "m.png")
    r = _run(face, binary, [str(tmp_path / "a.png"), "-o", str(tmp_path / "out"), flag, str(tmp_path / "m.png")],
             timeout=20)
    assert r.returncode == CONTRACT["bad_arguments"], r.stderr
    assert any(flag in x and "m.png" in x and "not a regular file" in x for x in _error_lines(r)), r.stderr


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no FIFOs here")
def test_stream_mode_refuses_a_fifo_mask_too(binary, tmp_path):
    os.mkfifo(tmp_path / "m.png")
    r = subprocess.run([binary, "restore", "--stream", "-o", str(tmp_path / "out"), "--mask", str(tmp_path / "m.png")],
                       input="", capture_output=True, text=True, timeout=60)
    assert r.returncode == CONTRACT["bad_arguments"] and "not a regular file" in r.stderr, r.stderr


@pytest.mark.parametrize("flag", ["--mask", "--water-mask"])
@pytest.mark.parametrize("face", ["python",
                                  "rust"])
def test_a_mask_of_the_wrong_size_is_a_bad_argument_in_both(binary, tmp_path, face, flag):
    """A mask's size is the user's option value against the input: 2
    (bad_arguments) in both commands, not 6 (internal, "a bug")."""
    _png(tmp_path / "a.png", 40, 60)
    _png(tmp_path / "m.png", 30, 60)
    r = _run(face, binary, [str(tmp_path / "a.png"), "-o", str(tmp_path / "out"), flag, str(tmp_path / "m.png")])
    assert r.returncode == CONTRACT["bad_arguments"], (r.returncode, r.stderr)
    assert any(flag.lstrip("-").replace("-", "_") in x.replace("-", "_") and "60x30" in x for x in _error_lines(r)), \
        r.stderr


# ------------------------------------------------------------- -o and stdout


@pytest.mark.parametrize("spelling", [["-o", ""], ["--out="], ["--output", ""]], ids=["-o", "--out=", "--output"])
@pytest.mark.parametrize("face", FACES)
def test_an_empty_output_folder_is_a_usage_error(binary, tmp_path, face, spelling):
    """``-o ''`` (an unset variable) used to write into the current folder."""
    _png(tmp_path / "a.png", 40, 60)
    r = _run(face, binary, [str(tmp_path / "a.png"), *spelling], cwd=tmp_path)
    assert r.returncode == CONTRACT["bad_arguments"], r.stderr
    assert "-o/--out" in r.stderr and "empty" in r.stderr, r.stderr
    assert sorted(os.listdir(tmp_path)) == ["a.png"]  # nothing written in the current folder


@pytest.mark.parametrize("face", FACES)
def test_stdout_as_the_output_folder_is_a_usage_error(binary, tmp_path, face):
    """``-o -`` is stdout (the binary's --raw-frames): neither command makes
    a folder named "-" of it."""
    _png(tmp_path / "a.png", 40, 60)
    r = _run(face, binary, [str(tmp_path / "a.png"), "-o", "-"], cwd=tmp_path)
    assert r.returncode == CONTRACT["bad_arguments"], r.stderr
    assert "- (stdout) is for" in r.stderr and "--raw-frames" in r.stderr, r.stderr
    assert sorted(os.listdir(tmp_path)) == ["a.png"]


def test_stream_mode_with_stdout_closed_restores_nothing_and_says_so(binary, tmp_path):
    """``>&-``: every frame's outcome is its JSON line on stdout; with
    stdout closed they used to be restored, their lines dropped, exit 0."""
    src = tmp_path / "frames"
    src.mkdir()
    for k in range(3):
        _png(src / f"f{k}.png", 40, 60, seed=k)
    out = tmp_path / "out"
    lines = "".join(f"{src / f'f{k}.png'}\n" for k in range(3))
    r = subprocess.run(["sh", "-c", 'exec "$@" >&-', "sh", binary, "restore", "--stream", "-o", str(out),
                        "--format", "png"], input=lines, stderr=subprocess.PIPE, text=True, timeout=120)
    assert r.returncode == CONTRACT["write_failed"], r.stderr
    assert "stdout is closed" in r.stderr, r.stderr
    assert not out.exists() or not [f for f in os.listdir(out) if f.endswith(".json")]


def test_stream_mode_into_dev_null_still_runs(binary, tmp_path):
    """The check is on a closed stdout, not on /dev/null: a caller that
    discards the lines (subprocess.DEVNULL, opened for reading and writing
    like the runtime's stand-in) still gets its frames restored."""
    _png(tmp_path / "f.png", 40, 60)
    out = tmp_path / "out"
    r = subprocess.run([binary, "restore", "--stream", "-o", str(out), "--format", "png"],
                       input=f"{tmp_path / 'f.png'}\n", stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True,
                       timeout=120)
    assert r.returncode == 0, r.stderr
    assert (out / "f.json").exists()


@pytest.mark.parametrize("face", FACES)
@pytest.mark.parametrize("args, needle", [
    (["--max-memory", "-5M"], '"-5M" is not a byte count > 0'),
    (["-j", "-2"], "-2"),
    (["--t-scale", "-0.5"], "-0.5"),
])
def test_a_value_that_starts_with_a_dash_reaches_the_options_own_check(binary, tmp_path, face, args, needle):
    """``--max-memory -5M`` is a byte count that is wrong, not a missing
    value: both commands take the next word as the value (as lexopt does)
    and say what is wrong with it, exit 2."""
    _png(tmp_path / "a.png", 32, 40)
    if face == "rust" and args[0] == "-j":
        pytest.skip("-j is the Python command's (the binary has no --jobs)")
    r = _run(face, binary, [str(tmp_path / "a.png"), "-o", str(tmp_path / "o"), *args])
    assert r.returncode == 2, (r.returncode, r.stderr)
    assert needle in r.stderr and "expected one argument" not in r.stderr, r.stderr
