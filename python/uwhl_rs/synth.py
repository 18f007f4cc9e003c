"""Synthetic underwater images with known truth.

This module renders the image-formation model of METHOD §0 from a
clean (object radiance) image, a distance map and a water type, and builds
procedural test scenes for it. Tests use it to check the restoration
pipeline against known truth (METHOD §11, "Synthetic"), and the README
demo uses it to make its built-in input, so no data is ever downloaded.

Everything is deterministic given a seed, depends only on NumPy, and works
on LINEAR RGB data (channel order R, G, B).

Public API
----------
JERLOV
    The ten Jerlov water types of METHOD §1: ``{name: (beta_BR, beta_BG)}``.
render
    Apply METHOD §0 to a clean image and a distance map.
transmissions
    The per-channel transmission maps (t_R, t_G, t_B) of METHOD §0.
default_veiling_light
    A plausible linear water color for a water type.
scene
    A procedural scene: clean radiance, distance (``inf`` for open water)
    and the water mask.
demo_input
    A rendered open-water scene and its truth, for demos and tests.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np

from . import WATER_TYPES

__all__ = [
    "JERLOV",
    "Scene",
    "default_veiling_light",
    "demo_input",
    "render",
    "scene",
    "transmissions",
]

#: Jerlov water types and their attenuation ratios (METHOD §1), in
#: table order: ``name -> (beta_BR, beta_BG)`` with
#: ``beta_BR = beta_B / beta_R`` and ``beta_BG = beta_B / beta_G``.
JERLOV: dict[str, tuple[float, float]] = dict(WATER_TYPES)  # the core's own table

_SCENE_KINDS = ("open_water", "looking_down")
_MIN_Z = 1.0  # objects in scenes are never nearer than this (meters)


# --------------------------------------------------------------------------
# Water types and veiling light
# --------------------------------------------------------------------------


def _check_beta(value: Any, what: str) -> float:
    """Return ``value`` as a positive finite float or raise ValueError."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(
        value, (int, float, np.integer, np.floating)
    ):
        raise ValueError(f"{what} must be a real number, got {value!r}")
    v = float(value)
    if not math.isfinite(v) or v <= 0.0:
        raise ValueError(f"{what} must be positive and finite, got {v!r}")
    return v


def _resolve_water_type(water_type: Any) -> tuple[str | None, float, float]:
    """Parse a water type into ``(name, beta_BR, beta_BG)``.

    Accepted: a name of :data:`JERLOV` (case-insensitive), a tuple
    ``(name, beta_BR, beta_BG)`` or a pair ``(beta_BR, beta_BG)`` (name
    ``None``).
    """
    if isinstance(water_type, str):
        key = water_type.strip().upper()
        if key not in JERLOV:
            raise ValueError(
                f"unknown water type {water_type!r}; expected one of "
                f"{', '.join(JERLOV)} or a tuple (name, beta_BR, beta_BG) "
                f"or (beta_BR, beta_BG)"
            )
        br, bg = JERLOV[key]
        return key, br, bg
    if isinstance(water_type, np.ndarray) and water_type.ndim == 1:
        water_type = water_type.tolist()
    if isinstance(water_type, (tuple, list)):
        if len(water_type) == 3:
            name, br, bg = water_type
            if not isinstance(name, str):
                raise ValueError(
                    f"water type tuple (name, beta_BR, beta_BG): name must be a "
                    f"string, got {name!r}"
                )
        elif len(water_type) == 2:
            name = None
            br, bg = water_type
        else:
            raise ValueError(
                "water type tuple must be (name, beta_BR, beta_BG) or "
                f"(beta_BR, beta_BG), got {len(water_type)} elements"
            )
        return name, _check_beta(br, "beta_BR"), _check_beta(bg, "beta_BG")
    raise ValueError(
        f"unknown water type {water_type!r}; expected a name of JERLOV, a tuple "
        "(name, beta_BR, beta_BG) or (beta_BR, beta_BG)"
    )


def _table_position(beta_br: float) -> float:
    """Position in [0, 1] along the Jerlov table (0 = type I, 1 = type 9C).

    beta_BR increases strictly along the table, so it is used as the table
    coordinate; values outside the table's range are clamped.
    """
    table_br = np.array([v[0] for v in JERLOV.values()])
    idx = np.interp(beta_br, table_br, np.arange(len(table_br), dtype=float))
    return float(idx) / (len(table_br) - 1)


def default_veiling_light(water_type: Any = "II") -> tuple[float, float, float]:
    """A plausible linear veiling-light color (A of METHOD §0) for a type.

    Oceanic types (I .. III) give a deep blue, coastal types (7C, 9C) a
    green, with a small red component throughout: type I is about
    (0.02, 0.20, 0.40) and type 9C about (0.04, 0.30, 0.18). The color is a
    smooth function of the position along the Jerlov table (METHOD §1);
    custom types are placed on the table by their beta_BR (clamped to the
    table's range).

    Parameters
    ----------
    water_type : str or tuple
        A name of :data:`JERLOV`, a tuple ``(name, beta_BR, beta_BG)`` or a
        pair ``(beta_BR, beta_BG)``.

    Returns
    -------
    tuple of 3 float
        Linear (R, G, B), every component in (0, 1).

    Raises
    ------
    ValueError
        Unknown type name or non-positive ratios.
    """
    _, br, _ = _resolve_water_type(water_type)
    s = _table_position(br)
    smooth = s * s * (3.0 - 2.0 * s)  # smoothstep: flat at both table ends
    r = 0.02 + 0.02 * s
    g = 0.20 + 0.10 * smooth
    b = 0.40 - 0.22 * s
    return (float(r), float(g), float(b))


# --------------------------------------------------------------------------
# Image formation (METHOD §0)
# --------------------------------------------------------------------------


def _check_distance(distance: Any) -> np.ndarray:
    d = np.asarray(distance, dtype=np.float64)
    if d.size and np.isnan(d).any():
        raise ValueError("distance contains NaN")
    if d.size and (d < 0).any():
        raise ValueError("distance must be non-negative (got a negative distance)")
    return d


def transmissions(
    distance: Any, water_type: Any, beta_b: float = 0.2
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Per-channel transmission maps of METHOD §0.

    ``t_B = exp(-beta_b * z)``, ``t_R = t_B ** (1 / beta_BR)``,
    ``t_G = t_B ** (1 / beta_BG)`` (since ``t_c = exp(-beta_c z)`` and
    ``beta_BR = beta_B / beta_R``). ``z = +inf`` (open water) gives 0, ``z = 0``
    gives 1.

    Parameters
    ----------
    distance : array_like
        Distances in meters, any shape, ``>= 0`` (``+inf`` allowed), no NaN.
    water_type : str or tuple
        A name of :data:`JERLOV`, ``(name, beta_BR, beta_BG)`` or
        ``(beta_BR, beta_BG)``.
    beta_b : float, default 0.2
        Attenuation coefficient of the blue channel, in 1/m.

    Returns
    -------
    (t_R, t_G, t_B) : tuple of float64 ndarray
        Same shape as ``distance``, values in [0, 1].

    Raises
    ------
    ValueError
        NaN or negative distance, unknown type, non-positive ratios or beta_b.
    """
    _, br, bg = _resolve_water_type(water_type)
    bb = _check_beta(beta_b, "beta_b")
    z = _check_distance(distance)
    with np.errstate(over="ignore", under="ignore"):
        t_b = np.exp(-bb * z)
        t_r = t_b ** (1.0 / br)
        t_g = t_b ** (1.0 / bg)
    return t_r, t_g, t_b


def render(
    clean: Any,
    distance: Any,
    water_type: Any = "II",
    *,
    veiling_light: Any = None,
    beta_b: float = 0.2,
    noise: float = 0.0,
    seed: Any = 0,
) -> np.ndarray:
    """Render an underwater image with the model of METHOD §0.

    Per channel c, on LINEAR data::

        I_c = t_c * J_c + (1 - t_c) * A_c

    with ``t_B = exp(-beta_b z)``, ``t_R = t_B ** (1/beta_BR)``,
    ``t_G = t_B ** (1/beta_BG)`` (see :func:`transmissions`). Where the
    distance is ``+inf`` (open water, no object) ``t = 0`` and ``I = A``.
    Gaussian noise of standard deviation ``noise`` is then added to every
    pixel and channel, and the result is clipped to [0, 1].

    Parameters
    ----------
    clean : array_like, H x W x 3
        Object radiance J, linear, finite and non-negative (normally in [0, 1]).
    distance : array_like, H x W
        Distance z in meters, ``>= 0``, ``+inf`` for open water, no NaN.
    water_type : str or tuple, default "II"
        A name of :data:`JERLOV` (METHOD §1), a tuple
        ``(name, beta_BR, beta_BG)`` or a pair ``(beta_BR, beta_BG)``.
    veiling_light : sequence of 3 float, optional
        A = linear (R, G, B) in [0, 1]; ``None`` uses
        :func:`default_veiling_light` of the water type.
    beta_b : float, default 0.2
        Blue attenuation coefficient in 1/m.
    noise : float, default 0.0
        Standard deviation of additive Gaussian noise, applied before clipping.
    seed : int or numpy seed, default 0
        Seed of ``numpy.random.default_rng`` for the noise.

    Returns
    -------
    ndarray, float32, H x W x 3
        The observed image I, linear, clipped to [0, 1].

    Raises
    ------
    ValueError
        Wrong shapes, NaN or non-finite clean values, NaN or negative
        distances, unknown water type, non-positive ratios or beta_b, a
        veiling light outside [0, 1], negative or non-finite noise.
    """
    _, br, bg = _resolve_water_type(water_type)
    bb = _check_beta(beta_b, "beta_b")

    j = np.asarray(clean, dtype=np.float64)
    if j.ndim != 3 or j.shape[2] != 3:
        raise ValueError(f"clean must have shape (H, W, 3), got {j.shape}")
    if j.shape[0] < 1 or j.shape[1] < 1:
        raise ValueError(f"clean must not be empty, got shape {j.shape}")
    if not np.isfinite(j).all():
        raise ValueError("clean contains NaN or infinite values")
    if (j < 0).any():
        raise ValueError("clean must be non-negative (linear radiance)")

    z = _check_distance(distance)
    if z.shape != j.shape[:2]:
        raise ValueError(
            f"distance must have shape (H, W) = {j.shape[:2]} matching clean, "
            f"got {z.shape}"
        )

    if veiling_light is None:
        a = np.array(default_veiling_light((br, bg)), dtype=np.float64)
    else:
        a = np.asarray(veiling_light, dtype=np.float64)
        if a.shape != (3,):
            raise ValueError(
                f"veiling_light must be 3 values (R, G, B), got shape {a.shape}"
            )
        if not np.isfinite(a).all() or (a < 0).any() or (a > 1).any():
            raise ValueError(f"veiling_light must be within [0, 1], got {a.tolist()}")

    if isinstance(noise, (bool, np.bool_)):
        raise ValueError(f"noise must be a real number, got {noise!r}")
    try:
        sigma = float(noise)
    except (TypeError, ValueError):
        raise ValueError(f"noise must be a real number, got {noise!r}") from None
    if not math.isfinite(sigma) or sigma < 0:
        raise ValueError(f"noise must be a finite standard deviation >= 0, got {sigma!r}")

    t_r, t_g, t_b = transmissions(z, (br, bg), bb)
    t = np.stack([t_r, t_g, t_b], axis=-1)
    img = t * j + (1.0 - t) * a
    if sigma > 0:
        rng = np.random.default_rng(seed)
        img += rng.normal(0.0, sigma, size=img.shape)
    np.clip(img, 0.0, 1.0, out=img)
    return img.astype(np.float32)


# --------------------------------------------------------------------------
# Procedural fields (NumPy only)
# --------------------------------------------------------------------------


def _smoothstep(x: np.ndarray) -> np.ndarray:
    return x * x * (3.0 - 2.0 * x)


def _ramp(x: np.ndarray, lo: float, hi: float) -> np.ndarray:
    """0 below lo, 1 above hi, smooth in between."""
    return _smoothstep(np.clip((x - lo) / (hi - lo), 0.0, 1.0))


def _interp_index(coord: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Lattice index, smoothed fraction and lattice size for 1-D coordinates."""
    base = math.floor(float(coord.min()))
    c = coord - base
    i0 = np.floor(c).astype(np.intp)
    f = _smoothstep(c - i0)
    return i0, f, int(i0.max()) + 2


def _value_noise(rng: np.random.Generator, yc: np.ndarray, xc: np.ndarray) -> np.ndarray:
    """Value noise in [0, 1] on the grid ``yc x xc`` (lattice units).

    Random values on an integer lattice, interpolated with a smoothstep
    weight, separably (rows, then columns). ``yc`` and ``xc`` are any 1-D
    coordinate arrays, so a row-dependent warp (perspective) is free.
    """
    iy, fy, ny = _interp_index(yc)
    ix, fx, nx = _interp_index(xc)
    grid = rng.random((ny, nx), dtype=np.float32)
    fy = fy.astype(np.float32)[:, None]
    rows = grid[iy] * (1 - fy) + grid[iy + 1] * fy  # (h, nx)
    fx = fx.astype(np.float32)[None, :]
    return rows[:, ix] * (1 - fx) + rows[:, ix + 1] * fx


def _fbm(
    rng: np.random.Generator,
    yc: np.ndarray,
    xc: np.ndarray,
    octaves: int = 3,
    gain: float = 0.5,
    min_step: float = 0.5,
) -> np.ndarray:
    """Fractal sum of value noise, rescaled to about [0, 1].

    ``yc``/``xc`` are the coordinates of the coarsest octave in lattice
    units; each further octave doubles the frequency and multiplies the
    amplitude by ``gain``. Octaves whose coordinate step per pixel would
    exceed ``min_step`` lattice cells are skipped (they would only alias).
    """
    dy = float(np.max(np.abs(np.diff(yc)))) if yc.size > 1 else 0.0
    dx = float(np.max(np.abs(np.diff(xc)))) if xc.size > 1 else 0.0
    step = max(dy, dx)
    total = np.zeros((yc.size, xc.size), dtype=np.float32)
    amp, norm, freq = 1.0, 0.0, 1.0
    for k in range(octaves):
        if k > 0 and step * freq > min_step:
            break
        off_y, off_x = rng.uniform(0.0, 64.0, size=2)
        total += amp * _value_noise(rng, yc * freq + off_y, xc * freq + off_x)
        norm += amp
        amp *= gain
        freq *= 2.0
    total /= norm
    # Value-noise sums concentrate around 0.5; spread them back to ~[0, 1].
    return np.clip((total - 0.5) * (1.6 if norm > 1 else 1.2) + 0.5, 0.0, 1.0)


def _mix(base: np.ndarray, color: Any, weight: np.ndarray) -> np.ndarray:
    """In-place lerp of a planar 3 x H x W image toward ``color``.

    ``weight`` is H x W in [0, 1]. (Planar layout keeps every operation on
    contiguous memory, which is several times faster than H x W x 3.)
    """
    for c in range(3):
        plane = base[c]
        tmp = np.float32(color[c]) - plane
        tmp *= weight
        plane += tmp
    return base


# --------------------------------------------------------------------------
# Objects (rocks, corals, sponges, fish)
# --------------------------------------------------------------------------

# (name, base color, second color, kind)
_OBJECT_PALETTE = [
    ("rock", (0.17, 0.155, 0.14), (0.22, 0.36, 0.16), "rock"),
    ("dark_rock", (0.10, 0.10, 0.11), (0.30, 0.28, 0.25), "rock"),
    ("red_coral", (0.80, 0.22, 0.16), (0.92, 0.50, 0.40), "coral"),
    ("yellow_coral", (0.86, 0.72, 0.16), (0.70, 0.50, 0.10), "coral"),
    ("purple_sponge", (0.50, 0.20, 0.62), (0.70, 0.40, 0.78), "coral"),
    ("blue_sponge", (0.14, 0.30, 0.82), (0.30, 0.55, 0.90), "coral"),
    ("green_coral", (0.30, 0.68, 0.26), (0.60, 0.82, 0.30), "coral"),
    ("cyan_coral", (0.20, 0.62, 0.70), (0.10, 0.35, 0.55), "coral"),
]
_FISH_PALETTE = [
    ((0.92, 0.80, 0.12), (0.08, 0.07, 0.06)),  # yellow, black stripes
    ((0.93, 0.42, 0.08), (0.92, 0.90, 0.86)),  # orange, white stripes
    ((0.12, 0.30, 0.86), (0.95, 0.82, 0.15)),  # blue, yellow stripes
    ((0.80, 0.16, 0.30), (0.90, 0.85, 0.80)),  # red, pale stripes
]


def _paint_blob(
    rng: np.random.Generator,
    clean: np.ndarray,
    dist: np.ndarray,
    tex: np.ndarray,
    cy: float,
    cx: float,
    ry: float,
    rx: float,
    z_back: float,
    relief: float,
    colors: tuple,
    kind: str,
) -> None:
    """Paint one irregular blob (rock/coral) with a z-buffer test.

    The blob's surface is at ``z_back - relief * dome`` (dome = 1 at the
    center, 0 at the rim), so it is nearer than ``z_back``.
    """
    h, w = dist.shape
    y0, y1 = max(0, int(math.floor(cy - ry * 1.6))), min(h, int(math.ceil(cy + ry * 1.6)) + 1)
    x0, x1 = max(0, int(math.floor(cx - rx * 1.6))), min(w, int(math.ceil(cx + rx * 1.6)) + 1)
    if y0 >= y1 or x0 >= x1:
        return
    yy = (np.arange(y0, y1, dtype=np.float32)[:, None] - cy) / ry
    xx = (np.arange(x0, x1, dtype=np.float32)[None, :] - cx) / rx
    rho = np.sqrt(yy * yy + xx * xx)
    theta = np.arctan2(yy, xx)
    lobes = 3 if kind == "rock" else 7
    edge = np.ones_like(theta)
    for k in range(2, lobes + 1):
        edge += rng.uniform(0.02, 0.10 if kind == "rock" else 0.16) / math.sqrt(k - 1) * np.cos(
            k * theta + rng.uniform(0.0, 2.0 * math.pi)
        )
    if kind == "rock":
        edge = np.where(yy > 0, np.maximum(edge, 1.0), edge)  # flat-ish sitting base
    rr = rho / np.maximum(edge, 0.3)
    inside = rr < 1.0
    if not inside.any():
        return
    dome = np.sqrt(np.clip(1.0 - rr * rr, 0.0, 1.0))
    z_obj = np.maximum(z_back - relief * dome, min(z_back, _MIN_Z))
    sub_d = dist[y0:y1, x0:x1]
    win = inside & (z_obj < sub_d)
    if not win.any():
        return
    t = tex[y0:y1, x0:x1]
    c1 = np.asarray(colors[0], dtype=np.float32)
    c2 = np.asarray(colors[1], dtype=np.float32)
    if kind == "rock":
        patch = _ramp(t, 0.55, 0.75)  # algae/encrusting patches on the rock
        detail = 0.70 + 0.55 * t
    else:
        # polyps/spots: a high-frequency radial pattern mixed with texture
        spots = 0.5 + 0.5 * np.cos(rho * rng.uniform(9.0, 16.0)) * np.cos(theta * rng.integers(5, 11))
        patch = _ramp(0.6 * spots + 0.4 * t, 0.55, 0.8)
        detail = 0.80 + 0.35 * t
    col = c1 * (1.0 - patch[..., None]) + c2 * patch[..., None]
    shade = (0.55 + 0.45 * dome) * (1.0 - 0.18 * yy.clip(-1, 1))  # lit from above
    col = col * (detail * shade)[..., None]
    sub_c = clean[y0:y1, x0:x1]
    sub_c[win] = col[win]
    sub_d[win] = z_obj[win]


def _paint_fish(
    rng: np.random.Generator,
    clean: np.ndarray,
    dist: np.ndarray,
    tex: np.ndarray,
    cy: float,
    cx: float,
    length: float,
    z_fish: float,
) -> None:
    """Paint a fish-like shape (ellipse body, triangular tail, stripes, eye)."""
    h, w = dist.shape
    facing = 1.0 if rng.random() < 0.5 else -1.0
    rx = 0.5 * length
    ry = rx * rng.uniform(0.32, 0.48)
    tail = 0.45 * rx
    y0, y1 = max(0, int(math.floor(cy - ry * 1.2))), min(h, int(math.ceil(cy + ry * 1.2)) + 1)
    x0 = max(0, int(math.floor(cx - rx - tail - 1)))
    x1 = min(w, int(math.ceil(cx + rx + tail + 1)) + 1)
    if y0 >= y1 or x0 >= x1:
        return
    dy = np.arange(y0, y1, dtype=np.float32)[:, None] - cy
    dx = (np.arange(x0, x1, dtype=np.float32)[None, :] - cx) * facing  # +x = head
    body_r = (dx / rx) ** 2 + (dy / ry) ** 2
    body = body_r < 1.0
    back = -dx - 0.8 * rx  # distance behind the tail root
    tail_m = (back > 0) & (back < tail) & (np.abs(dy) < 0.15 * ry + 0.9 * back * ry / tail)
    inside = body | tail_m
    win = inside & (z_fish < dist[y0:y1, x0:x1])
    if not win.any():
        return
    c1, c2 = _FISH_PALETTE[int(rng.integers(len(_FISH_PALETTE)))]
    c1 = np.asarray(c1, dtype=np.float32)
    c2 = np.asarray(c2, dtype=np.float32)
    stripes = _ramp(np.cos(dx / rx * math.pi * rng.uniform(1.5, 2.5)), 0.55, 0.8)
    col = c1 * (1.0 - stripes[..., None]) + c2 * stripes[..., None]
    col = np.where(tail_m[..., None], c2 * 0.9, col)
    eye = ((dx - 0.6 * rx) ** 2 + (dy + 0.15 * ry) ** 2) < (0.12 * ry + 0.5) ** 2
    col = np.where(eye[..., None], np.float32(0.04), col)
    dome = np.sqrt(np.clip(1.0 - body_r, 0.0, 1.0))
    shade = (0.65 + 0.35 * np.where(body, dome, 0.5)) * (1.0 - 0.25 * (dy / ry).clip(-1, 1))
    col = col * (shade * (0.85 + 0.3 * tex[y0:y1, x0:x1]))[..., None]
    clean[y0:y1, x0:x1][win] = col[win]
    dist[y0:y1, x0:x1][win] = z_fish


# --------------------------------------------------------------------------
# Scenes
# --------------------------------------------------------------------------


@dataclass
class Scene:
    """A synthetic scene with known truth.

    Attributes
    ----------
    clean : ndarray, float32, H x W x 3
        Linear object radiance J in [0.02, 0.95] (water pixels hold a neutral
        gray that the model of METHOD §0 never shows, since t = 0 there).
    distance : ndarray, float32, H x W
        Distance z in meters; ``np.inf`` on open water.
    water : ndarray, bool, H x W
        True where there is open water, i.e. exactly where ``distance`` is inf.
    """

    clean: np.ndarray
    distance: np.ndarray
    water: np.ndarray


def _floor_texture(
    rng: np.random.Generator,
    yc: np.ndarray,
    xc: np.ndarray,
    fine: np.ndarray,
    ripple_y: np.ndarray | None = None,
) -> np.ndarray:
    """Seabed radiance (planar 3 x H x W) on a coordinate grid.

    Mostly sand (grain and ripples), with patches of green algae, dark
    rubble and red coralline algae. ``yc``/``xc`` are the patch lattice
    coordinates (1-D), ``fine`` a full-size detail field in [0, 1].
    """
    h, w = yc.size, xc.size
    ry = yc if ripple_y is None else ripple_y
    warp = _fbm(rng, yc * 2.0, xc * 2.0, octaves=2)
    ripples = np.sin(ry[:, None] * 9.0 + xc[None, :] * 1.3 + 5.0 * warp)
    grain = 0.78 + 0.28 * fine + 0.04 * ripples
    img = np.empty((3, h, w), dtype=np.float32)  # planar, see _mix
    for c, v in enumerate((0.62, 0.56, 0.45)):  # sand
        np.multiply(grain, np.float32(v), out=img[c])
    green = _fbm(rng, yc, xc, octaves=3)
    _mix(img, (0.15, 0.40, 0.12), 0.92 * _ramp(green + 0.25 * (fine - 0.5), 0.62, 0.72)
         * (0.7 + 0.3 * fine))
    dark = _fbm(rng, yc * 1.4, xc * 1.4, octaves=3)
    _mix(img, (0.11, 0.105, 0.10), 0.95 * _ramp(dark + 0.3 * (fine - 0.5), 0.68, 0.76)
         * (0.55 + 0.45 * fine))
    red = _fbm(rng, yc * 2.2, xc * 2.2, octaves=3)
    _mix(img, (0.66, 0.20, 0.24), 0.85 * _ramp(red + 0.2 * (fine - 0.5), 0.78, 0.84)
         * (0.6 + 0.4 * fine))
    return img


def _gray_world(clean: np.ndarray, valid: np.ndarray, lo: float, hi: float) -> None:
    """Rescale channels in place so their means over ``valid`` agree, then clip.

    A few rounds, since clipping to [lo, hi] moves the means slightly.
    """
    weights = valid.ravel().astype(np.float32)
    n = float(np.count_nonzero(valid))
    flat = clean.reshape(-1, 3)
    np.clip(clean, lo, hi, out=clean)
    if n == 0:
        return
    for _ in range(8):
        means = (weights @ flat).astype(np.float64) / n
        if means.max() - means.min() < 0.002 * means.mean():
            break
        scale = (means.mean() / np.maximum(means, 1e-9)).astype(np.float32)
        clean *= scale
        np.clip(clean, lo, hi, out=clean)


def _object_count(h: int, w: int, lo: int, hi: int, rng: np.random.Generator) -> int:
    """Number of objects, fewer on tiny images."""
    n = int(rng.integers(lo, hi + 1))
    area_cap = max(2, (h * w) // 300)
    return min(n, area_cap)


def _scene_open_water(rng: np.random.Generator, h: int, w: int):
    s = min(h, w)
    ys = np.arange(h, dtype=np.float32)
    xs = np.arange(w, dtype=np.float32)

    # Irregular horizon: a reef silhouette, mean row at `target` * H.
    target = rng.uniform(0.36, 0.43)
    prof = _fbm(rng, np.zeros(1, np.float32), xs / max(8.0, 0.35 * w), octaves=4, min_step=0.6)[0]
    bumps = np.zeros(w, dtype=np.float32)
    for _ in range(int(rng.integers(2, 5))):  # a few coral heads on the reef
        bx, bw = rng.uniform(0, w), rng.uniform(0.03, 0.09) * w
        bumps += rng.uniform(0.4, 1.0) * np.exp(-0.5 * ((xs - bx) / max(bw, 1.0)) ** 2)
    sil = prof + 0.5 * bumps  # higher = reef reaches higher up
    sil = (sil - sil.mean()) / max(float(np.ptp(sil)), 1e-6)  # ptp ~ 1
    horizon = target * h - sil * 0.14 * h
    horizon = np.clip(horizon, 0.28 * h, 0.56 * h)
    horizon += target * h - horizon.mean()  # keep the mean water fraction
    water = ys[:, None] < horizon[None, :]

    # Seabed distance: geometric from z_bot (bottom row) to z_far (horizon).
    z_bot = rng.uniform(1.4, 1.7)
    z_far = rng.uniform(8.5, 11.5)
    span = np.maximum(h - 1 - horizon, 1.0)
    u = np.clip((ys[:, None] - horizon[None, :]) / span[None, :], 0.0, 1.0)
    zf = z_far * (z_bot / z_far) ** u
    und_y = ys / max(6.0, 0.25 * s)
    und_x = xs / max(6.0, 0.25 * s)
    und = _fbm(rng, und_y, und_x, octaves=2)
    zf *= 1.0 + 0.08 * (und - 0.5)
    dist = zf.astype(np.float32)
    dist[water] = np.inf  # objects painted later may occlude some water

    # Perspective-ish texture coordinates: rows follow the plane distance
    # along the mean horizon (extrapolated above it, where the reef rises),
    # columns scale with the image.
    hm = float(horizon.mean())
    u_row = np.clip((ys - hm) / max(h - 1 - hm, 1.0), -0.6, 1.0)
    z_row = z_far * (z_bot / z_far) ** u_row
    yc = (z_row / 0.9).astype(np.float32)
    xc = (xs / max(4.0, 0.12 * w)).astype(np.float32)
    fine = _fbm(rng, ys / max(2.0, 0.02 * s), xs / max(2.0, 0.02 * s), octaves=3)
    clean = _floor_texture(rng, yc, xc, fine, ripple_y=z_row / 0.3)

    # Along the horizon: a reef of dark rock dotted with colorful corals.
    tex = _fbm(rng, ys / max(2.0, 0.03 * s), xs / max(2.0, 0.03 * s), octaves=3)
    hue = _fbm(rng, ys / max(3.0, 0.05 * s), xs / max(3.0, 0.05 * s), octaves=1)
    coral_cols = np.array([c[1] for c in _OBJECT_PALETTE[2:]], dtype=np.float32)
    pick = np.minimum((hue * len(coral_cols)).astype(np.intp), len(coral_cols) - 1)
    reef = _ramp(1.0 - u, 0.80, 0.96)
    rock = 1.0 - _ramp(tex, 0.5, 0.62)
    shade = 0.6 + 0.4 * tex
    for c, rock_c in enumerate((0.20, 0.185, 0.17)):
        reef_c = coral_cols[pick, c] * shade
        reef_c += rock * (np.float32(rock_c) - reef_c)
        clean[c] += reef * (reef_c - clean[c])
    clean = np.ascontiguousarray(np.moveaxis(clean, 0, -1))

    # Objects on the floor, far ones first (z-buffer anyway).
    n_obj = _object_count(h, w, 8, 12, rng)
    objs = []
    for _ in range(n_obj):
        cx = rng.uniform(0.0, w - 1)
        hx = float(horizon[int(min(w - 1, max(0, round(cx))))])
        base = rng.uniform(hx + 0.12 * (h - hx), h - 1 + 0.1 * (h - hx))
        col = int(min(w - 1, max(0, round(cx))))
        row = int(min(h - 1, max(0, round(base))))
        z_base = float(zf[row, col]) if base <= h - 1 else z_bot * 0.95
        r = s * rng.uniform(0.05, 0.12) * (z_bot / z_base) ** 0.8 * 1.6
        r = max(r, 1.5)
        _, c1, c2, kind = _OBJECT_PALETTE[int(rng.integers(len(_OBJECT_PALETTE)))]
        ry = r * (rng.uniform(0.55, 0.85) if kind == "rock" else rng.uniform(0.7, 1.1))
        rx = r * rng.uniform(0.9, 1.4)
        objs.append((z_base, base - ry, cx, ry, rx, (c1, c2), kind))
    objs.sort(key=lambda o: -o[0])
    for z_base, cy, cx, ry, rx, colors, kind in objs:
        relief = min(0.35 * z_base, rx / s * 1.5 * z_base)
        _paint_blob(rng, clean, dist, tex, cy, cx, ry, rx, z_base * 0.985, relief, colors, kind)

    # Fish above the floor, nearer than what is behind them.
    for _ in range(int(rng.integers(2, 4)) if h * w >= 600 else 1):
        cx = rng.uniform(0.1 * w, 0.9 * w)
        hx = float(horizon[int(round(cx))])
        cy = rng.uniform(hx + 0.15 * (h - hx), hx + 0.7 * (h - hx))
        z_behind = float(dist[int(min(h - 1, round(cy))), int(round(cx))])
        z_fish = max(_MIN_Z, rng.uniform(0.45, 0.8) * z_behind)
        length = max(3.0, s * rng.uniform(0.10, 0.16) * (2.5 / max(z_fish, 1.0)))
        _paint_fish(rng, clean, dist, tex, cy, cx, length, z_fish)

    return clean, dist, np.isinf(dist)


def _scene_looking_down(rng: np.random.Generator, h: int, w: int):
    s = min(h, w)
    ys = np.arange(h, dtype=np.float32)
    xs = np.arange(w, dtype=np.float32)

    # A gently tilted, undulating seabed 1.5 .. 4 m away.
    z0 = rng.uniform(2.6, 3.0)
    tilt = rng.uniform(0.8, 1.3)  # upper rows farther
    und = _fbm(rng, ys / max(6.0, 0.3 * s), xs / max(6.0, 0.3 * s), octaves=3)
    zf = z0 + tilt * (0.5 - ys[:, None] / max(h - 1, 1)) + 0.5 * (und - 0.5)
    dist = np.clip(zf, 1.6, 3.9).astype(np.float32)

    fine = _fbm(rng, ys / max(2.0, 0.02 * s), xs / max(2.0, 0.02 * s), octaves=3)
    cell = max(4.0, 0.14 * s)
    clean = np.ascontiguousarray(np.moveaxis(_floor_texture(rng, ys / cell, xs / cell, fine), 0, -1))

    tex = _fbm(rng, ys / max(2.0, 0.03 * s), xs / max(2.0, 0.03 * s), octaves=3)
    n_obj = _object_count(h, w, 8, 13, rng)
    for _ in range(n_obj):
        cy, cx = rng.uniform(-0.05 * h, 1.05 * h), rng.uniform(-0.05 * w, 1.05 * w)
        z_back = float(dist[int(np.clip(round(cy), 0, h - 1)), int(np.clip(round(cx), 0, w - 1))])
        _, c1, c2, kind = _OBJECT_PALETTE[int(rng.integers(len(_OBJECT_PALETTE)))]
        r = max(1.5, s * rng.uniform(0.05, 0.12) * 2.5 / z_back)
        ry, rx = r * rng.uniform(0.75, 1.25), r * rng.uniform(0.75, 1.25)
        relief = rng.uniform(0.2, 0.7)
        _paint_blob(rng, clean, dist, tex, cy, cx, ry, rx, z_back, relief, (c1, c2), kind)
    for _ in range(int(rng.integers(2, 5)) if h * w >= 600 else 1):
        cy, cx = rng.uniform(0.1 * h, 0.9 * h), rng.uniform(0.1 * w, 0.9 * w)
        z_behind = float(dist[int(round(cy)), int(round(cx))])
        z_fish = max(1.5, z_behind - rng.uniform(0.4, 1.0))
        length = max(3.0, s * rng.uniform(0.10, 0.16) * 2.5 / z_fish)
        _paint_fish(rng, clean, dist, tex, cy, cx, length, z_fish)

    np.clip(dist, 1.5, 4.0, out=dist)
    water = np.zeros((h, w), dtype=bool)
    return clean, dist, water


def scene(
    height: int = 360, width: int = 480, *, kind: str = "open_water", seed: Any = 0
) -> Scene:
    """Build a procedural underwater scene with known distance and radiance.

    ``kind="open_water"``: the upper ~36-43 % of the image (mean over
    columns; the horizon is an irregular reef silhouette) is open water
    (distance ``inf``); below, a seabed recedes from ~1.5 m at the bottom
    row to ~8.5-11.5 m at the horizon, with rocks, corals, sponges and fish
    nearer than the floor behind them.

    ``kind="looking_down"``: no open water; a seabed seen from above at
    1.5-4 m with gentle undulation, rocks, corals and fish.

    The radiance is textured (value noise) with diverse hues (sand, dark
    rock, green algae, red/yellow/purple/blue corals and fish), kept in
    [0.02, 0.95], and rescaled per channel so that its mean over non-water
    pixels is gray (the gray-world assumption behind METHOD §9).

    Parameters
    ----------
    height, width : int
        Image size in pixels, each at least 8.
    kind : {"open_water", "looking_down"}
        Scene layout.
    seed : int or numpy seed
        Seed of ``numpy.random.default_rng``; the same seed and size give
        the same scene.

    Returns
    -------
    Scene
        ``clean`` (float32 H x W x 3), ``distance`` (float32 H x W, meters,
        inf on water) and ``water`` (bool H x W).

    Raises
    ------
    ValueError
        Size below 8 or not an integer, unknown kind.
    """
    for name, v in (("height", height), ("width", width)):
        if isinstance(v, (bool, np.bool_)) or not isinstance(v, (int, np.integer)):
            raise ValueError(f"{name} must be an integer, got {v!r}")
        if v < 8:
            raise ValueError(f"{name} must be at least 8 pixels, got {v}")
    if kind not in _SCENE_KINDS:
        raise ValueError(f"unknown scene kind {kind!r}; expected one of {_SCENE_KINDS}")
    h, w = int(height), int(width)
    rng = np.random.default_rng(seed)
    if kind == "open_water":
        clean, dist, water = _scene_open_water(rng, h, w)
    else:
        clean, dist, water = _scene_looking_down(rng, h, w)

    lo, hi = 0.02, 0.95
    valid = ~water
    _gray_world(clean, valid, lo, hi)
    # Water pixels: a neutral gray (never visible through t = 0).
    gray = float(clean[valid].mean()) if valid.any() else 0.5
    clean[water] = np.float32(gray)
    np.clip(clean, lo, hi, out=clean)
    return Scene(
        clean=np.ascontiguousarray(clean, dtype=np.float32),
        distance=np.ascontiguousarray(dist, dtype=np.float32),
        water=water,
    )


def demo_input(
    height: int = 480,
    width: int = 640,
    water_type: Any = "III",
    seed: Any = 7,
    noise: float = 0.003,
) -> tuple[np.ndarray, dict]:
    """A rendered open-water scene and its ground truth.

    The scene is ``scene(height, width, kind="open_water", seed=seed)``,
    rendered with :func:`render` (METHOD §0) with the default veiling
    light of the water type, ``beta_b = 0.2`` and Gaussian noise of std
    ``noise`` (seeded with ``seed``).

    Parameters
    ----------
    height, width : int
        Image size.
    water_type : str or tuple, default "III"
        A name of :data:`JERLOV`, ``(name, beta_BR, beta_BG)`` or
        ``(beta_BR, beta_BG)``.
    seed : int, default 7
        Seed of the scene and of the noise.
    noise : float, default 0.003
        Noise standard deviation.

    Returns
    -------
    image : ndarray, float32, H x W x 3
        Linear observed image in [0, 1].
    truth : dict
        ``water_type`` (name or None), ``beta_BR``, ``beta_BG``,
        ``veiling_light`` (tuple of 3 float), ``distance`` (H x W, inf on
        water), ``water`` (bool H x W), ``clean`` (H x W x 3), ``beta_b``.
    """
    name, br, bg = _resolve_water_type(water_type)
    beta_b = 0.2
    a = default_veiling_light((br, bg))
    sc = scene(height, width, kind="open_water", seed=seed)
    image = render(
        sc.clean, sc.distance, (br, bg), veiling_light=a, beta_b=beta_b, noise=noise, seed=seed
    )
    truth = {
        "water_type": name,
        "beta_BR": br,
        "beta_BG": bg,
        "veiling_light": a,
        "distance": sc.distance,
        "water": sc.water,
        "clean": sc.clean,
        "beta_b": beta_b,
    }
    return image, truth
