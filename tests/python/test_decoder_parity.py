"""One decoder for both commands (src/files/decode.rs): inputs that the
Python command once read with other libraries than the binary (CMYK JPEG,
1-bit and palette PNG, LZW-, Deflate- and JPEG-compressed TIFF, gray with
alpha) are restored by both, to the same pixels and estimates."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import numpy as np
import pytest

import uwhl_rs
from uwhl_rs import _core, images, synth

CASES = {
    "cmyk.jpg": lambda im: im.convert("CMYK").save,
    "onebit.png": lambda im: im.convert("1").save,
    "palette.png": lambda im: im.convert("P").save,
    "gray_alpha.png": lambda im: im.convert("LA").save,
    "lzw.tif": lambda im: (lambda p: im.save(p, compression="tiff_lzw")),
    "deflate.tif": lambda im: (lambda p: im.save(p, compression="tiff_adobe_deflate")),
    "jpeg_in.tif": lambda im: (lambda p: im.save(p, compression="jpeg")),
}


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    from PIL import Image

    d = tmp_path_factory.mktemp("decoder_inputs")
    img, _ = synth.demo_input(72, 96, water_type="3C", seed=5)
    codes = (images.linear_to_srgb(img) * 255 + 0.5).astype(np.uint8)
    im = Image.fromarray(codes)
    for name, saver in CASES.items():
        saver(im)(str(d / name))
    return d


def _env() -> dict:
    env = dict(os.environ)
    pkg = os.path.dirname(os.path.dirname(os.path.abspath(uwhl_rs.__file__)))
    env["PYTHONPATH"] = os.pathsep.join(p for p in [pkg, env.get("PYTHONPATH", "")] if p)
    return env


def _samples(path) -> np.ndarray:
    return np.asarray(_core._decode_png(open(path, "rb").read(), 10**9))


@pytest.mark.parametrize("name", sorted(CASES))
def test_both_commands_restore_it_alike(binary, inputs, tmp_path, name):
    outs = {}
    for face, cmd in (("python", [sys.executable, "-m", "uwhl_rs", "restore"]), ("rust", [binary, "restore"])):
        out = tmp_path / face
        r = subprocess.run([*cmd, str(inputs / name), "-o", str(out), "--format", "png", "-q"],
                           capture_output=True, text=True, timeout=300, env=_env())
        assert r.returncode == 0, (face, r.stderr)
        outs[face] = out
    stem = os.path.splitext(name)[0]
    for suffix in (".png", "_t.png", "_t_color.png"):
        a, b = _samples(outs["python"] / f"{stem}{suffix}"), _samples(outs["rust"] / f"{stem}{suffix}")
        assert a.shape == b.shape and np.array_equal(a, b), suffix
    sa = json.loads((outs["python"] / f"{stem}.json").read_text())
    sb = json.loads((outs["rust"] / f"{stem}.json").read_text())
    for k in ("water_type", "scores", "veiling_light", "source"):
        if k == "source":
            assert {x: v for x, v in sa[k].items() if x != "path"} == {x: v for x, v in sb[k].items() if x != "path"}
        else:
            assert sa[k] == sb[k], k
