"""Distance maps for ``restore(image, distance=...)`` (METHOD §13.7):
:func:`floor_distance` (a camera over a flat seabed), :func:`depth_to_range`
(photogrammetry's depth along the axis made range along each ray), and the
one check of a map that both ``restore`` and ``depth_to_range`` make
(:func:`distance_map`: float metres, (H, W) or (H, W, 1))."""

from __future__ import annotations

import numpy as np

from . import _core
from .errors import ParameterError, compact_numbers, shown

__all__ = ["floor_distance", "depth_to_range", "distance_map"]


def _number(name: str, value) -> float:
    """A number parameter as a float: a ParameterError for anything that
    is not a real number (text, a bool, None) or too large for a float
    (an integer of 400 digits); NaN and infinity pass, for the core's
    range checks to name."""
    if isinstance(value, (bool, np.bool_, str, bytes)) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ParameterError(f"{name} must be a number, not {shown(value)}")
    try:
        return float(value)
    except OverflowError:
        raise ParameterError(f"{name} {shown(value)} is out of range (too large for a float)") from None


def _port(value) -> str:
    """``port`` checked to be text (the core names a wrong word)."""
    if not isinstance(value, str):
        raise ParameterError(f"port {shown(value)} is not flat or dome")
    return value


def _core_call(f, *args):
    """``f(*args)`` of the core, whose ParameterError shows a number in
    full (1e308 as 309 digits): shown compactly here."""
    try:
        return f(*args)
    except ParameterError as e:
        raise ParameterError(compact_numbers(str(e))) from None


def _metres(a: np.ndarray, name: str) -> None:
    """Refuses an integer or boolean distance array: its unit cannot be
    known. Files of 16-bit integers are millimetres (``read_distance``
    reads them so), an array of integers may be either, and taking
    millimetres as metres would put every pixel beyond the 1000 m of a
    known distance, quietly."""
    if a.dtype == np.bool_ or np.issubdtype(a.dtype, np.integer):
        raise ParameterError(f"{name} has dtype {a.dtype}; expected float metres (integers are refused: their unit "
                             f"is not known; millimetres are {name}.astype(np.float32) / 1000, and read_distance "
                             "reads a 16-bit file as millimetres and gives metres)")


def distance_map(value, name: str) -> np.ndarray:
    """A distance or depth map as :func:`uwhl_rs.restore` and
    :func:`depth_to_range` both take it: real float metres, (H, W) or
    (H, W, 1) (a one-channel image's shape), anything else a
    ParameterError naming ``name``."""
    # a masked array's masked pixels are unknown, not the values under the mask
    if isinstance(value, np.ma.MaskedArray):
        _metres(np.asarray(value.data), name)
        value = np.ma.filled(value.astype(np.float64), np.nan)
    z = np.asarray(value)
    _metres(z, name)
    if z.ndim == 3 and z.shape[2] == 1:
        z = z[:, :, 0]
    if z.ndim != 2 or not np.issubdtype(z.dtype, np.number) or np.iscomplexobj(z):
        raise ParameterError(f"{name} must be a 2-D array of metres, not {z.dtype} of shape {z.shape}")
    return z


def floor_distance(shape, altitude: float, fov: float, *, pitch: float = 0.0, roll: float = 0.0,
                   port: str = "flat") -> np.ndarray:
    """The distance map of a downward camera over a flat seabed (METHOD
    §13.7), for ``restore(image, distance=...)``.

    Parameters
    ----------
    shape : (height, width), or an image whose first two dimensions are used
    altitude : float
        Metres from the camera down to the seabed.
    fov : float
        The lens's horizontal field of view in air across the photo's
        width, degrees.
    pitch, roll : float
        Degrees from looking straight down: pitch positive nose up (the
        camera looks towards the photo's top), roll positive starboard down
        (towards the photo's left).
    port : "flat" or "dome"
        The housing's window: a flat one narrows the angle in water
        (Snell's law), a dome does not.

    Returns
    -------
    float32 ndarray (height, width): the range in metres along each pixel's
    ray, NaN where the ray does not meet the seabed.
    """
    try:
        hw = tuple(np.shape(shape)[:2]) if isinstance(shape, np.ndarray) else tuple(shape)[:2]
    except TypeError:
        hw = ()
    ints = all(isinstance(v, (int, np.integer)) and not isinstance(v, bool) for v in hw)
    if len(hw) != 2 or not ints or min(hw) < 1:
        raise ParameterError(f"shape must be (height, width), two positive integers, not {shown(shape)}")
    from .images import DEFAULT_MAX_PIXELS

    h, w = int(hw[0]), int(hw[1])
    if h * w > DEFAULT_MAX_PIXELS:
        # checked here too: a side beyond the core's integers would not reach its own check
        raise ParameterError(f"shape ({shown(h)}, {shown(w)}) is over the largest input ({DEFAULT_MAX_PIXELS} pixels)")
    return _core_call(_core.floor_distance, h, w, _number("altitude", altitude), _number("fov", fov),
                      _number("pitch", pitch), _number("roll", roll), _port(port))


def depth_to_range(depth, fov: float, *, port: str = "flat") -> np.ndarray:
    """Depth along the camera's optical axis, as photogrammetry (Metashape,
    COLMAP) and most renderers export it, turned into the range along each
    pixel's ray that ``restore(image, distance=...)`` needs (METHOD §13.7):
    each value divided by the cosine of its ray's angle to the axis in
    water.

    Parameters
    ----------
    depth : float array (height, width), or (height, width, 1)
        Metres along the axis, covering the photo's field of view; NaN
        where unknown (it stays NaN). Integer arrays are refused (their
        unit is not known): millimetres are ``depth.astype(np.float32) / 1000``.
    fov : float
        The lens's horizontal field of view in air across the photo's
        width, degrees, in (0, 170].
    port : "flat" or "dome"
        The housing's window: behind a flat one the rays bend toward the
        axis in water (Snell's law), behind a dome they do not.

    Returns
    -------
    float32 ndarray (height, width): metres along each ray.
    """
    z = distance_map(depth, "depth")
    # as floor_distance: no larger than the largest input (a broadcast view is checked before it is copied)
    from .images import DEFAULT_MAX_PIXELS

    if z.size == 0 or z.size > DEFAULT_MAX_PIXELS:
        raise ParameterError(f"depth of shape {z.shape} is empty or over the largest input ({DEFAULT_MAX_PIXELS} pixels)")
    fov, port = _number("fov", fov), _port(port)
    return _core_call(_core.depth_to_range, np.ascontiguousarray(z, dtype=np.float32), fov, port)
