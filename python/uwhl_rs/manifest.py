"""The manifest of ``uwhl evaluate`` (docs/EVALUATE.md): reading it
safely (a regular file, bounded, UTF-8 JSON) and checking every entry, so
that a bad entry is one line naming it before anything runs."""

from __future__ import annotations

import errno
import json
import os
import stat
from dataclasses import dataclass, field

from . import _core
from .errors import ManifestError

#: Profiles ``--method`` can name (METHOD §12), the default first.
METHODS = tuple(next(o["choices"] for o in _core.OPTIONS if o["key"] == "method"))

_ENTRY_KEYS = {"path", "distance", "distance_depth", "water_type", "water_mask", "charts", "restore", "truth",
               "truth_mask"}
_CHART_KEYS = {"name", "gray_patches", "region"}
#: The Jerlov types in table order (METHOD §1).
TYPE_ORDER = [n for n, _, _ in _core.JERLOV_TABLE]
_METHOD_KEYS = {o["key"] for o in _core.OPTIONS if o["method"]}
#: restore keywords that set the machine's limits, not the method: the command line's only
_MACHINE_KEYS = {"max_memory", "threads"}
#: A manifest lists images and boxes; anything larger is not one (and is not read into memory).
MAX_MANIFEST_BYTES = 16 << 20
#: Most charts of an entry, and boxes of a chart's gray patches or region: each box is averaged or masked
#: on every profile and baseline, so a few kilobytes of boxes could hold a run for days.
MAX_CHARTS = 64
MAX_BOXES = 64


@dataclass
class Chart:
    """One chart of an image: its gray patches and the region it covers."""

    name: str
    gray_patches: list[tuple[int, int, int, int]]
    region: list[tuple[int, int, int, int]] = field(default_factory=list)


@dataclass
class Entry:
    """One image of a manifest."""

    label: str
    path: str
    distance: str | None = None
    water_type: str | None = None
    charts: list[Chart] = field(default_factory=list)
    restore: dict = field(default_factory=dict)
    water_mask: str | None = None
    #: the entry's ``path`` as written in the manifest (``path`` is it joined to the manifest's folder)
    manifest_path: str = ""
    #: the true radiance (linear) and the pixels to score against it (uwhl_rs.truth)
    truth: str | None = None
    truth_mask: str | None = None
    #: the distance map holds depth along the camera's axis: (the lens's horizontal
    #: field of view in air, degrees; the port), turned into ranges (METHOD §13.7)
    distance_depth: tuple[float, str] | None = None


def _box(v, what: str) -> tuple[int, int, int, int]:
    if not (isinstance(v, (list, tuple)) and len(v) == 4 and all(isinstance(x, int) and not isinstance(x, bool)
                                                                 for x in v)):
        raise ManifestError(f"{what}: a box is [x0, y0, x1, y1] in integer pixels, not {_short(v)}")
    x0, y0, x1, y1 = v
    if x0 < 0 or y0 < 0 or x1 <= x0 or y1 <= y0:
        raise ManifestError(f"{what}: box {_short(list(v))} is empty or starts before the image (need 0 <= x0 < x1, 0 <= y0 < y1)")
    return x0, y0, x1, y1


def _regular(path: str, label: str, what: str) -> None:
    """A file an entry names must be a regular file: one that is missing,
    and a FIFO, device or folder (which could block or never end), are
    each called what they are."""
    try:
        st = os.stat(path)
    except UnicodeEncodeError:
        # a lone surrogate other than an undecodable byte's escape (\udc80-\udcff) names no file
        raise ManifestError(f"{label}: the {what} path is not a file name (it holds a lone surrogate)") from None
    except ValueError:
        raise ManifestError(f"{label}: the {what} path is not a file name (it holds a NUL)") from None
    except OSError as e:
        why = "no such" if e.errno in (errno.ENOENT, errno.ENOTDIR) else f"cannot reach ({e.strerror or e}) the"
        raise ManifestError(f"{label}: {why} {what} file {path}") from None
    if not stat.S_ISREG(st.st_mode):
        kind = "a folder" if stat.S_ISDIR(st.st_mode) else "a FIFO" if stat.S_ISFIFO(st.st_mode) else \
            "a device" if stat.S_ISCHR(st.st_mode) or stat.S_ISBLK(st.st_mode) else "not a regular file"
        raise ManifestError(f"{label}: the {what} file {path} is {kind}, not a regular file")


def _entry(k: int, raw, folder: str) -> Entry:
    label = f"images[{k}]"
    if not isinstance(raw, dict):
        raise ManifestError(f"{label}: an entry is an object with a 'path', not {type(raw).__name__}")
    if "path" in raw and isinstance(raw["path"], str):
        label = f"images[{k}] ({raw['path']})"
    unknown = sorted(set(raw) - _ENTRY_KEYS)
    if unknown:
        raise ManifestError(f"{label}: unknown key(s) {_short(unknown)} (known: {sorted(_ENTRY_KEYS)})")
    if not isinstance(raw.get("path"), str):
        raise ManifestError(f"{label}: 'path' (the image, relative to the manifest) is required")
    path = os.path.join(folder, raw["path"])
    _regular(path, label, "image")

    def file_key(key: str, what: str):
        # an optional file named by the entry, relative to the manifest
        value = raw.get(key)
        if value is None:
            return None
        if not isinstance(value, str):
            raise ManifestError(f"{label}: '{key}' is a file path, not {_short(value)}")
        value = os.path.join(folder, value)
        _regular(value, label, what)
        return value

    distance = file_key("distance", "distance")
    depth = _distance_depth(raw.get("distance_depth"), label, distance is not None)
    water_mask = file_key("water_mask", "water-mask")
    truth = file_key("truth", "truth")
    truth_mask = file_key("truth_mask", "truth-mask")
    if truth_mask is not None and truth is None:
        raise ManifestError(f"{label}: 'truth_mask' says which pixels to score against 'truth', which is missing")
    wt = _table_name(raw.get("water_type"))
    if wt is not None and wt not in TYPE_ORDER:
        raise ManifestError(f"{label}: water_type {_short(wt)} is not one of {TYPE_ORDER}")
    charts = []
    raw_charts = raw.get("charts")
    if raw_charts is not None and not isinstance(raw_charts, list):
        raise ManifestError(f"{label}: 'charts' is a list of chart objects, not {_short(raw_charts)}")
    if len(raw_charts or []) > MAX_CHARTS:
        raise ManifestError(f"{label}: {len(raw_charts)} charts, over the limit of {MAX_CHARTS}")
    for c, ch in enumerate(raw_charts or []):
        what = f"{label} charts[{c}]"
        if not isinstance(ch, dict):
            raise ManifestError(f"{what}: a chart is an object, not {_short(ch)}")
        unknown = sorted(set(ch) - _CHART_KEYS)
        if unknown:
            raise ManifestError(f"{what}: unknown key(s) {_short(unknown)} (known: {sorted(_CHART_KEYS)})")
        patches = ch.get("gray_patches")
        if not isinstance(patches, list) or not patches:
            raise ManifestError(f"{what}: 'gray_patches' (a list of boxes) is required")
        region = ch.get("region") or []
        if not isinstance(region, list):
            raise ManifestError(f"{what}: 'region' is a list of boxes")
        for key, boxes in (("gray_patches", patches), ("region", region)):
            if len(boxes) > MAX_BOXES:
                raise ManifestError(f"{what}: {len(boxes)} boxes in '{key}', over the limit of {MAX_BOXES}")
        name = ch.get("name", f"chart {c + 1}")
        charts.append(Chart(str(name), [_box(b, f"{what} gray_patches[{i}]") for i, b in enumerate(patches)],
                            [_box(b, f"{what} region[{i}]") for i, b in enumerate(region)]))
    restore = raw.get("restore") or {}
    if not isinstance(restore, dict):
        raise ManifestError(f"{label}: 'restore' is an object of restore() keywords")
    machine = sorted(set(restore) & _MACHINE_KEYS)
    if machine:
        # the user's limits hold for every entry: a manifest must not lift --max-memory or ask for 1024 threads
        raise ManifestError(f"{label}: restore.{machine[0]} is the machine's, not the photo's: give "
                            f"--{machine[0].replace('_', '-')} to uwhl evaluate")
    unknown = sorted(set(restore) - _METHOD_KEYS)
    if unknown:
        raise ManifestError(f"{label}: unknown restore keyword(s) {_short(unknown)} (known: {sorted(_METHOD_KEYS - _MACHINE_KEYS)})")
    restore = dict(restore)
    if "water_types" in restore:
        restore["water_types"] = _water_types(restore["water_types"], f"{label}: restore.water_types")
    if "method" in restore and restore["method"] not in METHODS:
        raise ManifestError(f"{label}: restore.method {_short(restore['method'])} is not one of {list(METHODS)}")
    _check_restore(restore, label)
    return Entry(label, path, distance, wt, charts, restore, water_mask, raw["path"], truth, truth_mask, depth)


def _distance_depth(v, label: str, has_distance: bool) -> tuple[float, str] | None:
    """An entry's ``distance_depth``: ``{"fov": DEG, "port": "flat" | "dome"}``
    when its map holds depth along the camera's axis (photogrammetry's)."""
    if v is None:
        return None
    what = f"{label}: distance_depth"
    if not has_distance:
        raise ManifestError(f"{what} describes the entry's 'distance' map, which is missing")
    if not isinstance(v, dict) or set(v) - {"fov", "port"}:
        raise ManifestError(f"{what} is {{\"fov\": degrees, \"port\": \"flat\" or \"dome\"}}, not {_short(v)}")
    fov, port = v.get("fov"), v.get("port", "flat")
    if isinstance(fov, bool) or not isinstance(fov, (int, float)) or not (0 < fov <= 170):
        raise ManifestError(f"{what}: fov (the lens's horizontal field of view in air, degrees) is a number in "
                            f"(0, 170], not {_short(fov)}")
    if port not in ("flat", "dome"):
        raise ManifestError(f"{what}: port is \"flat\" or \"dome\", not {_short(port)}")
    return float(fov), port


def _short(v, limit: int = 80) -> str:
    """A value of the manifest as a message quotes it: its repr, cut short."""
    r = repr(v)
    return r if len(r) <= limit else r[:limit] + "..."


def _table_name(name):
    """A table water type's name as the table writes it, read in any case as
    ``restore`` reads it (``"3c"`` is ``"3C"``); anything else as it is."""
    if isinstance(name, str):
        return next((t for t in TYPE_ORDER if t.lower() == name.lower()), name)
    return name


def _water_types(value, what: str) -> list:
    """restore.water_types as ``restore`` takes it. JSON has no tuples, so a
    custom type is written ``[NAME, BETA_BR, BETA_BG]`` or
    ``{"name": NAME, "beta_br": BETA_BR, "beta_bg": BETA_BG}``."""
    if not isinstance(value, list):
        raise ManifestError(f"{what}: a list of type names or custom types, not {_short(value)}")
    out = []
    for i, t in enumerate(value):
        if isinstance(t, dict) and set(t) == {"name", "beta_br", "beta_bg"}:
            t = [t["name"], t["beta_br"], t["beta_bg"]]
        if isinstance(t, str):
            t = _table_name(t)
            if t not in TYPE_ORDER:
                raise ManifestError(f"{what}[{i}]: unknown water type {_short(t)} (known: {', '.join(TYPE_ORDER)}; "
                                    'a custom type is [NAME, BETA_BR, BETA_BG] or {"name": ..., "beta_br": ..., '
                                    '"beta_bg": ...})')
            out.append(t)
        elif (isinstance(t, list) and len(t) == 3 and isinstance(t[0], str)
              and all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in t[1:])):
            out.append((t[0], float(t[1]), float(t[2])))
        else:
            raise ManifestError(f"{what}[{i}]: a water type is a name, [NAME, BETA_BR, BETA_BG] or "
                                f'{{"name": ..., "beta_br": ..., "beta_bg": ...}}, not {_short(t)}')
    return out


def _check_restore(restore: dict, label: str) -> None:
    """The entry's restore keywords checked now, without an image, so a bad
    value is a bad entry (named, exit 3) before anything runs."""
    import uwhl_rs

    try:
        uwhl_rs.Sequence(**restore)
    except (uwhl_rs.ParameterError, TypeError, ValueError, OverflowError) as e:
        raise ManifestError(f"{label}: restore: {e}") from None


def _read_manifest(path: str) -> dict:
    """The manifest's JSON document. Only a regular file is read (a FIFO or
    a device would block or never end), at most MAX_MANIFEST_BYTES of it."""
    try:
        fd = os.open(path, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0) | getattr(os, "O_CLOEXEC", 0))
    except OSError as e:
        raise ManifestError(f"{path}: cannot read the manifest ({e.strerror or e})") from None
    try:
        st = os.fstat(fd)
        if not stat.S_ISREG(st.st_mode):
            raise ManifestError(f"{path}: the manifest must be a regular file, not "
                                f"{'a folder' if stat.S_ISDIR(st.st_mode) else 'a FIFO' if stat.S_ISFIFO(st.st_mode) else 'a device or socket'}")
        if st.st_size > MAX_MANIFEST_BYTES:
            raise ManifestError(f"{path}: the manifest is {st.st_size} bytes, over the limit of {MAX_MANIFEST_BYTES}")
        chunks, size = [], 0
        while size <= MAX_MANIFEST_BYTES:
            b = os.read(fd, min(1 << 20, MAX_MANIFEST_BYTES + 1 - size))
            if not b:
                break
            chunks.append(b)
            size += len(b)
    except OSError as e:
        raise ManifestError(f"{path}: cannot read the manifest ({e.strerror or e})") from None
    finally:
        os.close(fd)
    if size > MAX_MANIFEST_BYTES:  # it grew while read
        raise ManifestError(f"{path}: the manifest is over the limit of {MAX_MANIFEST_BYTES} bytes")
    data = b"".join(chunks)
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as e:
        raise ManifestError(f"{path}: the manifest is not UTF-8 text (byte 0x{data[e.start]:02x} at offset "
                            f"{e.start})") from None
    try:
        return json.loads(text, object_pairs_hook=_once_each)
    except json.JSONDecodeError as e:
        raise ManifestError(f"{path}: not JSON ({e})") from None
    except RecursionError:
        raise ManifestError(f"{path}: not a manifest (JSON nested too deeply)") from None
    except ValueError as e:  # e.g. an integer of more digits than Python converts
        raise ManifestError(f"{path}: not a manifest ({e})") from None


def _once_each(pairs: list) -> dict:
    """A JSON object whose keys are each given once: with two ``images``
    the last would be taken and the first list dropped without a word."""
    out = {}
    for k, v in pairs:
        if k in out:
            raise ValueError(f"the key {json.dumps(k)[:100]} is given twice in one object")
        out[k] = v
    return out


def load_manifest(path: str) -> tuple[list[Entry], list[str]]:
    """The entries of a manifest and one message per entry that cannot be
    evaluated (the others are). A manifest that is not JSON, or has no
    ``images`` list, raises :class:`ManifestError`."""
    doc = _read_manifest(path)
    if not isinstance(doc, dict) or not isinstance(doc.get("images"), list):
        raise ManifestError(f"{path}: a manifest is an object with an 'images' list")
    unknown = sorted(set(doc) - {"images"})
    # refused like an entry's unknown key (a misspelt key would otherwise go unnoticed); the entries still run
    problems = [f"{path}: unknown top-level key(s) {_short(unknown)} (the manifest has only 'images')"] if unknown else []
    folder = os.path.dirname(os.path.abspath(path))
    entries = []
    for k, raw in enumerate(doc["images"]):
        try:
            entries.append(_entry(k, raw, folder))
        except ManifestError as e:
            problems.append(str(e))
    return entries, problems
