"""uwhl_rs: underwater single-image color restoration with haze-lines.

Berman, Levy, Avidan & Treibitz, "Underwater Single Image Color Restoration
Using Haze-Lines and a New Quantitative Dataset", IEEE TPAMI 2020. The
method runs in a Rust core (``uwhl_rs._core``); this module checks and
converts the numpy inputs and documents the API.

>>> import uwhl_rs
>>> from uwhl_rs import synth
>>> img, truth = synth.demo_input(120, 160)
>>> res = uwhl_rs.restore(img)
>>> res.image.shape, res.transmission.shape
((120, 160, 3), (120, 160))
"""

from __future__ import annotations

import math
import os as _os

import numpy as np

from . import _core
from ._core import Restoration
from . import distances
from .distances import depth_to_range, floor_distance
from .errors import (
    BatchError,
    CommandError,
    IfdoError,
    ImageError,
    ImageReadError,
    ImageTooLargeError,
    ManifestError,
    ParameterError,
    UwhlError,
    shown,
)

__all__ = [
    "restore",
    "floor_distance",
    "depth_to_range",
    "Sequence",
    "Restoration",
    "WATER_TYPES",
    "UwhlError",
    "ImageError",
    "ParameterError",
    "synth",
    "read_image",
    "read_distance",
    "to_srgb",
    "write_image",
    "restore_file",
    "ImageMeta",
    "ImageReadError",
    "ImageTooLargeError",
    "BatchError",
    "IfdoError",
    "ManifestError",
    "CommandError",
    "FileResult",
    "DEFAULTS",
    "STEP_KEYS",
    "method_steps",
    "__version__",
]

__version__: str = _core.__version__

# rayon's thread pools do not survive fork(): a forked child (multiprocessing
# with the "fork" start method) would wait forever on threads that are gone.
# After a fork the core builds fresh pools in the child.
if hasattr(_os, "register_at_fork"):
    _os.register_at_fork(after_in_child=_core._after_fork)

#: The defaults of the method's keyword arguments, read from the core's one
#: option table (docs/CLI.md): ``{keyword: default}``.
DEFAULTS: dict = {o["key"]: o["default"] for o in _core.OPTIONS if o["method"]}

#: The Jerlov water types of METHOD §1: ``{name: (beta_BR, beta_BG)}``
#: in table order (clear oceanic I ... turbid coastal 9C).
WATER_TYPES: dict[str, tuple[float, float]] = {n: (br, bg) for n, br, bg in _core.JERLOV_TABLE}


# name -> submodule defining it; imported on first use so that
# `import uwhl_rs` stays fast (rawpy, imageio and Pillow load only when used)
_LAZY = {
    "synth": None,
    "images": None,
    "files": None,
    "cli": None,
    "read_image": "images",
    "read_distance": "images",
    "to_srgb": "images",
    "write_image": "images",
    "ImageMeta": "images",
    "restore_file": "files",
    "FileResult": "files",
}


def __getattr__(name: str):
    if name in _LAZY:
        import importlib

        sub = _LAZY[name]
        if sub is None:
            return importlib.import_module(f".{name}", __name__)
        return getattr(importlib.import_module(f".{sub}", __name__), name)
    raise AttributeError(f"module 'uwhl_rs' has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_LAZY))


def _check_room(image, params, distance=None) -> None:
    """Refuses, from the shapes alone and before any copy, an image whose
    restoration is over ``max_memory``, and a distance
    map of more than MAP_PER_PHOTO_PIXEL times its pixels (a broadcast
    view of gigabytes costs nothing until it is copied)."""
    shape = np.shape(image)
    if len(shape) != 3 or shape[2] != 3:
        return  # _as_image says what is wrong
    h, w = int(shape[0]), int(shape[1])
    needed, limit = params.budget(h, w)
    if needed > limit:
        # the core's check and words (src/error.rs), made before the copy
        raise MemoryError(f"image of {h}x{w} pixels needs about {needed} bytes of working memory, over the limit of "
                          f"{limit} bytes (raise max_memory or downscale the image)")
    if distance is not None:
        zs = np.shape(distance)
        if len(zs) >= 2:
            if int(zs[0]) * int(zs[1]) > _core.map_cap(h, w):
                raise ParameterError(f"the distance map is {int(zs[0])}x{int(zs[1])} (height x width), more than "
                                     f"{_core.MAP_PER_PHOTO_PIXEL} times the image's {h}x{w} pixels")


def _as_image(image) -> np.ndarray:
    a = np.asarray(image)
    if a.dtype.kind == "f" and a.dtype.itemsize in (4, 8) and not a.dtype.isnative:
        a = a.astype(a.dtype.newbyteorder("="))  # a big-endian file's floats are the same numbers
    if a.dtype not in (np.float32, np.float64):
        raise ImageError(
            f"image has dtype {a.dtype}; expected float32 or float64 linear RGB in [0, 1] "
            "(convert integer images with img / 255.0 or img / 65535.0 and linearize sRGB first)"
        )
    if a.ndim != 3 or a.shape[2] != 3:
        raise ImageError(f"image has shape {a.shape}; expected (H, W, 3)")
    if a.dtype == np.float64:
        # Check before the cast: a large finite float64 would become inf.
        # Same order and wording as the core: first offending value in
        # raster order, non-finite or outside [0, 1].
        bad = ~np.isfinite(a) | (a < 0.0) | (a > 1.0)
        if bad.any():
            r, c, ch = np.argwhere(bad)[0]
            v = a[r, c, ch]
            if not np.isfinite(v):
                raise ImageError(f"image has a non-finite value ({v}) at row {r}, column {c}, channel {ch}")
            raise ImageError(
                f"image value {v} at row {r}, column {c}, channel {ch} is outside [0, 1]; "
                "the input must be linear RGB scaled to [0, 1]"
            )
    return np.ascontiguousarray(a, dtype=np.float32)


_MAX_INT = 2**63 - 1


def _int_param(name: str, value, lo: int):
    """None, or an integer in [lo, 2**63 - 1]; anything else -> ParameterError."""
    if value is None:
        return None
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise ParameterError(f"{name} must be an integer; got {value!r}")
    if not lo <= int(value) <= _MAX_INT:
        raise ParameterError(f"{name} must be an integer in [{lo}, {_MAX_INT}]; got {value!r}")
    return int(value)


def _as_mask(mask, name: str, shape) -> np.ndarray | None:
    if mask is None:
        return None
    m = np.asarray(mask)
    if m.dtype != np.bool_:
        raise ParameterError(f"{name} has dtype {m.dtype}; expected bool (True/False per pixel)")
    if m.shape != tuple(shape):
        raise ParameterError(f"{name} has shape {m.shape}; the image needs {tuple(shape)}")
    # a bool view of other bytes (uint8 2 as bool) is True to NumPy but no bool to the core: every
    # byte made 0 or 1 here, so the core sees the pixels NumPy does
    return np.not_equal(m.view(np.uint8), 0)


def _nearest_type(water: dict, beta) -> str:
    """The name of a given water's one candidate type: its ``nearest_type``,
    which a fit (and uwhl-rs's --water-from, which names the dive's water
    from its betas) only ever makes the Jerlov type nearest its ``beta``, or
    "fitted" without one. Anything else (another type's name: the sidecar
    would name a water it was not restored with; text that could drive a
    terminal or bury a line in the sidecar and the summary) is refused."""
    name = water.get("nearest_type")
    if name is None:
        return "fitted"
    if not isinstance(name, str) or name not in WATER_TYPES:
        raise ParameterError(f"water's nearest_type must be a Jerlov type ({', '.join(WATER_TYPES)}) or None, "
                             f"not {shown(name)}")
    nearest = _core.nearest_type(beta)[0]
    if name != nearest:
        raise ParameterError(f"water's nearest_type is {name}, but its beta is nearest to {nearest}")
    return name


def restore(image, *, water_mask=None, mask=None, distance=None, water=None, **method) -> Restoration:
    """Restore the colors of one underwater image (METHOD §2-§10).

    Parameters
    ----------
    image : ndarray, float32 or float64, (H, W, 3)
        LINEAR RGB in [0, 1] (raw-derived camera RGB, or sRGB decoded
        through the inverse sRGB curve). At least 4x4 pixels; NaN/Inf,
        values outside [0, 1] and constant images are rejected.
    water_types : list, optional
        Candidate water types: names from :data:`WATER_TYPES` and/or
        ``(name, beta_BR, beta_BG)`` tuples with ratios in [1/30, 30] (above ~45
        the t_B floor 0.1^beta_BR underflows in float32; below 1/30 its exponents pass 30's).
        Default: all ten Jerlov types (METHOD §1).
    veiling_light : 3 floats in (0, 1], optional
        A given veiling light A; default: estimated from the water region
        (METHOD §3), or by the documented fallback when there is none.
    water_mask : bool ndarray (H, W), optional
        A given water region VL, used instead of detection (METHOD §3).
    mask : bool ndarray (H, W), optional
        False = do not use this pixel for estimation (e.g. a color chart);
        such regions are filled (METHOD §4.5) and get one transmission each
        (METHOD §6). At least one pixel must be True.
    distance : float ndarray (h, w), optional
        The distance of each pixel in metres (NaN, below 1 cm or above
        1000 m = unknown;
        integer arrays are refused: their unit is not known, convert
        millimetres with ``z.astype(np.float32) / 1000``),
        of any size with the image's aspect ratio (resized by nearest
        neighbour). The water (attenuation per channel, A) is then fitted
        from it and the transmission taken from it where known (METHOD §13);
        ``water`` of the result holds the fit. A map that does not fit the
        photo, or that orders near and far against the photo's own haze
        (``distance["haze_order"]`` below -0.5: flipped or rotated against
        the photo, disparity given as distance; METHOD §13.1), is not used:
        the result is flagged ``distance_rejected`` and
        ``distance["rejected"]`` says why. A water given beside it
        (``water_types`` or ``water``) is used only then: a distance that is
        used gives the photo the water fitted to it.
    water : dict, optional
        A water fitted on another photo of the same water (the ``water`` of
        a restoration given ``distance``, or a sidecar's ``distance.water``):
        its attenuation ratios become the one candidate type, named after
        its nearest Jerlov type (``nearest_type``: a Jerlov name, as a fit
        gives it, or None: "fitted"); A is this photo's own. Its ``beta`` must be three positive
        numbers (not text or booleans). Not with ``water_types``, which is
        a list (a dict or a string would be read as names only).
    guided_radius : int, optional
        Guided-filter radius; default ``round(min(H, W) / 4)`` (METHOD §6).
    guided_eps : float
        Guided-filter regulariser, > 0; default 1e-3 (METHOD §6).
    sphere_points : int
        Number of haze-line clusters; default 500 (METHOD §4.3).
    threads : int, optional
        Worker threads; default all cores. Results are bit-identical for
        any value.
    max_memory : int, optional
        Working-memory limit in bytes of this call (default: 16 GiB, or
        what the machine, its cgroup or ``ulimit -v`` gives if less,
        ``_core.default_max_memory()``); a larger image raises MemoryError
        before anything large is allocated, and so does one the system
        would not give the memory for now.
    selection : {"exhaustive", "fast"}, optional
        How the candidate types are scored (METHOD §9); default: the
        profile's (revised ``"fast"``, paper ``"exhaustive"``). ``"exhaustive"``
        restores every candidate type at full resolution and scores it.
        ``"fast"`` scores the types on a block-averaged copy whose longer
        side is about 1024 px (with the full-resolution veiling light and
        water region), then restores the chosen type once at full
        resolution, exactly as the exhaustive mode restores it; ``scores``
        are then the copy's. Images whose longer side is at most 1024 px
        are processed exhaustively either way.
    guided_subsample : int >= 0 or "auto"
        Guided-filter subsampling factor s. ``1`` (default): the exact
        filter of METHOD §6. ``s >= 2``: He and Sun's fast guided filter: the
        coefficients (a, b) are computed on samples at the centres of
        s x s blocks and interpolated bilinearly back to full resolution.
        ``"auto"`` (or ``0``): ``max(1, radius // 32)`` for the guided
        radius in use. Measured at 1920x1080 on a rendered scene with one
        water type: 144 ms -> 98 ms, t_B mean absolute difference 4e-4,
        maximum 7.6e-3. Recommended for video / sequence mode; not needed
        for single photos. Larger than max(H, W) raises ParameterError.
    t_scale : float in (0, 1]
        Scale of the haze-line transmission t~: the t_B given to the
        nearest object of each haze-line; default 0.9 (METHOD §4.6).
    method : {"revised", "paper"}
        The profile (METHOD §12): the steps used where ``white_balance`` or
        ``type_choice`` is not given. ``"revised"`` (default): the
        radiance white-balanced on the object pixels and, of the three
        types with the least chromatic shades-of-gray color, the one whose
        display is nearest the other two (METHOD §12.1-12.2).
        ``"paper"``: METHOD §2-10 exactly (display stretch of METHOD §8,
        gray world with the t_R rule of METHOD §9).
    white_balance : {"stretch", "gray_world", "shades_of_gray", "white_patch"}, optional
        How the radiance is displayed: the stretch of METHOD §8, or
        per-channel gains from the object pixels' mean, 4-norm mean or
        (masked-in pixels) 99th percentile, then one exposure (METHOD §12.1).
        Default: the profile's.
    type_choice : {"gray_world", "shades_of_gray", "central"}, optional
        How the water type is chosen: METHOD §9, the shades-of-gray score
        of METHOD §12.2, or of its three best-scored types the one whose
        displayed colours are nearest the other two' (METHOD §12.2,
        ``"central"``). Default: the profile's (revised ``"central"``).
    haze_floor : "none" or a Jerlov type name, optional
        The transmission of a type clearer than this one is estimated with
        this type's ratios (its haze-lines are otherwise dominated by noise
        in the red channel); the recovery keeps each type's own ratios
        (METHOD §12.3). Default: the profile's (revised "3C", paper "none").

    Returns
    -------
    Restoration
        ``image`` (H, W, 3) float32: the displayed result (METHOD §12.1, or
        §8 with ``white_balance="stretch"``); ``radiance`` (H, W, 3)
        float32: J before the display (METHOD §7); ``transmission`` (H, W) float32: t_B, whose ``-log`` is
        a distance proxy; ``water_type`` (str); ``scores`` (dict name ->
        score of the type choice in use, lower is better); ``excluded`` (names ruled out
        by the t_R test of METHOD §9); ``veiling_light`` (A); ``veiling_mask``
        (H, W) bool; ``flags`` (list of fallbacks used, e.g.
        ``"veiling_fallback"``); ``guided_radius``; ``guided_subsample``
        (the factor used, "auto" resolved); ``timings`` (dict stage name ->
        wall seconds, in the order the stages ran; for profiling, not
        reproducible); ``beta_ratios``;
        ``channel_transmissions()`` -> (H, W, 3) t_R, t_G, t_B.

    Raises
    ------
    ImageError, ParameterError
        (both ValueError) for unusable input, with a message naming it.
    MemoryError
        when the estimated working memory exceeds ``max_memory``.
    """
    if water is not None:
        if method.get("water_types") is not None:
            raise ParameterError("water and water_types both name the water: give one")
        try:
            beta = water["beta"]
            # an ordered sequence of three numbers: bytes iterate as codes, a set in any order
            if not isinstance(beta, (list, tuple, np.ndarray)) or len(beta) != 3:
                raise TypeError("not three numbers")
            if any(isinstance(v, (bool, str, bytes)) for v in beta):
                raise TypeError("not numbers")
            br, bg, bb = (float(v) for v in beta)
        except OverflowError:
            # an integer beyond a float: a number, but no attenuation
            raise ParameterError(f"water's beta must be three positive numbers, not {shown(list(water['beta']))}") \
                from None
        except (TypeError, KeyError, ValueError):
            raise ParameterError("water must be a dict with 'beta': three attenuations in 1/m "
                                 "(the water of a restoration given distance)") from None
        if not all(np.isfinite(v) and v > 0 for v in (br, bg, bb)):
            raise ParameterError(f"water's beta must be three positive numbers, not {shown(list(water['beta']))}")
        method["water_types"] = [(_nearest_type(water, (br, bg, bb)), bb / br, bb / bg)]
    params = _method_params(**method)
    # after the ratios' own check (its message names them): a water no fit gives
    if water is not None and not _core.water_writable((br, bg, bb)):
        raise ParameterError(f"water's beta {shown([br, bg, bb])} is no water a fit gives (blue 0.001 to 5 1/m, "
                             "the ratios on the Jerlov curve's stretch; METHOD §13.6), as --water-from refuses it")
    _check_room(image, params, distance)
    img = _as_image(image)
    hw = img.shape[:2]
    wm = _as_mask(water_mask, "water_mask", hw)
    m = _as_mask(mask, "mask", hw)
    z = None
    if distance is not None:
        z = np.ascontiguousarray(distances.distance_map(distance, "distance"), dtype=np.float32)
    return _core.restore_f32(img, params, water_mask=wm, mask=m, distance=z)


def _method_params(**kw) -> _core.Params:
    """The method's keyword arguments of :func:`restore` and :class:`Sequence`
    as the core's parameters: the core checks each (a ParameterError naming
    a bad one, a TypeError for an unknown keyword)."""
    wt = kw.get("water_types")
    if isinstance(wt, (dict, str, bytes)):
        # a dict or a string iterates as names only: its values, or its letters, would be taken quietly
        raise ParameterError(f"water_types is a list of names or (name, beta_BR, beta_BG), not a {type(wt).__name__}")
    return _core.Params(**kw)


def _signature_from_table(f, before: list[str]) -> None:
    """Gives ``f`` (which takes the method's keywords as ``**method``) a
    signature listing every method keyword with its default, from the
    option table: what help() and IDEs show. ``before``: the first
    (positional) parameter, then keyword-only ones defaulting to None."""
    import inspect

    first = [inspect.Parameter(before[0], inspect.Parameter.POSITIONAL_OR_KEYWORD)]
    rest = [inspect.Parameter(k, inspect.Parameter.KEYWORD_ONLY, default=None) for k in before[1:]]
    kw = [inspect.Parameter(k, inspect.Parameter.KEYWORD_ONLY, default=v) for k, v in DEFAULTS.items()]
    f.__signature__ = inspect.Signature(first + rest + kw, return_annotation=Restoration)


#: The keywords that name a profile and its steps (METHOD §12).
STEP_KEYS = ("method", "selection", "white_balance", "type_choice", "haze_floor", "fallback")


def method_steps(**kw) -> dict:
    """The profile and the steps that ``restore(**kw)`` uses, by keyword
    (``method``, ``selection``, ``white_balance``, ``type_choice``, ``haze_floor``, ``fallback``), defaults resolved:
    what the sidecar and ``uwhl evaluate`` record."""
    return dict(_core.Params(**{k: kw.get(k) for k in STEP_KEYS}).steps())


class Sequence:
    """Sequence mode: the frames of one video or dive, restored in order.

    The first frame (and, with ``refresh_every=N``, every N-th frame after
    it) runs the whole method with the keyword arguments given here, which
    are those of :func:`restore`: the water type is chosen among
    ``water_types`` and the veiling light A estimated. The frames in
    between reuse that water type and A (one type instead of ten; METHOD §3
    and 9 are skipped, METHOD §4-8 run on the frame), and with
    ``reuse_water_mask=True`` also its water region (right for a camera
    that holds its attitude; a frame of another size detects its own).
    The full-resolution work buffers (32 bytes per pixel) are kept from
    frame to frame, so frames of one size do not have their memory mapped
    and zeroed again: at 1920x1080 with ``guided_subsample="auto"`` a
    frame takes about 10% less than the same :func:`restore` call.

    A frame gives the same bits as :func:`restore` called with the reused
    ``water_types=[type]``, ``veiling_light=A`` (and ``water_mask``); its
    result's ``flags`` include ``"estimates_reused"``. A frame that raises
    changes nothing. Calls from several threads take turns.

    >>> from uwhl_rs import synth
    >>> img, _ = synth.demo_input(120, 160)
    >>> seq = Sequence(guided_subsample="auto")
    >>> first = seq.restore(img)          # every type scored
    >>> nxt = seq.restore(img)            # reuses first.water_type and A
    >>> nxt.water_type == first.water_type, len(nxt.scores)
    (True, 1)

    Parameters
    ----------
    refresh_every : int >= 0
        Re-estimate once N frames have passed since the last estimate (0,
        the default: on the first frame only, until :meth:`reset`).
    scene_cut : float in [0, 1]
        Re-estimate when a frame's colours (its chromaticity histogram,
        METHOD §10) differ from the previous frame's by more than this (a
        cut: estimated afresh) or from the last estimating frame's (a
        drift). 0 (the default) or 1: never. Videos use 0.3.
    smoothing : float in (0, 1]
        A scheduled or drift estimate moves A this share of the way from
        the A in use (1, the default: all the way); the frame is restored
        with the new type and that A. Videos use 0.5.
    reuse_water_mask : bool
        Reuse the estimating frame's water region (default False: each
        frame detects its own).
    **kwargs
        As :func:`restore` (``water_types``, ``veiling_light``,
        ``guided_radius``, ``guided_eps``, ``sphere_points``, ``threads``,
        ``max_memory``, ``selection``, ``guided_subsample``, ``t_scale`` and
        the profile and its steps: ``method``, ``white_balance``,
        ``type_choice``, ``haze_floor``).
    """

    def __init__(self, *, refresh_every: int = 0, reuse_water_mask: bool = False, scene_cut: float = 0.0,
                 smoothing: float = 1.0, **kwargs):
        refresh_every = _int_param("refresh_every", refresh_every, 0)
        if refresh_every is None:
            raise ParameterError("refresh_every must be an integer >= 0 (0: estimate on the first frame only); got None")
        if not isinstance(reuse_water_mask, (bool, np.bool_)):
            raise ParameterError(f"reuse_water_mask must be True or False; got {reuse_water_mask!r}")
        for name, v, lo_open in (("scene_cut", scene_cut, False), ("smoothing", smoothing, True)):
            ok = isinstance(v, (int, float, np.floating)) and not isinstance(v, (bool, np.bool_))
            # an integer past a float's range is no share either (math.isfinite would overflow on it)
            ok = ok and abs(v) <= 1e308 and math.isfinite(v)
            if not ok or not ((0 < v) if lo_open else (0 <= v)) or v > 1:
                raise ParameterError(f"{name} must be a number in {'(0, 1]' if lo_open else '[0, 1]'}; "
                                     f"got {shown(v)}")
        params = _method_params(**kwargs)
        self._params = params
        self._core = _core.Sequence(params, refresh_every=refresh_every, reuse_water_mask=bool(reuse_water_mask),
                                    scene_cut=float(scene_cut), smoothing=float(smoothing))

    def restore(self, image, *, mask=None, water_mask=None) -> Restoration:
        """Restore the next frame; ``image``, ``mask`` and ``water_mask`` as
        in :func:`restore` (a given ``water_mask`` is used on that frame)."""
        _check_room(image, self._params)
        img = _as_image(image)
        hw = img.shape[:2]
        return self._core.restore(
            img, mask=_as_mask(mask, "mask", hw), water_mask=_as_mask(water_mask, "water_mask", hw)
        )

    def reset(self) -> None:
        """Forget the estimates (the next frame estimates again, e.g. after a
        scene change) and free the kept buffers."""
        self._core.reset()

    @property
    def water_type(self) -> str | None:
        """The water type the next frame reuses (None before the first frame)."""
        return self._core.water_type

    @property
    def veiling_light(self) -> tuple[float, float, float] | None:
        """The veiling light A the next frame reuses (None before the first frame)."""
        return self._core.veiling_light

    @property
    def last_decision(self) -> tuple[str, float]:
        """Why the last frame estimated or reused ("first", "scheduled",
        "cut", "drift" or "reused") and how much its colours changed from
        the previous frame's (0-1; 0 when ``scene_cut`` is off)."""
        return self._core.last_decision

    @property
    def estimates_next(self) -> bool:
        """Whether the next frame chooses the water type and estimates A."""
        return self._core.estimates_next

    @property
    def buffer_bytes(self) -> int:
        """Bytes of work buffers kept between frames."""
        return self._core.buffer_bytes

    def __repr__(self) -> str:
        return (
            f"Sequence(water_type={self.water_type!r}, refresh_every={self._core.refresh_every}, "
            f"reuse_water_mask={self._core.reuse_water_mask})"
        )


_signature_from_table(restore, ["image", "water_mask", "mask", "distance", "water"])
