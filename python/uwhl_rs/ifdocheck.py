"""What the iFDO 2.0.1 schema (ifdo-v2.0.1.json, image-set-header and
image-set-items) asks of the fields ``uwhl_rs.ifdo`` writes or takes from
a header file: types, ranges, the UUID form, URIs and the enumerations.
A document that passes these checks passes the schema's own (the tests
validate every written file with jsonschema against the schema itself);
the point is to refuse a bad value here, naming its field, rather than
write a file an ingester rejects."""

from __future__ import annotations

import math
import re

__all__ = ["field_problems", "plain_data", "uri_problem", "UUID_PATTERN", "DEFAULT_TIME_FORMAT"]

#: the schema's ``uuid`` (version 4, with or without hyphens)
UUID_PATTERN = re.compile(r"[0-9a-fA-F]{8}-[0-9a-fA-F]{4}-4[0-9a-fA-F]{3}-[89abAB][0-9a-fA-F]{3}-[0-9a-fA-F]{12}"
                          r"|[0-9a-fA-F]{12}4[0-9a-fA-F]{3}[89abAB][0-9a-fA-F]{15}")

_URI = re.compile(r"[A-Za-z][A-Za-z0-9+.-]*:[^\s\x00-\x1f\x7f<>\"{}|\\^`]*")

_TEXT = ("image-set-name", "image-set-handle", "image-set-ifdo-version", "image-datetime", "image-handle",
         "image-coordinate-reference-system", "image-hash-sha256", "image-copyright", "image-abstract",
         "image-set-local-path", "image-datetime-format", "image-objective", "image-target-environment",
         "image-target-timescale", "image-spatial-constraints", "image-temporal-constraints",
         "image-time-synchronisation", "image-item-identification-scheme", "image-curation-protocol",
         "image-visual-constraints")

#: number fields and their bounds (None: unbounded)
_NUMBER = {
    "image-latitude": (-90, 90), "image-longitude": (-180, 180),
    # beyond the deepest trench or the edge of space: not a place on Earth (the schema bounds none)
    "image-altitude-meters": (-12000, 100000),
    "image-coordinate-uncertainty-meters": (0, None), "image-entropy": (0, 1),
    "image-area-square-meters": (None, None), "image-meters-above-ground": (None, None),
    "image-camera-yaw-degrees": (None, None), "image-camera-pitch-degrees": (None, None),
    "image-camera-roll-degrees": (None, None), "image-overlap-fraction": (None, 1),
    "image-set-min-latitude-degrees": (-90, 90), "image-set-max-latitude-degrees": (-90, 90),
    "image-set-min-longitude-degrees": (-180, 180), "image-set-max-longitude-degrees": (-180, 180),
}

#: object fields; those with a name/uri pair have the uri checked
_OBJECT = ("image-context", "image-project", "image-event", "image-platform", "image-sensor", "image-pi",
           "image-license", "image-acquisition-settings", "image-camera-pose", "image-camera-housing-viewport",
           "image-flatport-parameters", "image-domeport-parameters", "image-camera-calibration-model",
           "image-photometric-calibration", "image-set-provenance")

_ARRAY = ("image-creators", "image-average-color", "image-mpeg7-colorlayout", "image-mpeg7-colorstatistic",
          "image-mpeg7-colorstructure", "image-mpeg7-dominantcolor", "image-mpeg7-edgehistogram",
          "image-mpeg7-homogeneoustexture", "image-mpeg7-scalablecolor", "image-set-related-material")

_ENUM = {
    "image-acquisition": ("photo", "video", "slide"),
    "image-quality": ("raw", "processed", "product"),
    "image-deployment": ("mapping", "stationary", "survey", "exploration", "experiment", "sampling"),
    "image-navigation": ("satellite", "beacon", "transponder", "reconstructed"),
    "image-scale-reference": ("3D camera", "calibrated camera", "laser marker", "optical flow"),
    "image-illumination": ("sunlight", "artificial light", "mixed light"),
    "image-pixel-magnitude": ("km", "hm", "dam", "m", "cm", "mm", "µm"),
    "image-marine-zone": ("seafloor", "water column", "sea surface", "atmosphere", "laboratory"),
    "image-spectral-resolution": ("grayscale", "rgb", "multi-spectral", "hyper-spectral"),
    "image-capture-mode": ("timer", "manual", "mixed"),
    "image-fauna-attraction": ("none", "baited", "light"),
}

_URI_FIELDS = ("image-set-handle", "image-handle")


#: iFDO's default ``image-datetime-format``
DEFAULT_TIME_FORMAT = "%Y-%m-%d %H:%M:%S.%f"


#: the longest ``image-datetime-format`` taken (it is written into every item's time)
MAX_TIME_FORMAT = 200


def _is_time(v: str, fmt) -> bool:
    """``v`` is a real time in ``fmt`` (the header's image-datetime-format,
    when it gives one as text), or in iFDO's default format, to the second
    or finer. 9999-99-99 is not, though the schema takes any text."""
    import datetime as dt

    forms = [fmt] if isinstance(fmt, str) else [DEFAULT_TIME_FORMAT, "%Y-%m-%d %H:%M:%S"]
    for f in forms:
        try:
            dt.datetime.strptime(v, f)
            return True
        except Exception:  # noqa: BLE001 - a format can make strptime raise more than ValueError (re.error)
            continue
    return False


def time_format_problem(fmt) -> str | None:
    """Why ``fmt`` cannot be an ``image-datetime-format`` the photos' times
    are written in, or None: it must be text of at most
    :data:`MAX_TIME_FORMAT` characters that gives two different times as
    two different, non-empty texts, each of which it reads back."""
    import datetime as dt

    if not isinstance(fmt, str):
        return "must be text"
    if len(fmt) > MAX_TIME_FORMAT:
        return f"is longer than {MAX_TIME_FORMAT} characters"
    utc = dt.timezone.utc
    one, two = dt.datetime(2001, 2, 3, 4, 5, 6, 7000, utc), dt.datetime(2026, 11, 30, 22, 33, 44, 500000, utc)
    try:
        a, b = one.strftime(fmt), two.strftime(fmt)
        if not a.strip() or a == b:
            return "gives no time (the same text for any time)"
        for text in (a, b):
            dt.datetime.strptime(text, fmt)
    except Exception as e:  # noqa: BLE001 - strftime/strptime raise ValueError, re.error, ...
        return f"cannot be written and read back as a time ({str(e).splitlines()[0][:100] or type(e).__name__})"
    return None


def _finite(v) -> bool:
    try:
        return math.isfinite(v)
    except OverflowError:  # an integer of hundreds of digits is no measurement either
        return False


def _is_number(v) -> bool:
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def uri_problem(v) -> str | None:
    """Why ``v`` is no URI (text of ``scheme:...`` without spaces), or None."""
    if not isinstance(v, str):
        return "must be a URI (text)"
    return None if _URI.fullmatch(v) else "must be a URI (scheme:..., no spaces)"


def field_problems(fields: dict) -> list[str]:
    """What is wrong with the iFDO fields ``fields`` (a header or one
    item), one line per field, each starting with the field's name."""
    out = []
    fmt = fields.get("image-datetime-format")
    for k, v in fields.items():
        if k in _TEXT and not isinstance(v, str):
            out.append(f"{k} must be text, not {v!r:.60}")
        if k == "image-datetime-format" and (why := time_format_problem(v)):
            out.append(f"{k} {why}: {v!r:.60}")
        if k == "image-datetime" and isinstance(v, str) and not _is_time(v, fmt):
            out.append(f"{k} must be a time in the form {fmt if isinstance(fmt, str) else DEFAULT_TIME_FORMAT!r}"
                       f" (image-datetime-format), not {v!r:.60}")
        if k in ("image-set-header", "image-set-items"):
            out.append(f"{k} is a part of the iFDO file, not a field: the header gives the fields of "
                       "image-set-header itself")
        if k in _URI_FIELDS and isinstance(v, str) and uri_problem(v):
            out.append(f"{k} {uri_problem(v)}: {v!r:.80}")
        if k in _NUMBER:
            lo, hi = _NUMBER[k]
            if not _is_number(v) or not _finite(v):
                out.append(f"{k} must be a finite number, not {v!r:.60}")
            elif (lo is not None and v < lo) or (hi is not None and v > hi):
                out.append(f"{k} must be between {lo} and {hi}, not {v!r}".replace("None", "any"))
        if k == "image-particle-count" and not (isinstance(v, int) and not isinstance(v, bool) and v >= 0):
            out.append(f"{k} must be a whole number >= 0")
        if k in ("image-set-uuid", "image-uuid") and not (isinstance(v, str) and UUID_PATTERN.fullmatch(v)):
            out.append(f"{k} must be a version-4 UUID (8-4-4-4-12 hexadecimal digits), not {v!r:.60}")
        if k in _ENUM and v not in _ENUM[k]:
            out.append(f"{k} must be one of {', '.join(_ENUM[k])}, not {v!r:.60}")
        if k in _OBJECT:
            if not isinstance(v, dict):
                out.append(f"{k} must be a mapping")
            elif "uri" in v and uri_problem(v["uri"]):
                out.append(f"{k}.uri {uri_problem(v['uri'])}")
        if k in _ARRAY:
            if not isinstance(v, list):
                out.append(f"{k} must be a list")
            elif k in ("image-creators", "image-set-related-material"):
                for n, c in enumerate(v):
                    if isinstance(c, dict) and "uri" in c and uri_problem(c["uri"]):
                        out.append(f"{k}[{n}].uri {uri_problem(c['uri'])}")
            elif k == "image-average-color" and not all(isinstance(c, int) and 0 <= c <= 256 for c in v):
                out.append(f"{k} must be whole numbers from 0 to 256")
    return out


def plain_data(value, where: str = "") -> str | None:
    """Why ``value`` (a header as YAML gave it) cannot be written as JSON
    and YAML alike, or None: only mappings with text keys, lists, text,
    finite numbers, true/false and null (no YAML dates, sets, binary,
    NaN or infinity)."""
    stack = [(where, value)]
    while stack:
        at, v = stack.pop()
        if isinstance(v, dict):
            for k, x in v.items():
                if not isinstance(k, str):
                    return f"{at or 'the header'} has a key that is not text ({k!r:.40})"
                stack.append((f"{at}.{k}" if at else k, x))
        elif isinstance(v, list):
            stack.extend((f"{at}[{n}]", x) for n, x in enumerate(v))
        elif isinstance(v, float) and not math.isfinite(v):
            return f"{at} must be a finite number, not {v!r}"
        elif not (v is None or isinstance(v, (str, bool, int, float))):
            return f"{at} must be text, a number, true/false or a list or mapping of them (not a {type(v).__name__}; " \
                   "quote a date to make it text)"
    return None
