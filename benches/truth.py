"""Colours against ground truth: renders of natural photographs through water.

    python3 benches/truth.py [--split tune|held|all] [--size 360] [--json OUT.json] [--only default,input,...]
    python3 benches/truth.py --split held --write DIR      # the renders as files, then:
    uwhl evaluate DIR/truth.json -o OUT                      # the same scores through the command
    python3 benches/truth.py --split held --compare OUT/results.json   # how far the two agree
    python3 benches/truth.py --rows OUT.json                  # the tables again from an earlier --json

Needs scikit-image for its bundled photographs (``pip install scikit-image``;
nothing is downloaded). Each scene is a natural photograph used as the true
radiance J (sRGB decoded to linear), laid on a geometry with known distance,
and rendered through one of the ten Jerlov types with the model of METHOD §0,
in four conditions:

- scene colours: ``own`` (the photograph's own colour statistics) or ``gray``
  (each channel scaled so that the object pixels' mean is gray: the
  gray-world prior holds);
- light on the scene: ``white`` (a strobe) or ``tinted`` (daylight that has
  crossed ``LIGHT_PATH`` metres of the same water, E_c = exp(-beta_c d)).

Geometries: ``floor`` (a plane receding from 1 m at the bottom row to 20 m at
the top), ``floor_water`` (the same floor under open water in the top
quarter), ``wall`` (a plane slanting from 2 to 8 m), ``stereo`` (the
motorcycle pair's disparity turned into distance, 1.5 m at its nearest).
Blue attenuation follows the type (``BETA_B``, approximately Jerlov's Kd at
475 nm), so clear water is hazy in red and barely in blue, as in the sea.
The camera exposes each render so that its 99th percentile is 0.85; two
noise levels alternate.

Split: ``tune`` = chelsea, coffee, rocket; ``held`` = astronaut, motorcycle;
``fresh`` = blackmagic, kodak, hopper (``FRESH``: raw files of ../shared/data
and matplotlib's sample portrait, added on 2026-12-04 after every constant
was chosen).
Nothing is tuned on ``held``; report on it.

``--write DIR`` writes each render of the split as files a user's
``uwhl evaluate`` manifest would name: the observed image as a float32 TIFF
(read as linear, exactly: no sRGB curve is applied to float TIFFs), its true
radiance (``truth``, float32 TIFF), the object pixels (``truth_mask``, PNG),
the distance (``.npy``, 0 = open water), the true type, and for scenes with
open water its region (``water_mask``, PNG). ``truth.json`` lets the method
find the water itself, as the ``default`` row here does; ``truth_given.json``
gives the water region where there is one.

Scores (uwhl_rs.truth): median per-pixel angle to the truth over the object
pixels, raw and after the best global per-channel gains; type exact / within
one step; rho(z, -ln t_B). Rows: the baselines (input, gray world of the
input, contrast stretch), the default profile, the default told the true
type, the paper profile, the default told the distance (METHOD §13:
``distance`` the true map, open water unknown; ``distance_holes`` with 30%
of it lost in blocks; ``distance_noise`` with 10% log-normal noise;
``distance_other`` another scene's map, which must be rejected; with the
share of fitted beta within 10% of the truth and the share of maps used),
and three floors: ``floor_truth`` (true t, A and
light: only noise and clipping remain), ``floor_tA_gw`` (the estimated t_B
of a restoration told the true type and A, recovered with the true A and a
gray-world balance) and ``floor_affine`` (the same t_B after the best affine
map of -ln t_B onto the true optical depth, known only from the truth).
"""

from __future__ import annotations

import argparse
import functools
import json
import math
import sys
import time
from dataclasses import dataclass

import numpy as np

import uwhl_rs
from uwhl_rs import evaluate as ev
from uwhl_rs import synth, truth

TYPES = ["I", "IA", "IB", "II", "III", "1C", "3C", "5C", "7C", "9C"]
#: Blue attenuation per type, 1/m (Jerlov's Kd near 475 nm, approximate).
BETA_B = {"I": 0.02, "IA": 0.025, "IB": 0.032, "II": 0.052, "III": 0.10,
          "1C": 0.16, "3C": 0.23, "5C": 0.33, "7C": 0.47, "9C": 0.71}
LIGHT_PATH = 5.0
NOISE = (0.003, 0.015)
SPLITS = {"tune": ("chelsea", "coffee", "rocket"), "held": ("astronaut", "motorcycle"),
          "fresh": ("blackmagic", "kodak", "hopper")}
#: The ``fresh`` split's photographs, added after every constant was chosen and never tuned on:
#: two raw files of land scenes in ../shared/data (a landscape of grass, sea, cars and a cloudy
#: sky; white tower blocks under a gray sky), decoded linear by the package's raw reader and taken
#: to linear sRGB by the camera's matrix where the file has one, and matplotlib's sample portrait
#: of Grace Hopper (a red and blue flag, a dark uniform; sRGB JPEG). The shared Nikon NEF is left
#: out: it has no as-shot white balance, so LibRaw balances it to a gray mean.
FRESH = {"blackmagic": "raw/Blackmagic.dng", "kodak": "raw/RAW_KODAK_DC50.KDC"}
GEOMETRIES = ("floor", "floor_water", "wall")
CONDITIONS = [("gray", "white"), ("gray", "tinted"), ("own", "white"), ("own", "tinted")]


@dataclass
class Render:
    """One rendered scene and its truth."""

    name: str
    content: str
    geometry: str
    stats: str
    light: str
    water_type: str
    noise: float
    image: np.ndarray  # observed, linear, float32
    truth: np.ndarray  # true radiance under white light, linear
    distance: np.ndarray  # metres, inf = open water
    t: np.ndarray  # H x W x 3 true transmissions
    a: np.ndarray  # true veiling light as seen by the camera
    light_rgb: np.ndarray  # the light on the scene, as seen by the camera (exposure included)

    @property
    def objects(self) -> np.ndarray:
        return np.isfinite(self.distance)


def _srgb_to_linear(u8: np.ndarray) -> np.ndarray:
    x = u8.astype(np.float64) / 255.0
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def _resize(img: np.ndarray, side: int, nearest: bool = False) -> np.ndarray:
    from PIL import Image

    h, w = img.shape[:2]
    s = side / max(h, w)
    if s >= 1:
        return img
    size = (max(1, round(w * s)), max(1, round(h * s)))
    if nearest:
        return np.asarray(Image.fromarray(img.astype(np.float32)).resize(size, Image.NEAREST))
    return np.asarray(Image.fromarray(img).resize(size, Image.LANCZOS))


@functools.lru_cache(maxsize=8)
def content(name: str, side: int) -> tuple[np.ndarray, np.ndarray | None]:
    """A photograph as linear radiance in [0, 1], and its distance map if it has one."""
    import skimage.data as data

    if name == "motorcycle":
        left, _, disp = data.stereo_motorcycle()
        disp = np.asarray(disp, dtype=np.float64)
        bad = ~np.isfinite(disp) | (disp <= 0)
        if bad.any():
            from scipy.ndimage import distance_transform_edt

            idx = distance_transform_edt(bad, return_distances=False, return_indices=True)
            disp = disp[tuple(idx)]
        z = 1.5 * np.percentile(disp, 99) / disp
        z = np.minimum(z, 25.0)
        return _srgb_to_linear(_resize(left, side)), _resize(z, side, nearest=True).astype(np.float64)
    if name in FRESH:
        return _raw_content(FRESH[name], side), None
    if name == "hopper":
        try:
            from matplotlib import cbook
        except ImportError:
            raise SystemExit("the fresh split's portrait is matplotlib's sample data: pip install matplotlib") from None
        with cbook.get_sample_data("grace_hopper.jpg") as f:
            from PIL import Image

            return _srgb_to_linear(_resize(np.asarray(Image.open(f).convert("RGB")), side)), None
    return _srgb_to_linear(_resize(getattr(data, name)(), side)), None


def shared_data() -> str:
    """../shared/data beside the repository (UWHL_SHARED_DATA overrides)."""
    import os

    here = os.path.dirname(os.path.abspath(__file__))
    return os.environ.get("UWHL_SHARED_DATA", os.path.join(here, "..", "..", "shared", "data"))


def _raw_content(rel: str, side: int) -> np.ndarray:
    """A raw photograph as linear radiance: decoded (camera colours to linear sRGB by the file's
    matrix, as uwhl_rs.to_srgb does), shrunk by block means to ``side``,
    its 99.5th percentile scaled to 1 and clipped (the brightest specks saturate)."""
    import os

    path = os.path.join(shared_data(), rel)
    if not os.path.isfile(path):
        raise SystemExit(f"the fresh split needs {path} (../shared/data beside the repository)")
    x, meta = uwhl_rs.read_image(path)
    x = np.asarray(x, dtype=np.float64)
    if meta.camera_matrix is not None:
        x = np.clip(x @ np.asarray(meta.camera_matrix, dtype=np.float64).T, 0, None)
    f = max(1, -(-max(x.shape[:2]) // side))
    h, w = (x.shape[0] // f) * f, (x.shape[1] // f) * f
    x = x[:h, :w].reshape(h // f, f, w // f, f, 3).mean(axis=(1, 3))
    return np.clip(x / max(float(np.percentile(x, 99.5)), 1e-6), 0, 1)


def geometry(kind: str, h: int, w: int) -> np.ndarray:
    """Distance in metres per pixel for a geometry of the module docstring."""
    yy, xx = np.mgrid[0:h, 0:w].astype(np.float64)
    if kind in ("floor", "floor_water"):
        top = 0 if kind == "floor" else h // 4
        far, near = (20.0, 1.0) if kind == "floor" else (15.0, 1.0)
        f = np.clip((yy - top) / max(1, h - 1 - top), 0, 1)
        z = 1.0 / (1.0 / far + (1.0 / near - 1.0 / far) * f)
        if kind == "floor_water":
            z[yy < top] = np.inf
        return z
    if kind == "wall":
        return 2.0 + 6.0 * xx / max(1, w - 1)
    raise ValueError(kind)


def render(cname: str, wtype: str, stats: str, light: str, noise: float, geom: str, side: int, seed: int) -> Render:
    """Render one scene (METHOD §0) with its truth."""
    rho, zmap = content(cname, side)
    h, w = rho.shape[:2]
    z = zmap if zmap is not None else geometry(geom, h, w)
    name = f"{cname}_{geom}_{stats}_{light}_{wtype}_n{noise:g}"
    return through_water(name, cname, geom, rho, z, wtype, stats, light, noise, seed)


def through_water(name: str, cname: str, geom: str, rho: np.ndarray, z: np.ndarray, wtype: str, stats: str,
                  light: str, noise: float, seed: int) -> Render:
    """The radiance ``rho`` at distances ``z`` (inf = open water) seen through
    water of type ``wtype`` (METHOD §0) in one condition of the module
    docstring, exposed and with noise; benches/altitude.py renders its ray-cast
    seabeds through this too."""
    rho = rho.copy()
    obj = np.isfinite(z)
    if stats == "gray":
        means = rho[obj].mean(axis=0)
        rho = rho * (means.mean() / np.maximum(means, 1e-6))
        rho = rho / max(1.0, float(np.percentile(rho, 99.9)))
        rho = np.clip(rho, 0, 1)
    br, bg = synth.JERLOV[wtype]
    bb = BETA_B[wtype]
    beta = np.array([bb / br, bb / bg, bb])
    if light == "tinted":
        e = np.exp(-beta * LIGHT_PATH)
        e = e / e.max()
    else:
        e = np.ones(3)
    a = np.array(synth.default_veiling_light(wtype))
    with np.errstate(over="ignore"):
        t = np.exp(-beta[None, None, :] * z[:, :, None])
    clean = t * (rho * e) + (1 - t) * a
    k = 0.85 / max(float(np.percentile(clean, 99)), 1e-6)
    k = float(np.clip(k, 0.25, 8.0))
    clean *= k
    rng = np.random.default_rng(seed)
    img = np.clip(clean + rng.normal(0.0, noise, clean.shape), 0, 1).astype(np.float32)
    return Render(name, cname, geom, stats, light, wtype, noise, img, rho, z, t, a * k, e * k)


def scenes(split: str = "tune", side: int = 360, conditions=None):
    """Every render of a split: each content x ten types in each condition.

    The geometry cycles with the type (the motorcycle is always ``stereo``)
    and the noise level alternates, so each condition holds one render per
    content and type.
    """
    names = SPLITS["tune"] + SPLITS["held"] + SPLITS["fresh"] if split == "all" else SPLITS[split]
    for ci, (stats, light) in enumerate(conditions or CONDITIONS):
        for ni, cname in enumerate(names):
            for ti, wt in enumerate(TYPES):
                geom = "stereo" if cname == "motorcycle" else GEOMETRIES[(ti + ni + ci) % len(GEOMETRIES)]
                noise = NOISE[(ti + ni) % 2]
                yield render(cname, wt, stats, light, noise, geom, side, seed=1000 * ci + 100 * ni + ti)


def holes(z: np.ndarray, share: float, seed: int) -> np.ndarray:
    """``z`` with rectangles set to NaN until ``share`` of it is unknown, as
    depth maps lose it (reflections, textureless sand, the far field)."""
    rng = np.random.default_rng(seed)
    out = z.copy()
    h, w = z.shape
    while np.isnan(out).mean() < share + np.isnan(z).mean() * (1 - share):
        bh, bw = int(rng.integers(h // 10, h // 3)), int(rng.integers(w // 10, w // 3))
        y, x = int(rng.integers(0, h - bh)), int(rng.integers(0, w - bw))
        out[y:y + bh, x:x + bw] = np.nan
    return out


def type_steps(chosen: str, true: str) -> int | None:
    """|index difference| in the Jerlov order, None for a custom type."""
    if chosen not in TYPES:
        return None
    return abs(TYPES.index(chosen) - TYPES.index(true))


def recover(img: np.ndarray, t_b: np.ndarray, wtype: str, a: np.ndarray) -> np.ndarray:
    """J = A + (I - A) / t_c with t_c = t_B^(beta_c / beta_B) (METHOD §0, §7 floors), clipped at 0."""
    br, bg = synth.JERLOV[wtype]
    tb = np.clip(t_b, 1e-3, 1)[:, :, None]
    t = np.concatenate([tb ** (1 / br), tb ** (1 / bg), tb], axis=2)
    t = np.maximum(t, 0.05)
    return np.maximum(a + (img - a) / t, 0)


def gray_world_on(img: np.ndarray, valid: np.ndarray) -> np.ndarray:
    """Gains that make the valid pixels' channel means equal."""
    m = img[valid].mean(axis=0)
    return img * (m.mean() / np.maximum(m, 1e-9))


def rho_of(z: np.ndarray, t_b: np.ndarray) -> float:
    ok = np.isfinite(z) & (t_b > 0)
    return ev.pearson(z[ok], -np.log(t_b[ok]))


def baseline_rows(r: Render) -> dict:
    """Outputs that need no restoration: baselines and the truth floor."""
    obj = r.objects
    rows = {
        "input": r.image,
        "gray_world": ev.grayworld(r.image),
        "stretch": ev.stretch(r.image),
    }
    tt = np.where(obj[:, :, None], r.t, 1.0)
    j = np.maximum((r.image - r.a * (1 - tt)) / np.maximum(tt, 1e-6), 0) / r.light_rgb
    rows["floor_truth"] = np.where(obj[:, :, None], j, 0)
    return rows


def method_rows(r: Render, only=None) -> tuple[dict, dict]:
    """Restorations of a render; returns (outputs, extra facts per row)."""
    out, facts = {}, {}
    want = (lambda k: only is None or k in only)
    if want("default"):
        res = uwhl_rs.restore(r.image)
        out["default"] = res.image
        facts["default"] = {"type": res.water_type, "rho": rho_of(r.distance, res.transmission)}
    if want("default_true_type"):
        res = uwhl_rs.restore(r.image, water_types=[r.water_type])
        out["default_true_type"] = res.image
        facts["default_true_type"] = {"rho": rho_of(r.distance, res.transmission)}
    if want("paper"):
        res = uwhl_rs.restore(r.image, method="paper")
        out["paper"] = res.image
        facts["paper"] = {"type": res.water_type, "rho": rho_of(r.distance, res.transmission)}
    # METHOD §13: the true distance given (open water unknown), with 30% of
    # it lost in blocks, with 10% multiplicative noise, and another scene's map
    z = np.where(np.isfinite(r.distance), r.distance, np.nan).astype(np.float32)
    beta_true = np.array([BETA_B[r.water_type] / synth.JERLOV[r.water_type][0],
                          BETA_B[r.water_type] / synth.JERLOV[r.water_type][1], BETA_B[r.water_type]])
    variants = {"distance": z, "distance_holes": holes(z, 0.3, seed=len(r.name)),
                "distance_noise": z * np.random.default_rng(len(r.name)).lognormal(0.0, 0.1, z.shape).astype(np.float32),
                "distance_other": np.ascontiguousarray(z[::-1, ::-1])}
    for key, zz in variants.items():
        if not want(key):
            continue
        res = uwhl_rs.restore(r.image, distance=zz)
        out[key] = res.image
        f = {"type": res.water_type, "rho": rho_of(r.distance, res.transmission), "used": res.distance["used"]}
        if res.water is not None:
            beta = np.array(res.water["beta"])
            f["beta_err"] = float(np.max(np.abs(beta / beta_true - 1)))
            # METHOD §13.2 step 6: does the fit's range hold the true water?
            rng = np.array(res.water["beta_range"])
            f["in_range"] = bool(np.all((rng[:, 0] <= beta_true) & (beta_true <= rng[:, 1])))
            f["plausible"] = r.water_type in res.water["plausible_types"]
        facts[key] = f
    if want("floor_tA_gw") or want("floor_affine"):
        a = tuple(float(x) for x in np.clip(r.a, 1e-4, 1))
        res = uwhl_rs.restore(r.image, water_types=[r.water_type], veiling_light=a)
        obj = r.objects
        tb = np.asarray(res.transmission, dtype=np.float64)
        out["floor_tA_gw"] = gray_world_on(recover(r.image, tb, r.water_type, r.a), obj)
        x = -np.log(np.clip(tb[obj], 1e-6, 1))
        y = BETA_B[r.water_type] * r.distance[obj]
        s, o = np.polyfit(x, y, 1)
        tb2 = tb.copy()
        tb2[obj] = np.exp(-np.maximum(s * x + o, 0))
        out["floor_affine"] = gray_world_on(recover(r.image, tb2, r.water_type, r.a), obj)
    return out, facts


def run(split: str, side: int, only=None, candidates=None, conditions=None, verbose=True) -> list[dict]:
    """Score every render of a split; ``candidates`` maps extra row names to f(Render) -> image."""
    rows = []
    for r in scenes(split, side, conditions):
        t0 = time.time()
        outs = baseline_rows(r)
        m, facts = method_rows(r, only)
        outs.update(m)
        for name, fn in (candidates or {}).items():
            got = fn(r)
            if isinstance(got, tuple):
                outs[name], facts[name] = got
            else:
                outs[name] = got
        for name, img in outs.items():
            if only is not None and name not in only and name not in (candidates or {}):
                continue
            s = truth.score(img, r.truth, r.objects, gains=True)
            row = {"scene": r.name, "content": r.content, "condition": f"{r.stats}/{r.light}",
                   "type_true": r.water_type, "row": name, **s}
            f = facts.get(name, {})
            if "type" in f:
                row["type"] = f["type"]
                row["steps"] = type_steps(f["type"], r.water_type)
            if "rho" in f:
                row["rho"] = f["rho"]
            for k in ("beta_err", "used", "in_range", "plausible"):
                if k in f:
                    row[k] = f[k]
            rows.append(row)
        if verbose:
            print(f"{r.name}: {time.time() - t0:.1f}s", file=sys.stderr)
    return rows


def table(rows: list[dict]) -> str:
    """Markdown: per condition and row, median of the per-scene median angles (raw / best gains), type, rho."""
    names = list(dict.fromkeys(r["row"] for r in rows))
    conds = list(dict.fromkeys(r["condition"] for r in rows))
    lines = ["| row | " + " | ".join(conds) + " |", "|---|" + "---|" * len(conds)]
    for n in names:
        cells = []
        for c in conds:
            sel = [r for r in rows if r["row"] == n and r["condition"] == c]
            if not sel:
                cells.append("-")
                continue
            med = np.median([r["median"] for r in sel])
            gm = np.median([r["gain_median"] for r in sel])
            cell = f"{med:.1f}° ({gm:.1f}°)"
            steps = [r["steps"] for r in sel if r.get("steps") is not None]
            if steps:
                cell += f" type {sum(s == 0 for s in steps)}/{sum(s <= 1 for s in steps)}/{len(sel)}"
            rhos = [r["rho"] for r in sel if r.get("rho") is not None and math.isfinite(r["rho"])]
            if rhos:
                cell += f" rho {np.median(rhos):.2f}"
            errs = [r["beta_err"] for r in sel if r.get("beta_err") is not None]
            if errs:
                cell += f" beta±10% {sum(e <= 0.1 for e in errs)}/{len(sel)}"
            inside = [r["in_range"] for r in sel if r.get("in_range") is not None]
            if inside:
                cell += f" in range {sum(inside)}/{len(inside)}"
            plaus = [r["plausible"] for r in sel if r.get("plausible") is not None]
            if plaus:
                cell += f" type plausible {sum(plaus)}/{len(plaus)}"
            used = [r["used"] for r in sel if r.get("used") is not None]
            if used:
                cell += f" used {sum(used)}/{len(sel)}"
            cells.append(cell)
        lines.append(f"| {n} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def paired_table(rows: list[dict], methods=("default", "distance"), against=("input", "gray_world")) -> str:
    """Markdown: per condition, each method's median minus each baseline's, over
    the same renders, with a 95% paired-bootstrap interval and how many renders
    the method wins / loses (uwhl_rs.truth.paired_medians). An interval that
    holds 0 means the comparison could go either way on other renders."""
    conds = list(dict.fromkeys(r["condition"] for r in rows))
    by = {(r["row"], r["scene"]): r["median"] for r in rows}
    lines = ["| method - baseline | " + " | ".join(conds) + " |", "|---|" + "---|" * len(conds)]
    for m in methods:
        for b in against:
            cells = []
            for c in conds:
                scenes = [r["scene"] for r in rows if r["row"] == m and r["condition"] == c]
                if not scenes:
                    cells.append("-")
                    continue
                p = truth.paired_medians([by[(m, s)] for s in scenes], [by.get((b, s)) for s in scenes])
                cells.append(f"{p['difference']:+.1f}° [{p['low']:+.1f}, {p['high']:+.1f}] "
                             f"{p['better']}/{p['worse']}")
            if any(x != "-" for x in cells):
                lines.append(f"| {m} - {b} | " + " | ".join(cells) + " |")
    return "\n".join(lines)


def write_split(split: str, side: int, folder: str, conditions=None) -> int:
    """Write every render of a split as files and two manifests (module docstring); returns the count."""
    import os

    import tifffile
    from PIL import Image

    os.makedirs(folder, exist_ok=True)
    plain, given = [], []
    for r in scenes(split, side, conditions):
        obj = r.objects
        tifffile.imwrite(os.path.join(folder, f"{r.name}.tif"), np.ascontiguousarray(r.image, np.float32),
                         compression="zlib", photometric="rgb")
        tifffile.imwrite(os.path.join(folder, f"{r.name}_truth.tif"), np.ascontiguousarray(r.truth, np.float32),
                         compression="zlib", photometric="rgb")
        Image.fromarray((obj * 255).astype(np.uint8)).save(os.path.join(folder, f"{r.name}_objects.png"))
        np.save(os.path.join(folder, f"{r.name}_distance.npy"), np.where(obj, r.distance, 0.0))
        entry = {"path": f"{r.name}.tif", "truth": f"{r.name}_truth.tif", "truth_mask": f"{r.name}_objects.png",
                 "distance": f"{r.name}_distance.npy", "water_type": r.water_type}
        plain.append(entry)
        if not obj.all():
            Image.fromarray((~obj * 255).astype(np.uint8)).save(os.path.join(folder, f"{r.name}_water.png"))
            entry = {**entry, "water_mask": f"{r.name}_water.png"}
        given.append(entry)
    for name, entries in (("truth.json", plain), ("truth_given.json", given)):
        with open(os.path.join(folder, name), "w") as f:
            json.dump({"images": entries}, f, indent=1)
    return len(plain)


#: ``uwhl evaluate``'s names for the rows this bench also computes.
EVALUATE_ROWS = {"input": "input", "grayworld": "gray_world", "stretch": "stretch", "revised": "default",
                 "paper": "paper", "revised+distance": "distance"}


def compare(results_path: str, rows: list[dict]) -> str:
    """The largest differences between ``uwhl evaluate``'s results on the written renders and this bench's rows."""
    import os

    with open(results_path) as f:
        doc = json.load(f)
    mine = {(r["scene"], r["row"]): r for r in rows}
    worst: dict[str, list] = {}
    for im in doc["images"]:
        scene = os.path.splitext(os.path.basename(im["manifest_path"]))[0]
        for m, row in EVALUATE_ROWS.items():
            ours, theirs = mine.get((scene, row)), im["truth_angles"].get(m)
            if ours is None or theirs is None:
                continue
            w = worst.setdefault(row, [0.0, 0.0, None, 0])
            w[0] = max(w[0], abs(ours["median"] - theirs["median_deg"]), abs(ours["p90"] - theirs["p90_deg"]))
            w[1] = max(w[1], abs(ours["gain_median"] - theirs["gain_median_deg"]),
                       abs(ours["gain_p90"] - theirs["gain_p90_deg"]))
            rho = im["rho"].get(m, {}).get("rho_B")
            if rho is not None and ours.get("rho") is not None:
                w[2] = max(w[2] or 0.0, abs(ours["rho"] - rho))
            w[3] += 1
    lines = ["| row | renders | max diff, median/p90 raw (deg) | after gains (deg) | rho |", "|---|---|---|---|---|"]
    for row, (a, g, rho, n) in worst.items():
        lines.append(f"| {row} | {n} | {a:.2e} | {g:.2e} | {'-' if rho is None else f'{rho:.2e}'} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--split", default="tune", choices=["tune", "held", "fresh", "all"])
    p.add_argument("--size", type=int, default=360, help="longer side of the renders (default 360)")
    p.add_argument("--only", default=None, help="comma list of method rows to run (baselines always run)")
    p.add_argument("--json", default=None, help="write every per-scene row to this file")
    p.add_argument("--rows", default=None, metavar="JSON",
                   help="tabulate the per-scene rows an earlier --json wrote instead of rendering again")
    p.add_argument("--write", default=None, metavar="DIR",
                   help="write the split's renders, truths and manifests to DIR instead of scoring them")
    p.add_argument("--compare", default=None, metavar="RESULTS",
                   help="compare with uwhl evaluate's results.json on the renders --write wrote")
    a = p.parse_args(argv)
    if a.write:
        n = write_split(a.split, a.size, a.write)
        print(f"{n} renders in {a.write}; uwhl evaluate {a.write}/truth.json -o OUT")
        return 0
    only = set(a.only.split(",")) if a.only else None
    if a.compare and only is None:
        only = {"default", "paper"}
    if only is not None:
        only |= {"input", "gray_world", "stretch", "floor_truth"}
    if a.rows:
        with open(a.rows) as f:
            rows = json.load(f)
    else:
        rows = run(a.split, a.size, only)
    if a.json:
        with open(a.json, "w") as f:
            json.dump(rows, f, indent=1)
    print(f"split {a.split}, {a.size} px; cells: median angle (after best gains), type exact/within one/of n, rho")
    print(table(rows))
    print()
    print("paired: difference of medians [95% bootstrap interval] renders better/worse")
    print(paired_table(rows))
    if a.compare:
        print(compare(a.compare, rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
