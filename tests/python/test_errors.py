"""Error paths of ``uwhl_rs.restore``.

Every unusable input must raise the documented exception (ImageError or
ParameterError, both ValueError subclasses; MemoryError over the memory
budget) with a message naming the problem (METHOD §2; docstring of
``uwhl_rs.restore``). The expected exception classes and message key words
come from the SPEC, the docstring and the brief, never from running the code.
"""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

import uwhl_rs
from uwhl_rs import ImageError, ParameterError

H, W = 12, 16  # a small valid image: every call below is cheap


def _base(dtype=np.float32) -> np.ndarray:
    """A valid, non-constant linear RGB image in [0.05, 0.95]."""
    rng = np.random.default_rng(1234)
    return (0.05 + 0.9 * rng.random((H, W, 3))).astype(dtype)


def _with(value, pos, dtype=np.float32) -> np.ndarray:
    a = _base(dtype)
    a[pos] = value
    return a


def _ones_mask(shape=(H, W), dtype=bool):
    return np.ones(shape, dtype=dtype)


def _mask_word(name: str):
    """Regex: the mask's own name ('mask' must not merely be part of 'water_mask')."""
    return re.compile(r"(?<!water_)mask") if name == "mask" else re.compile(r"water_mask")


# A case: (id, call -> (image, kwargs), expected exception, key words).
# A key word is a str (case-insensitive substring), a tuple of str
# (any one of them), or a compiled regex.
CASES = []
BUG_CASES = {}  # id -> xfail reason


def case(cid, make, exc, words, bug=None):
    CASES.append((cid, make, exc, words))
    if bug:
        BUG_CASES[cid] = bug


# --- dtypes ---------------------------------------------------------------
for _dt in ["uint8", "uint16", "int32", "int64", "bool", "complex64", "complex128", "object", "float16"]:
    case(
        f"dtype-{_dt}",
        lambda dt=_dt: (_base(np.float64).astype(dt), {}),
        ImageError,
        [_dt, ("float32", "float64")],
    )

# --- shapes ---------------------------------------------------------------
case("ndim2", lambda: (_base()[..., 0], {}), ImageError, [("(12, 16)",), "(h, w, 3)"])
case("ndim4", lambda: (_base()[None], {}), ImageError, ["(1, 12, 16, 3)", "(h, w, 3)"])
case("last-axis-1", lambda: (_base()[..., :1], {}), ImageError, ["(12, 16, 1)", "(h, w, 3)"])
case(
    "last-axis-4",
    lambda: (np.concatenate([_base(), _base()[..., :1]], axis=-1), {}),
    ImageError,
    ["(12, 16, 4)", "(h, w, 3)"],
)
for _h, _w in [(0, 0), (1, 1), (3, 3), (1, 20), (20, 1)]:
    case(
        f"size-{_h}x{_w}",
        lambda h=_h, w=_w: (np.full((h, w, 3), 0.5, np.float32) if h * w == 0
                            else np.random.default_rng(0).random((h, w, 3)).astype(np.float32), {}),
        ImageError,
        [(f"{_h}x{_w}", f"({_h}, {_w}"), ("empty", "small", "at least")],
    )

# --- non-finite values at a known place: row 2, column 5, channel 1 --------
for _dt in [np.float32, np.float64]:
    for _v, _vname in [(np.nan, "nan"), (np.inf, "inf"), (-np.inf, "-inf")]:
        case(
            f"nonfinite-{_dt.__name__}-{_vname}",
            lambda v=_v, dt=_dt: (_with(v, (2, 5, 1), dt), {}),
            ImageError,
            ["non-finite", _vname, "row 2", "column 5", "channel 1"],
        )

# --- out of [0, 1], at row 3, column 6, channel 2 ---------------------------
for _dt in [np.float32, np.float64]:
    for _v, _vs in [(-0.01, "-0.01"), (1.01, "1.01"), (-3.0, "-3"), (7.5, "7.5")]:
        case(
            f"range-{_dt.__name__}-{_vs}",
            lambda v=_v, dt=_dt: (_with(v, (3, 6, 2), dt), {}),
            ImageError,
            ["outside [0, 1]", _vs, "row 3", "column 6", "channel 2"],
        )
# A finite float64 value beyond float32's range is out of [0, 1], not non-finite.
case(
    "range-float64-1e39",
    lambda: (_with(1e39, (3, 6, 2), np.float64), {}),
    ImageError,
    ["outside [0, 1]", "row 3", "column 6", "channel 2"],
)

# --- constant images --------------------------------------------------------
for _c in [0.0, 1.0, 0.5]:
    case(f"constant-{_c}", lambda c=_c: (np.full((H, W, 3), c, np.float32), {}), ImageError, ["constant"])

# --- masks ------------------------------------------------------------------
for _name in ["mask", "water_mask"]:
    case(
        f"{_name}-shape",
        lambda n=_name: (_base(), {n: _ones_mask((H, W + 1))}),
        ParameterError,
        [_mask_word(_name), "(12, 17)", ("(12, 16)", "12x16")],
    )
    case(
        f"{_name}-transposed",
        lambda n=_name: (_base(), {n: _ones_mask((W, H))}),
        ParameterError,
        [_mask_word(_name), "(16, 12)"],
    )
    case(
        f"{_name}-uint8",
        lambda n=_name: (_base(), {n: _ones_mask(dtype=np.uint8)}),
        ParameterError,
        [_mask_word(_name), "uint8", "bool"],
    )
case(
    "mask-all-false",
    lambda: (_base(), {"mask": np.zeros((H, W), bool)}),
    ParameterError,
    [_mask_word("mask"), ("true", "no pixel", "all false", "empty")],
)

# --- water types -------------------------------------------------------------
case("type-unknown", lambda: (_base(), {"water_types": ["Atlantis"]}), ParameterError, ["atlantis", "water type"])
case("type-unknown-mixed", lambda: (_base(), {"water_types": ["II", "XII"]}), ParameterError, ["xii"])
for _br, _bg, _label, _val in [
    (0.0, 1.0, "beta_br", "0"),
    (1.0, 0.0, "beta_bg", "0"),
    (-1.0, 1.0, "beta_br", "-1"),
    (1.0, -0.5, "beta_bg", "-0.5"),
    (float("nan"), 1.0, "beta_br", "nan"),
    (1.0, float("nan"), "beta_bg", "nan"),
    (float("inf"), 1.0, "beta_br", "inf"),
    (1.0, float("-inf"), "beta_bg", "-inf"),
]:
    case(
        f"type-custom-{_label}={_val}",
        lambda br=_br, bg=_bg: (_base(), {"water_types": [("mine", br, bg)]}),
        ParameterError,
        ["mine", _label, _val],
    )
case(
    "type-string-not-list",
    lambda: (_base(), {"water_types": "II"}),
    ParameterError,
    ["water_types", "list", ("string", "str")],
)
case(
    "type-tuple-2-values",
    lambda: (_base(), {"water_types": [("mine", 0.5)]}),
    ParameterError,
    ["mine", "beta_br"],
)
case(
    "type-tuple-4-values",
    lambda: (_base(), {"water_types": [("mine", 0.5, 0.5, 0.5)]}),
    ParameterError,
    ["mine", "beta_br"],
)
case(
    "type-tuple-str-ratio",
    lambda: (_base(), {"water_types": [("mine", "a", 0.5)]}),
    ParameterError,
    ["mine", "beta_br"],
)
case(
    "type-tuple-no-name",
    lambda: (_base(), {"water_types": [(0.7, 0.5, 0.5)]}),
    ParameterError,
    ["name", "beta_br"],
)
case(
    "type-item-int",
    lambda: (_base(), {"water_types": [42]}),
    ParameterError,
    ["42", "water type"],
)
case(
    "type-duplicate-names",
    lambda: (_base(), {"water_types": ["II", "II"]}),
    ParameterError,
    ["ii", ("twice", "duplicate", "more than once")],
)
case(
    "type-duplicate-custom",
    lambda: (_base(), {"water_types": [("mine", 0.5, 0.5), ("mine", 0.7, 0.9)]}),
    ParameterError,
    ["mine", ("twice", "duplicate", "more than once")],
)
case("type-empty-list", lambda: (_base(), {"water_types": []}), ParameterError, ["empty"])

# --- veiling light -----------------------------------------------------------
case(
    "veiling-2-values",
    lambda: (_base(), {"veiling_light": (0.1, 0.2)}),
    ParameterError,
    ["veiling_light", "3"],
)
for _vl, _val in [
    ((0.0, 0.2, 0.3), "0"),
    ((0.1, -0.2, 0.3), "-0.2"),
    ((0.1, 0.2, 1.5), "1.5"),
    ((float("nan"), 0.2, 0.3), "nan"),
]:
    case(
        f"veiling-{_val}",
        lambda vl=_vl: (_base(), {"veiling_light": vl}),
        ParameterError,
        ["veiling_light", _val],
    )
case(
    "veiling-strings",
    lambda: (_base(), {"veiling_light": ("a", "b", "c")}),
    ParameterError,
    ["veiling_light"],
)

# --- guided filter, sphere, threads ------------------------------------------
for _e, _val in [(0.0, "0"), (-1e-3, "-0.001"), (float("nan"), "nan")]:
    case(
        f"guided_eps-{_val}",
        lambda e=_e: (_base(), {"guided_eps": e}),
        ParameterError,
        ["guided_eps", _val],
    )
case("guided_radius-negative", lambda: (_base(), {"guided_radius": -1}), ParameterError, ["guided_radius", "-1"])
case(
    "guided_radius-too-large",
    lambda: (_base(), {"guided_radius": max(H, W) + 1}),
    ParameterError,
    ["guided_radius", str(max(H, W) + 1), ("larger", "image")],
)
case(
    "guided_radius-huge",
    lambda: (_base(), {"guided_radius": 10**6}),
    ParameterError,
    ["guided_radius", "1000000"],
)
for _gs, _val in [(-1, "-1"), (True, "True"), (False, "False"), (2.0, "2.0"), ("fast", "fast"), ("AUTO", "AUTO"),
                 (np.float32(3), "3"), (2**64, str(2**64))]:
    case(
        f"guided_subsample-{_val}",
        lambda g=_gs: (_base(), {"guided_subsample": g}),
        ParameterError,
        ["guided_subsample", _val],
    )
case(
    "guided_subsample-too-large",
    lambda: (_base(), {"guided_subsample": max(H, W) + 1}),
    ParameterError,
    ["guided_subsample", str(max(H, W) + 1), ("larger", "image")],
)
case("sphere_points-0", lambda: (_base(), {"sphere_points": 0}), ParameterError, ["sphere_points"])
case(
    "sphere_points-2**64",
    lambda: (_base(), {"sphere_points": 2**64}),
    ParameterError,
    ["sphere_points"],
)
case("threads-0", lambda: (_base(), {"threads": 0}), ParameterError, ["threads"])
for _sel in ["Fast", "quick", "", 1]:
    case(
        f"selection-{_sel!r}",
        lambda sel=_sel: (_base(), {"selection": sel}),
        ParameterError,
        ["selection", "exhaustive", "fast"],
    )

# --- memory budget -------------------------------------------------------------
for _lim in [0, 1000]:
    case(
        f"max_memory-{_lim}",
        lambda lim=_lim: (_base(), {"max_memory": lim}),
        MemoryError,
        ["bytes", f"{_lim} bytes"],
    )
case(
    "max_memory-negative",
    lambda: (_base(), {"max_memory": -1}),
    ParameterError,
    ["max_memory"],
)


def _matches(msg: str, word) -> bool:
    low = msg.lower()
    if isinstance(word, re.Pattern):
        return word.search(msg) is not None
    if isinstance(word, tuple):
        return any(w.lower() in low for w in word)
    return word.lower() in low


def _params():
    out = []
    for cid, make, exc, words in CASES:
        marks = []
        if cid in BUG_CASES:
            marks.append(pytest.mark.xfail(reason=BUG_CASES[cid], strict=True))
        out.append(pytest.param(make, exc, words, id=cid, marks=marks))
    return out


def test_exception_hierarchy():
    """ImageError and ParameterError are ValueError subclasses (docstring of restore)."""
    assert issubclass(ImageError, ValueError)
    assert issubclass(ParameterError, ValueError)
    assert issubclass(uwhl_rs.UwhlError, ValueError)
    assert issubclass(ImageError, uwhl_rs.UwhlError)
    assert issubclass(ParameterError, uwhl_rs.UwhlError)
    assert not issubclass(ImageError, ParameterError)
    assert not issubclass(ParameterError, ImageError)


def test_base_image_is_valid():
    """The image the parameter cases start from is accepted (so errors come from the bad part only)."""
    res = uwhl_rs.restore(_base(), water_types=["II"])
    assert res.image.shape == (H, W, 3)


@pytest.mark.parametrize("make, exc, words", _params())
def test_error_path(make, exc, words):
    """The bad input raises the documented exception with a message naming the problem."""
    image, kwargs = make()
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # a bad input must not go through a numpy warning
        with pytest.raises(exc) as info:
            uwhl_rs.restore(image, **kwargs)
    assert type(info.value) is exc or issubclass(type(info.value), exc)
    msg = str(info.value)
    missing = [w if not isinstance(w, re.Pattern) else w.pattern for w in words if not _matches(msg, w)]
    assert not missing, f"message {msg!r} lacks {missing}"


def test_nonfinite_reports_first_in_raster_order():
    """With several bad values, the one first in raster order (row, column, channel) is reported."""
    a = _base()
    a[7, 1, 0] = np.nan
    a[4, 9, 2] = np.inf
    a[4, 9, 1] = -np.inf  # same pixel, earlier channel: this one comes first
    with pytest.raises(ImageError) as info:
        uwhl_rs.restore(a)
    msg = str(info.value).lower()
    assert "row 4" in msg and "column 9" in msg and "channel 1" in msg, msg


def test_water_mask_all_false_is_not_an_error():
    """An all-False water_mask is valid: no water region, so the documented fallback flag is raised."""
    rng = np.random.default_rng(5)
    img = (0.05 + 0.9 * rng.random((32, 40, 3))).astype(np.float32)
    res = uwhl_rs.restore(img, water_mask=np.zeros((32, 40), bool), water_types=["II"])
    assert "veiling_fallback" in res.flags
    assert not res.veiling_mask.any()


def test_memory_error_reports_both_byte_counts():
    """Over budget: MemoryError whose message holds the limit and a larger 'needed' byte count."""
    limit = 12345
    with pytest.raises(MemoryError) as info:
        uwhl_rs.restore(_base(), max_memory=limit)
    assert not isinstance(info.value, ValueError)
    numbers = [int(n) for n in re.findall(r"\d+", str(info.value))]
    assert limit in numbers, str(info.value)
    assert any(n > limit for n in numbers), str(info.value)


def test_generous_memory_limit_is_accepted():
    """The limit is an upper bound, not a fixed threshold: a generous max_memory lets the call run."""
    res = uwhl_rs.restore(_base(), max_memory=1 << 30, water_types=["II"])
    assert res.transmission.shape == (H, W)


def test_every_error_is_an_exception():
    """Catching Exception catches every error above: nothing (e.g. a pyo3 PanicException) escapes."""
    escaped = []
    for cid, make, _exc, _words in CASES:
        image, kwargs = make()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                uwhl_rs.restore(image, **kwargs)
        except Exception:
            pass
        except BaseException as e:  # noqa: BLE001 - exactly what must not happen
            escaped.append((cid, type(e).__name__, str(e)))
    assert not escaped, escaped
