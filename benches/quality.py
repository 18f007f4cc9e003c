#!/usr/bin/env python3
"""Quality figures of uwhl_rs (METHOD §11), printed as plain-text tables.

Run from the repository root with the package importable, e.g.::

    python3 benches/quality.py                  # full run, default profile (package installed)
    python3 benches/quality.py --method paper   # the same figures for the paper profile
    python3 benches/quality.py --quick          # small run; PYTHONPATH=python for a dev build

Every ``restore`` call runs the profile ``--method`` names (default: the
package's default, ``revised``; METHOD §12), and the report's first line
names it.

Sections
--------
1. Rendered scenes (``uwhl_rs.synth``, METHOD §0) with known truth, all ten
   Jerlov types, two noise levels: rho = Pearson(z, -ln t_B) over non-water
   pixels, once with the true water region given (``water_mask``) and once
   with detection; the profile's choice of the water type (``paper``: gray
   world with the t_R exclusion rule, METHOD §9, also ranked without it;
   ``revised``: shades of gray, METHOD §12.2, which excludes none); the
   veiling-light error |A - A_true|; the mean angular color error of
   non-water pixels before and after.
2. VL detection on the renders: IoU with the true water region (full, and
   restricted to the rows VL may occupy, METHOD §3.4), and how often the
   looking-down scenes (no water) raise ``veiling_fallback``.
3. Real photos of ../shared/data/images (sRGB, linearized): VL fraction,
   fallback, A, chosen type, time; one PNG per photo (input with VL tinted |
   restored, sRGB | t_B as gray) in ``--out``. The expectation (open water
   visible or looking down) comes from ../shared/data/PROVENANCE.md.
4. Timing of one ``restore`` call at 1 MP and at the largest shared photo.
"""

from __future__ import annotations

import argparse
import math
import os
import pathlib
import sys
import time
from collections import Counter

import numpy as np

try:
    import uwhl_rs
    from uwhl_rs import synth
except ImportError as exc:  # pragma: no cover - a clear message for a missing build
    sys.exit(f"cannot import uwhl_rs ({exc}); run with PYTHONPATH=python from the repo root")

TYPES = list(synth.JERLOV)
# the profiles and the default one (the option table's row of `method`)
_METHOD_ROW = next(o for o in uwhl_rs._core.OPTIONS if o["key"] == "method")
METHODS, DEFAULT_METHOD = tuple(_METHOD_ROW["choices"]), _METHOD_ROW["default"]
CHOICE = {"paper": "gray world, METHOD §9", "revised": "shades of gray, METHOD §12.2"}
# ../shared/data beside the repository (as in CI); UWHL_DATA overrides.
DATA_DIR = pathlib.Path(os.environ.get("UWHL_DATA", pathlib.Path(__file__).resolve().parents[2] / "shared" / "data")) / "images"
LARGEST_PHOTO = "udc_5-2.jpg"

# What each shared photo shows, from ../shared/data/PROVENANCE.md ("what it
# is" column): "water" = open water visible as a background (VL should be
# found, in the upper part), "down" = looking down at the bottom, no water
# background (VL should be empty -> veiling_fallback), "?" = PROVENANCE does
# not say that a water background is visible (turbid/murky, charts in a pool).
# Looking at the overlays shows where these labels are loose: lcm_sample_7 has
# open water above a sand horizon in its top quarter and udc_hazed2 turbid
# water above the sand slope (a VL there is right although the label says
# "down"); udc_hazed3 is filled by a fish school (a VL there lands on blurred
# fish, although the label says "water"); uieb_880's top is defocused far
# sand. udc_5-2 is a high-resolution copy of the galdran1 scene.
EXPECT = {
    "uwhl_Ancuti2_input.jpg": ("?", "turbid coastal, divers + statue; little open water"),
    "uwhl_galdran1_input.jpg": ("water", "reef, blue-green water background (top)"),
    "uwhl_ship_highres_input.jpg": ("water", "open-ocean wreck + diver, large water background"),
    "uwhl_shipwreck_input.jpg": ("water", "blue wreck, open water background"),
    "uieb_616.png": ("water", "blue reef + fish, open water background"),
    "uieb_866.png": ("down", "goatfish over sand, looking down, no water background"),
    "uieb_880.png": ("down", "fish over sand/pink, looking down, no water background"),
    "udc_1.jpg": ("?", "fish in strongly blue/hazy water, low contrast"),
    "udc_3.jpg": ("?", "strong green cast, diver + statue (turbid)"),
    "udc_8.jpg": ("?", "murky/turbid greenish, low visibility"),
    "udc_9.jpg": ("?", "murky reef, greenish"),
    "udc_10.jpg": ("water", "sharks in murky blue-green water, open water everywhere"),
    "udc_5-2.jpg": ("water", "reef, green-blue water background, high-res"),
    "udc_hazed2.jpg": ("down", "looking down at sand with fish, no water background"),
    "udc_hazed3.jpg": ("water", "fish school, blue, open water"),
    "udc_hazed5.jpg": ("?", "wreck + fish, blue-grey"),
    "lcm_sample_1.jpg": ("water", "cyan-green coastal water, pipe + fish, open water background"),
    "lcm_sample_5.jpg": ("water", "reef, green water background"),
    "lcm_sample_7.jpg": ("down", "sand + coral, looking down-ish, green cast"),
    "chart_calib_1_under.png": ("?", "colour board underwater (pool, strong green)"),
    "chart_calib_2_under.jpg": ("?", "two colour charts underwater (blue-green)"),
    "chart_calib_3_under.jpg": ("down", "24-patch checker on sand underwater, looking down"),
    "euvp_7.jpg": ("water", "diver + turtle, blue open water"),
    "euvp_13.jpg": ("down", "ray on sand, looking down, greenish"),
    "euvp_17.jpg": ("water", "turtle, blue, open water"),
    "euvp_22.jpg": ("down", "anemones/starfish, looking down, no water"),
}


# --------------------------------------------------------------------------
# Small helpers
# --------------------------------------------------------------------------


def srgb_to_linear(x: np.ndarray) -> np.ndarray:
    """Inverse sRGB curve (IEC 61966-2-1), float in [0, 1] -> linear."""
    x = np.asarray(x, dtype=np.float64)
    return np.where(x <= 0.04045, x / 12.92, ((x + 0.055) / 1.055) ** 2.4)


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    """sRGB curve, linear in [0, 1] -> encoded in [0, 1]."""
    x = np.clip(np.asarray(x, dtype=np.float64), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1.0 / 2.4) - 0.055)


def to_unit_float(a: np.ndarray) -> np.ndarray:
    """Integer or float image -> float64 in [0, 1], RGB only (alpha dropped)."""
    if a.ndim == 2:
        a = np.stack([a] * 3, axis=-1)
    a = a[..., :3]
    if np.issubdtype(a.dtype, np.integer):
        return a.astype(np.float64) / float(np.iinfo(a.dtype).max)
    return np.clip(a.astype(np.float64), 0.0, 1.0)


def pearson(x: np.ndarray, y: np.ndarray) -> float:
    x = np.asarray(x, dtype=np.float64).ravel()
    y = np.asarray(y, dtype=np.float64).ravel()
    x = x - x.mean()
    y = y - y.mean()
    d = math.sqrt(float(x @ x) * float(y @ y))
    return float(x @ y) / d if d > 0 else float("nan")


def iou(a: np.ndarray, b: np.ndarray) -> float:
    u = np.count_nonzero(a | b)
    return np.count_nonzero(a & b) / u if u else float("nan")


def vl_row_limit(h: int, w: int) -> int:
    """Rows y < this may hold VL (METHOD §3.4 as pinned in METHOD §3)."""
    s = max(1, math.ceil(max(h, w) / 512))
    hs = math.ceil(h / s)
    return min(h, s * math.ceil(hs / 4))


def mean_angle_deg(a: np.ndarray, b: np.ndarray, sel: np.ndarray) -> float:
    """Mean per-pixel angle (degrees) between RGB vectors a and b over sel."""
    x = np.asarray(a, dtype=np.float64)[sel]
    y = np.asarray(b, dtype=np.float64)[sel]
    num = np.einsum("ij,ij->i", x, y)
    den = np.linalg.norm(x, axis=1) * np.linalg.norm(y, axis=1)
    cos = np.clip(num / np.maximum(den, 1e-12), -1.0, 1.0)
    return float(np.degrees(np.arccos(cos)).mean())


def score_ranking(scores: dict) -> list:
    """Type names ordered by score (best first); ties by table order."""
    names = list(scores)
    return sorted(names, key=lambda n: (scores[n], names.index(n)))


def table(header: list, rows: list, indent: str = "  ") -> str:
    """Plain-text table with right-aligned columns (first column left)."""
    cells = [[str(c) for c in header]] + [[str(c) for c in r] for r in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(header))]
    out = []
    for k, r in enumerate(cells):
        parts = [r[0].ljust(widths[0])] + [r[i].rjust(widths[i]) for i in range(1, len(r))]
        out.append(indent + "  ".join(parts).rstrip())
        if k == 0:
            out.append(indent + "  ".join("-" * w for w in widths))
    return "\n".join(out)


def fmt(x, nd: int = 3) -> str:
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return "-"
    return f"{x:.{nd}f}"


def med_min(v) -> str:
    v = [x for x in v if not math.isnan(x)]
    return f"{np.median(v):.3f} / {min(v):.3f}" if v else "-"


def med_max(v) -> str:
    v = [x for x in v if not math.isnan(x)]
    return f"{np.median(v):.3f} / {max(v):.3f}" if v else "-"


def counts(names) -> str:
    c = Counter(names)
    return " ".join(f"{n}:{c[n]}" for n in TYPES if c[n]) or "-"


# --------------------------------------------------------------------------
# 1 + 2: rendered scenes
# --------------------------------------------------------------------------


def run_renders(args) -> list:
    """One record per (kind, seed, type, noise, mode)."""
    recs = []
    h, w = args.size
    for kind in ("open_water", "looking_down"):
        for seed in args.seeds:
            sc = synth.scene(h, w, kind=kind, seed=seed)
            nonwater = ~sc.water
            z = sc.distance[nonwater].astype(np.float64)
            lim = vl_row_limit(h, w)
            water_top = sc.water.copy()
            water_top[lim:] = False
            for ti, wt in enumerate(TYPES):
                a_true = np.array(synth.default_veiling_light(wt))
                for ni, noise in enumerate(args.noise):
                    img = synth.render(sc.clean, sc.distance, wt, noise=noise,
                                       seed=1000 * seed + 10 * ti + ni)
                    ang_in = mean_angle_deg(img, sc.clean, nonwater)
                    for mode in ("given", "detected"):
                        wm = sc.water if mode == "given" else None
                        res = uwhl_rs.restore(img, water_mask=wm, threads=args.threads, method=args.method)
                        tb = np.asarray(res.transmission, dtype=np.float64)
                        ranking = score_ranking(res.scores)
                        vm = np.asarray(res.veiling_mask)
                        recs.append(dict(
                            kind=kind, seed=seed, type=wt, noise=noise, mode=mode,
                            rho=pearson(z, -np.log(np.maximum(tb[nonwater], 1e-12))),
                            chosen=res.water_type,
                            noexcl=ranking[0],
                            rank=ranking.index(wt) + 1,
                            excluded=list(res.excluded),
                            a_err=float(np.abs(np.asarray(res.veiling_light) - a_true).max()),
                            flags=list(res.flags),
                            vl_frac=float(vm.mean()),
                            iou_full=iou(vm, sc.water) if sc.water.any() else float("nan"),
                            iou_top=iou(vm, water_top) if water_top.any() else float("nan"),
                            ang_in=ang_in,
                            ang_out=mean_angle_deg(res.image, sc.clean, nonwater),
                        ))
            print(f"  [rendered {kind} seed {seed}]", file=sys.stderr, flush=True)
    return recs


def report_renders(recs: list, args) -> None:
    h, w = args.size
    n_runs = len(args.seeds) * len(args.noise)
    print("=" * 78)
    print("1. RENDERED SCENES (synth.scene + synth.render, METHOD §0)")
    print("=" * 78)
    print(f"size {h}x{w}, seeds {args.seeds}, noise {args.noise}, beta_b 0.2 (default),")
    print(f"A = synth.default_veiling_light(type); {n_runs} runs per type, kind and mode.")
    print("rho = Pearson(z, -ln t_B) over non-water pixels (METHOD §11).")
    print("'given' = restore(img, water_mask=scene.water); 'detected' = VL detected.")
    print("|A-A_true| = max over channels (linear). Angle = mean per-pixel angle (deg)")
    print("between RGB and the clean radiance over non-water pixels (input / res.image).")
    for kind in ("open_water", "looking_down"):
        sub = [r for r in recs if r["kind"] == kind]
        print()
        print(f"1.{'a' if kind == 'open_water' else 'b'} {kind}: transmission, veiling light, color"
              + ("" if kind == "open_water" else
                 "  (no water in the scene: 'given' = an all-False mask -> fallback A;"
                 "\n    A_true is the water color the model uses, never visible directly)"))
        rows = []
        for wt in TYPES + ["all"]:
            s = [r for r in sub if wt == "all" or r["type"] == wt]
            g = [r for r in s if r["mode"] == "given"]
            d = [r for r in s if r["mode"] == "detected"]
            row = [wt]
            for mode_recs in (g, d):
                for noise in args.noise:
                    row.append(med_min([r["rho"] for r in mode_recs if r["noise"] == noise]))
            row += [
                med_max([r["a_err"] for r in g]), med_max([r["a_err"] for r in d]),
                fmt(np.median([r["ang_in"] for r in g]), 1),
                fmt(np.median([r["ang_out"] for r in g]), 1),
                fmt(np.median([r["ang_out"] for r in d]), 1),
            ]
            rows.append(row)
        print(table(["type"]
                    + [f"rho given n={n} med/min" for n in args.noise]
                    + [f"rho det n={n} med/min" for n in args.noise]
                    + ["|A-A| given med/max", "|A-A| det med/max",
                       "angle in", "out given", "out det"], rows))

        for mode in ("given", "detected"):
            print()
            print(f"   {kind}, water-type choice ({CHOICE[args.method]}), VL {mode}: ranks are by score"
                  " over all ten types (1 = lowest score)")
            rows = []
            for wt in TYPES:
                s = [r for r in sub if r["type"] == wt and r["mode"] == mode]
                rows.append([
                    wt,
                    f"{sum(r['chosen'] == wt for r in s)}/{len(s)}",
                    f"{sum(r['rank'] <= 2 for r in s)}/{len(s)}",
                    f"{sum(r['rank'] <= 3 for r in s)}/{len(s)}",
                    ",".join(str(r["rank"]) for r in s),
                    f"{sum(r['noexcl'] == wt for r in s)}/{len(s)}",
                    f"{sum(wt in r['excluded'] for r in s)}/{len(s)}",
                    counts(r["chosen"] for r in s),
                    counts(r["noexcl"] for r in s),
                ])
            s = [r for r in sub if r["mode"] == mode]
            rows.append([
                "all",
                f"{sum(r['chosen'] == r['type'] for r in s)}/{len(s)}",
                f"{sum(r['rank'] <= 2 for r in s)}/{len(s)}",
                f"{sum(r['rank'] <= 3 for r in s)}/{len(s)}",
                f"med {np.median([r['rank'] for r in s]):.1f}",
                f"{sum(r['noexcl'] == r['type'] for r in s)}/{len(s)}",
                f"{sum(r['type'] in r['excluded'] for r in s)}/{len(s)}",
                "", "",
            ])
            print(table(["true", "chosen=true", "top-2", "top-3", "rank of true (runs)",
                         "no-excl=true", "true excluded", "chosen (with exclusion)",
                         "argmin w/o exclusion"], rows))

    # Section 2: VL detection.
    print()
    print("=" * 78)
    print("2. VL DETECTION ON RENDERS (VL detected, METHOD §3)")
    print("=" * 78)
    lim = vl_row_limit(h, w)
    print(f"IoU of res.veiling_mask with the true water region: 'full' = all of it,"
          f"\n'top' = restricted to rows < {lim} (the rows VL may occupy, METHOD §3.4).")
    ow = [r for r in recs if r["kind"] == "open_water" and r["mode"] == "detected"]
    rows = []
    for noise in args.noise:
        s = [r for r in ow if r["noise"] == noise]
        rows.append([f"noise {noise}", len(s), med_min([r["iou_full"] for r in s]),
                     med_min([r["iou_top"] for r in s]),
                     sum("veiling_fallback" in r["flags"] for r in s)])
    rows.append(["all", len(ow), med_min([r["iou_full"] for r in ow]),
                 med_min([r["iou_top"] for r in ow]),
                 sum("veiling_fallback" in r["flags"] for r in ow)])
    print(table(["open_water", "runs", "IoU full med/min", "IoU top med/min", "fallbacks"], rows))
    print()
    rows = []
    for wt in TYPES:
        row = [wt]
        for noise in args.noise:
            s = [r for r in ow if r["type"] == wt and r["noise"] == noise]
            row.append(med_min([r["iou_top"] for r in s]))
        rows.append(row)
    print(table(["type"] + [f"IoU top, noise {n} med/min" for n in args.noise], rows))
    print()
    ld = [r for r in recs if r["kind"] == "looking_down" and r["mode"] == "detected"]
    rows = []
    for noise in args.noise + ["all"]:
        s = ld if noise == "all" else [r for r in ld if r["noise"] == noise]
        fb = [r for r in s if "veiling_fallback" in r["flags"]]
        nofb = [r for r in s if "veiling_fallback" not in r["flags"]]
        miss = counts(r["type"] for r in nofb)
        rows.append([noise if noise == "all" else f"noise {noise}", len(s),
                     f"{len(fb)}/{len(s)} = {len(fb) / max(len(s), 1):.2f}",
                     fmt(max([r["vl_frac"] for r in nofb], default=float("nan")) * 100, 2),
                     miss])
    print(table(["looking_down", "runs", "veiling_fallback raised",
                 "max VL % when not", "types where VL was found"], rows))


# --------------------------------------------------------------------------
# 3: real photos
# --------------------------------------------------------------------------


def _resize(img: np.ndarray, max_side: int) -> np.ndarray:
    from PIL import Image

    h, w = img.shape[:2]
    f = max_side / max(h, w)
    if max_side <= 0 or f >= 1:
        return img
    size = (max(1, round(w * f)), max(1, round(h * f)))
    u8 = (np.clip(img, 0, 1) * 255 + 0.5).astype(np.uint8)
    squeeze = u8.ndim == 2
    out = Image.fromarray(u8).resize(size, Image.LANCZOS if not squeeze else Image.BILINEAR)
    return np.asarray(out).astype(np.float64) / 255.0


def save_panel(path: pathlib.Path, srgb: np.ndarray, res, panel: int) -> None:
    """input with VL tinted | restored (sRGB) | t_B (gray), one PNG."""
    import imageio.v3 as iio

    h, w = srgb.shape[:2]
    vm = np.asarray(res.veiling_mask)
    ov = srgb.copy()
    tint = np.array([1.0, 0.0, 1.0])  # magenta
    ov[vm] = 0.45 * ov[vm] + 0.55 * tint
    # VL outline (4-neighbour boundary), a few pixels thick on large images
    edge = vm & ~(np.roll(vm, 1, 0) & np.roll(vm, -1, 0) & np.roll(vm, 1, 1) & np.roll(vm, -1, 1))
    k = max(1, round(max(h, w) / 600))
    for _ in range(k - 1):
        edge = edge | np.roll(edge, 1, 0) | np.roll(edge, 1, 1)
    ov[edge] = tint
    # the lowest row VL may reach (METHOD §3.4): dashed yellow line
    lim = vl_row_limit(h, w)
    if lim < h:
        dash = (np.arange(w) // max(4, w // 60)) % 2 == 0
        ov[max(0, lim - k):lim + k, dash] = (1.0, 1.0, 0.0)
    restored = linear_to_srgb(res.image)
    t = np.clip(np.asarray(res.transmission, dtype=np.float64), 0, 1)
    tgray = np.repeat(t[..., None], 3, axis=-1)
    panels = [_resize(p, panel) for p in (ov, restored, tgray)]
    ph = panels[0].shape[0]
    sep = np.ones((ph, 6, 3))
    row = np.concatenate([panels[0], sep, panels[1], sep, panels[2]], axis=1)
    iio.imwrite(path, (np.clip(row, 0, 1) * 255 + 0.5).astype(np.uint8))


def run_photos(args) -> None:
    import imageio.v3 as iio

    print()
    print("=" * 78)
    print(f"3. REAL PHOTOS (sRGB decoded, inverse sRGB curve, restore with method={args.method})")
    print("=" * 78)
    if not DATA_DIR.is_dir():
        print(f"skipped: {DATA_DIR} is absent")
        return
    files = sorted(p for p in DATA_DIR.iterdir()
                   if p.is_file() and p.suffix.lower() in (".jpg", ".jpeg", ".png", ".tif", ".tiff")
                   and "_above" not in p.name)
    if args.quick:
        files = [p for p in files if p.name in args.quick_photos]
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    print("expect (from PROVENANCE.md): water = open water background visible (VL should be")
    print("found), down = looking down, no water (veiling_fallback expected), ? = not stated.")
    print("VL rows = first..last row holding VL, as a fraction of the height.")
    if args.photo_max_side:
        print(f"(photos downscaled to at most {args.photo_max_side} px before restore)")
    rows = []
    agree = Counter()
    for p in files:
        try:
            raw = iio.imread(p)
        except Exception as exc:  # noqa: BLE001 - report and go on
            rows.append([p.name, "-", "-", "-", "-", f"unreadable: {exc}", "", "", "", ""])
            continue
        srgb = to_unit_float(raw)
        if args.photo_max_side:
            srgb = _resize(srgb, args.photo_max_side)
        lin = srgb_to_linear(srgb).astype(np.float32)
        h, w = lin.shape[:2]
        t0 = time.perf_counter()
        res = uwhl_rs.restore(lin, threads=args.threads, method=args.method)
        dt = time.perf_counter() - t0
        vm = np.asarray(res.veiling_mask)
        frac = float(vm.mean())
        fb = "veiling_fallback" in res.flags
        exp, _desc = EXPECT.get(p.name, ("?", ""))
        found = (not fb) and frac > 0
        if exp == "water":
            ok = "yes" if found else "NO"
        elif exp == "down":
            ok = "yes" if fb else ("~ (<2%)" if frac < 0.02 else "NO")
        else:
            ok = "-"
        agree[(exp, ok)] += 1
        rws = np.flatnonzero(vm.any(axis=1))
        vrows = f"{rws[0] / h:.2f}-{(rws[-1] + 1) / h:.2f}" if rws.size else "-"
        rk = score_ranking(res.scores)
        a = res.veiling_light
        rows.append([
            p.name, f"{w}x{h}", exp, f"{100 * frac:.1f}", vrows,
            ",".join(res.flags) or "-", ok,
            f"({a[0]:.3f},{a[1]:.3f},{a[2]:.3f})",
            res.water_type + ("" if rk[0] == res.water_type else f" (argmin {rk[0]})"),
            f"{dt:.2f}",
        ])
        save_panel(out / f"{p.stem}_quality.png", srgb, res, args.panel)
        print(f"  [photo {p.name}: {dt:.2f} s]", file=sys.stderr, flush=True)
    print(table(["image", "size", "expect", "VL %", "VL rows", "flags", "agrees",
                 "A (linear RGB)", "type", "time s"], rows))
    print()
    for exp in ("water", "down"):
        tot = sum(v for (e, _), v in agree.items() if e == exp)
        ok = sum(v for (e, o), v in agree.items() if e == exp and o == "yes")
        part = sum(v for (e, o), v in agree.items() if e == exp and o.startswith("~"))
        extra = f", {part} more with VL < 2%" if exp == "down" else ""
        print(f"  expect {exp}: VL agrees on {ok}/{tot}{extra}")
    print(f"  panels (input + VL tinted magenta, yellow dashes = lowest VL row | restored |"
          f" t_B): {out}/<name>_quality.png")


# --------------------------------------------------------------------------
# 4: timing
# --------------------------------------------------------------------------


def best_of(fn, n: int) -> float:
    best = float("inf")
    for _ in range(n):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def run_timing(args) -> None:
    import imageio.v3 as iio

    print()
    print("=" * 78)
    print(f"4. TIMING (one restore call, best of {args.repeats}, threads="
          f"{args.threads if args.threads else 'default (all)'}, {os.cpu_count()} CPUs, shared)")
    print("=" * 78)
    rows = []
    img, _ = synth.demo_input(1000, 1000, water_type="III", seed=3)
    t = best_of(lambda: uwhl_rs.restore(img, threads=args.threads, method=args.method), args.repeats)
    rows.append(["render 1000x1000 (1.0 MP)", f"{t:.2f}", f"{t / 1.0:.2f}"])
    p = DATA_DIR / LARGEST_PHOTO
    if p.is_file() and not args.quick:
        lin = srgb_to_linear(to_unit_float(iio.imread(p))).astype(np.float32)
        h, w = lin.shape[:2]
        mp = h * w / 1e6
        t = best_of(lambda: uwhl_rs.restore(lin, threads=args.threads, method=args.method), args.repeats)
        rows.append([f"{LARGEST_PHOTO} {w}x{h} ({mp:.1f} MP)", f"{t:.2f}", f"{t / mp:.2f}"])
    elif not p.is_file():
        rows.append([f"{LARGEST_PHOTO}", "absent", "-"])
    print(table(["input", "seconds", "s / MP"], rows))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true",
                    help="small run: 180x240 renders, 1 seed, noise 0.002, 6 photos at "
                         "<= 640 px, 1 MP timing once")
    ap.add_argument("--out", default="/tmp/uwhl_quality", help="folder for the photo PNGs")
    ap.add_argument("--method", choices=METHODS, default=DEFAULT_METHOD,
                    help=f"the profile every restore call runs (METHOD §12; default {DEFAULT_METHOD})")
    ap.add_argument("--threads", type=int, default=None, help="restore threads (default all)")
    ap.add_argument("--panel", type=int, default=720,
                    help="longest side of each panel in the saved PNGs (0 = full size)")
    ap.add_argument("--json", default=None,
                    help="also write the per-run records of sections 1-2 to this JSON file")
    ap.add_argument("--skip", default="", help="comma list of sections to skip: renders,photos,timing")
    args = ap.parse_args(argv)
    if args.quick:
        args.size, args.seeds, args.noise, args.repeats = (180, 240), [0], [0.002], 1
        args.photo_max_side = 640
        args.quick_photos = {"uwhl_galdran1_input.jpg", "uwhl_shipwreck_input.jpg", "euvp_17.jpg",
                             "uieb_866.png", "euvp_13.jpg", "udc_hazed2.jpg"}
    else:
        args.size, args.seeds, args.noise, args.repeats = (360, 480), [0, 1], [0.002, 0.01], 2
        args.photo_max_side = 0
    skip = {s.strip() for s in args.skip.split(",") if s.strip()}

    print(f"uwhl_rs {uwhl_rs.__version__} quality report, method={args.method} "
          f"({'quick' if args.quick else 'full'} run)")
    t0 = time.perf_counter()
    if "renders" not in skip:
        recs = run_renders(args)
        report_renders(recs, args)
        if args.json:
            import json

            pathlib.Path(args.json).parent.mkdir(parents=True, exist_ok=True)
            with open(args.json, "w") as f:
                json.dump(recs, f, indent=0)
    if "photos" not in skip:
        run_photos(args)
    if "timing" not in skip:
        run_timing(args)
    print()
    print(f"total wall time {time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
