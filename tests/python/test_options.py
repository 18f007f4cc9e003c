"""One definition of each parameter (src/files/options.rs): the Python API, the
command, the stubs and the docs agree with the core's table, and the
names of flags and timing stages are the documented ones."""

from __future__ import annotations

import inspect
import os
import re

import numpy as np

import uwhl_rs
from uwhl_rs import _core, files, synth

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
TABLE = {o["key"]: o for o in _core.OPTIONS}


def test_restore_and_sequence_take_the_tables_method_keywords_with_its_defaults():
    params = inspect.signature(uwhl_rs.restore).parameters
    method = {k for k, o in TABLE.items() if o["method"]}
    # the per-call arrays (and a fitted water) are not options
    assert set(params) - {"image", "mask", "water_mask", "distance", "water"} == method
    for k in method:
        assert params[k].default == TABLE[k]["default"], k
    # Sequence takes the same keywords (an unknown one is refused)
    uwhl_rs.Sequence(**{k: TABLE[k]["default"] for k in method if TABLE[k]["default"] is not None})


def test_restore_file_defaults_are_the_tables():
    params = inspect.signature(files.restore_staged).parameters
    for k in ("format", "bits", "quality", "preprocess", "half_size", "max_side", "max_pixels"):
        assert params[k].default == TABLE[k]["default"], k
    assert set(files.METHOD_KEYS) == {k for k, o in TABLE.items() if o["method"]}


def test_none_is_the_default_for_every_method_keyword():
    """The core's one check of a keyword's value (no second one in Python):
    None, for any method keyword, is the restore with that keyword absent."""
    img, _ = synth.demo_input(40, 56, seed=3)
    plain = uwhl_rs.restore(img)
    for key in (k for k, o in TABLE.items() if o["method"]):
        r = uwhl_rs.restore(img, **{key: None})
        assert np.array_equal(r.image, plain.image) and r.water_type == plain.water_type, key


def test_the_tables_defaults_are_the_cores():
    """A restore with every default given explicitly is the restore with none."""
    img, _ = synth.demo_input(48, 64, seed=1)
    given = {k: o["default"] for k, o in TABLE.items() if o["method"] and o["default"] is not None}
    a, b = uwhl_rs.restore(img), uwhl_rs.restore(img, **given)
    assert np.array_equal(a.image, b.image) and a.scores == b.scores


def test_parse_option_follows_the_ranges():
    assert _core.parse_option("quality", "95") == 95
    assert _core.parse_option("guided_subsample", "auto") == 0
    assert _core.parse_option("format", "TIF") == "tiff"
    assert _core.parse_option("veiling_light", "0.1,0.2 0.3") == (0.1, 0.2, 0.3)
    for key, bad in [("quality", "0"), ("quality", "101"), ("bits", "12"), ("guided_eps", "0"),
                     ("max_memory", "lots"), ("threads", "0"), ("selection", "quick")]:
        try:
            _core.parse_option(key, bad)
        except ValueError as e:
            assert TABLE[key]["flag"] in str(e) and repr(bad)[1:-1] in str(e), str(e)
        else:
            raise AssertionError(f"{key}={bad!r} accepted")


def test_stubs_declare_every_public_name_of_the_module():
    stub = open(os.path.join(ROOT, "python", "uwhl_rs", "_core.pyi")).read()
    declared = set(re.findall(r"^(?:class |def )?(\w+)\s*[:(=]", stub, re.M)) | set(
        re.findall(r"^class (\w+)", stub, re.M))
    public = {n for n in dir(_core) if not n.startswith("_")}
    assert public <= declared, sorted(public - declared)


def test_flags_and_stages_are_the_documented_names():
    doc = open(os.path.join(ROOT, "docs", "OUTPUTS.md")).read()
    for name in _core.FLAGS + _core.STAGES:
        assert f"`{name}`" in doc, name
    img, _ = synth.demo_input(60, 80, seed=3)
    res = uwhl_rs.restore(img)
    assert set(res.flags) <= set(_core.FLAGS)
    assert list(res.timings) == [s for s in _core.STAGES if s in res.timings]
    # looking down: no water region, the fallback flags
    sc = synth.scene(60, 80, kind="looking_down", seed=2)
    down = synth.render(sc.clean, sc.distance, "II", beta_b=0.2, noise=0.003, seed=2)
    flags = uwhl_rs.restore(down).flags
    assert set(flags) <= set(_core.FLAGS)
