"""The one reader of sidecars (``NAME.json``, docs/OUTPUTS.md "Sidecar"):
bytes in, a checked document or one line saying what is wrong out.

An output folder is shared and may be written by anyone, so a sidecar is
read as untrusted input: bounded in size and nesting, strict UTF-8, no
NaN or infinity (``1e400`` included), and every field the readers use
(``uwhl report``, ``uwhl ifdo``, the summary rows of skipped inputs)
checked against :data:`FIELDS` before any of them looks at it. A reader then never meets a
value of the wrong type, and a malformed sidecar is a note naming it,
never a traceback.

Keys may be added to sidecars (docs/OUTPUTS.md), so unknown keys pass;
:data:`SCHEMA_VERSION` says which set of fields this module checks.
"""

from __future__ import annotations

import datetime as _dt
import json
import math
import os
import re

import numpy as np

from .errors import UwhlError

__all__ = ["SCHEMA_VERSION", "MAX_BYTES", "MAX_DEPTH", "SidecarError", "parse", "plain_name", "local_outputs_problem",
           "LOCAL_SEPARATORS", "display", "printable", "is_uuid_hex", "is_sha256", "json_depth", "has_lone_surrogate"]

#: the version of the checked fields (the sidecar's own ``uwhl_version`` says which program wrote it)
SCHEMA_VERSION = 1

#: the largest sidecar read, in bytes: a photo's is a few kB; a video's lists up to
#: 5000 estimates (some 650 kB) and a still for every N-th frame (some 170 bytes each:
#: 19,000 stills fit, a two-hour dive at --every 12)
MAX_BYTES = 4 << 20

#: the deepest nesting of arrays and objects accepted (the writers use 3)
MAX_DEPTH = 16

#: the most estimates a video's sidecar lists (its cuts first, then its scheduled estimates thinned evenly)
VIDEO_ESTIMATES = 5000

#: the longest text field accepted (names, paths, notes)
MAX_TEXT = 4096

#: the most entries of ``parameters`` (the writers use about 30)
MAX_PARAMETERS = 256

#: the most bytes of ``parameters`` as JSON (the writers' are about 1 kB; four
#: paths of MAX_TEXT characters fit)
MAX_PARAMETER_BYTES = 32 << 10

#: keys whose presence makes a JSON object a sidecar (else it is another file, left alone)
_MARKS = ("input", "outputs", "water_type", "uwhl_version")

_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f]")
# line and paragraph separators and the bidirectional marks, embeddings, overrides and isolates
_ORDER = re.compile("[\u061c\u200e\u200f\u2028-\u202e\u2066-\u2069]")
_HEX32 = re.compile(r"[0-9a-fA-F]{32}")
_HEX64 = re.compile(r"[0-9a-fA-F]{64}")
# JSON strings (with their escapes), removed before the brackets are counted
_STRINGS = re.compile(rb'"(?:[^"\\]|\\.)*"', re.S)


class _NonFinite:
    """What NaN, Infinity and numbers beyond a float (1e400) are read as:
    refused where a field needs a number, null where one may be unknown
    (a score: the Python writer's ``Infinity`` for a black radiance is
    the Rust writer's ``null``)."""

    def __repr__(self) -> str:
        return "NaN"


_NONFINITE = _NonFinite()


class SidecarError(UwhlError):
    """A sidecar that cannot be used; the message names the problem. (A
    ValueError, as every UwhlError.)"""

    kind = "unreadable_input"


def display(text: str) -> str:
    """``text`` as it can be shown and written as UTF-8: the undecodable
    bytes of a file name (lone surrogates) become U+FFFD, one a byte, as
    the core writes them (docs/OUTPUTS.md "Names")."""
    try:
        return os.fsencode(text).decode("utf-8", "replace")
    except UnicodeEncodeError:  # a surrogate no file name's byte gives
        return text.encode("utf-8", "surrogatepass").decode("utf-8", "replace")


def printable(text: str) -> str:
    """``text`` (:func:`display`) with control characters written as
    ``\\xNN`` escapes, and line and paragraph separators and bidirectional
    formatting characters (U+061C, U+200E, U+200F, U+2028-U+202E,
    U+2066-U+2069) as ``\\uNNNN``: a note quoting a file name or a
    sidecar's value can neither move the cursor or recolour the terminal it
    is printed on, nor break a line or reorder how the rest of it reads
    (the binary's ``printable`` follows the same rule)."""
    text = _CONTROL.sub(lambda m: f"\\x{ord(m.group()):02x}", display(text))
    return _ORDER.sub(lambda m: f"\\u{ord(m.group()):04x}", text)


#: what separates folders in a local path here: ``/``, and on Windows ``\\`` too
LOCAL_SEPARATORS = "".join(sorted({"/", os.sep, os.altsep or "/"}))


def plain_name(name: object, separators: str = "/") -> bool:
    """Whether ``name`` is a bare file name (an output beside its sidecar):
    none of ``separators`` (a folder part), not ``.`` or ``..``, no NUL.
    A backslash is an ordinary character of a POSIX file name and of an
    object's key, and ``restore`` names the outputs of ``back\\slash.png``
    ``back\\slash.jpg``: only a local folder where it separates folders
    (Windows: :data:`LOCAL_SEPARATORS`) refuses it. Control characters are
    allowed: ``restore`` writes the outputs of a photo whose name holds
    them, and every reader shows names escaped (the page as text, the
    console through :func:`printable`)."""
    return (isinstance(name, str) and 0 < len(name) <= 255 and name not in (".", "..")
            and not any(c in name for c in separators + "\0"))


def local_outputs_problem(doc: dict) -> str | None:
    """Why a checked sidecar's outputs cannot be beside it in a local
    folder here (an output's name holds a backslash and this is Windows),
    as :func:`parse` says a field's problem; None when they can."""
    outputs = doc.get("outputs") or {}
    for role in OUTPUT_ROLES:
        name = outputs.get(role)
        if name is not None and not plain_name(name, LOCAL_SEPARATORS):
            return f"outputs.{role} {_NOT_PLAIN}"
    return None


def is_uuid_hex(v: object) -> bool:
    """32 hexadecimal digits (EXIF ImageUniqueID's form)."""
    return isinstance(v, str) and bool(_HEX32.fullmatch(v))


def is_sha256(v: object) -> bool:
    """64 hexadecimal digits."""
    return isinstance(v, str) and bool(_HEX64.fullmatch(v))


# ------------------------------------------------------------------ field checks
# each check returns None when the value is fine, else what is wrong


def _at(where: str, why: str) -> str:
    """``why`` said of the field at ``where`` (nested paths join: ``metadata.gps.latitude``)."""
    return where + (why if why[:1] in ".[" else " " + why)


def _text(v):
    if not isinstance(v, str):
        return "must be text"
    return None if len(v) <= MAX_TEXT else f"is longer than {MAX_TEXT} characters"


def _nonempty_text(v):
    return _text(v) or (None if v else "must not be empty")


def _path_text(v):
    return _nonempty_text(v) or (None if "\x00" not in v else "holds a NUL character")


def _number(v):
    if v is _NONFINITE:
        return "is not a finite number (NaN, Infinity, or beyond a float)"
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        return "must be a number"
    return None if math.isfinite(v) else "must be finite"


def _count(v):
    return None if isinstance(v, int) and not isinstance(v, bool) and v >= 0 else "must be a whole number >= 0"


def _flag(v):
    return None if isinstance(v, bool) else "must be true or false"


def _score(v):
    return None if v is None or v is _NONFINITE else _number(v)


def _optional(check):
    return lambda v: None if v is None else check(v)


def _list_of(check, length: int | None = None, most: int = 1000):
    def f(v):
        if not isinstance(v, list):
            return "must be a list"
        if length is not None and len(v) != length:
            return f"must have {length} entries, not {len(v)}"
        if len(v) > most:
            return f"has more than {most} entries"
        for k, x in enumerate(v):
            why = check(x)
            if why:
                return _at(f"[{k}]", why)
        return None
    return f


def _map_of(check, most: int = 1000):
    def f(v):
        if not isinstance(v, dict):
            return "must be an object"
        if len(v) > most:
            return f"has more than {most} entries"
        for k, x in v.items():
            why = _text(k) or check(x)
            if why:
                return _at(f"[{json.dumps(k)[:60]}]", why)
        return None
    return f


def _object(fields: dict, required: tuple = ()):
    def f(v):
        if not isinstance(v, dict):
            return "must be an object"
        for k in required:
            if k not in v:
                return f"has no {k}"
        for k, check in fields.items():
            if k in v:
                why = check(v[k])
                if why:
                    return _at(f".{k}", why)
        return None
    return f


def _parameters(v):
    """The options a photo was restored with: an object of at most
    :data:`MAX_PARAMETERS` entries and :data:`MAX_PARAMETER_BYTES` as JSON.
    The report and the iFDO export copy it whole into every photo's entry,
    so a planted one of 4 MiB of small lists became a YAML file of 20 MB
    and 750 MB of memory a sidecar; real ones are about 1 KB."""
    why = _object({})(v)
    if why:
        return why
    if len(v) > MAX_PARAMETERS:
        return f"has more than {MAX_PARAMETERS} entries"
    size = len(json.dumps(v))
    return None if size <= MAX_PARAMETER_BYTES else f"is {size} bytes as JSON, over {MAX_PARAMETER_BYTES}"


def _in_range(lo: float, hi: float):
    def f(v):
        return _number(v) or (None if lo <= v <= hi else f"must be between {lo:g} and {hi:g}")
    return f


_NOT_PLAIN = "must be a file name beside the sidecar (no folder, no ..)"

#: the outputs a sidecar names (``outputs``), each a file beside it
OUTPUT_ROLES = ("image", "transmission", "transmission_color", "confidence", "contact_sheet", "video", "strip")


def _output_name(v):
    return None if v is None or plain_name(v) else _NOT_PLAIN


def _iso_time(v):
    if v is None:
        return None
    if not isinstance(v, str) or len(v) > 64:
        return "must be an ISO 8601 time (text)"
    try:
        _dt.datetime.fromisoformat(v)
    except ValueError:
        return "is not an ISO 8601 time"
    return None


def _hex(pattern_check, what):
    return lambda v: None if v is None or pattern_check(v) else f"must be {what}"


#: the fields the readers use, and what each must be (absent is fine unless in REQUIRED)
FIELDS = {
    "input": _path_text,
    "outputs": _object({r: _output_name for r in OUTPUT_ROLES}),
    "kind": _text,
    # a video's sidecar (docs/OUTPUTS.md "Videos")
    "video": _object({
        # the report draws every estimate: each has what it draws
        "estimates": _list_of(_object({"frame": _count, "time": _optional(_number), "event": _text,
                                       "change": _optional(_number), "water_type": _text,
                                       "veiling_light": _list_of(_number, 3)},
                                      required=("frame", "event", "water_type", "veiling_light")),
                              most=VIDEO_ESTIMATES),
        "frames": _object({"decoded": _count, "restored": _count, "reused": _count, "unrestored": _count,
                           "every": _count}),
        "stopped": _optional(_object({"frame": _count, "time": _optional(_number), "error": _text},
                                     required=("frame", "error"))),
        "unrestored": _list_of(_object({"frame": _count, "time": _optional(_number), "error": _optional(_text)}),
                               most=1000),
        "stream": _object({"width": _optional(_count), "height": _optional(_count), "rate": _optional(_number),
                           "codec": _optional(_text), "duration": _optional(_number)}),
    }),
    "uwhl_version": _text,
    "implementation": _text,
    "water_type": _nonempty_text,
    "scores": _map_of(_score),
    "excluded": _list_of(_text),
    "veiling_light": _list_of(_number, 3),
    "flags": _list_of(_text),
    "beta_ratios": _list_of(_number, 2),
    "reused_estimates": _flag,
    "vl_pixels": _count,
    "vl_fraction": _number,
    "veil_excess": _optional(_in_range(0, 1)),
    "fallback_share": _optional(_in_range(0, 1)),
    "guided_radius": _count,
    "guided_subsample": _count,
    "parameters": _parameters,
    "source": _object({"path": _optional(_text), "height": _optional(_count), "width": _optional(_count),
                       "notes": _optional(_list_of(_text))}),
    "seconds": _map_of(_optional(_number)),
    "metadata": _object({
        "written": _optional(_flag),
        "taken_at": _iso_time,
        "gps": _optional(_object({"latitude": _optional(_in_range(-90, 90)),
                                  "longitude": _optional(_in_range(-180, 180)),
                                  "altitude": _optional(_number)})),
        "image_uuid": _hex(is_uuid_hex, "32 hexadecimal digits"),
        "photo_sha256": _hex(is_sha256, "64 hexadecimal digits"),
        "input_sha256": _hex(is_sha256, "64 hexadecimal digits"),
        "input_image_uuid": _optional(_text),
        "notes": _optional(_list_of(_text)),
    }),
}

#: the fields every sidecar has
REQUIRED = ("input", "outputs", "water_type")


def _no_constant(name: str):
    return _NONFINITE


def _finite_float(text: str):
    v = float(text)
    return v if math.isfinite(v) else _NONFINITE


def _unknown_as_null(v):
    """``v`` with every non-finite number left after the checks as None."""
    if v is _NONFINITE:
        return None
    if isinstance(v, dict):
        return {k: _unknown_as_null(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_unknown_as_null(x) for x in v]
    return v


def _bounded_int(text: str):
    # a 5000-digit integer is no count or coordinate, and would not convert to a float
    return int(text) if len(text) <= 19 else _finite_float(text)


def json_depth(data: bytes) -> int:
    """The deepest nesting of ``data``'s arrays and objects, counted
    without recursion (outside strings)."""
    # the running depth as a cumulative sum (a byte at a time in Python took
    # 0.15 s a 4 MiB file: a folder of planted ones took minutes)
    b = np.frombuffer(_STRINGS.sub(b'""', data), dtype=np.uint8)
    if not b.size:
        return 0
    step = (b == ord("[")).astype(np.int32) + (b == ord("{")) - (b == ord("]")) - (b == ord("}"))
    return max(0, int(np.cumsum(step).max()))


def has_lone_surrogate(doc) -> bool:
    """Whether a string (a key or a value) of ``doc`` holds a surrogate
    code point that is not half of a pair (JSON's escapes allow one; UTF-8
    cannot encode it)."""
    try:
        json.dumps(doc, ensure_ascii=False).encode("utf-8")
    except UnicodeEncodeError:
        return True
    return False


def _replace_surrogates(v):
    """``v`` with every lone surrogate of its strings (keys too) as U+FFFD."""
    if isinstance(v, str):
        return v.encode("utf-16", "surrogatepass").decode("utf-16", "replace")
    if isinstance(v, dict):
        return {_replace_surrogates(k): _replace_surrogates(x) for k, x in v.items()}
    if isinstance(v, list):
        return [_replace_surrogates(x) for x in v]
    return v


def parse(data: bytes) -> dict | None:
    """The checked sidecar in ``data`` (the bytes of a ``.json`` file of an
    output folder); None when it is a JSON object that is no sidecar at
    all (no ``input``, ``outputs``, ``water_type`` or ``uwhl_version``:
    another program's file, left alone). Raises :class:`SidecarError`
    saying what is wrong: too large, not UTF-8, not JSON, too deeply
    nested, a number out of range, not an object, a field missing or of
    the wrong shape."""
    if len(data) > MAX_BYTES:
        raise SidecarError(f"larger than {MAX_BYTES} bytes ({len(data)})")
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError as e:
        raise SidecarError(f"not UTF-8 text (byte {e.start})") from None
    if json_depth(data) > MAX_DEPTH:
        raise SidecarError(f"nested deeper than {MAX_DEPTH} levels")
    try:
        doc = json.loads(text, parse_constant=_no_constant, parse_float=_finite_float,
                         parse_int=_bounded_int)
    except (ValueError, RecursionError) as e:
        raise SidecarError(f"not JSON ({str(e)[:200]})") from None
    if not isinstance(doc, dict):
        raise SidecarError(f"not a JSON object (a {type(doc).__name__})")
    if not any(k in doc for k in _MARKS):
        return None
    if b"\\u" in data and has_lone_surrogate(doc):
        # "\ud800" parses to a str no file name, console or YAML file can
        # hold: read as U+FFFD, as the core reads a sidecar
        doc = _replace_surrogates(doc)
    check(doc)
    return _unknown_as_null(doc)


def check(doc: dict) -> None:
    """Raises :class:`SidecarError` naming the first field of ``doc`` that
    is missing or of the wrong shape."""
    missing = [k for k in REQUIRED if k not in doc]
    if missing:
        raise SidecarError(f"no {', '.join(missing)} (not a complete sidecar)")
    for k, rule in FIELDS.items():
        if k in doc:
            why = rule(doc[k])
            if why:
                raise SidecarError(_at(k, why))
