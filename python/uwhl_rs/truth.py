"""Scores against a known radiance: per-pixel angles to the truth (METHOD §11).

A restored image is compared with the true radiance J of the scene (the
object's colours under white light), pixel by pixel, as the angle between the
two RGB vectors. The angle ignores each pixel's brightness but not its colour,
so a white balance is part of what is scored. ``best_gains`` gives the floor
that any global per-channel balance of the same output could reach.

``read_truth`` and ``read_truth_mask`` read the files a manifest entry of
``uwhl evaluate`` names in its ``truth`` and ``truth_mask`` keys
(docs/EVALUATE.md).
"""

from __future__ import annotations

import os
import stat

import numpy as np

from . import _core
from .errors import ManifestError
from .images import DEFAULT_MAX_PIXELS

__all__ = ["MIN_TRUTH_SUM", "MAX_TRUTH_PIXELS", "MAX_TRUTH_VALUE", "pixel_angles", "angle_stats", "best_gains", "score",
           "median_interval", "paired_medians", "resize_nearest", "load_npy", "read_truth", "read_truth_mask", "memory_budget", "TRUTH_PER_PHOTO_PIXEL"]

#: the most pixels a truth or truth mask may have for each of its photo's
#: (at least 4 Mpx)
TRUTH_PER_PHOTO_PIXEL = 64

#: Truth pixels darker than this (sum of R, G, B, linear) carry no colour
#: worth scoring: their angle is dominated by quantisation and noise.
MIN_TRUTH_SUM = 0.02
#: A truth or truth mask is resized to its photo; a file claiming more pixels than a photo may have is not read.
MAX_TRUTH_PIXELS = DEFAULT_MAX_PIXELS
#: the largest value of a truth's pixel that is scored (linear radiance; white is 1)
MAX_TRUTH_VALUE = 1e6


def pixel_angles(out: np.ndarray, truth: np.ndarray, valid: np.ndarray | None = None) -> np.ndarray:
    """Angles in degrees between ``out`` and ``truth`` (both H x W x 3) at the valid pixels.

    A black output pixel (all channels 0) has no colour and scores 90
    degrees: a restoration that loses a pixel is not rewarded for it.
    """
    o = np.asarray(out, dtype=np.float64).reshape(-1, 3)
    t = np.asarray(truth, dtype=np.float64).reshape(-1, 3)
    if valid is not None:
        keep = np.asarray(valid, dtype=bool).reshape(-1)
        o, t = o[keep], t[keep]
    on = np.linalg.norm(o, axis=1)
    tn = np.linalg.norm(t, axis=1)
    cos = np.einsum("ij,ij->i", o, t) / np.maximum(on * tn, 1e-300)
    ang = np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))
    ang[on <= 0] = 90.0
    return ang


def angle_stats(angles: np.ndarray) -> dict:
    """Median and 90th percentile of per-pixel angles (NaN when empty)."""
    if angles.size == 0:
        return {"median": float("nan"), "p90": float("nan")}
    return {"median": float(np.median(angles)), "p90": float(np.percentile(angles, 90))}


def best_gains(out: np.ndarray, truth: np.ndarray, valid: np.ndarray, samples: int = 4000, seed: int = 0) -> np.ndarray:
    """The global per-channel gains (G fixed at 1) that minimise the median angle.

    Found by Nelder-Mead over log(g_R), log(g_B) from the least-squares
    gains, on at most ``samples`` valid pixels drawn with a fixed seed.
    This is the best any white balance of ``out`` can do.
    """
    from scipy.optimize import minimize

    o = np.asarray(out, dtype=np.float64).reshape(-1, 3)[np.asarray(valid).reshape(-1)]
    t = np.asarray(truth, dtype=np.float64).reshape(-1, 3)[np.asarray(valid).reshape(-1)]
    if len(o) == 0:
        return np.ones(3)
    if len(o) > samples:
        pick = np.random.default_rng(seed).choice(len(o), samples, replace=False)
        o, t = o[pick], t[pick]
    ls = np.einsum("ij,ij->j", o, t) / np.maximum(np.einsum("ij,ij->j", o, o), 1e-300)
    ls = np.where(ls > 0, ls, 1.0)
    ls = ls / ls[1]

    def cost(x):
        g = np.array([np.exp(x[0]), 1.0, np.exp(x[1])])
        return float(np.median(pixel_angles(o * g, t)))

    x0 = np.log(np.clip([ls[0], ls[2]], 1e-6, 1e6))
    best = minimize(cost, x0, method="Nelder-Mead", options={"xatol": 1e-3, "fatol": 1e-3, "maxiter": 200})
    x = best.x if best.fun <= cost(x0) else x0
    return np.array([np.exp(x[0]), 1.0, np.exp(x[1])])


def score(out: np.ndarray, truth: np.ndarray, valid: np.ndarray | None = None, gains: bool = True) -> dict:
    """Angles of ``out`` to ``truth``: raw and after the best global per-channel gains.

    Scored: the pixels of ``valid`` (default: all) whose truth is bright
    enough to have a colour (R + G + B > ``MIN_TRUTH_SUM``). Returns
    ``median``, ``p90`` and, with ``gains``, ``gain_median`` and ``gain_p90``
    (NaN when no pixel is scored).
    """
    truth = np.asarray(truth, dtype=np.float64)
    ok = truth.sum(axis=2) > MIN_TRUTH_SUM
    if valid is not None:
        ok &= np.asarray(valid, dtype=bool)
    res = angle_stats(pixel_angles(out, truth, ok))
    if gains:
        g = best_gains(out, truth, ok)
        st = angle_stats(pixel_angles(np.asarray(out, dtype=np.float64) * g, truth, ok))
        res["gain_median"], res["gain_p90"] = st["median"], st["p90"]
    return res


# ------------------------------------------------------------ over images

#: Bootstrap resamples behind :func:`median_interval` and :func:`paired_medians`.
RESAMPLES = 4000


def _floats(values) -> np.ndarray:
    """``values`` as a flat float64 array, None as NaN."""
    return np.asarray([np.nan if x is None else x for x in values], dtype=np.float64).reshape(-1)


def _check_level(level: float) -> None:
    if not 0 < level < 1:
        raise ValueError("level must be in (0, 1)")


def _bootstrap_medians(columns: list[np.ndarray], resamples: int, seed: int) -> list[np.ndarray]:
    """The medians of each column over the same resamples of the rows (chunked: memory stays small)."""
    n = columns[0].size
    rng = np.random.default_rng(seed)
    out = [np.empty(resamples) for _ in columns]
    step = max(1, min(resamples, 2_000_000 // max(n, 1)))
    for lo in range(0, resamples, step):
        idx = rng.integers(0, n, size=(min(step, resamples - lo), n))
        for col, dst in zip(columns, out):
            dst[lo:lo + idx.shape[0]] = np.median(col[idx], axis=1)
    return out


def median_interval(values, level: float = 0.95, resamples: int = RESAMPLES, seed: int = 0) -> tuple[float, float]:
    """A percentile-bootstrap interval of the median of ``values`` (None and NaN left out).

    How far the median over a set of images could move had other images of
    the same kind been drawn: a difference between two methods smaller than
    this is not a finding. Deterministic for a given ``seed``. NaN, NaN when
    nothing is left; the value itself when one is.
    """
    _check_level(level)
    v = _floats(values)
    v = v[np.isfinite(v)]
    if v.size == 0:
        return float("nan"), float("nan")
    if v.size == 1:
        return float(v[0]), float(v[0])
    (meds,) = _bootstrap_medians([v], resamples, seed)
    lo, hi = np.quantile(meds, [(1 - level) / 2, (1 + level) / 2])
    return float(lo), float(hi)


def paired_medians(a, b, level: float = 0.95, resamples: int = RESAMPLES, seed: int = 0) -> dict:
    """``median(a) - median(b)`` over the images both score, with a paired bootstrap interval.

    ``a`` and ``b`` are per-image values of two methods on the same images
    (index i is one image in both); pairs with a missing value are left out.
    The images are resampled together, so the interval reflects that both
    methods saw the same scenes. Returns ``difference`` (negative: ``a`` has
    the smaller median), ``low`` and ``high`` (the interval), ``better`` and
    ``worse`` (images where ``a`` is below / above ``b``) and ``images``.
    """
    _check_level(level)
    x, y = _floats(a), _floats(b)
    if x.size != y.size:
        raise ValueError(f"paired values of different lengths: {x.size} and {y.size}")
    ok = np.isfinite(x) & np.isfinite(y)
    x, y = x[ok], y[ok]
    out = {"images": int(x.size), "better": int((x < y).sum()), "worse": int((x > y).sum())}
    if x.size == 0:
        return {**out, "difference": float("nan"), "low": float("nan"), "high": float("nan")}
    out["difference"] = float(np.median(x) - np.median(y))
    if x.size == 1:
        return {**out, "low": out["difference"], "high": out["difference"]}
    mx, my = _bootstrap_medians([x, y], resamples, seed)
    lo, hi = np.quantile(mx - my, [(1 - level) / 2, (1 + level) / 2])
    return {**out, "low": float(lo), "high": float(hi)}


# ------------------------------------------------------------------ files


def resize_nearest(a: np.ndarray, height: int, width: int) -> np.ndarray:
    """``a`` (H x W or H x W x C) resized to height x width by nearest neighbour
    (the pixel whose area holds each output pixel's top-left corner)."""
    rows = (np.arange(height) * a.shape[0]) // height
    cols = (np.arange(width) * a.shape[1]) // width
    return a[rows][:, cols]


def _regular(path: str, what: str) -> None:
    # a FIFO or a device would block or never end: regular files only
    try:
        st = os.stat(path)
    except OSError as e:
        raise ManifestError(f"{path}: cannot read the {what} ({e.strerror or e})") from None
    if not stat.S_ISREG(st.st_mode):
        raise ManifestError(f"{path}: the {what} must be a regular file")


def _check_size(path: str, shape, what: str, photo=None, max_memory: int | None = None) -> None:
    """Refuses, from a header's shape, what no truth or mask is or what is
    too large to read: not H x W, H x W x C or C x H x W with at most four
    channels (a 1-D array, the frames of an animation), over
    ``MAX_TRUTH_PIXELS`` pixels or, for the photo (height, width)
    ``photo``, over :data:`TRUTH_PER_PHOTO_PIXEL` times its pixels (and
    4 Mpx: a small compressed file must not decode to gigabytes beside a
    thumbnail, while the truth of a photo evaluated at an eighth of its
    size is read), or more float64 values than ``max_memory`` (default: the
    machine's budget) holds. Sizes in Python integers: a header's product
    cannot wrap."""
    shape = tuple(int(x) for x in shape)
    if len(shape) == 2:
        channels = 1
    elif len(shape) == 3 and shape[2] <= 4:
        channels = shape[2]
    elif len(shape) == 3 and shape[0] <= 4:
        channels = shape[0]  # a planar TIFF page: C x H x W
    else:
        raise ManifestError(f"{path}: the {what} has shape {shape}, not one H x W image (with at most 4 "
                            "channels); not read")
    values = 1
    for x in shape:
        values *= x
    pixels = values // max(channels, 1)
    if pixels > MAX_TRUTH_PIXELS:
        raise ManifestError(f"{path}: the {what} is {pixels} pixels, over the limit of {MAX_TRUTH_PIXELS}; not read")
    if photo is not None and pixels > max(TRUTH_PER_PHOTO_PIXEL * int(photo[0]) * int(photo[1]), 4 << 20):
        raise ManifestError(f"{path}: the {what} is {pixels} pixels, more than {TRUTH_PER_PHOTO_PIXEL} times "
                            f"the photo's {photo[1]}x{photo[0]}; not read")
    # read as float64, with a copy or two while it is checked and resized
    need = values * 8 * 3
    budget = memory_budget(max_memory)
    if need > budget:
        raise ManifestError(f"{path}: the {what} needs about {need} bytes, over the memory budget of {budget} "
                            "(--max-memory); not read")


def memory_budget(max_memory: int | None) -> int:
    """The memory a truth or mask may take: ``max_memory``, else the machine's budget."""
    return int(max_memory) if max_memory is not None else int(_core.default_max_memory())


def load_npy(path: str, what: str, photo=None, max_memory: int | None = None) -> np.ndarray:
    """The numbers of a ``.npy`` file as float64, for a message that names
    it as ``what``. Another file under that name is said to be one (numpy's
    own message would suggest unpickling it); a header claiming more than
    ``MAX_TRUTH_PIXELS`` pixels is refused before anything is read."""
    with open(path, "rb") as f:
        if f.read(6) != b"\x93NUMPY":
            raise ManifestError(f"{path}: cannot read the {what}: not a .npy file (no NumPy header)")
    # mapped, not read: a header claiming a huge array costs nothing until its size is checked
    a = np.load(path, mmap_mode="r", allow_pickle=False)
    _check_size(path, a.shape, what, photo, max_memory)
    if a.dtype.kind not in "biuf":
        raise ManifestError(f"{path}: a .npy {what} holds numbers, not {a.dtype}")
    return np.array(a, dtype=np.float64)


def _png16(path: str, what: str, photo=None, max_memory: int | None = None) -> np.ndarray:
    """A 16-bit PNG's codes / 65535, as they are (no sRGB curve: the truth is linear)."""
    def header(h, w, bpp, oriented):
        _check_size(path, (h, w), what, photo, max_memory)

    img, info = _core.decode_file(path, False, MAX_TRUTH_PIXELS, memory_budget(max_memory), header)
    if info["bits"] != 16 or info["is_float"]:
        raise ManifestError(f"{path}: a PNG {what} is 16-bit, read as linear / 65535 (this one is "
                            f"{info['bits']}-bit; an 8-bit file is sRGB, too coarse to be a truth)")
    return np.asarray(img, dtype=np.float64)


def _load_array(path: str, what: str, photo=None, max_memory: int | None = None) -> np.ndarray:
    """The numbers of a float TIFF, a ``.npy`` or a 16-bit PNG (linear / 65535),
    within the limits of :func:`_check_size`."""
    ext = os.path.splitext(path)[1].lower()
    _regular(path, what)
    try:
        if ext in (".tif", ".tiff"):
            import tifffile

            with tifffile.TiffFile(path) as tf:
                page = tf.pages[0]
                _check_size(path, page.shape, what, photo, max_memory)
                a = page.asarray()
            if a.dtype.kind == "u" and a.dtype.itemsize == 2:
                a = a.astype(np.float64) / 65535.0
            elif a.dtype.kind != "f":
                raise ManifestError(f"{path}: a TIFF {what} holds floats or 16-bit integers (linear / 65535), "
                                    f"not {a.dtype}")
        elif ext == ".npy":
            a = load_npy(path, what, photo, max_memory)
        elif ext == ".png":
            a = _png16(path, what, photo, max_memory)
        else:
            raise ManifestError(f"{path}: a {what} is a float TIFF, a .npy or a 16-bit PNG, not {ext or 'none'}")
    except ManifestError:
        raise
    except Exception as e:  # decoders raise many types; name the file and the reason
        raise ManifestError(f"{path}: cannot read the {what} ({type(e).__name__}: {e})") from None
    return np.asarray(a, dtype=np.float64)


def read_truth(path: str, height: int, width: int, max_memory: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """A true radiance image for a photo of height x width: ``(truth, usable)``.

    ``truth`` is H x W x 3 linear RGB (float TIFF or ``.npy`` as stored,
    16-bit PNG or TIFF as code / 65535; gray is replicated, alpha dropped),
    resized by nearest neighbour; ``usable`` is False where a value is
    non-finite, negative or over ``MAX_TRUTH_VALUE`` (those pixels hold 0
    and are not scored).
    At most 16 times the photo's pixels are read, within ``max_memory``.
    Raises :class:`ManifestError` naming the file for anything else.
    """
    a = _load_array(path, "truth", (height, width), max_memory)
    if a.ndim == 2:
        a = np.repeat(a[:, :, None], 3, axis=2)
    elif a.ndim == 3 and a.shape[2] == 1:
        a = np.repeat(a, 3, axis=2)
    elif a.ndim == 3 and a.shape[2] == 4:
        a = a[:, :, :3]
    if a.ndim != 3 or a.shape[2] != 3 or a.shape[0] == 0 or a.shape[1] == 0:
        raise ManifestError(f"{path}: a truth is an H x W x 3 RGB image, not shape {a.shape}")
    # a linear radiance is at most a few times white: beyond MAX_TRUTH_VALUE a value is no radiance (and its
    # square, in the angle's norms, would overflow)
    usable = np.isfinite(a).all(axis=2) & (a >= 0).all(axis=2) & (a <= MAX_TRUTH_VALUE).all(axis=2)
    a = np.where(usable[:, :, None], a, 0.0)
    return resize_nearest(a, height, width), resize_nearest(usable, height, width)


def read_truth_mask(path: str, height: int, width: int, max_memory: int | None = None) -> np.ndarray:
    """A truth mask (nonzero = score this pixel; any channel of a colour
    image), any size, resized by nearest neighbour to height x width. PNG,
    TIFF, JPEG or ``.npy``."""
    _regular(path, "truth mask")
    try:
        if path.lower().endswith(".npy"):
            m = load_npy(path, "truth mask", (height, width), max_memory)
        else:
            import imageio.v3 as iio

            meta = iio.improps(path)
            _check_size(path, meta.shape, "truth mask", (height, width), max_memory)
            # the first page only: improps describes page 0, and a 300-page TIFF of 1.3 MB decoded whole
            # took 1.2 GB past --max-memory (imageio's index is a TIFF's series, not its page)
            if path.lower().endswith((".tif", ".tiff")):
                import tifffile

                m = np.asarray(tifffile.imread(path, key=0))
            else:
                m = np.asarray(iio.imread(path, index=0))
    except ManifestError:
        raise
    except Exception as e:
        raise ManifestError(f"{path}: cannot read the truth mask ({type(e).__name__}: {e})") from None
    if m.ndim == 3:
        m = (m[..., :3] != 0).any(axis=-1)
    if m.ndim != 2 or m.size == 0:
        raise ManifestError(f"{path}: a truth mask is one 2-D image, not shape {m.shape}")
    return resize_nearest(np.asarray(m != 0), height, width)
