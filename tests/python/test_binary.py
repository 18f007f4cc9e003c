"""The Rust binary ``uwhl-rs`` against the Python command ``uwhl restore``
(docs/OUTPUTS.md): for the same PNG/TIFF input and options both write the
same pixels (image, t, colour-mapped t) and the same sidecar estimates.

The binary comes from the ``binary`` fixture of ``conftest.py``. JPEG inputs are left out
on purpose: Pillow (libjpeg-turbo) and the image crate (zune-jpeg) decode
the same file to slightly different pixels.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

import uwhl_rs
from uwhl_rs import _core, synth

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

try:
    import uwhl_rs.cli  # noqa: F401  (the Python command under comparison)

    HAVE_PY_CLI = True
except ImportError:
    HAVE_PY_CLI = False

ESTIMATES = ["water_type", "scores", "excluded", "veiling_light", "vl_pixels", "vl_fraction", "flags", "veil_excess",
             "fallback_share", "guided_radius", "guided_subsample", "beta_ratios"]


def _env() -> dict:
    env = dict(os.environ)
    pkg = os.path.dirname(os.path.dirname(os.path.abspath(uwhl_rs.__file__)))
    env["PYTHONPATH"] = os.pathsep.join(p for p in [pkg, env.get("PYTHONPATH", "")] if p)
    return env


def _png(path, codes: np.ndarray, exif_orientation: int | None = None):
    from PIL import Image

    im = Image.fromarray(codes)
    if exif_orientation is None:
        im.save(path)
    else:
        exif = Image.Exif()
        exif[0x0112] = exif_orientation
        im.save(path, exif=exif)


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """Rendered scenes as sRGB files: 8-bit PNG, 16-bit PNG (through the
    package's writer), 8-bit PNG with EXIF orientation 6, 16-bit TIFF, and
    a mask that hides a block (a colour chart)."""
    d = tmp_path_factory.mktemp("bin_inputs")
    img, _ = synth.demo_input(90, 120, water_type="3C", seed=3)
    img = np.ascontiguousarray(img, dtype=np.float32)
    codes8 = _core._quantize(img, 8, True)
    _png(d / "scene8.png", codes8)
    _png(d / "rotated.png", codes8, exif_orientation=6)
    uwhl_rs.images.write_image(d / "scene16.png", img, bits=16, encoding="linear")
    uwhl_rs.images.write_image(d / "scene16.tif", img, bits=16, encoding="linear")
    mask = np.full((90, 120), 255, np.uint8)
    mask[60:80, 20:50] = 0
    _png(d / "mask.png", mask)
    return d


def _read(path: str) -> np.ndarray:
    """Decoded samples of an output file (16-bit RGB PNG through the core's
    PNG reader: Pillow truncates those)."""
    if path.endswith((".tif", ".tiff")):
        import tifffile

        return tifffile.imread(path)
    with open(path, "rb") as f:
        data = f.read()
    return np.asarray(_core._decode_png(data, 10**9))


def _run_both(binary, tmp_path, src, args):
    py_out, rs_out = tmp_path / "py", tmp_path / "rs"
    p = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", str(src), "-o", str(py_out), "-q", *args],
                       capture_output=True, text=True, timeout=600, env=_env())
    assert p.returncode == 0, p.stderr
    r = subprocess.run([binary, str(src), "-o", str(rs_out), "-q", *args], capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr
    return py_out, rs_out


CASES = [
    ("scene8.png", ["--format", "png"]),
    ("scene16.png", ["--format", "png", "--bits", "16", "--water-type", "II,III", "--water-type", "3C,7C"]),
    ("scene16.tif", ["--format", "tiff", "--mask", "{mask}", "--max-side", "50"]),
    ("scene8.png", ["--format", "png", "--preprocess", "reference", "--guided-radius", "9",
                    "--sphere-points", "200", "--guided-eps", "0.01"]),
    ("rotated.png", ["--format", "tiff", "--bits", "8", "--veiling-light", "0.05,0.2,0.3"]),
    ("scene8.png", ["--format", "png", "--selection", "fast"]),
    ("scene16.tif", ["--guided-subsample", "3", "--format", "png", "--water-type", "II,3C,7C"]),
    ("scene8.png", ["--guided-subsample", "auto", "--format", "tiff", "--guided-radius", "70", "--water-type", "3C"]),
]


@pytest.mark.skipif(not HAVE_PY_CLI, reason="the Python command (uwhl_rs.cli) is not in this build")
@pytest.mark.parametrize("name,args", CASES, ids=[f"{n}:{' '.join(a[:2])}" for n, a in CASES])
def test_binary_writes_what_the_python_command_writes(binary, inputs, tmp_path, name, args):
    args = [a.format(mask=inputs / "mask.png") for a in args]
    py_out, rs_out = _run_both(binary, tmp_path, inputs / name, args)
    stem = os.path.splitext(name)[0]
    py_side = json.loads((py_out / f"{stem}.json").read_text())
    rs_side = json.loads((rs_out / f"{stem}.json").read_text())
    assert rs_side["implementation"] == "rust" and py_side["implementation"] == "python"
    for key in ESTIMATES:
        assert rs_side[key] == py_side[key], key
    assert list(rs_side["scores"]) == list(py_side["scores"])
    assert rs_side["outputs"] == py_side["outputs"]
    for key in ["format", "bits", "height", "width", "orientation", "processed_height", "processed_width",
                "kind", "linear", "preprocess"]:
        assert rs_side["source"][key] == py_side["source"][key], key
    for key, value in py_side["parameters"].items():
        if key not in ("threads",):
            assert rs_side["parameters"].get(key) == value, key
    for role in ["image", "transmission", "transmission_color"]:
        f = py_side["outputs"][role]
        a, b = _read(str(py_out / f)), _read(str(rs_out / f))
        assert a.dtype == b.dtype and a.shape == b.shape, (role, a.dtype, b.dtype, a.shape, b.shape)
        assert np.array_equal(a, b), (role, int(np.abs(a.astype(int) - b.astype(int)).max()))


@pytest.mark.skipif(not HAVE_PY_CLI, reason="the Python command (uwhl_rs.cli) is not in this build")
def test_orientation_is_applied_like_python(binary, inputs, tmp_path):
    _, rs_out = _run_both(binary, tmp_path, inputs / "rotated.png", ["--format", "png"])
    side = json.loads((rs_out / "rotated.json").read_text())
    assert side["source"]["orientation"] == 6
    assert (side["source"]["height"], side["source"]["width"]) == (120, 90)
