"""``--altitude`` over seabeds that are not flat: ray-cast renders with known range.

    python3 benches/altitude.py [--split tune|held] [--size 256] [--json OUT.json]
    python3 benches/altitude.py --sweep [--json OUT.json]
    python3 benches/altitude.py --write DIR          # a few renders as PNGs, to look at

``--altitude`` (METHOD §13.7) turns a downward camera's altitude over a FLAT
seabed, its lens and its pitch and roll into a range per pixel
(``uwhl_rs.floor_distance``). This bench measures what the flat model costs
when the seabed slopes or has relief.

**Renders.** A pinhole camera with the ray model of METHOD §13.7 (flat port,
horizontal fov 50, 70 or 90 degrees in air) at altitude h above the seabed
point straight below it (what an altimeter measures), pitched and rolled,
over

- ``level``: the plane h below the camera;
- ``tilted``: a plane through that point sloping 5, 10 or 20 degrees
  downhill towards a seeded azimuth (the user does not know it);
- ``bumpy``: a smooth random heightfield through that point (Gaussian-filtered
  white noise, filter width ``BUMP_SCALE``, relief 0.1, 0.3 or 0.6 m rms,
  seeded), the altitude at least 3 rms + 0.5 m so that the camera does not
  sit inside a boulder.

The true range along each ray is where the ray meets the true surface: in
closed form for the planes, by marching (steps of ``MARCH_STEP`` between the
depths the field can reach) and bisection for the heightfield (``march``;
tests/python/test_altitude.py checks it against the closed form on a tilted
plane). A ray that meets nothing within ``Z_MAX`` sees open water. The
seabed's texture is a natural photograph (``truth.content``) laid on the
surface's horizontal coordinates (forward = the photo's top, 3 m across,
mirrored beyond), sampled with a mip pyramid at each pixel's footprint so
that far pixels average their texels as a lens would, not alias them. The
radiance is then seen through the water exactly as in benches/truth.py
(``truth.through_water``: METHOD §0, the ten types with ``truth.BETA_B``,
gray-mean or own colour statistics, white or tinted light, exposure, the two
noise levels).

Views: ``down`` (pitch and roll within 5 degrees of nadir) and ``oblique``
(an ROV pitched forward 30-60 degrees, roll within 8): straight down the
ranges of a photo span a ratio of 1.1-1.4, under the 2.5 the fit needs
(METHOD §13.1); obliquely many spans exceed it.

**Rows** per render: ``input``, ``gray_world``, ``stretch`` (baselines);
``default`` (no distance); ``flat`` (``restore(distance=floor_distance(...))``
from the true altitude, pose and lens: what ``--altitude`` gives); ``true``
(the true range map, open water unknown); ``floor_truth`` (true t, A and
light). Scores: ``uwhl_rs.truth.score`` (median angle to the true radiance,
raw and after the best global gains); facts: whether the map was used or why
it was rejected, the fitted beta's largest relative channel error, the map's
5th-95th percentile span, and the flat map's own error against the true
range (median |z_flat / z_true - 1| over pixels both know).

**--sweep**: the camera 2 m over a level floor, 70 degree lens behind a flat
port, pitched 15-60 degrees (spans 1.23-3.66), chelsea (tune) and astronaut
(held) reported apart, all ten types in the four conditions: at which span
the fitted attenuation becomes trustworthy (METHOD §13.1's limit of 2.5).
With a core built with that limit every fit under it is refused (used
0/40); to see what the fit does below it, build the core with
``MIN_DEPTH_RATIO`` lowered (src/method/distance.rs; METHOD §13.1 used 1.0)
and run the sweep on that build: the bench prints the limit the build
applied, and above the limit the two builds give the same rows.

Times on a loaded 2-core machine, one thread: tune 5 min (432 renders),
held 3 min (288), the sweep 4-5 min (960 at 240 x 320).

Deterministic (seeded); run with ``RAYON_NUM_THREADS=1`` beside other work.
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import os
import re
import sys
import time
from dataclasses import dataclass

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

import truth as T  # noqa: E402  (benches/truth.py)

import uwhl_rs  # noqa: E402
from uwhl_rs import evaluate as ev  # noqa: E402
from uwhl_rs import synth  # noqa: E402

#: Refractive index of sea water behind a flat port (METHOD §13.7).
N_WATER = 1.333
#: A ray that meets no seabed nearer than this sees open water (m).
Z_MAX = 40.0
#: Marching step along a ray over the heightfield (m); then bisection.
MARCH_STEP = 0.02
#: Width (sigma) of the Gaussian filter that smooths the heightfield's white noise (m):
#: rms slopes about 7, 20 and 35 degrees at 0.1, 0.3 and 0.6 m rms relief.
BUMP_SCALE = 0.6
#: Grid of the heightfield: spacing (m) and half-width (m), centred below the camera.
GRID_STEP, GRID_HALF = 0.05, Z_MAX
#: The texture photo spans this many metres along its longer side.
TEX_METRES = 3.0
#: Mip levels of the texture (the photo is cropped to a multiple of 2**MIP_LEVELS).
MIP_LEVELS = 6
FOVS = (50.0, 70.0, 90.0)
KINDS = {"level": (0.0,), "tilted": (5.0, 10.0, 20.0), "bumpy": (0.1, 0.3, 0.6)}
VIEWS = {"down": ((-5.0, 5.0), 5.0), "oblique": ((30.0, 60.0), 8.0)}  # pitch range, |roll| bound
ALTITUDE = (1.5, 4.0)
#: Renders per floor kind, view, condition and content (the slope or relief cycles).
PER = 6
SWEEP_PITCHES = (15.0, 20.0, 25.0, 30.0, 35.0, 40.0, 45.0, 50.0, 52.5, 55.0, 57.5, 60.0)
SWEEP_CONTENT = {"tune": "chelsea", "held": "astronaut"}


# -- geometry -----------------------------------------------------------------------------------------------------


def camera_rays(h: int, w: int, fov: float, pitch: float = 0.0, roll: float = 0.0, port: str = "flat") -> np.ndarray:
    """Unit ray directions in water, world frame (X forward, Y starboard, Z down), H x W x 3 (METHOD §13.7)."""
    f = (w / 2) / math.tan(math.radians(fov) / 2)
    v, u = np.mgrid[0:h, 0:w].astype(np.float64)
    d = np.stack([u + 0.5 - w / 2, v + 0.5 - h / 2, np.full((h, w), f)], axis=-1)
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    if port == "flat":  # Snell's law at a window perpendicular to the axis
        dx, dy = d[..., 0] / N_WATER, d[..., 1] / N_WATER
        d = np.stack([dx, dy, np.sqrt(1 - dx * dx - dy * dy)], axis=-1)
    body = np.stack([-d[..., 1], d[..., 0], d[..., 2]], axis=-1)  # photo top forward, right to starboard
    p, r = math.radians(pitch), math.radians(roll)
    rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
    ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    return body @ (ry @ rx).T


@dataclass
class Plane:
    """A seabed plane ``altitude`` below the camera at the point straight below it, sloping
    ``slope`` degrees downhill towards ``azimuth`` degrees (0 = forward, 90 = starboard)."""

    altitude: float
    slope: float = 0.0
    azimuth: float = 0.0

    def _grad(self) -> tuple[float, float]:
        g = math.tan(math.radians(self.slope))
        a = math.radians(self.azimuth)
        return g * math.cos(a), g * math.sin(a)

    def depth(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        gx, gy = self._grad()
        return self.altitude + gx * x + gy * y

    def bounds(self) -> None:
        return None  # unbounded: intersected in closed form

    def intersect(self, w: np.ndarray) -> np.ndarray:
        """Range along each ray to the plane: t w_Z = h + g . (t w_X, t w_Y); NaN when it never meets it."""
        gx, gy = self._grad()
        den = w[..., 2] - gx * w[..., 0] - gy * w[..., 1]
        with np.errstate(divide="ignore", invalid="ignore"):
            t = self.altitude / den
        return np.where((den > 0) & (t <= Z_MAX), t, np.nan)


class Heightfield:
    """A seabed at depth ``altitude + b(X, Y)`` below the camera, b bilinear on a grid with b(0, 0) = 0."""

    def __init__(self, altitude: float, b: np.ndarray, step: float, half: float):
        self.altitude, self.b, self.step, self.half = altitude, b, step, half
        self.lo, self.hi = float(b.min()), float(b.max())

    def depth(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        n = self.b.shape[0]
        gx = np.clip((x + self.half) / self.step, 0, n - 1.000001)
        gy = np.clip((y + self.half) / self.step, 0, n - 1.000001)
        i, j = gx.astype(np.int64), gy.astype(np.int64)
        fx, fy = gx - i, gy - j
        b = self.b
        top = b[i, j] * (1 - fy) + b[i, j + 1] * fy
        bot = b[i + 1, j] * (1 - fy) + b[i + 1, j + 1] * fy
        return self.altitude + top * (1 - fx) + bot * fx

    def intersect(self, w: np.ndarray) -> np.ndarray:
        # a hit lies where the ray's depth is within the field's range of depths
        wz = w[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            t_lo = np.where(wz > 0, np.maximum(self.altitude + self.lo - 1e-6, 0) / wz, np.inf)
            t_hi = np.where(wz > 0, (self.altitude + self.hi) / wz, np.inf)
        return march(self.depth, w, t_lo, np.minimum(t_hi, Z_MAX))


def march(depth, w: np.ndarray, t_lo, t_hi, step: float = MARCH_STEP, iters: int = 40) -> np.ndarray:
    """The first range t in [t_lo, t_hi] where the ray t w reaches the surface Z = depth(X, Y) from
    above: steps of ``step`` from t_lo (which must be above the surface), then bisection of the
    first step that crosses it. NaN where the ray does not meet it in the interval. A feature of
    the surface thinner than ``step`` along the ray can be missed."""
    shape = w.shape[:-1]
    wf = w.reshape(-1, 3)
    lo = np.broadcast_to(np.asarray(t_lo, dtype=np.float64), shape).reshape(-1).copy()
    hi = np.broadcast_to(np.asarray(t_hi, dtype=np.float64), shape).reshape(-1).copy()
    out = np.full(wf.shape[0], np.nan)

    def f(t, idx):
        d = wf[idx]
        return t * d[:, 2] - depth(t * d[:, 0], t * d[:, 1])

    idx = np.flatnonzero(np.isfinite(lo) & (lo <= hi))
    prev = lo[idx]
    below = f(prev, idx) >= 0  # already under the surface at t_lo: the caller's bound was wrong
    out[idx[below]] = prev[below]
    idx, prev = idx[~below], prev[~below]
    while idx.size:
        t = np.minimum(prev + step, hi[idx])
        hit = f(t, idx) >= 0
        if hit.any():
            a, b, hid = prev[hit], t[hit], idx[hit]
            for _ in range(iters):
                m = 0.5 * (a + b)
                under = f(m, hid) >= 0
                b = np.where(under, m, b)
                a = np.where(under, a, m)
            out[hid] = b
        done = hit | (t >= hi[idx])
        idx, prev = idx[~done], t[~done]
    return out.reshape(shape)


@functools.lru_cache(maxsize=4)
def bump_field(seed: int, rms: float) -> np.ndarray:
    """A smooth random relief on the grid, ``rms`` m, 0 at the grid's centre (below the camera)."""
    from scipy.ndimage import gaussian_filter

    n = int(round(2 * GRID_HALF / GRID_STEP)) + 1
    noise = np.random.default_rng(seed).standard_normal((n, n))
    b = gaussian_filter(noise, BUMP_SCALE / GRID_STEP, mode="wrap")
    b *= rms / b.std()
    return b - b[n // 2, n // 2]


def surface(kind: str, param: float, altitude: float, rng: np.random.Generator):
    if kind == "level":
        return Plane(altitude)
    if kind == "tilted":
        return Plane(altitude, param, float(rng.uniform(0, 360)))
    if kind == "bumpy":
        return Heightfield(altitude, bump_field(int(rng.integers(1 << 30)), param), GRID_STEP, GRID_HALF)
    raise ValueError(kind)


# -- texture ------------------------------------------------------------------------------------------------------


@functools.lru_cache(maxsize=8)
def pyramid(cname: str) -> tuple[np.ndarray, ...]:
    """The photo (linear) cropped to a multiple of 2**MIP_LEVELS, and its 2x2 box-mean levels."""
    rho, _ = T.content(cname, 512)
    k = 1 << MIP_LEVELS
    h, w = (rho.shape[0] // k) * k, (rho.shape[1] // k) * k
    y0, x0 = (rho.shape[0] - h) // 2, (rho.shape[1] - w) // 2
    levels = [rho[y0:y0 + h, x0:x0 + w].astype(np.float64)]
    for _ in range(MIP_LEVELS):
        a = levels[-1]
        levels.append(0.25 * (a[0::2, 0::2] + a[1::2, 0::2] + a[0::2, 1::2] + a[1::2, 1::2]))
    return tuple(levels)


def _mirror(i: np.ndarray, n: int) -> np.ndarray:
    i = np.mod(i, 2 * n)
    return np.where(i >= n, 2 * n - 1 - i, i)


def _bilinear(img: np.ndarray, r: np.ndarray, c: np.ndarray) -> np.ndarray:
    """Sample ``img`` at continuous texel coordinates (texel j covers [j, j+1)), mirrored beyond its edges."""
    h, w = img.shape[:2]
    r, c = r - 0.5, c - 0.5
    r0, c0 = np.floor(r), np.floor(c)
    fr, fc = (r - r0)[..., None], (c - c0)[..., None]
    r0, c0 = r0.astype(np.int64), c0.astype(np.int64)
    ra, rb, ca, cb = _mirror(r0, h), _mirror(r0 + 1, h), _mirror(c0, w), _mirror(c0 + 1, w)
    return ((img[ra, ca] * (1 - fc) + img[ra, cb] * fc) * (1 - fr)
            + (img[rb, ca] * (1 - fc) + img[rb, cb] * fc) * fr)


def texture(cname: str, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """The photo laid on the seabed's horizontal coordinates (X forward = the photo's top, Y starboard
    = its right, its centre below the camera), averaged over each pixel's footprint (trilinear mip)."""
    levels = pyramid(cname)
    h0, w0 = levels[0].shape[:2]
    s = TEX_METRES / max(h0, w0)
    rows, cols = h0 / 2 - x / s, w0 / 2 + y / s
    # footprint of a pixel on the seabed, in texels: the longer of its steps to the next row and column
    ok = np.isfinite(rows)
    rr, cc = np.where(ok, rows, 0.0), np.where(ok, cols, 0.0)
    steps = []
    for ax in (0, 1):
        dr, dc = np.gradient(rr, axis=ax), np.gradient(cc, axis=ax)
        steps.append(np.hypot(dr, dc))
    foot = np.maximum(*steps)
    lev = np.clip(np.log2(np.maximum(foot, 1.0)), 0, MIP_LEVELS)
    out = np.zeros(rows.shape + (3,))
    lo = np.floor(lev).astype(int)
    frac = (lev - lo)[..., None]
    for k in range(MIP_LEVELS + 1):
        for kk, wgt in ((lo == k, 1 - frac), (np.minimum(lo + 1, MIP_LEVELS) == k, frac)):
            m = kk & ok
            if m.any():
                sc = 1 << k
                out[m] += wgt[m] * _bilinear(levels[k], rows[m] / sc, cols[m] / sc)
    return out


# -- renders ------------------------------------------------------------------------------------------------------


@dataclass
class Shot:
    """One ray-cast render, its pose and the two range maps."""

    r: T.Render  # image, truth, distance (inf = open water), t, a, light
    kind: str
    param: float  # slope (deg) or relief (m rms); 0 for level
    view: str
    altitude: float
    fov: float
    pitch: float
    roll: float
    flat: np.ndarray  # floor_distance from the true altitude and pose (NaN = none)


def shoot(cname: str, kind: str, param: float, view: str, altitude: float, fov: float, pitch: float, roll: float,
          wtype: str, stats: str, light: str, noise: float, size: tuple[int, int], rng: np.random.Generator,
          seed: int) -> Shot:
    """Cast the rays of a camera over a seabed, texture the hits and render them through water."""
    h, w = size
    wv = camera_rays(h, w, fov, pitch, roll)
    surf = surface(kind, param, altitude, rng)
    z = surf.intersect(wv)
    hit = np.isfinite(z)
    x, y = np.where(hit, z * wv[..., 0], np.nan), np.where(hit, z * wv[..., 1], np.nan)
    rho = np.where(hit[..., None], texture(cname, x, y), 0.0)
    zz = np.where(hit, z, np.inf)
    name = f"{cname}_{kind}{param:g}_{view}_p{pitch:.0f}_{stats}_{light}_{wtype}"
    r = T.through_water(name, cname, f"{kind}{param:g}", rho, zz, wtype, stats, light, noise, seed)
    flat = uwhl_rs.floor_distance((h, w), altitude, fov, pitch=pitch, roll=roll, port="flat")
    return Shot(r, kind, param, view, altitude, fov, pitch, roll, flat)


def shots(split: str, size: tuple[int, int]):
    """Every render of the main run: each floor kind x view x condition x content, PER of each (module docstring)."""
    names = T.SPLITS[split]
    for ki, (kind, params) in enumerate(KINDS.items()):
        for vi, (view, ((p0, p1), rmax)) in enumerate(VIEWS.items()):
            k = 0
            for ci, (stats, light) in enumerate(T.CONDITIONS):
                for ni, cname in enumerate(names):
                    for i in range(PER):
                        rng = np.random.default_rng([ki, vi, ci, ni, i])
                        param = params[i % len(params)]
                        lo = max(ALTITUDE[0], 3 * param + 0.5) if kind == "bumpy" else ALTITUDE[0]
                        alt = float(rng.uniform(lo, ALTITUDE[1]))
                        pitch, roll = float(rng.uniform(p0, p1)), float(rng.uniform(-rmax, rmax))
                        wtype = T.TYPES[(k * 3 + ki + vi) % len(T.TYPES)]
                        fov = FOVS[(i + ci + ni) % len(FOVS)]
                        noise = T.NOISE[(i + ni + ci) % 2]
                        k += 1
                        yield shoot(cname, kind, param, view, alt, fov, pitch, roll, wtype, stats, light, noise,
                                    size, rng, seed=10_000 * ki + 1000 * vi + 100 * ci + 10 * ni + i)


# -- scoring ------------------------------------------------------------------------------------------------------


def true_beta(wtype: str) -> np.ndarray:
    br, bg = synth.JERLOV[wtype]
    bb = T.BETA_B[wtype]
    return np.array([bb / br, bb / bg, bb])


def span(z: np.ndarray) -> float:
    """The 95th over the 5th percentile of the known ranges (METHOD §13.1, nearest rank as the core)."""
    q = np.sort(z[np.isfinite(z) & (z > 0)])
    if q.size == 0:
        return float("nan")
    pick = lambda a: q[int(round((q.size - 1) * a))]  # noqa: E731
    return float(pick(0.95) / pick(0.05))


def why(rejected: str | None) -> str | None:
    if rejected is None:
        return None
    if "too narrow" in rejected:
        return "span"
    if "suspect" in rejected or "residual" in rejected or "optical depth" in rejected:
        return "suspect"
    return "other"


def with_distance(r: T.Render, z: np.ndarray) -> tuple[np.ndarray, dict]:
    res = uwhl_rs.restore(r.image, distance=z.astype(np.float32))
    d = res.distance
    f = {"used": bool(d["used"]), "why": why(d["rejected"]), "span": span(z), "rejected": d["rejected"]}
    if d["used"] and res.water is not None:
        beta = np.array(res.water["beta"])
        f["beta_err"] = float(np.max(np.abs(beta / true_beta(r.water_type) - 1)))
        f["beta_b_ratio"] = float(beta[2] / true_beta(r.water_type)[2])
    return res.image, f


def score_shot(s: Shot, gains: bool = True, rows=None) -> list[dict]:
    r = s.r
    outs, facts = {}, {}
    base = T.baseline_rows(r)
    want = (lambda k: rows is None or k in rows)
    for k in ("input", "gray_world", "stretch"):
        if want(k):
            outs[k] = base[k]
    if want("default"):
        outs["default"] = uwhl_rs.restore(r.image).image
    z_true = np.where(np.isfinite(r.distance), r.distance, np.nan)
    both = np.isfinite(z_true) & np.isfinite(s.flat)
    flat_err = float(np.median(np.abs(s.flat[both] / z_true[both] - 1))) if both.any() else float("nan")
    if want("flat"):
        outs["flat"], facts["flat"] = with_distance(r, s.flat)
        facts["flat"]["flat_err"] = flat_err
    if want("true"):
        outs["true"], facts["true"] = with_distance(r, z_true)
    if want("floor_truth"):
        outs["floor_truth"] = base["floor_truth"]
    out = []
    for name, img in outs.items():
        sc = uwhl_rs.truth.score(img, r.truth, r.objects, gains=gains)
        row = {"scene": r.name, "content": r.content, "condition": f"{r.stats}/{r.light}", "type_true": r.water_type,
               "kind": s.kind, "param": s.param, "view": s.view, "altitude": s.altitude, "fov": s.fov,
               "pitch": s.pitch, "roll": s.roll, "water_share": float((~r.objects).mean()), "flat_err": flat_err,
               "row": name, **sc}
        row.update({k: v for k, v in facts.get(name, {}).items() if k != "flat_err"})
        out.append(row)
    return out


# -- tables -------------------------------------------------------------------------------------------------------

ROW_NAMES = {"input": "input", "gray_world": "gray world", "stretch": "contrast stretch",
             "default": "default, no distance", "flat": "**flat model** (--altitude)", "true": "true range map",
             "floor_truth": "floor (true t, A, light)"}


def _cell(sel: list[dict]) -> str:
    if not sel:
        return "-"
    med = np.median([x["median"] for x in sel])
    if "gain_median" in sel[0]:
        return f"{med:.1f} ({np.median([x['gain_median'] for x in sel]):.1f})"
    return f"{med:.1f}"


def _facts(sel: list[dict]) -> str:
    """used / n (rejected for the span, as suspect), beta within 10% / n, median beta error of the used fits."""
    if not sel:
        return "-"
    used = [x for x in sel if x.get("used")]
    good = sum(x.get("beta_err", 9) <= 0.1 for x in used)
    errs = [x["beta_err"] for x in used if "beta_err" in x]
    e = f", {100 * np.median(errs):.0f}%" if errs else ""
    nspan = sum(x.get("why") == "span" for x in sel)
    nsus = sum(x.get("why") == "suspect" for x in sel)
    return f"{len(used)}/{len(sel)} ({nspan} span, {nsus} suspect), {good} ±10%{e}"


def _harm(sel: list[dict], base: dict) -> str:
    """Over the renders whose map was used: median angle with it / without (default), and how many
    came out more than 2 degrees worse than without."""
    used = [x for x in sel if x.get("used")]
    if not used:
        return "-"
    w = np.median([x["median"] for x in used])
    d = np.median([base[x["scene"]]["median"] for x in used])
    worse = sum(x["median"] > base[x["scene"]]["median"] + 2 for x in used)
    return f"{w:.1f} / {d:.1f}, {worse} worse"


def column_table(rows: list[dict], cols: list[tuple[str, object]], corner: str) -> str:
    """Rows x columns, each column the renders a predicate keeps, pooled over conditions and contents."""
    sel = lambda n, keep: [x for x in rows if x["row"] == n and keep(x)]  # noqa: E731
    lines = [f"| {corner} | " + " | ".join(h for h, _ in cols) + " |", "|---|" + "---|" * len(cols)]
    names = [n for n in ROW_NAMES if any(x["row"] == n for x in rows)]
    for n in names:
        lines.append(f"| {ROW_NAMES[n]} | " + " | ".join(_cell(sel(n, k)) for _, k in cols) + " |")
    base = {x["scene"]: x for x in rows if x["row"] == "default"}
    for n in ("flat", "true"):
        if n in names:
            lines.append(f"| {n} map: used (rejected: span, suspect), beta ±10%, median err | "
                         + " | ".join(_facts(sel(n, k)) for _, k in cols) + " |")
            lines.append(f"| {n} map used: angle with / without, > 2° worse | "
                         + " | ".join(_harm(sel(n, k), base) for _, k in cols) + " |")
    if "flat" in names:
        cells = []
        for _, k in cols:
            s = sel("flat", k)
            cells.append(f"{100 * np.nanmedian([x['flat_err'] for x in s]):.1f}%" if s else "-")
        lines.append("| flat map's error, median \\|z_flat/z_true - 1\\| | " + " | ".join(cells) + " |")
        cells = []
        for _, k in cols:
            s = sel("true", k) or sel("flat", k)
            sp = [x["span"] for x in s]
            cells.append(f"{np.nanmedian(sp):.2f}, {sum(v >= 2.5 for v in sp)}/{len(sp)} ≥2.5" if sp else "-")
        lines.append("| true span (median), spans ≥ 2.5 | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def variant_table(rows: list[dict], view: str) -> str:
    """Rows x floor variants (level, each slope, each relief) for one view."""
    cols = []
    for k, ps in KINDS.items():
        for p in ps:
            head = "level" if k == "level" else (f"tilted {p:g}°" if k == "tilted" else f"bumpy {p:g} m")
            cols.append((head, lambda x, k=k, p=p: x["view"] == view and x["kind"] == k and x["param"] == p))
    return column_table(rows, cols, view)


def kind_table(rows: list[dict]) -> str:
    """Rows x (view, floor kind), slopes and reliefs pooled: the summary."""
    cols = [(f"{v}, {k}", lambda x, v=v, k=k: x["view"] == v and x["kind"] == k) for v in VIEWS for k in KINDS]
    return column_table(rows, cols, "view, floor")


def condition_table(rows: list[dict], kind: str, view: str) -> str:
    """Rows x the four conditions for one floor kind and view (slopes or reliefs pooled)."""
    conds = [f"{a}/{b}" for a, b in T.CONDITIONS]
    sel = [x for x in rows if x["kind"] == kind and x["view"] == view]
    n = len([x for x in sel if x["row"] == "input"]) // len(conds)
    lines = [f"| {kind}, {view} ({n} per condition) | " + " | ".join(conds) + " |", "|---|" + "---|" * len(conds)]
    for n in ROW_NAMES:
        if not any(x["row"] == n for x in sel):
            continue
        cells = [_cell([x for x in sel if x["row"] == n and x["condition"] == c]) for c in conds]
        lines.append(f"| {ROW_NAMES[n]} | " + " | ".join(cells) + " |")
    base = {x["scene"]: x for x in sel if x["row"] == "default"}
    for n in ("flat", "true"):
        cells = [_facts([x for x in sel if x["row"] == n and x["condition"] == c]) for c in conds]
        lines.append(f"| {n}: used (rejected: span, suspect), beta ±10%, median err | " + " | ".join(cells) + " |")
        cells = [_harm([x for x in sel if x["row"] == n and x["condition"] == c], base) for c in conds]
        lines.append(f"| {n} used: angle with / without, > 2° worse | " + " | ".join(cells) + " |")
    return "\n".join(lines)


# -- the sweep ----------------------------------------------------------------------------------------------------


def sweep(size: tuple[int, int], verbose: bool = True) -> list[dict]:
    """A camera 2 m over a level floor, 70 degree lens, pitched SWEEP_PITCHES; every type and condition."""
    rows = []
    for split, cname in SWEEP_CONTENT.items():
        for pitch in SWEEP_PITCHES:
            t0 = time.time()
            for ci, (stats, light) in enumerate(T.CONDITIONS):
                for ti, wtype in enumerate(T.TYPES):
                    rng = np.random.default_rng([7, ci, ti])
                    s = shoot(cname, "level", 0.0, "oblique", 2.0, 70.0, pitch, 0.0, wtype, stats, light,
                              T.NOISE[(ti + ci) % 2], size, rng, seed=100 * ci + ti)
                    for row in score_shot(s, gains=False, rows={"input", "gray_world", "default", "true"}):
                        rows.append({**row, "split": split})
            if verbose:
                print(f"sweep {cname} pitch {pitch:g}: {time.time() - t0:.1f}s", file=sys.stderr)
    return rows


def sweep_table(rows: list[dict], split: str) -> str:
    """Per pitch: the span, how many fits the core used, how good their attenuation was, and the
    colours with the distance against without it (over every render, and over the used ones)."""
    lines = ["| pitch | span | used | beta ±10% | median beta err (used) | beta_B fitted/true (used) "
             "| with distance | default | gray world | used: with / default | used and > 2° worse |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for pitch in SWEEP_PITCHES:
        sel = [x for x in rows if x["split"] == split and x["pitch"] == pitch]
        if not sel:
            continue
        d = {x["scene"]: x for x in sel if x["row"] == "true"}
        base = {x["scene"]: x for x in sel if x["row"] == "default"}
        gw = [x["median"] for x in sel if x["row"] == "gray_world"]
        used = [x for x in d.values() if x["used"]]
        good = sum(x["beta_err"] <= 0.1 for x in used)
        ratios = [x["beta_b_ratio"] for x in used]
        rr = f"{min(ratios):.2f}-{max(ratios):.2f}" if ratios else "-"
        err = f"{100 * np.median([x['beta_err'] for x in used]):.0f}%" if used else "-"
        pair = (f"{np.median([x['median'] for x in used]):.1f} / "
                f"{np.median([base[x['scene']]['median'] for x in used]):.1f}") if used else "-"
        worse = sum(x["median"] > base[x["scene"]]["median"] + 2 for x in used)
        sp = np.median([x["span"] for x in d.values()])
        lines.append(f"| {pitch:g}° | {sp:.2f} | {len(used)}/{len(d)} | {good}/{len(d)} | {err} | {rr} "
                     f"| {np.median([x['median'] for x in d.values()]):.1f} "
                     f"| {np.median([x['median'] for x in base.values()]):.1f} | {np.median(gw):.1f} "
                     f"| {pair} | {worse}/{len(used)} |")
    return "\n".join(lines)


def limit(rows: list[dict]) -> str:
    """The span limit recorded with a run's rows (each row carries it), or this build's."""
    if not rows or "span_limit" not in rows[0]:
        lim = build_limit()
        for x in rows:
            x["span_limit"] = lim
    return rows[0]["span_limit"] if rows else build_limit()


def build_limit() -> str:
    """The span limit the core on the path applies, read from its refusal of a map spanning 1.01."""
    img = np.random.default_rng(0).uniform(0.1, 0.6, (64, 64, 3)).astype(np.float32)
    z = np.linspace(2.0, 2.02, 64 * 64, dtype=np.float32).reshape(64, 64)
    res = uwhl_rs.restore(img, distance=z)
    m = re.search(r"at least a ratio of ([0-9.]+)", res.distance["rejected"] or "")
    return m.group(1) if m else "below 1.01 (no span refusal)"


# -- pictures -----------------------------------------------------------------------------------------------------


def write_pngs(folder: str, size: tuple[int, int]) -> None:
    """A few renders as sRGB PNGs: the photo seen through water, its true radiance, the true range,
    the flat model's range and their ratio (gray = equal), to check the geometry by eye."""
    from PIL import Image

    os.makedirs(folder, exist_ok=True)
    cases = [("level", 0.0, 0.0), ("level", 0.0, 50.0), ("tilted", 20.0, 0.0), ("tilted", 20.0, 50.0),
             ("bumpy", 0.3, 0.0), ("bumpy", 0.6, 45.0)]
    for i, (kind, param, pitch) in enumerate(cases):
        rng = np.random.default_rng([99, i])
        alt = 2.5 if kind != "bumpy" else 3.0
        s = shoot("chelsea", kind, param, "x", alt, 70.0, pitch, 0.0, "3C", "own", "white", 0.003, size, rng, seed=i)
        z = np.where(np.isfinite(s.r.distance), s.r.distance, np.nan)
        zmax = np.nanpercentile(np.concatenate([z[np.isfinite(z)], s.flat[np.isfinite(s.flat)]]), 99)

        def gray(a, lo, hi):
            v = np.clip((a - lo) / (hi - lo), 0, 1)
            return np.where(np.isfinite(a), (v * 255).round(), 0).astype(np.uint8)

        tiles = [uwhl_rs.to_srgb(s.r.image), uwhl_rs.to_srgb(np.clip(s.r.truth, 0, 1))]
        tiles = [(np.clip(t, 0, 1) * 255).round().astype(np.uint8) for t in tiles]
        for a in (gray(z, 0, zmax), gray(s.flat, 0, zmax), gray(s.flat / z, 0.5, 1.5)):
            tiles.append(np.repeat(a[..., None], 3, axis=2))
        Image.fromarray(np.concatenate(tiles, axis=1)).save(os.path.join(folder, f"{i}_{kind}{param:g}_p{pitch:g}.png"))
        print(f"{folder}/{i}_{kind}{param:g}_p{pitch:g}.png: true span {span(z):.2f}, flat span {span(s.flat):.2f}, "
              f"open water {100 * np.isnan(z).mean():.0f}%")


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--split", default="tune", choices=["tune", "held"])
    p.add_argument("--size", default="192x256", help="HxW of the renders (default 192x256)")
    p.add_argument("--sweep", action="store_true", help="the pitch sweep over a level floor (module docstring)")
    p.add_argument("--write", default=None, metavar="DIR", help="write a few renders as PNGs and stop")
    p.add_argument("--json", default=None, help="write every per-render row to this file")
    p.add_argument("--tables", default=None, metavar="JSON", help="print the tables of a run's --json and stop")
    a = p.parse_args(argv)
    size = tuple(int(v) for v in a.size.split("x"))
    if a.write:
        write_pngs(a.write, size)
        return 0
    t0 = time.time()
    old = None
    if a.tables:
        with open(a.tables) as f:
            old = json.load(f)
        a.sweep = any("split" in x for x in old)
    if a.sweep and a.size == "192x256":
        size = (240, 320)
    rows = old
    if rows is None:
        rows = sweep(size) if a.sweep else []
        if not a.sweep:
            for s in shots(a.split, size):
                t1 = time.time()
                rows.extend(score_shot(s))
                print(f"{s.r.name}: {time.time() - t1:.1f}s", file=sys.stderr)
        lim = limit(rows)
        print(f"{time.time() - t0:.0f} s", file=sys.stderr)
        if a.json:  # saved before the tables: a closed pipe does not lose the run
            with open(a.json, "w") as f:
                json.dump(rows, f, indent=1)
    lim = limit(rows)
    if a.sweep:
        print(f"sweep: 2 m over a level floor, 70° lens, flat port, {size[0]}x{size[1]}; span limit of the build: "
              f"{lim}; 40 renders per pitch (10 types x 4 conditions); angles raw, median over renders")
        for split, cname in SWEEP_CONTENT.items():
            print(f"\n{cname} ({split})\n")
            print(sweep_table(rows, split))
        return 0
    split = next((k for k, v in T.SPLITS.items() if rows and rows[0]["content"] in v), a.split)
    print(f"split {split}, {size[0]}x{size[1]}, {len(rows) // len(ROW_NAMES)} renders, span limit of the build: "
          f"{lim}; cells: median angle (after best gains), median over renders; used/n, beta within 10%/n, "
          f"median beta error of the used")
    print("\n### by view and floor kind (slopes, reliefs and conditions pooled)\n")
    print(kind_table(rows))
    for view in VIEWS:
        print(f"\n### {view}, by floor (conditions pooled)\n")
        print(variant_table(rows, view))
    for kind in KINDS:
        for view in VIEWS:
            print(f"\n### {kind}, {view}, by condition\n")
            print(condition_table(rows, kind, view))
    return 0


if __name__ == "__main__":
    sys.exit(main())
