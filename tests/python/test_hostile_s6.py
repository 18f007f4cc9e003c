"""Hostile sidecars for the weighted ``--water-from`` dive (METHOD §13.6),
and the escaping of line separators and bidirectional controls in the
JSON error lines and usage errors (both commands)."""

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from bothcmds import cmds as _cmds

tifffile = pytest.importorskip("tifffile")

# what a console line must never hold raw (C0 but \n and \t, DEL, C1, the
# line/paragraph separators and the bidirectional controls)
RAW = set(map(chr, [*range(0, 9), *range(11, 32), *range(0x7F, 0xA0), 0x061C, 0x200E, 0x200F,
                    *range(0x2028, 0x202F), *range(0x2066, 0x206A)]))


def _raw(text: str) -> set:
    return {f"U+{ord(c):04X}" for c in text if c in RAW}


@pytest.fixture(scope="module")
def photo(tmp_path_factory):
    """A small photo to restore (its content does not matter here)."""
    d = tmp_path_factory.mktemp("photo")
    img = np.random.default_rng(3).random((40, 60, 3)).astype(np.float32) * 0.6 + 0.2
    tifffile.imwrite(d / "p.tif", img, photometric="rgb")
    return d / "p.tif"


def _cal(tmp_path, fits):
    """A folder of sidecars whose distance was used: ``fits`` is a list of
    (beta, beta_range) with beta_range stored as given."""
    cal = tmp_path / "cal"
    cal.mkdir()
    for k, (beta, rng) in enumerate(fits):
        water = {"beta": beta}
        if rng is not None:
            water["beta_range"] = rng
        (cal / f"c{k}.json").write_text(json.dumps({"distance": {"used": True, "water": water}}))
    return cal


def _water_from(cmd, photo, cal, out):
    r = subprocess.run([*cmd, "restore", str(photo), "-o", str(out), "--water-from", str(cal), "-q"],
                       capture_output=True, text=True, timeout=300)
    side = json.loads((out / "p.json").read_text()) if r.returncode == 0 else None
    return r, side


# three fits whose blue-to-red ratios are, by hand, 0.1, 0.2 and 0.3 (the
# plain median 0.2) and blue-to-green 0.5, 0.6, 0.7 (median 0.6)
BETAS = [[0.5, 0.1, 0.05], [0.4, 0.1 / 0.6 * 0.8, 0.08], [0.3, 0.09 / 0.7, 0.09]]
FAIR = [[0.01, 1.0], [0.01, 1.0]]
#: the ratios of the plain median beta (0.4, 0.09 / 0.7, 0.08), by hand
PLAIN = [0.08 / 0.4, 0.08 / (0.09 / 0.7)]


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_equal_weights_give_the_plain_median_even_when_each_span_overflows(impl, binary, photo, tmp_path):
    """A blue range [1e-320, 1] has a span that overflows (hi / lo = inf, a
    weight of 0): it is no range, and the folder gets the ratios of the
    plain median beta (0.2, 0.622), not those of the smallest of each list
    that a zero total weight would give (0.3, 0.1, 0.05: 0.167, 0.5)."""
    cal = _cal(tmp_path, [(b, [*FAIR, [1e-320, 1.0]]) for b in BETAS])
    r, side = _water_from(_cmds(binary)[impl], photo, cal, tmp_path / impl)
    assert r.returncode == 0, r.stderr
    assert side["beta_ratios"] == pytest.approx(PLAIN, rel=1e-9), side["parameters"]["water_from"]


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_a_range_that_does_not_hold_its_own_fit_is_not_a_range(impl, binary, photo, tmp_path):
    """The fit always lies inside its range (METHOD §13.2 step 6). A sidecar
    claiming blue beta 0.09 with a range [50, 50] would get the capped weight
    1 / ln 1.01 = 100 and outweigh the others (0.43 each): such a range is
    not usable, so the folder gets the ratios of the plain median beta
    (0.2, 0.622), weighted=false."""
    fits = [(BETAS[0], [*FAIR, [0.01, 0.1]]), (BETAS[1], [*FAIR, [0.01, 0.1]]), (BETAS[2], [*FAIR, [50.0, 50.0]])]
    cal = _cal(tmp_path, fits)
    r, side = _water_from(_cmds(binary)[impl], photo, cal, tmp_path / impl)
    assert r.returncode == 0, r.stderr
    assert side["parameters"]["water_from"]["weighted"] is False, side["parameters"]["water_from"]
    assert side["beta_ratios"] == pytest.approx(PLAIN, rel=1e-9)


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_a_beta_range_that_is_an_object_is_not_a_range(impl, binary, photo, tmp_path):
    """OUTPUTS: beta_range is a list of three [lo, hi]; an object with a key
    "2" (which a JSON pointer would resolve) is not one."""
    fits = [(BETAS[0], [*FAIR, [0.01, 0.1]]), (BETAS[1], [*FAIR, [0.01, 0.1]]), (BETAS[2], {"2": [0.01, 0.1]})]
    cal = _cal(tmp_path, fits)
    r, side = _water_from(_cmds(binary)[impl], photo, cal, tmp_path / impl)
    assert r.returncode == 0, r.stderr
    assert side["parameters"]["water_from"]["weighted"] is False, side["parameters"]["water_from"]


@pytest.mark.parametrize("impl", ["python", "rust"])
def test_a_beta_with_a_non_number_is_not_a_fit(impl, binary, photo, tmp_path):
    """A ``beta`` of four values with a non-number among them is not a fit
    (dropping the non-number would read the sidecar's blue as its green),
    and a folder with no other is refused (exit 2)."""
    cal = _cal(tmp_path, [([0.3, "x", 0.2, 0.2], None)])
    r, _ = _water_from(_cmds(binary)[impl], photo, cal, tmp_path / impl)
    assert r.returncode == 2 and "no sidecar there records a water" in r.stderr, (r.returncode, r.stderr)


NAMES = ["a\u202egnp.exe.jpg", "b\u2028x.jpg", "c\u2029y.jpg", "d\u0085z.jpg", "e\u200f\u061c\u2066.jpg"]


def test_json_errors_hold_no_raw_separator_or_bidi_control_in_either_command(binary, tmp_path):
    """--json-errors: one JSON object a line, with U+202E, U+2028, U+2029,
    U+0085, U+200F, U+061C, U+2066 as JSON escapes in both commands: raw,
    a reader splitting with str.splitlines would cut the lines apart
    (U+0085, U+2028 and U+2029 are line boundaries there) and a terminal
    would show them reordered. Both read back as the same names."""
    d = tmp_path / "in"
    d.mkdir()
    for n in NAMES:
        (d / n).write_bytes(b"not a jpeg at all")
    got = {}
    for face, cmd in _cmds(binary).items():
        r = subprocess.run([*cmd, "restore", str(d), "-o", str(tmp_path / face), "--json-errors", "-q"],
                           capture_output=True, timeout=300)
        err = r.stderr.decode("utf-8", "surrogateescape")
        assert r.returncode == 3, (face, err)
        assert not _raw(err), (face, _raw(err))
        lines = err.splitlines()
        assert len(lines) == len(NAMES), (face, lines)
        got[face] = sorted(json.loads(ln)["input"] for ln in lines)
    assert got["python"] == got["rust"]


@pytest.mark.parametrize("arg", ["--x\x1b[31mRED\u202egnp.exe\u2028", "--w=\x1b[31mRED\u202e"])
def test_the_python_commands_usage_errors_escape_what_they_quote(binary, photo, tmp_path, arg):
    """A word the parser does not know (e.g. a file named like an option,
    expanded by ``uwhl restore *``) is quoted in the usage error, escaped in
    both commands: argparse's "unrecognized arguments" and "ambiguous option"
    lines as the binary's "invalid option"."""
    for face, cmd in _cmds(binary).items():
        r = subprocess.run([*cmd, "restore", str(photo), "-o", str(tmp_path / face), arg],
                           capture_output=True, timeout=60)
        err = r.stderr.decode("utf-8", "surrogateescape")
        assert r.returncode == 2, (face, err)
        assert not _raw(err), (face, _raw(err), err[-300:])


def test_names_of_undecodable_bytes_are_named_the_same_by_both_commands(binary, tmp_path):
    """A path option whose value is not UTF-8 (a name's bytes) is a usage
    error that shows the bytes, and a file of such a name that is no image
    is named with U+FFFD for each byte in the JSON error line, in both."""
    bad = tmp_path / "in"
    bad.mkdir()
    (bad / os.fsdecode(b"junk\xff.jpg")).write_bytes(b"not a jpeg at all")
    lines = {}
    for face, cmd in _cmds(binary).items():
        r = subprocess.run([*cmd, "restore", str(bad), "-o", str(tmp_path / face),
                            "--distance", os.fsdecode(os.fsencode(str(tmp_path)) + b"/d\xff.npy")],
                           capture_output=True, timeout=60)
        err = r.stderr.decode("utf-8", "replace")
        assert r.returncode == 2 and "d\\xFF.npy\" is not valid UTF-8" in err, (face, err)
        r = subprocess.run([*cmd, "restore", str(bad), "-o", str(tmp_path / face), "--json-errors", "-q"],
                           capture_output=True, timeout=60)
        assert r.returncode == 3, (face, r.stderr)
        lines[face] = json.loads(r.stderr.decode("utf-8"))
    assert lines["python"]["input"] == lines["rust"]["input"] == str(bad / "junk\ufffd.jpg")


def test_a_raw_file_of_undecodable_name_is_read(tmp_path):
    """rawpy takes a path only as text: a raw file whose name is not UTF-8
    is read from the opened file instead (it was refused as "not a raw file
    LibRaw can read")."""
    from datapaths import RAW_DIR

    src = RAW_DIR / "Blackmagic.dng"
    if not src.exists():
        pytest.skip("../shared/data is not beside the repository")
    name = os.fsdecode(b"dive\xff.dng")
    (tmp_path / name).write_bytes(src.read_bytes())
    r = subprocess.run([sys.executable, "-m", "uwhl_rs", "restore", str(tmp_path / name), "-o", str(tmp_path / "out"),
                        "--max-side", "200", "-q"], capture_output=True, timeout=300)
    assert r.returncode == 0, r.stderr.decode("utf-8", "replace")
    assert (tmp_path / "out" / "dive\ufffd.json").exists()  # output names: U+FFFD a byte (OUTPUTS.md "Names")
