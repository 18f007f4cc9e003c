"""Reading and writing images: raw camera files (rawpy/LibRaw), JPEG, PNG
and TIFF (read by the core's decoder, the binary's own), the sRGB transfer
curves and the camera matrix.

Everything here converts between files and the LINEAR float32 HxWx3
arrays that :func:`uwhl_rs.restore` takes (METHOD §2) and returns (METHOD §10).
The pixel conventions (curves, rounding, colour map) are shared with the
``uwhl-rs`` binary through ``uwhl_rs._core`` and documented in
``docs/OUTPUTS.md``. rawpy and imageio (writing :func:`write_image`) are
imported on first use only.
"""

from __future__ import annotations

import contextlib
import dataclasses
import os
import re
import sys
import tempfile
import threading
from dataclasses import asdict, dataclass, field

import numpy as np

from . import _core
from .errors import ImageReadError, ImageTooLargeError, ParameterError, shown
from .imagewrite import IMAGE_EXTENSIONS, atomic_write_bytes, path_arg, quantize, write_image
from .sidecars import display

__all__ = [
    "ImageMeta",
    "ImageReadError",
    "RAW_EXTENSIONS",
    "IMAGE_EXTENSIONS",
    "PREPROCESS_MODES",
    "DEFAULT_MAX_PIXELS",
    "read_image",
    "read_distance",
    "path_arg",
    "to_srgb",
    "srgb_to_linear",
    "linear_to_srgb",
    "write_image",
    "atomic_write_bytes",
    "quantize",
    "colorize_transmission",
]

#: Extensions read through LibRaw (every format LibRaw reads; other names
#: are sniffed, and what is not JPEG/PNG/TIFF is refused).
#: The list is the core's, which both commands' folder walks use.
RAW_EXTENSIONS = frozenset("." + e for e in _core.RAW_EXTENSIONS)
#: ``none``: linear data (sRGB decoded through the inverse curve; raw as
#: decoded). ``reference``: the reference code's preprocessing (METHOD §2).
PREPROCESS_MODES = ("none", "reference")
#: Refuse images with more pixels than this unless told otherwise (a
#: 300 MP frame needs ~3.6 GB as float32 before any processing).
DEFAULT_MAX_PIXELS: int = next(o["default"] for o in _core.OPTIONS if o["key"] == "max_pixels")

# linear sRGB (D65) -> CIE XYZ, IEC 61966-2-1
_SRGB_TO_XYZ = np.array(
    [[0.4124564, 0.3575761, 0.1804375], [0.2126729, 0.7151522, 0.0721750], [0.0193339, 0.1191920, 0.9503041]]
)
# LibRaw's flip code -> EXIF orientation
_FLIP_TO_EXIF = {0: 1, 3: 3, 5: 8, 6: 6}


@dataclass(frozen=True)
class ImageMeta:
    """What :func:`read_image` knows about the file it read."""

    path: str
    #: "raw" (LibRaw), "srgb" (JPEG/PNG/TIFF) or "linear" (float TIFF)
    kind: str
    #: "JPEG", "PNG", "TIFF" or the raw file's extension in capitals
    format: str
    #: bits per sample in the file (raw: 16 after demosaicing)
    bits: int
    #: of the returned array, after orientation and half-size
    height: int
    width: int
    #: EXIF orientation of the file (1 = upright); the array is already upright
    orientation: int = 1
    #: True if the returned data is linear light (False only for sRGB with preprocess="reference")
    linear: bool = True
    preprocess: str = "none"
    #: 3x3 camera RGB -> linear sRGB (raw only), applied by :func:`to_srgb`
    camera_matrix: np.ndarray | None = None
    #: the as-shot white-balance multipliers applied (raw only)
    white_balance: tuple | None = None
    #: documented fallbacks taken while reading
    notes: tuple = field(default_factory=tuple)
    #: the embedded ICC profile: {"description", "converted"} (converted:
    #: not sRGB, so the codes went to the working space through it), or None
    icc_profile: dict | None = None

    def to_dict(self) -> dict:
        """A JSON-ready dict (the sidecar's ``source``)."""
        d = asdict(self)
        d["camera_matrix"] = None if self.camera_matrix is None else np.asarray(self.camera_matrix).tolist()
        d["white_balance"] = None if self.white_balance is None else list(self.white_balance)
        d["notes"] = list(self.notes)
        return d


def srgb_to_linear(encoded: np.ndarray) -> np.ndarray:
    """sRGB-encoded values in [0, 1] -> linear (IEC 61966-2-1), float64."""
    x = np.asarray(encoded, dtype=np.float64)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(linear: np.ndarray) -> np.ndarray:
    """Linear values -> sRGB-encoded, clipped to [0, 1] first, float64."""
    x = np.clip(np.nan_to_num(np.asarray(linear, dtype=np.float64), nan=0.0), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)


def _sniff(path: str) -> str | None:
    """The container by magic bytes: "JPEG", "PNG", "TIFF" or None."""
    with open(path, "rb") as f:
        head = f.read(8)
    if head[:3] == b"\xff\xd8\xff":
        return "JPEG"
    if head == b"\x89PNG\r\n\x1a\n":
        return "PNG"
    if head[:4] in (b"II*\x00", b"MM\x00*", b"II+\x00", b"MM\x00+"):
        return "TIFF"
    return None


def read_image(
    path: str | os.PathLike,
    *,
    preprocess: str = "none",
    half_size: bool = False,
    max_pixels: int = DEFAULT_MAX_PIXELS,
    _on_header=None,
    _flags: bool = False,
) -> tuple[np.ndarray, ImageMeta]:
    """Read a photograph as the linear float32 HxWx3 image ``restore`` takes.

    Raw files (any format LibRaw reads) are demosaiced by rawpy: linear
    (gamma 1), no auto-brightening, the as-shot white balance, 16 bits, in
    the camera's colour space (``meta.camera_matrix`` takes it to sRGB; see
    :func:`to_srgb`), upright; ``half_size`` halves each side (faster).
    JPEG, PNG and TIFF (8 or 16 bit) are decoded through the inverse sRGB
    curve with the EXIF orientation applied; float TIFFs are taken as
    linear. Gray is replicated to three channels, alpha dropped.

    ``preprocess="reference"`` applies METHOD §2's reference preprocessing
    instead: raw is scaled so the 99.999th percentile of the channel
    maximum is 1 and each channel stretched to clip its top 0.1%; sRGB is
    NOT linearised and gets the reference's pulled 1%/99% stretch
    (``meta.linear`` is then False).

    Returns ``(image, meta)``. Raises :class:`ImageReadError` naming the
    file and the reason (missing, truncated, corrupt, unsupported, or more
    than ``max_pixels`` pixels).

    ``_on_header(height, width, decoded_bytes_per_pixel, oriented)`` (the
    commands' memory plan) is called from the header, before decoding;
    what it raises propagates. ``_flags`` (the command's): the pixel limit
    is named ``--max-pixels``, as the command's flag, not ``max_pixels``.
    """
    path = path_arg("path", path)
    if preprocess not in PREPROCESS_MODES:
        raise ValueError(f"preprocess must be one of {PREPROCESS_MODES}, not {preprocess!r}")
    _check_max_pixels(max_pixels)
    if not os.path.exists(path):
        raise ImageReadError(f"{path}: no such file or folder")
    if os.path.isdir(path):
        raise ImageReadError(f"{path}: is a folder, not an image")
    if not os.path.isfile(path):
        # a FIFO would block the read, a device never end: not opened (as the commands' reader)
        raise ImageReadError(f"{path}: is not a regular file (a FIFO, socket or device): not opened")
    try:
        size = os.path.getsize(path)
        # raw formats are often TIFF containers (DNG, NEF): the extension decides
        ext = os.path.splitext(path)[1].lower()
        kind = None if ext in RAW_EXTENSIONS else _sniff(path)
    except OSError as e:
        raise ImageReadError(f"{path}: cannot open ({e.strerror or e})") from None
    if size == 0:
        raise ImageReadError(f"{path}: empty file")
    if kind is None and ext not in RAW_EXTENSIONS:
        # LibRaw takes a file of a headerless camera's exact size for that camera's
        # raw data (a text file became a photo of noise): only a raw extension goes to it
        raise ImageReadError(f"{path}: not a JPEG, PNG, TIFF or raw file (its first bytes are none of these, "
                             f"and {ext or 'no extension'!s} is not a raw camera format's extension)")
    try:
        if kind is None:
            failed = None
            with _decoder_messages() as said:
                try:
                    img, meta = _read_raw(path, preprocess, half_size, max_pixels, _on_header,
                                          "--max-pixels" if _flags else "max_pixels")
                except Exception as e:  # judged below, with what the decoder said
                    failed = e
            if failed is not None:
                early = _ends_early(said, path)
                if early and not isinstance(failed, (ImageTooLargeError, MemoryError)):
                    raise ImageReadError(f"{path}: the raw data ends early (a file cut short?): {early}") from None
                raise failed
            return img, _judged_raw(path, meta, said)
        img, meta = _read_encoded(path, kind, preprocess, max_pixels, _on_header)
        if half_size:
            meta = dataclasses.replace(meta, notes=tuple(meta.notes) + (
                "half_size applies to raw files only: this file is read at full size",))
        return img, meta
    except ImageReadError:
        raise
    except MemoryError:
        raise ImageTooLargeError(f"{path}: not enough memory to decode") from None
    except Exception as e:  # decoders raise many types; name the file and the reason
        raise ImageReadError(f"{path}: cannot decode {kind or 'raw'} ({type(e).__name__}: {_reason(e)})") from None


def read_distance(path: str | os.PathLike, *, max_pixels: int = DEFAULT_MAX_PIXELS) -> np.ndarray:
    """Read a distance map as the float32 (H, W) metres ``restore(distance=)``
    takes, with the commands' own reader (docs/OUTPUTS.md "Distance"):
    ``.npy`` (metres; uint16 millimetres), TIFF (float metres; 16-bit
    millimetres), 16-bit PNG (millimetres), OpenEXR (the ``Z`` or
    ``depth`` channel, or the only one; metres) and COLMAP's dense depth
    maps (depth along the axis: see :func:`uwhl_rs.depth_to_range`), told
    apart by their first bytes. Unknown distances (NaN, infinite, 0, negative, beyond 1000 m)
    are NaN.

    Raises
    ------
    ImageError
        The file is missing, not a regular file, or not a distance map
        (the message says why).
    MemoryError
        Its header gives more than ``max_pixels`` pixels, or more memory
        than the core's default limit.
    """
    _check_max_pixels(max_pixels)
    arg = path_arg("path", path)
    try:
        return np.asarray(_core.read_distance_file(arg, int(max_pixels), int(_core.default_max_memory())))
    except (_core.ImageError, MemoryError) as e:  # the core's reason, named by its file as read_image names it
        # the command's flag is this function's keyword
        raise type(e)(f"{path}: {str(e).replace('--max-pixels', 'max_pixels')}") from None


#: the largest max_pixels (the option table's: the core's 64-bit count)
_MAX_PIXELS_LIMIT: int = next(o["max"] for o in _core.OPTIONS if o["key"] == "max_pixels")


def _check_max_pixels(max_pixels) -> None:
    """ParameterError unless ``max_pixels`` is an integer in the option
    table's range (one past 2^64 would not reach the core)."""
    if isinstance(max_pixels, (bool, np.bool_)) or not isinstance(max_pixels, (int, np.integer)) \
            or not 1 <= max_pixels <= _MAX_PIXELS_LIMIT:
        raise ParameterError(f"max_pixels must be a positive integer up to {_MAX_PIXELS_LIMIT}, "
                             f"not {shown(max_pixels)}")


def _check_pixels(path: str, h: int, w: int, max_pixels: int, on_header=None, bpp: int = 3,
                  oriented: bool = False, limit: str = "max_pixels") -> None:
    """The header's checks: the pixel limit (named ``limit``), a non-empty
    image, and the caller's ``on_header`` (see :func:`read_image`)."""
    if h * w > max_pixels:
        # the words of the core's decoder (JPEG, PNG, TIFF), so that raw files say the same
        raise ImageTooLargeError(f"{path}: {w}x{h} = {w * h} pixels is over the limit of {max_pixels} pixels ({limit})")
    if h < 1 or w < 1:
        raise ImageReadError(f"{path}: the image is empty ({w}x{h})")
    if on_header is not None:
        on_header(h, w, bpp, oriented)


def _read_encoded(path: str, kind: str, preprocess: str, max_pixels: int,
                  on_header=None) -> tuple[np.ndarray, ImageMeta]:
    """JPEG, PNG and TIFF through the core's decoder, the binary's own
    (src/files/decode.rs): the same pixels, orientation and ICC handling in
    both commands."""
    linearize = preprocess == "none"
    try:
        img, info = _core.decode_file(path, linearize, int(max_pixels), int(_core.default_max_memory()), on_header)
    except MemoryError as e:
        raise ImageTooLargeError(f"{path}: {e}") from None
    except _core.ImageError as e:
        # the core's words, as the binary says them (they name the format where it matters)
        raise ImageReadError(f"{path}: {e}") from None
    orientation = int(info["orientation"])
    notes = tuple(info["notes"])
    if info["is_float"]:
        if preprocess == "reference":
            notes += (_core.FLOAT_NOT_PREPROCESSED,)
        meta = ImageMeta(path, "linear", info["format"], int(info["bits"]), img.shape[0], img.shape[1], orientation,
                         True, "none", notes=notes)
        return img, meta
    profile = None
    if info["icc_profile"] is not None:
        description, converted, why = info["icc_profile"]
        profile = {"description": description, "converted": bool(converted)}
        if why is not None:
            notes += (f"the ICC profile cannot be read ({why}); read as sRGB",)
    if preprocess == "reference":
        img = _core._reference_srgb(img)
    meta = ImageMeta(path, "srgb", info["format"], int(info["bits"]), img.shape[0], img.shape[1], orientation,
                     linearize, preprocess, notes=notes, icc_profile=profile)
    return img, meta


def _camera_matrix(raw) -> tuple[np.ndarray | None, list[str]]:
    """Camera RGB (white balanced) -> linear sRGB, from LibRaw's colour data."""
    cm = np.asarray(raw.color_matrix, dtype=np.float64)[:3, :3]
    if np.any(cm != 0) and np.all(np.isfinite(cm)):
        return cm, []
    xyz = np.asarray(raw.rgb_xyz_matrix, dtype=np.float64)[:3, :3]
    if np.any(xyz != 0):
        # camera <- XYZ <- sRGB, rows normalised so white stays white, inverted
        cam_rgb = xyz @ _SRGB_TO_XYZ
        cam_rgb /= cam_rgb.sum(axis=1, keepdims=True)
        try:
            return np.linalg.inv(cam_rgb), []
        except np.linalg.LinAlgError:
            pass
    return None, ["no_camera_matrix"]


def _reason(e: Exception) -> str:
    """An exception's message as text: LibRaw's carry bytes (b'Input/output error')."""
    return e.args[0].decode("utf-8", "replace") if e.args and isinstance(e.args[0], bytes) else str(e)


#: what LibRaw and libjpeg write when a raw file's data ends early: the
#: decoder then fills the rest with what it had, and the photo looks whole
_TRUNCATED = ("premature end of jpeg file", "end of file", "truncated")
#: a decoder's line on stderr: "NAME: message" from LibRaw, or libjpeg's own
_DECODER_LINE = re.compile(r"(premature end|unexpected end|end of file|corrupt|bogus|invalid|data error|"
                           r"not enough|warning|truncated)", re.IGNORECASE)
_RAW_LOCK = threading.Lock()


@contextlib.contextmanager
def _decoder_messages():
    """While a raw file decodes, what LibRaw and libjpeg print on the
    process's stderr (fd 2) is collected instead of shown: it would break
    ``--json-errors`` and says what the photo's result must say (a file
    cut short). Raw decodes take turns (fd 2 is the process's); a line of
    another thread written meanwhile is passed on to stderr afterwards.
    Yields a list that holds the decoder's lines once the block ends."""
    said: list[str] = []
    with _RAW_LOCK:
        try:
            sys.stderr.flush()
        except (AttributeError, OSError, ValueError):
            pass
        try:
            saved = os.dup(2)
        except OSError:  # no stderr at all: nothing to collect or pass on
            yield said
            return
        with tempfile.TemporaryFile() as tmp:
            os.dup2(tmp.fileno(), 2)
            try:
                yield said
            finally:
                try:
                    sys.stderr.flush()
                except (AttributeError, OSError, ValueError):
                    pass
                os.dup2(saved, 2)
                os.close(saved)
                tmp.seek(0)
                text = tmp.read(1 << 20).decode("utf-8", "replace")
                others = []
                for line in text.splitlines():
                    # the command's own lines (another input's error, its JSON) are never the decoder's
                    ours = line.startswith(("uwhl:", "uwhl ", "uwhl-rs:", "{", "["))
                    (said if _DECODER_LINE.search(line) and not ours else others).append(line)
                if others:
                    try:
                        os.write(2, ("\n".join(others) + "\n").encode("utf-8", "replace"))
                    except OSError:
                        pass


def _ends_early(said: list[str], path: str) -> str | None:
    """The decoder's first line saying a raw file's data ended early, shown
    without the file's name (LibRaw's lines begin with it; the message
    names it once)."""
    for x in said:
        if any(k in x.lower() for k in _TRUNCATED):
            return display(x.strip().removeprefix(f"{path}: ").removeprefix(f"{path}:"))[:200]
    return None


def _judged_raw(path: str, meta: "ImageMeta", said: list[str]) -> "ImageMeta":
    """The decoder's lines about a raw file: one that says its data ended
    early makes it unreadable (its pixels past that point are not the
    photo's); any other becomes a note of the sidecar's ``source.notes``."""
    early = _ends_early(said, path)
    if early:
        raise ImageReadError(f"{path}: the raw data ends early (a file cut short?): {early}")
    shown = [display(x.strip())[:200] for x in said if x.strip()]
    if not shown:
        return meta
    return dataclasses.replace(meta, notes=tuple(meta.notes) + tuple(f"raw decoder: {x}" for x in shown[:5]))


def _read_raw(path: str, preprocess: str, half_size: bool, max_pixels: int,
              on_header=None, limit: str = "max_pixels") -> tuple[np.ndarray, ImageMeta]:
    try:
        import rawpy
    except ImportError:  # pragma: no cover - rawpy is a dependency
        raise ImageReadError(f"{path}: reading raw files needs rawpy (pip install rawpy)") from None
    # LibRaw reads a tile or strip table as far as the size says, past its end
    why = _core.raw_problem(path)
    if why:
        raise ImageReadError(f"{path}: a damaged raw file: {why}")
    try:
        try:
            raw = rawpy.imread(path)
        except UnicodeEncodeError:
            # a name of undecodable bytes, which rawpy cannot pass on as a path: the opened file instead
            with open(path, "rb") as f:
                raw = rawpy.imread(f)
    except Exception as e:
        ext = os.path.splitext(path)[1].lower()
        what = "a raw file LibRaw can read" if ext in RAW_EXTENSIONS else "a JPEG, PNG, TIFF or raw file"
        raise ImageReadError(f"{path}: not {what} ({type(e).__name__}: {_reason(e)})") from None
    with raw:
        s = raw.sizes
        # the mosaic (2 bytes a pixel) and LibRaw's 16-bit RGB output
        _check_pixels(path, s.height, s.width, max_pixels, on_header, 8, int(s.flip) != 0, limit)
        notes: list[str] = []
        # Some files declare a white level below their own data (the shared
        # Nikon NEF: 255 vs 54998): every pixel would clip. Use the data's
        # maximum as the saturation level instead.
        data_max = int(raw.raw_image_visible.max())
        user_sat = None
        if data_max > raw.white_level > 0:
            user_sat = data_max
            notes.append("white_level_below_data")
        wb = tuple(float(v) for v in raw.camera_whitebalance)
        if not (wb[0] > 0 and wb[1] > 0 and wb[2] > 0):
            notes.append("no_as_shot_white_balance")
        rgb = raw.postprocess(
            gamma=(1, 1),
            no_auto_bright=True,
            output_bps=16,
            use_camera_wb=True,
            output_color=rawpy.ColorSpace.raw,
            half_size=half_size,
            user_sat=user_sat,
        )
        cm, more = _camera_matrix(raw)
        notes += more
        orientation = _FLIP_TO_EXIF.get(int(s.flip), 1)
    if rgb.ndim != 3 or rgb.shape[2] < 3:
        # a header that states another number of colours (a damaged or patched file) demosaics to fewer
        raise ImageReadError(f"{path}: LibRaw made {rgb.shape[2] if rgb.ndim == 3 else 1} colour channel(s) of it, "
                             "not 3 (a damaged raw header?)")
    img = _core._decode_u16(np.ascontiguousarray(rgb[:, :, :3]), False)
    if preprocess == "reference":
        img = _core._reference_raw(img)
    meta = ImageMeta(
        path,
        "raw",
        os.path.splitext(path)[1].lstrip(".").upper() or "RAW",
        16,
        img.shape[0],
        img.shape[1],
        orientation,
        True,
        preprocess,
        cm,
        wb[:3],
        tuple(notes),
    )
    return img, meta


def to_srgb(linear: np.ndarray, meta: ImageMeta | None = None) -> np.ndarray:
    """Linear float HxWx3 -> sRGB-encoded float32 in [0, 1] for display.

    For a raw source the camera matrix (``meta.camera_matrix``) takes the
    camera colours to linear sRGB first. For data that was never linearised
    (``meta.linear`` False, ``preprocess="reference"`` on an sRGB file) the
    values are only clipped.
    """
    x = display_linear(linear, meta)
    if meta is not None and not meta.linear:
        return np.clip(np.nan_to_num(x, nan=0.0), 0.0, 1.0).astype(np.float32)
    return linear_to_srgb(x).astype(np.float32)


def display_linear(linear: np.ndarray, meta: ImageMeta | None) -> np.ndarray:
    """Apply the camera matrix when the source was raw (float32, clipped to [0, 1])."""
    x = np.asarray(linear, dtype=np.float32)
    if meta is not None and meta.camera_matrix is not None:
        m = np.asarray(meta.camera_matrix, dtype=np.float32)
        x = np.clip(x @ m.T, 0.0, 1.0)
    return np.ascontiguousarray(x, dtype=np.float32)


def colorize_transmission(t: np.ndarray) -> np.ndarray:
    """A transmission map (HxW in [0, 1]) -> uint8 HxWx3 through the
    viridis-like map of docs/OUTPUTS.md (dark purple = far, yellow = near)."""
    return _core._colormap(np.ascontiguousarray(t, dtype=np.float32))
