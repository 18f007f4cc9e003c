"""The confidence map as a file of both commands (docs/OUTPUTS.md,
METHOD §12.5): written by the default profile, named in the sidecar and
summary.csv, low where the truth says the transmission is least to be
trusted, absent with ``--fallback none`` and removed by such a rerun."""

import csv

import numpy as np
import pytest
from PIL import Image

from bothcmds import cmds, run_restore, sidecar
from uwhl_rs import synth

tifffile = pytest.importorskip("tifffile")


@pytest.fixture(scope="module")
def seabed(tmp_path_factory):
    """A looking-down seabed through 3C water with noise: the far rows (low
    t) are where noise, amplified by 1/t, swamps the colour."""
    sc = synth.scene(120, 160, kind="looking_down", seed=5)
    img = synth.render(sc.clean, sc.distance, "3C", beta_b=0.4, noise=0.01, seed=1)
    d = tmp_path_factory.mktemp("conf")
    # a float TIFF is read as linear, exactly (no sRGB curve)
    tifffile.imwrite(d / "sea.tif", np.ascontiguousarray(img, np.float32), photometric="rgb")
    return d / "sea.tif", sc


def _run(cmd, src, out, *args):
    p = run_restore(cmd, src, "-o", out, *args)
    assert p.returncode == 0, p.stderr
    return sidecar(out, "sea")


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_the_confidence_file_is_written_named_and_low_where_t_is_least_trusted(impl, binary, seabed, tmp_path):
    src, sc = seabed
    out = tmp_path / impl
    side = _run(cmds(binary)[impl], src, out)
    assert side["outputs"]["confidence"] == "sea_confidence.png"
    with Image.open(out / "sea_confidence.png") as im:
        assert im.mode in ("I;16", "I") and im.size == (160, 120)
        c = np.asarray(im, dtype=np.float64) / 65535.0
    assert 0.0 <= c.min() and c.max() <= 1.0
    # the true transmission ranks the rows: confidence is higher on the
    # nearest third of the seabed than on the farthest third
    t_r = synth.transmissions(sc.distance, "3C", 0.4)[0]
    obj = np.isfinite(sc.distance)
    near, far = t_r >= np.percentile(t_r[obj], 67), t_r <= np.percentile(t_r[obj], 33)
    assert c[near & obj].mean() > c[far & obj].mean() + 0.05, (c[near & obj].mean(), c[far & obj].mean())
    with open(out / "summary.csv", newline="") as f:
        row = next(csv.DictReader(f))
    assert row["confidence"] == str(out / "sea_confidence.png")


def test_both_commands_write_the_same_confidence_file(binary, seabed, tmp_path):
    src, _ = seabed
    for impl, cmd in cmds(binary).items():
        _run(cmd, src, tmp_path / impl)
    a = np.asarray(Image.open(tmp_path / "python" / "sea_confidence.png"))
    b = np.asarray(Image.open(tmp_path / "rust" / "sea_confidence.png"))
    assert np.array_equal(a, b)


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_without_the_trust_step_there_is_no_confidence_file_and_a_rerun_removes_an_old_one(impl, binary, seabed,
                                                                                           tmp_path):
    src, _ = seabed
    cmd = cmds(binary)[impl]
    out = tmp_path / impl
    _run(cmd, src, out)
    assert (out / "sea_confidence.png").exists()
    side = _run(cmd, src, out, "--overwrite", "--fallback", "none")
    assert "confidence" not in side["outputs"]
    assert not (out / "sea_confidence.png").exists()
    assert sorted(p.name for p in out.iterdir()) == ["sea.jpg", "sea.json", "sea_t.png", "sea_t_color.png",
                                                      "summary.csv"]
    with open(out / "summary.csv", newline="") as f:
        row = next(csv.DictReader(f))
    assert row["confidence"] == ""
