"""One photograph in, corrected files out: :func:`restore_file`, the JSON
sidecar and the contact sheet (file names and contents: docs/OUTPUTS.md)."""

from __future__ import annotations

import inspect
import json
import numbers
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

import uwhl_rs

from . import _core
from ._core import ParameterError
from .errors import ImageReadError, ImageTooLargeError, shown
from .images import ImageMeta, colorize_transmission, display_linear, path_arg, read_image, to_srgb

__all__ = ["FileResult", "restore_file", "output_paths", "contact_sheet", "input_need", "max_side_factor", "spelt",
           "check_name"]

#: Every option's default, from the core's one table (docs/CLI.md).
_D = {o["key"]: o["default"] for o in _core.OPTIONS}

#: The keywords of :func:`uwhl_rs.restore` (and of :class:`uwhl_rs.Sequence`).
METHOD_KEYS = tuple(o["key"] for o in _core.OPTIONS if o["method"])

#: keyword -> flag, from the core's table (``contact`` is restore_file's name of --contact-sheet)
_FLAGS = {**{o["key"]: o["flag"] for o in _core.OPTIONS}, "contact": "--contact-sheet"}


def spelt(key: str, flags: bool) -> str:
    """The option ``key`` as a message names it: the command's flag
    (``--max-memory``) when ``flags`` (the message is the command's, and
    uwhl-rs says the same), else the keyword (``max_memory``) a caller of
    the API passed."""
    return _FLAGS.get(key, "--" + key.replace("_", "-")) if flags else key


@dataclass
class FileResult:
    """What :func:`restore_file` did for one input."""

    restoration: object
    meta: ImageMeta
    #: role ("image", "transmission", "transmission_color", "confidence" when
    #: the method made a confidence map, "contact_sheet", "sidecar") -> path
    paths: dict = field(default_factory=dict)
    sidecar: dict = field(default_factory=dict)


def output_suffixes(fmt: str = "jpg", contact: bool = False) -> list[str]:
    """What follows ``NAME`` in the names of an input's outputs, in writing
    order, without the sidecar's ``.json`` (the claim of ``_core`` adds it):
    the files layer's one list (``_core.output_suffixes``), which the binary
    uses too. An unknown ``fmt`` is a ``ParameterError`` (a ValueError)."""
    return _core.output_suffixes(fmt, contact)


def claim_outputs(out_dir: str, name: str, in_path: str, fmt: str, contact: bool, *, overwrite: bool, rename: bool):
    """Claims ``name`` (or, with ``rename``, the first free ``name_2``, ...) for
    ``in_path``'s outputs in ``out_dir`` (``_core.claim_outputs``; the rules
    are in docs/OUTPUTS.md): ``(status, sidecar, pid, claim)``. An OSError
    (a name too long for the folder, a folder that cannot be written) is
    a failed write of the outputs (its ``kind`` ``write_failed``), also
    when the names are claimed in a staging folder for object storage."""
    try:
        return _core.claim_outputs(out_dir, name, in_path, output_suffixes(fmt, contact), overwrite, rename)
    except OSError as e:
        # claiming is the outputs' first write: the same failure is exit 5 wherever they go (a
        # caller that restores before it writes, as for object storage, would say unreadable input)
        e.kind = "write_failed"
        raise


def output_paths(out_dir: str, name: str, fmt: str = "jpg", contact: bool = False) -> dict:
    """The files written for an input whose outputs are called ``name``:
    role -> path, in writing order (:func:`output_suffixes`), the sidecar last.
    ``confidence`` is written only when the method makes a confidence map
    (METHOD §12.5; the default profile does, ``method="paper"`` does not)."""
    roles = ["image", "transmission", "transmission_color", "confidence"] + (["contact_sheet"] if contact else [])
    p = {role: os.path.join(out_dir, name + s) for role, s in zip(roles, output_suffixes(fmt, contact))}
    p["sidecar"] = os.path.join(out_dir, name + ".json")
    return p


def read_mask(mask, shape, what: str, *, max_pixels: int | None = None, max_memory: int | None = None,
              of: str = "the image", orientation: int = 1) -> np.ndarray | None:
    """A bool mask from an array or an image file (nonzero = True). A mask
    is an argument: one that cannot be read, or of another size than the
    image, is a ``ParameterError`` (exit 2, as in the binary). Files are
    read by the binary's mask reader (``_core.decode_mask_file``: regular
    files only, ``max_pixels`` and ``max_memory`` checked from the header).
    ``what`` names the mask in messages and ``of`` what it must match (an
    input turned upright by its EXIF ``orientation``: said)."""
    if mask is None:
        return None
    if isinstance(mask, (str, os.PathLike)):
        m = _core.decode_mask_file(os.fspath(mask), what, int(max_pixels or _D["max_pixels"]),
                                   int(max_memory or _core.default_max_memory()))
    else:
        m = np.asarray(mask, dtype=bool)
        if m.ndim != 2:
            raise ParameterError(f"{what} must be a 2-D array of bools or an image file, not {shown(mask)}")
    if m.shape != tuple(shape):
        raise ParameterError(f"{what} is {m.shape[1]}x{m.shape[0]} pixels but {of} is {shape[1]}x{shape[0]}"
                             + _core.upright_said(int(orientation)))
    return m


def _shrink_mask(m: np.ndarray | None, s: int, rule: str) -> np.ndarray | None:
    """Downscale a mask by blocks: "all" (every pixel true) or "half" (>= 50%)."""
    if m is None or s <= 1:
        return m
    frac = _core._downscale(np.ascontiguousarray(m, dtype=np.float32)[:, :, None], s)[:, :, 0]
    return frac >= 1.0 if rule == "all" else frac >= 0.5


def max_side_factor(h: int, w: int, n: int | None) -> int:
    """The block size that brings the longer of ``h``, ``w`` to at most ``n``
    (``--max-side``; 1 without), as the core's downscale takes it."""
    return 1 if not n else max(1, -(-max(h, w) // max(1, int(n))))


def input_need(h: int, w: int, bpp: int, oriented: bool, *, half_size: bool = False, max_side: int | None = None,
               preprocess: str = "none", masks: int = 0, contact: bool = False,
               sphere_points: int | None = None) -> int:
    """Bytes one input of ``h`` x ``w`` pixels (``bpp`` decoded bytes per
    pixel, ``oriented``: rotated on reading) needs from decoding to its last
    output: the binary's plan (``_core.input_plan``) with what the Python
    writers add. The process's own base is not included."""
    if half_size:
        h, w = (h + 1) // 2, (w + 1) // 2
    s = max_side_factor(h, w, max_side)
    # Pillow's or LibRaw's buffer and its numpy copy are both alive: never "already RGB"
    # ... and, writing, the display copy of the image and Pillow's copy of its codes (20 B/px)
    extra = {} if sphere_points is None else {"sphere_points": int(sphere_points)}
    plan = _core.input_plan(h, w, bpp, False, oriented, s, preprocess == "reference", masks, 20, **extra)
    # the contact sheet: four cells of at most 360 px a side, and their labels
    return plan + ((8 << 20) if contact else 0)


def restore_file(in_path: str | os.PathLike, out_dir: str | os.PathLike, **kwargs) -> FileResult:
    """Restore one photograph and write its outputs (docs/OUTPUTS.md).

    Reads ``in_path`` (raw or JPEG/PNG/TIFF, see :func:`uwhl_rs.images.read_image`
    for ``preprocess``, ``half_size``, ``max_pixels``), optionally shrinks it
    so the longer side is at most ``max_side``, runs :func:`uwhl_rs.restore`
    with ``restore_kwargs`` (``mask``/``water_mask`` may be bool arrays or
    image files, nonzero = True, of the input's size), and writes into
    ``out_dir``: the corrected photo (``format`` "jpg", "tiff" (16-bit) or
    "png"; ``bits`` 8/16), t_B as a 16-bit PNG and colour-mapped, the
    confidence map as a 16-bit PNG when the method makes one, the contact
    sheet when ``contact``, and the JSON sidecar last. Every file
    is written atomically; if anything fails, the files already written
    for this input are removed and the error propagates.

    With ``sequence`` (a :class:`uwhl_rs.Sequence`, made with the same
    method keywords as ``restore_kwargs``, which then only label the
    sidecar), the image is restored as that sequence's next frame and the
    sidecar says in ``reused_estimates`` whether it reused the estimates.

    A distance (METHOD §13) comes from ``distance`` (an array, or a
    template as ``--distance`` takes it) or from ``altitude`` as
    ``--altitude`` takes it: metres (a number), a navigation log's path, or
    ``"xmp"``, with ``fov`` and ``port`` (METHOD §13.7). ``water_from``
    (a folder of calibrated sidecars, METHOD §13.6) is read at each call.

    Returns a :class:`FileResult` (the ``Restoration``, the read metadata,
    the paths written and the sidecar dict).
    """
    if kwargs.get("water_from") is not None or kwargs.get("altitude") is not None:
        _core.new_run()  # each call is a run of its own: the folder and the log as they are now
    return restore_staged(in_path, out_dir, **kwargs)()


def check_name(name) -> None:
    """A caller's ``name`` is the start of file names in ``out_dir``, never
    a path: no separator, not ``.`` or ``..``, no control characters (it
    is printed and written into summary.csv)."""
    if not isinstance(name, str) or not name or name in (".", "..") or "/" in name or os.sep in name \
            or any(ord(c) < 32 or ord(c) == 127 for c in name):
        raise ParameterError(f"name must be a file name in the output folder (no path, no control characters), "
                             f"not {shown(name)}")


def restore_staged(
    in_path: str | os.PathLike,
    out_dir: str | os.PathLike,
    *,
    name: str | None = None,
    format: str = _D["format"],
    bits: int | None = _D["bits"],
    quality: int = _D["quality"],
    preprocess: str = _D["preprocess"],
    half_size: bool = _D["half_size"],
    max_side: int | None = _D["max_side"],
    max_pixels: int = _D["max_pixels"],
    mask=None,
    water_mask=None,
    distance=None,
    altitude=None,
    distance_kind: str = _D["distance_kind"],
    fov=None,
    port: str | None = None,
    water_from=None,
    contact: bool = False,
    sequence=None,
    _claim=None,
    _base: int = 0,
    _label: str | None = None,
    _flags: bool = False,
    _make_room=None,
    **restore_kwargs,
) -> Callable[[], FileResult]:
    """:func:`restore_file` in two steps: this call reads and restores the
    input (raising what ``restore_file`` raises for that), and returns the
    function that writes its outputs (and returns the :class:`FileResult`),
    so that a caller can write one input while restoring the next.
    ``seconds.total`` in the sidecar then includes the time between.

    ``_claim`` (the command's): the ``_core.Claim`` of the output names,
    made by :func:`claim_outputs`; without, ``name`` in ``out_dir`` is
    claimed here and whatever is there replaced (the caller chose it).

    From the header, before decoding, the whole input's memory plan
    (decoding, ``max_side``, ``restore``, the outputs: the binary's plan,
    ``_core.input_plan``) plus ``_base`` (the command: what the process
    holds anyway, ``_core.process_base()``) is checked against
    ``max_memory`` (default ``_core.default_max_memory()``). ``_make_room``
    (a batch's, as :class:`uwhl_rs.tasks.MemoryGate`): the input's own bytes
    of that plan are reserved in it before decoding; when the inputs
    restored or written beside it leave no room, the read is given up, the
    room waited for outside the decoder (a raw file's decoding holds the
    process's stderr), and the input read again.

    ``_label`` (batches on object storage): the input's name in the sidecar
    (``input``, ``source.path``) and in errors, when ``in_path`` is a local
    copy of it. ``_flags`` (the command's): errors name options by their
    flags (``--max-memory``), as uwhl-rs does, instead of the keywords."""
    t_start = time.perf_counter()
    if altitude is not None and distance is not None:
        raise ParameterError("distance and altitude are two sources of distance: give one")
    if not isinstance(format, str):
        raise ParameterError(f"format must be 'jpg', 'png' or 'tiff', not {shown(format)}")
    if not isinstance(contact, (bool, np.bool_)):
        raise ParameterError(f"contact must be True or False, not {shown(contact)}")
    if sequence is not None and not isinstance(sequence, uwhl_rs.Sequence):
        raise ParameterError(f"sequence must be a uwhl_rs.Sequence or None, not {shown(sequence)}")
    in_path = path_arg("in_path", in_path)
    out_dir = path_arg("out_dir", out_dir)
    settings = settings_of(format=format, bits=bits, quality=quality, preprocess=preprocess, half_size=half_size,
                           max_side=max_side, max_pixels=max_pixels, mask=mask, water_mask=water_mask,
                           distance=distance, altitude=altitude, fov=fov, port=port, distance_kind=distance_kind,
                           water_from=water_from, **restore_kwargs)
    if settings.dive_water_type is not None:
        # METHOD §13, a dive learns once: the water of its calibrated photos
        restore_kwargs = {**restore_kwargs, "water_types": [settings.dive_water_type]}
    if name and _claim is None:
        check_name(name)  # a caller's name (a batch's names are the core's, claimed); a stem is a file name already
    name = name or os.path.splitext(os.path.basename(in_path))[0]
    if _claim is None:
        status, sidecar_path, reason, _claim = claim_outputs(out_dir, name, in_path, format, contact,
                                                             overwrite=True, rename=False)
        if status != "claimed":
            who = reason if status == "busy" else "being written by this process"
            raise OSError(f"{sidecar_path} is {who}")
    claim = _claim
    try:
        staged = _read_and_restore(in_path, out_dir, claim, settings, format=format, preprocess=preprocess,
                                   half_size=half_size, max_side=max_side, max_pixels=max_pixels, mask=mask,
                                   water_mask=water_mask, distance=distance, contact=contact, sequence=sequence,
                                   restore_kwargs=restore_kwargs, t_start=t_start, base=_base,
                                   label=_label or in_path, flags=_flags, make_room=_make_room)
    except BaseException:
        claim.release()
        raise
    return staged


class _WaitForRoom(ImageReadError):
    """Raised from the header hook to give a read up until the room for
    ``need`` bytes is there (:func:`_read_and_restore`): an ImageReadError,
    which ``read_image`` lets through as it is."""

    def __init__(self, need: int):
        super().__init__(need)
        self.need = need


def _read_and_restore(in_path, out_dir, claim, settings, *, format, preprocess, half_size, max_side, max_pixels, mask,
                      water_mask, distance, contact, sequence, restore_kwargs, t_start, base, label,
                      flags=False, make_room=None) -> Callable[[], FileResult]:
    """The body of :func:`restore_staged` once the names are claimed."""
    paths = output_paths(out_dir, claim.name, format, contact)
    budget = settings.max_memory
    masks = int(mask is not None) + int(water_mask is not None)
    photo_need = [0]
    reserved = [False]

    def plan(h: int, w: int, bpp: int, oriented: bool) -> None:
        need = input_need(h, w, bpp, oriented, half_size=half_size, max_side=max_side, preprocess=preprocess,
                          masks=masks, contact=contact, sphere_points=restore_kwargs.get("sphere_points")) + base
        photo_need[0] = need - base
        side, memory = spelt("max_side", flags), spelt("max_memory", flags)
        if make_room is not None and need <= budget and not reserved[0]:
            if not make_room.try_reserve(need - base):
                raise _WaitForRoom(need - base)
            reserved[0] = True
        if need > budget:
            raise ImageTooLargeError(f"{label}: {w}x{h} pixels need about {need} bytes, over {memory} {budget} "
                                     f"(use {side} or raise {memory})")
        if not _core.can_allocate(need - base):
            raise ImageTooLargeError(f"{label}: {w}x{h} pixels need about {need} bytes, more than the system "
                                     f"gives now (free memory, a container limit or ulimit -v); use {side}")

    while True:
        try:
            image, meta = read_image(in_path, preprocess=preprocess, half_size=half_size, max_pixels=max_pixels,
                                     _on_header=plan, _flags=flags)
            break
        except _WaitForRoom as w:
            make_room.reserve(w.need)
            reserved[0] = True
    full_hw = image.shape[:2]
    # the binary's words for its own flags: "--mask is 32x24 pixels but the input is 64x48"
    of = "the input" if flags else "the image"
    turned = int(meta.orientation or 1)
    m = read_mask(mask, full_hw, spelt("mask", flags), max_pixels=max_pixels, max_memory=budget, of=of,
                  orientation=turned)
    wm = read_mask(water_mask, full_hw, spelt("water_mask", flags), max_pixels=max_pixels, max_memory=budget, of=of,
                   orientation=turned)
    s = max_side_factor(*full_hw, max_side)
    if s > 1:
        image = _core._downscale(image, s)
        m = _shrink_mask(m, s, "all")
        wm = _shrink_mask(wm, s, "half")
    # METHOD §13: a template names the input's map (the binary's reader); one
    # that cannot be read leaves the photo restored without it, flagged
    z, z_source, z_missing, z_floor, z_depth, z_out = None, None, None, None, None, 0
    if isinstance(distance, (str, os.PathLike)):
        # the map gets what the budget leaves beside the photo (its plan, and the map at the photo's
        # processed size that restore makes): one that does not fit is left out, the photo restored
        room = max(0, int(budget) - photo_need[0] - 4 * image.shape[0] * image.shape[1])
        z_source, z, z_missing, z_out = _core.read_distance_for(os.fspath(distance), in_path, int(max_pixels), room,
                                                         tuple(int(x) for x in full_hw))
        if z is not None and settings.depth_along_axis:
            # METHOD §13.7: depth along the camera's axis, turned into ranges with the lens
            z, z_depth, z_missing = _core.depth_to_range_for(settings, in_path, z, *full_hw)
        # a map of any size (checked against the photo as read) goes to restore as it is, which
        # samples it at the processed size (--max-side), as the binary does
    elif distance is not None:
        z, z_source = distance, "array"
    elif settings.altitude is not None:
        # METHOD §13.7: the camera over a flat seabed, at the processed size
        z_source, z, z_missing, z_floor = _core.floor_for(settings, in_path, *full_hw, *image.shape[:2])
    if z is not None and sequence is not None:
        raise ParameterError("distance fits each photo's water: it does not go with a sequence")
    t_read = time.perf_counter()
    if sequence is not None:
        res = sequence.restore(image, mask=m, water_mask=wm)
    else:
        res = uwhl_rs.restore(image, mask=m, water_mask=wm, distance=z, **restore_kwargs)
    t_restore = time.perf_counter()

    def write() -> FileResult:
        try:
            sheet, t_sheet = None, None
            if contact:
                t0 = time.perf_counter()
                drawn = contact_sheet(image, meta, res, mask=m, restore_kwargs=restore_kwargs)
                sheet = _core._encode_png(np.ascontiguousarray(drawn))
                t_sheet = time.perf_counter() - t0
            hp, wp = res.transmission.shape
            source = {**meta.to_dict(), "path": label, "height": int(full_hw[0]), "width": int(full_hw[1]),
                      "processed_height": int(hp), "processed_width": int(wp)}
            icc = source["icc_profile"]  # its note, when unreadable, is among the notes already
            source["icc_profile"] = None if icc is None else (icc["description"], bool(icc["converted"]), None)
            reused = ("estimates_reused" in res.flags) if sequence is not None else None
            # the binary's writing half: encodes, metadata, sidecar, commit (src/files/pipeline.rs)
            text = _core.write_input_outputs(claim, res, display_linear(res.image, meta), source, settings, in_path,
                                             label, sheet, reused, t_read - t_start, t_restore - t_read, t_sheet,
                                             time.perf_counter() - t_start, distance_source=z_source,
                                             distance_missing=z_missing, distance_floor=z_floor,
                                             distance_depth=z_depth, distance_out_of_range=z_out)
        finally:
            # committed: nothing left to release; failed: the temporaries go
            claim.release()
        written = {k: v for k, v in paths.items() if k != "confidence" or res.confidence is not None}
        return FileResult(res, meta, written, json.loads(text))

    return write


# restore_file takes exactly restore_staged's keywords: show them (help(), IDEs)
_signature = inspect.signature(restore_staged)
restore_file.__signature__ = _signature.replace(
    parameters=[p for p in _signature.parameters.values() if not p.name.startswith("_")],
    return_annotation="FileResult",
)


def _subsample_label(v) -> int:
    """The requested guided_subsample as the sidecar writes it: "auto" -> 0."""
    return 0 if isinstance(v, str) and v == "auto" else int(v)


def _fov(fov):
    """``fov`` for the core: an integer too large for a float is named
    here, compactly (the core's message would show all of its digits)."""
    if isinstance(fov, int) and not isinstance(fov, bool):
        try:
            float(fov)
        except OverflowError:
            raise ParameterError(f"fov {shown(fov)} is out of range (too large for a float)") from None
    return fov


def _altitude_source(altitude) -> str | None:
    """``altitude`` as ``--altitude`` takes it: metres (a number, as the
    flag's text), a navigation log's path, or ``"xmp"``; a ParameterError
    for anything else (a bool is not metres)."""
    if altitude is None:
        return None
    if isinstance(altitude, numbers.Real) and not isinstance(altitude, (bool, np.bool_)):
        try:
            return repr(float(altitude))
        except OverflowError:
            raise ParameterError(f"altitude {shown(altitude)} is out of range (too large for a float)") from None
    if isinstance(altitude, (str, os.PathLike)):
        return os.fspath(altitude)
    raise ParameterError(f"altitude must be metres (a number), a navigation log's path or 'xmp', not {shown(altitude)}")


def settings_of(*, format: str = _D["format"], bits: int | None = _D["bits"], quality: int = _D["quality"],
                preprocess: str = _D["preprocess"], half_size: bool = _D["half_size"],
                max_side: int | None = _D["max_side"], max_pixels: int = _D["max_pixels"], mask=None,
                water_mask=None, distance=None, altitude=None, distance_kind: str = _D["distance_kind"], fov=None,
                port: str | None = None, water_from=None, contact: bool = False, **restore_kwargs):
    """The core's settings of a file's restoration (``_core.FileSettings``:
    every option checked by the core's table, the binary's checks and
    messages); its ``parameters`` (JSON text) is what the sidecar records."""
    if water_from is not None and not isinstance(water_from, (str, os.PathLike)):
        raise ParameterError(f"water_from must be a folder's path or None, not {shown(water_from)}")
    if distance is not None and not isinstance(distance, (str, os.PathLike)) and distance_kind == "depth":
        raise ParameterError("distance_kind depth turns the maps read from files into ranges: turn an array of depth "
                             "into ranges with uwhl_rs.depth_to_range and give that")
    try:
        return _core.FileSettings(format=format, bits=bits, quality=quality, preprocess=preprocess,
                                  half_size=half_size, max_side=max_side, max_pixels=max_pixels,
                                  mask=_mask_label(mask), water_mask=_mask_label(water_mask),
                                  distance=os.fspath(distance) if isinstance(distance, (str, os.PathLike)) else None,
                                  altitude=_altitude_source(altitude), fov=_fov(fov), port=port,
                                  distance_kind=distance_kind,
                                  water_from=None if water_from is None else os.fspath(water_from), **restore_kwargs)
    except (TypeError, OverflowError) as e:
        # a value of the wrong kind (format=None, bits=8.0): the core's argument named, not a traceback
        raise ParameterError(str(e)) from None


def _mask_label(mask):
    """A mask as the sidecar names it: its path, or "array"."""
    if mask is None:
        return None
    if isinstance(mask, (str, os.PathLike)):
        return os.fspath(mask)
    return "array"


# ---------------------------------------------------------------- contact sheet

_ORANGE = (255, 140, 0)


def contact_sheet(image, meta: ImageMeta, res, *, mask=None, restore_kwargs=None, cell: int = 360) -> np.ndarray:
    """An 8-bit RGB sheet for judging the water-type choice by eye.

    Cells: the input with the water region VL overlaid (magenta), then
    every evaluated water type's restoration labelled with its gray-world
    score (the chosen one framed in orange, excluded ones marked), then the
    chosen type's colour-mapped transmission. The candidates are restored
    on a copy shrunk so its longer side is about ``cell`` pixels, with the
    full image's veiling light A and water region, so they show what each
    type does, not a re-estimate.
    """
    from PIL import Image, ImageDraw, ImageFont

    kw = dict(restore_kwargs or {})
    h, w = image.shape[:2]
    s = max_side_factor(h, w, cell)
    thumb = _core._downscale(np.ascontiguousarray(image, dtype=np.float32), s) if s > 1 else image
    vl = _shrink_mask(res.veiling_mask, s, "half") if s > 1 else res.veiling_mask
    m = _shrink_mask(mask, s, "all") if s > 1 else mask
    th, tw = thumb.shape[:2]
    specs = {}
    for spec in kw.get("water_types") or []:
        specs[spec if isinstance(spec, str) else spec[0]] = spec
    radius = kw.get("guided_radius")
    sub = {k: kw[k] for k in ("guided_eps", "sphere_points", "threads") if k in kw}
    if radius is not None:
        sub["guided_radius"] = max(1, int(round(radius / s)))
    # the subsampling factor shrinks with the radius, so the thumbnails use
    # the same filter window in blocks; "auto"/0 resolves on the thumbnail
    gs = kw.get("guided_subsample")
    if gs is not None:
        gs = _subsample_label(gs)
        sub["guided_subsample"] = gs if gs <= 1 else max(1, int(round(gs / s)))

    def label_font(size: int):
        try:
            return ImageFont.load_default(size=size)
        except TypeError:  # Pillow < 10.1
            return ImageFont.load_default()

    bar = 24
    cells = []
    # input with VL overlay
    shown = to_srgb(thumb, meta)
    over = shown.copy()
    over[vl] = 0.45 * over[vl] + 0.55 * np.array([1.0, 0.0, 1.0], np.float32)
    n_vl = int(res.veiling_mask.sum())
    cells.append((over, ("input", f"; VL {n_vl} px ({res.veiling_mask.mean():.1%})"), None))
    for name, score in res.scores.items():
        label = name
        try:
            r = uwhl_rs.restore(
                thumb,
                water_types=[specs.get(name, name)],
                veiling_light=res.veiling_light,
                water_mask=vl,
                mask=m,
                **sub,
            )
            img = to_srgb(r.image, meta)
        except (ValueError, MemoryError) as e:
            img = np.full((th, tw, 3), 0.3, np.float32)
            label = f"{name} failed: {e}"[:40]
        tag = " CHOSEN" if name == res.water_type else (" excluded" if name in res.excluded else "")
        cells.append((img, (label, f"  {score:.4f}{tag}"), _ORANGE if name == res.water_type else None))
    t_small = _core._downscale(np.ascontiguousarray(res.transmission, dtype=np.float32)[:, :, None], s)[:, :, 0]
    cells.append((colorize_transmission(t_small).astype(np.float32) / 255.0, ("t_B of ", res.water_type), None))

    cols = 4
    rows = -(-len(cells) // cols)
    pad = 6
    sheet = Image.new("RGB", (cols * (tw + pad) + pad, rows * (th + bar + pad) + pad + 30), (24, 24, 24))
    draw = ImageDraw.Draw(sheet)
    def fitted(head: str, tail: str, size: int, width: int):
        """``head + tail`` and a font small enough (down to 8 px) for
        ``width`` pixels; if even that is too wide, ``head`` (a name) is cut
        short first, so the tail (score, choice, flags) stays: a small sheet
        (``--max-side 200``) keeps its labels in their cells."""
        f = label_font(size)
        need = draw.textlength(head + tail, font=f)
        if need > width:
            f = label_font(max(8, int(size * width / need)))
            while len(head) > 1 and draw.textlength(head + tail, font=f) > width:
                head = head[:-2] + "\u2026"
            while len(tail) > 1 and draw.textlength(head + tail, font=f) > width:
                tail = tail[:-2] + "\u2026"
        return head + tail, f

    title, title_font = fitted(os.path.basename(meta.path),
                               f": chosen {res.water_type}, A = ({', '.join(f'{v:.3f}' for v in res.veiling_light)}); "
                               f"flags: {', '.join(res.flags) or 'none'}", 17, sheet.width - 2 * pad)
    draw.text((pad, 6), title, fill=(235, 235, 235), font=title_font)
    for k, (img, text, frame) in enumerate(cells):
        x0 = pad + (k % cols) * (tw + pad)
        y0 = 30 + pad + (k // cols) * (th + bar + pad)
        tile = Image.fromarray((np.clip(img, 0, 1) * 255 + 0.5).astype(np.uint8))
        sheet.paste(tile, (x0, y0))
        if frame is not None:
            draw.rectangle([x0 - 3, y0 - 3, x0 + tw + 2, y0 + th + bar - 1], outline=frame, width=4)
        text, f = fitted(*text, 15, tw - 8)
        draw.text((x0 + 4, y0 + th + 4), text, fill=frame or (235, 235, 235), font=f)
    return np.asarray(sheet)
