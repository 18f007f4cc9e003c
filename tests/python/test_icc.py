"""Inputs tagged with an ICC profile other than sRGB are converted to the
linear working space (src/files/icc.rs, moxcms) by both commands; sRGB-tagged
ones are read exactly as untagged ones. The forward conversion in these
tests is LittleCMS's (Pillow's ImageCms), which shares no code with moxcms."""

import io
import json
import subprocess
import sys

import numpy as np
import pytest
from PIL import Image, ImageCms

from datapaths import IMAGES_DIR
from uwhl_rs import synth
from uwhl_rs.images import linear_to_srgb, read_image

ADOBE_PHOTO = IMAGES_DIR / "chart_calib_3_under.jpg"


@pytest.fixture(scope="module")
def adobe_icc():
    if not ADOBE_PHOTO.exists():
        pytest.skip("../shared/data is not here")
    with Image.open(ADOBE_PHOTO) as im:
        icc = im.info["icc_profile"]
    assert b"Adobe RGB" in icc
    return icc


def _srgb_scene():
    img, _ = synth.demo_input(90, 120, water_type="3C", seed=5)
    return (np.clip(linear_to_srgb(img), 0, 1) * 255 + 0.5).astype(np.uint8), img


def _in_adobe(codes, adobe_icc):
    """sRGB codes converted by LittleCMS into Adobe RGB (1998) codes."""
    src = ImageCms.createProfile("sRGB")
    dst = ImageCms.ImageCmsProfile(io.BytesIO(adobe_icc))
    t = ImageCms.buildTransform(src, dst, "RGB", "RGB", renderingIntent=ImageCms.Intent.RELATIVE_COLORIMETRIC)
    return ImageCms.applyTransform(Image.fromarray(codes), t)


def test_an_adobe_rgb_png_reads_as_its_colours(adobe_icc, tmp_path):
    codes, _ = _srgb_scene()
    adobe = _in_adobe(codes, adobe_icc)
    p = tmp_path / "adobe.png"
    adobe.save(p, icc_profile=adobe_icc)
    got, meta = read_image(p)
    assert meta.icc_profile == {"description": "Adobe RGB (1998)", "converted": True}
    want = np.asarray(read_image(_png(tmp_path / "srgb.png", codes))[0])
    # one 8-bit step in Adobe RGB is at most ~1.5 sRGB steps; in linear light well under 0.01
    err = np.abs(got - want)
    assert float(err.mean()) < 2e-3 and float(err.max()) < 0.02, (err.mean(), err.max())
    # read as if sRGB (what happened before), the same pixels are far off: the test can fail
    naive = read_image(_png(tmp_path / "naive.png", np.asarray(adobe)))[0]
    assert float(np.abs(naive - want).mean()) > 5 * float(err.mean())


def _png(path, codes, icc=None):
    Image.fromarray(codes).save(path, **({"icc_profile": icc} if icc else {}))
    return path


def test_srgb_tagged_is_read_bit_for_bit_as_untagged(tmp_path):
    codes, _ = _srgb_scene()
    srgb_icc = ImageCms.ImageCmsProfile(ImageCms.createProfile("sRGB")).tobytes()
    a, ma = read_image(_png(tmp_path / "tagged.png", codes, srgb_icc))
    b, mb = read_image(_png(tmp_path / "plain.png", codes))
    assert np.array_equal(a, b)
    assert ma.icc_profile["converted"] is False and mb.icc_profile is None


def test_an_unreadable_profile_is_a_note_and_srgb(tmp_path):
    codes, _ = _srgb_scene()
    a, ma = read_image(_png(tmp_path / "bad.png", codes, b"\0" * 200))
    b, _ = read_image(_png(tmp_path / "plain.png", codes))
    assert np.array_equal(a, b)
    assert ma.icc_profile == {"description": "", "converted": False}
    assert any("ICC profile cannot be read" in n for n in ma.notes)


def test_both_commands_convert_alike(binary, adobe_icc, tmp_path):
    """A PNG (decoded to the same codes by both) tagged Adobe RGB: the same
    source record and the same restoration from both commands."""
    codes, _ = _srgb_scene()
    p = tmp_path / "adobe.png"
    _in_adobe(codes, adobe_icc).save(p, icc_profile=adobe_icc)
    sides = {}
    for face, cmd in (("python", [sys.executable, "-m", "uwhl_rs", "restore"]), ("rust", [binary, "restore"])):
        r = subprocess.run(cmd + [str(p), "-o", str(tmp_path / face), "-q"], capture_output=True, text=True,
                           timeout=300)
        assert r.returncode == 0, r.stderr
        sides[face] = json.load(open(tmp_path / face / "adobe.json"))
    py, rs = sides["python"], sides["rust"]
    assert py["source"]["icc_profile"] == rs["source"]["icc_profile"] == {"description": "Adobe RGB (1998)",
                                                                            "converted": True}
    assert py["water_type"] == rs["water_type"] and py["veiling_light"] == rs["veiling_light"]
    assert py["scores"] == rs["scores"]
