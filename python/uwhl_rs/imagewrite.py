"""Writing images: JPEG, PNG and TIFF, atomically and durably
(docs/API.md ``write_image``); ``uwhl_rs.images`` re-exports these."""

from __future__ import annotations

import os

import numpy as np

from . import _core
from .errors import ParameterError, shown

__all__ = ["IMAGE_EXTENSIONS", "quantize", "atomic_write_bytes", "path_arg", "write_image"]

#: Extensions read through imageio as sRGB-encoded images, and written (the core's list).
IMAGE_EXTENSIONS = frozenset("." + e for e in _core.IMAGE_EXTENSIONS)


def quantize(image: np.ndarray, bits: int, *, encoding: str) -> np.ndarray:
    """Float image -> uint8/uint16 codes (docs/OUTPUTS.md): ``encoding``
    "linear" applies the sRGB curve, "srgb" (already encoded) does not."""
    if encoding not in ("linear", "srgb"):
        raise ValueError(f"encoding must be 'linear' or 'srgb', not {encoding!r}")
    return _core._quantize(np.ascontiguousarray(image, dtype=np.float32), bits, encoding == "linear")


def atomic_write_bytes(path: str | os.PathLike, write) -> None:
    """Create ``path`` atomically and durably: ``write(tmp_path)`` fills a
    temporary file of the same folder (created exclusively under a short
    name with ``path``'s extension), which is then synced, renamed over
    ``path``, and the folder synced (``_core.place``). On any failure (full
    disk, interrupt) the temporary file is removed and ``path`` is
    untouched."""
    path = os.fspath(path)
    tmp = os.fspath(_core.create_temp(path))
    try:
        write(tmp)
    except BaseException:
        try:
            os.remove(tmp)
        except OSError:
            pass
        raise
    _core.place(tmp, path)


def _encodable(path: str, image: np.ndarray, bits: int, encoding: str) -> tuple[str, np.ndarray]:
    """The extension and the integer samples :func:`write_image` writes (or a ParameterError naming what cannot be written)."""
    ext = os.path.splitext(path)[1].lower()
    if ext not in IMAGE_EXTENSIONS:
        raise ParameterError(f"{path}: cannot write {ext or 'a file without extension'}; use .jpg, .png or .tif")
    a = np.asarray(image)
    if a.ndim not in (2, 3) or (a.ndim == 3 and a.shape[2] != 3) or a.size == 0:
        raise ParameterError(f"{path}: cannot write an array of shape {a.shape} (need HxW or HxWx3, non-empty)")
    if a.dtype.kind == "f":
        a = quantize(a, bits, encoding=encoding)
    elif a.dtype not in (np.uint8, np.uint16):
        raise ParameterError(f"{path}: cannot write samples of type {a.dtype} (float, uint8 or uint16)")
    if ext in (".jpg", ".jpeg") and a.dtype != np.uint8:
        raise ParameterError(f"{path}: JPEG holds 8 bits per sample; use .png or .tif for 16 bits")
    return ext, a


def _encode_into(target: str, ext: str, a: np.ndarray, quality: int) -> None:
    """Writes samples ``a`` into the file ``target`` in the format of ``ext``."""
    if ext == ".png":
        with open(target, "wb") as f:
            f.write(_png_bytes(a))
    elif ext in (".tif", ".tiff"):
        import tifffile

        tifffile.imwrite(target, a, photometric="rgb" if a.ndim == 3 else "minisblack", compression="zlib")
    else:
        import imageio.v3 as iio

        iio.imwrite(target, a, extension=ext, quality=int(quality))


def _os_error(path: str, e: OSError) -> OSError:
    return OSError(e.errno, f"cannot write {path}: {e.strerror or e}")


def path_arg(what: str, path) -> str:
    """``path`` as text, or a ParameterError naming ``what`` (bytes and
    other objects are no path the readers and writers take)."""
    if not isinstance(path, (str, os.PathLike)) or isinstance(os.fspath(path), bytes):
        raise ParameterError(f"{what} must be a path (str or os.PathLike), not {shown(path)}")
    return os.fspath(path)


def write_image(
    path: str | os.PathLike,
    image: np.ndarray,
    *,
    bits: int = 8,
    encoding: str = "srgb",
    quality: int = 95,
) -> str:
    """Write an image atomically as JPEG, PNG or TIFF (chosen by the extension).

    ``image``: HxWx3 or HxW; float values in [0, 1] are quantised to
    ``bits`` (8, or 16 for PNG/TIFF) — ``encoding="linear"`` means they are
    linear and get the sRGB curve, ``"srgb"`` that they are already
    encoded — while uint8/uint16 arrays are written as they are. The file
    appears complete or not at all, and is synced (with its folder) before
    this returns. Returns the path.
    """
    path = path_arg("path", path)
    if isinstance(bits, (bool, np.bool_)) or not isinstance(bits, (int, np.integer)) or bits not in (8, 16):
        raise ParameterError(f"bits must be 8 or 16, not {shown(bits)}")
    if isinstance(quality, (bool, np.bool_)) or not isinstance(quality, (int, np.integer)) or not 1 <= quality <= 100:
        raise ParameterError(f"quality must be an integer in [1, 100], not {shown(quality)}")
    ext, a = _encodable(path, image, bits, encoding)
    try:
        atomic_write_bytes(path, lambda tmp: _encode_into(tmp, ext, a, quality))
    except OSError as e:
        raise _os_error(path, e) from None
    return path


def _png_bytes(a: np.ndarray) -> bytes:
    """Encode uint8/uint16 HxW or HxWx3 as PNG: the core's encoder (fdeflate
    with adaptive row filters; the GIL is released while it works)."""
    return _core._encode_png(np.ascontiguousarray(a))
