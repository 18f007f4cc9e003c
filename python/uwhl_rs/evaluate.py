"""``uwhl evaluate``: the paper's colour and distance metrics (SPEC 11) on
annotated photographs, beside simple baselines computed in the same run on
the same pixels. The manifest format and the outputs are in docs/EVALUATE.md.

Metrics:

- per chart, psi-bar: the mean over its gray patches of the angle, in
  degrees, between the patch's mean linear RGB and (1, 1, 1);
- per image with a distance map: Pearson rho between the distance and
  -ln t_B over the valid pixels, and the same for t_R = t_B^(1/beta_BR);
- per image with a true water type: whether the chosen type is it, or
  within one step of it in the table order.
- per image with a true radiance (``truth``): the per-pixel angle to it,
  median and 90th percentile, raw and after the best global per-channel
  gains (``uwhl_rs.truth.score``).

Evaluated: the method (``--method``, with any option of ``restore``),
every other profile of METHOD §12 with its own defaults (so the revised
profile and the paper's are always side by side), and the baselines ``input`` (the linear input), ``stretch`` (a global
per-channel 1%/99% contrast stretch of it), ``grayworld`` (gray-world white
balance of it) and ``type:NAME`` for every candidate water type (restored
with that type alone and the method's veiling light).
"""

from __future__ import annotations

import csv
import json
import math
import os

import numpy as np

from . import _core
from . import truth as gt
from .errors import ManifestError
# the manifest's format and reader, re-exported: uwhl_rs.evaluate is where the command and tests find them
from .manifest import METHODS, TYPE_ORDER, Chart, Entry, load_manifest
from .evaluate_report import SUMMARY_EXTRAS, TRUTH_KEYS, image_section, report_methods, write_report
from .sidecars import printable

__all__ = ["METHODS", "Chart", "Entry", "ManifestError", "load_manifest", "evaluate_entry", "summarize",
           "write_results", "write_report", "image_section", "report_methods"]


# ------------------------------------------------------------------ metrics


def angle_deg(rgb) -> float:
    """The angle in degrees between an RGB vector and gray (1, 1, 1); NaN
    for a zero vector (a black patch has no hue)."""
    v = np.asarray(rgb, dtype=np.float64)
    n = float(np.linalg.norm(v))
    if not n > 0:
        return float("nan")
    c = float(v.sum()) / (n * math.sqrt(3.0))
    return math.degrees(math.acos(min(1.0, max(-1.0, c))))


def _patch_mean(img: np.ndarray, box) -> np.ndarray:
    x0, y0, x1, y1 = box
    return img[y0:y1, x0:x1].reshape(-1, 3).astype(np.float64).mean(axis=0)


def chart_angles(img: np.ndarray, chart: Chart) -> tuple[float, list[float]]:
    """(psi-bar, per-patch angles) of a chart on a linear HxWx3 image."""
    per = [angle_deg(_patch_mean(img, b)) for b in chart.gray_patches]
    ok = [a for a in per if not math.isnan(a)]
    return (float(np.mean(ok)) if ok else float("nan")), per


def pearson(a, b) -> float:
    """Pearson's correlation of two equally long samples (NaN if either is constant)."""
    a = np.asarray(a, dtype=np.float64).ravel()
    b = np.asarray(b, dtype=np.float64).ravel()
    if a.size < 2:
        return float("nan")
    a = a - a.mean()
    b = b - b.mean()
    d = math.sqrt(float((a * a).sum()) * float((b * b).sum()))
    return float((a * b).sum()) / d if d > 0 else float("nan")


def type_steps(a: str, b: str) -> int | None:
    """How many rows apart two Jerlov types are in the table order (None if either is custom)."""
    if a in TYPE_ORDER and b in TYPE_ORDER:
        return abs(TYPE_ORDER.index(a) - TYPE_ORDER.index(b))
    return None


#: what evaluating one image keeps, per pixel: the baselines (input,
#: stretch, gray world), the truth and the distance, and then each
#: restoration kept to be scored (every profile, the distance's, each
#: candidate type: image, radiance, transmission, confidence, masks). With
#: two profiles and ten types a 2 MP photo peaked at about 1.05 GB, 445
#: bytes a pixel over the process's own (2026-12-05): 48 + 12 x 36 = 480
EVALUATE_BASE_PER_PIXEL = 48
EVALUATE_PER_RESTORATION = 36


#: bytes a .mat may hold beyond its one map's doubles (headers, names, a few small variables)
MAT_SLACK = 1 << 20


def _mat_inflates_within(path: str, cap: int) -> bool:
    """Whether the compressed data elements of the MAT v5 file ``path``
    inflate to at most ``cap`` bytes in all, counted while inflating (never
    held): scipy trusts the sizes inside, and an element that says 2 x 2
    can inflate to 4 GiB. Uncompressed elements are bounded by the file."""
    import struct
    import zlib

    with open(path, "rb") as f:
        head = f.read(128)
        if len(head) < 128:
            return True  # no v5 file: scipy says so
        order = "<" if head[126:128] == b"IM" else ">"
        total = 0
        while len(tag := f.read(8)) == 8:
            kind, n = struct.unpack(order + "II", tag)
            if kind != 15:  # miCOMPRESSED
                f.seek(n + (-n % 8), os.SEEK_CUR)
                continue
            z, left = zlib.decompressobj(), n
            while left > 0 and (block := f.read(min(left, 1 << 20))):
                left -= len(block)
                while block:
                    total += len(z.decompress(block, 1 << 20))
                    if total > cap:
                        return False
                    block = z.unconsumed_tail
    return True


def read_distance(path: str, height: int, width: int, max_memory: int | None = None) -> np.ndarray:
    """A distance map in metres, resized to height x width with nearest
    neighbour; NaN where it has no value (0, NaN, negative, beyond 1000 m).
    Read by the commands' own reader (``.npy``, float or 16-bit TIFF, 16-bit
    PNG in millimetres, OpenEXR: docs/OUTPUTS.md "Distance"), or a ``.mat``
    holding one 2-D array (scipy). Within ``max_memory`` (default: the
    machine's budget)."""
    ext = os.path.splitext(path)[1].lower()
    try:
        if ext == ".mat":
            try:
                from scipy.io import loadmat
            except ImportError:
                raise ManifestError(f"{path}: reading .mat distance maps needs scipy (pip install scipy)") from None
            from scipy.io import whosmat

            # the shapes from the file's headers: an array is decompressed only once its size is known
            numeric = ("double", "single", "int8", "uint8", "int16", "uint16", "int32", "uint32", "int64", "uint64")
            found = [(k, tuple(int(x) for x in shape)) for k, shape, cls in whosmat(path)
                     if cls in numeric and len(shape) == 2 and min(shape) > 1]
            if len(found) != 1:
                raise ManifestError(f"{path}: a .mat distance file holds exactly one 2-D numeric array "
                                    f"(found {len(found)})")
            name, (h, w) = found[0]
            if h * w > min(_core.map_cap(height, width), gt.MAX_TRUTH_PIXELS):
                raise ManifestError(f"{path}: the distance map is {w}x{h} pixels, more than "
                                    f"{_core.MAP_PER_PHOTO_PIXEL} times the photo's {width}x{height}: not read")
            cap = 8 * h * w + MAT_SLACK
            if not _mat_inflates_within(path, cap):
                raise ManifestError(f"{path}: its compressed arrays hold more than the {w}x{h} map's {cap} bytes: "
                                    "not read")
            d = np.asarray(loadmat(path, variable_names=[name])[name], dtype=np.float64)
        else:
            # the commands' reader, with their limits and the cap against the photo's size
            d = np.asarray(_core.read_distance_file(path, int(gt.MAX_TRUTH_PIXELS), gt.memory_budget(max_memory),
                                                    (int(height), int(width))), dtype=np.float64)
    except ManifestError:
        raise
    except (_core.ImageError, MemoryError) as e:
        raise ManifestError(f"{path}: {e}") from None
    except Exception as e:
        raise ManifestError(f"{path}: cannot read the distance map ({type(e).__name__}: {e})") from None
    if d.ndim == 3 and d.shape[2] == 1:
        d = d[:, :, 0]
    if d.ndim != 2 or d.size == 0:
        raise ManifestError(f"{path}: a distance map is one 2-D array, not shape {d.shape}")
    d = np.where(np.isfinite(d) & (d > 0), d, np.nan)
    return gt.resize_nearest(d, height, width)


def stretch(img: np.ndarray) -> np.ndarray:
    """The global per-channel contrast stretch baseline: each channel's
    1st and 99th percentiles mapped to 0 and 1, clipped."""
    out = np.empty_like(img, dtype=np.float32)
    for c in range(3):
        lo, hi = np.percentile(img[:, :, c], [1, 99])
        out[:, :, c] = np.clip((img[:, :, c] - lo) / max(hi - lo, 1e-12), 0, 1)
    return out


def grayworld(img: np.ndarray) -> np.ndarray:
    """The gray-world white balance baseline: each channel scaled so that
    its mean is the mean of the three means, clipped to [0, 1]."""
    means = img.reshape(-1, 3).astype(np.float64).mean(axis=0)
    gain = means.mean() / np.maximum(means, 1e-12)
    return np.clip(img * gain.astype(np.float32), 0, 1).astype(np.float32)


def _rho_pair(distance: np.ndarray, res) -> dict:
    """rho of the distance against -ln t_B and -ln t_R (the method's t_R,
    with its floor of METHOD §7, so not merely a multiple of -ln t_B)."""
    ok = np.isfinite(distance)
    if ok.sum() < 2:
        return {"rho_B": None, "rho_R": None, "distance_pixels": int(ok.sum())}
    d = distance[ok]
    t_b = np.clip(res.transmission[ok].astype(np.float64), 1e-12, 1)
    t_r = np.clip(res.channel_transmissions()[:, :, 0][ok].astype(np.float64), 1e-12, 1)
    return {"rho_B": _finite(pearson(d, -np.log(t_b))), "rho_R": _finite(pearson(d, -np.log(t_r))),
            "distance_pixels": int(ok.sum())}


def _finite(x):
    return None if x is None or (isinstance(x, float) and math.isnan(x)) else x


def evaluate_entry(entry: Entry, method: str = METHODS[0], mask_charts: bool = False, compare=None,
                   **restore_kwargs) -> dict:
    """Every metric of one image for the method, the profiles in
    ``compare`` (default: every other profile; each with its own step
    defaults and the other keywords given) and the baselines (see the
    module documentation). Raises :class:`ManifestError` for a box outside
    the image or an unreadable distance map, and what ``restore`` raises."""
    import uwhl_rs
    from .images import read_image

    # the entry's own restore.method is the method evaluated for it (its keywords override the command's)
    method = entry.restore.get("method", method)
    if method not in METHODS:
        raise ValueError(f"method must be one of {METHODS}, not {method!r}")
    compare = [m for m in METHODS if m != method] if compare is None else [m for m in compare if m != method]
    img, meta = read_image(entry.path)
    h, w = img.shape[:2]
    # every profile's and every candidate type's restoration is kept to be scored: refused
    # whole, before the first, when they cannot all fit (the restores check only themselves)
    budget = restore_kwargs.get("max_memory")
    kept = 1 + len(compare) + (1 if entry.distance else 0) + len(entry.restore.get("water_types")
                                                                 or restore_kwargs.get("water_types") or TYPE_ORDER)
    need = h * w * (EVALUATE_BASE_PER_PIXEL + EVALUATE_PER_RESTORATION * kept)
    limit = gt.memory_budget(budget)
    if need > limit:
        raise MemoryError(f"evaluating {w}x{h} pixels keeps the restorations of every profile and candidate type, "
                          f"about {need} bytes, more than the {limit} "
                          + ("of --max-memory" if budget is not None else "the machine gives") + "; evaluate a smaller copy")
    for ch in entry.charts:
        for b in ch.gray_patches + ch.region:
            if b[2] > w or b[3] > h:
                raise ManifestError(f"{entry.label}: chart {ch.name!r} box {list(b)} is outside the {w}x{h} image "
                                    "(x1 <= width, y1 <= height; pixels as displayed, after EXIF orientation)")
    distance = read_distance(entry.distance, h, w, budget) if entry.distance else None
    if distance is not None and entry.distance_depth is not None:
        import uwhl_rs

        # depth along the axis, at the photo's grid: each pixel's own ray (METHOD §13.7)
        distance = uwhl_rs.depth_to_range(distance, entry.distance_depth[0], port=entry.distance_depth[1])
    water = None
    if entry.water_mask:
        from .files import read_mask

        try:
            water = read_mask(entry.water_mask, (h, w), "water_mask", max_memory=budget)
        except ValueError as e:
            raise ManifestError(f"{entry.label}: {e}") from None
    truth_img, scored = read_truth(entry, h, w, water, budget) if entry.truth else (None, None)
    mask = None
    if mask_charts:
        mask = np.ones((h, w), bool)
        for ch in entry.charts:
            for x0, y0, x1, y1 in ch.region:
                mask[y0:y1, x0:x1] = False
        if not mask.any():
            raise ManifestError(f"{entry.label}: with --mask-charts the charts' regions cover the whole photo: "
                                "no pixel is left to estimate from")
    kwargs = {**restore_kwargs, **entry.restore, "method": method}
    if water is not None:
        kwargs["water_mask"] = water
    try:
        res = uwhl_rs.restore(img, mask=mask, **kwargs)
    except uwhl_rs.ParameterError as e:
        if not entry.restore:
            raise
        # a value only the image can check (the others were checked with the manifest): the entry is bad
        raise ManifestError(f"{entry.label}: restore: {e}") from None
    images = {"input": img, "stretch": stretch(img), "grayworld": grayworld(img), method: res.image}
    restorations = {method: res}
    steps = {method: uwhl_rs.method_steps(**kwargs)}
    for m in compare:
        other = {k: v for k, v in kwargs.items() if k not in uwhl_rs.STEP_KEYS}
        other["method"] = m
        restorations[m] = uwhl_rs.restore(img, mask=mask, **other)
        images[m] = restorations[m].image
        steps[m] = uwhl_rs.method_steps(**other)
    if distance is not None:
        # METHOD §13: the same method told the distance, beside it without
        r = uwhl_rs.restore(img, mask=mask, distance=distance, **kwargs)
        images[f"{method}+distance"] = r.image
        restorations[f"{method}+distance"] = r
        distance_use = r.distance
    else:
        distance_use = None
    types = {}
    # a custom candidate is restored alone by its (name, beta_BR, beta_BG), a table type by its name
    spec = {t[0] if isinstance(t, (tuple, list)) else t: t for t in kwargs.get("water_types") or []}
    for name in res.scores:
        one = {**kwargs, "water_types": [spec.get(name, name)], "veiling_light": tuple(res.veiling_light)}
        r = uwhl_rs.restore(img, mask=mask, **one)
        images[f"type:{name}"] = r.image
        restorations[f"type:{name}"] = r
        types[name] = {"score": float(res.scores[name]), "excluded": name in res.excluded}
    rows = []
    for m, im in images.items():
        for ch in entry.charts:
            psi, per = chart_angles(im, ch)
            rows.append({"method": m, "chart": ch.name, "psi_deg": _finite(psi),
                         "patches_deg": [_finite(a) for a in per]})
    angles = {}
    if truth_img is not None:
        for m, im in images.items():
            angles[m] = {f"{k}_deg": _finite(v) for k, v in gt.score(im, truth_img, scored).items()}
    rho = {}
    if distance is not None:
        # not for a restoration given the map: its t_B is the map's own (rho 1 by construction)
        for m, r in restorations.items():
            if not m.endswith("+distance"):
                rho[m] = _rho_pair(distance, r)
    truth = None
    profiles = {}
    for m in [method, *compare]:
        r = restorations[m]
        t = None
        if entry.water_type:
            n = type_steps(r.water_type, entry.water_type)
            t = {"true": entry.water_type, "chosen": r.water_type, "exact": r.water_type == entry.water_type,
                 "within_one": n is not None and n <= 1}
        profiles[m] = {"water_type": r.water_type, "veiling_light": [float(v) for v in r.veiling_light],
                       "steps": steps[m], "truth": t}
    if distance is not None:
        # the fit's water named and judged like a profile's choice (METHOD §13), and whether the
        # true type was among the types the fit found plausible (§13.2 step 6)
        r = restorations[f"{method}+distance"]
        t = None
        water = r.water if r.distance and r.distance.get("used") else None
        if entry.water_type and water is not None:
            n = type_steps(r.water_type, entry.water_type)
            t = {"true": entry.water_type, "chosen": r.water_type, "exact": r.water_type == entry.water_type,
                 "within_one": n is not None and n <= 1,
                 "plausible": entry.water_type in (water.get("plausible_types") or [])}
        profiles[f"{method}+distance"] = {"water_type": r.water_type,
                                          "veiling_light": [float(v) for v in r.veiling_light],
                                          "steps": steps[method], "truth": t}
    truth = profiles[method]["truth"]
    for name in types:
        types[name]["psi_deg"] = _finite(_mean([r["psi_deg"] for r in rows if r["method"] == f"type:{name}"]))
    return {
        "image": entry.label, "path": entry.path, "manifest_path": entry.manifest_path, "width": w, "height": h,
        "orientation": meta.orientation,
        "water_type": res.water_type, "veiling_light": [float(v) for v in res.veiling_light],
        "flags": list(res.flags), "charts": rows, "rho": rho, "water_type_truth": truth, "types": types,
        "distance_use": distance_use,
        "method": method, "profiles": profiles,
        "truth_pixels": None if scored is None else int(scored.sum()), "truth_angles": angles,
        "_images": images, "_transmission": res.transmission, "_distance": distance,
        "_truth": truth_img, "_truth_scored": scored,
    }


def read_truth(entry: Entry, height: int, width: int, water=None, max_memory: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The entry's true radiance, resized to the photo, and the pixels to
    score: those of its ``truth_mask`` (default: outside the water region
    ``water`` when given) where the truth is finite, not negative and
    bright enough (``uwhl_rs.truth.MIN_TRUTH_SUM``). A truth with no such
    pixel raises :class:`ManifestError`: it would measure nothing."""
    img, scored = gt.read_truth(entry.truth, height, width, max_memory)
    if entry.truth_mask:
        scored &= gt.read_truth_mask(entry.truth_mask, height, width, max_memory)
    elif water is not None:
        scored &= ~water
    scored &= img.sum(axis=2) > gt.MIN_TRUTH_SUM
    if not scored.any():
        raise ManifestError(f"{entry.truth}: no pixel of the truth can be scored (finite, not negative, at most "
                            f"{gt.MAX_TRUTH_VALUE:g}, "
                            f"R + G + B above {gt.MIN_TRUTH_SUM} in linear units where 1 is white"
                            + (", inside truth_mask" if entry.truth_mask else
                               ", outside the water region" if water is not None else "") + ")")
    return img, scored


def _median(xs) -> float:
    xs = [x for x in xs if x is not None and not (isinstance(x, float) and math.isnan(x))]
    return float(np.median(xs)) if xs else float("nan")


def _mean(xs) -> float:
    xs = [x for x in xs if x is not None and not (isinstance(x, float) and math.isnan(x))]
    return float(np.mean(xs)) if xs else float("nan")


#: What each profile is compared with, image by image, in ``summary.paired``.
PAIRED_BASELINES = ("input", "grayworld", "stretch")


def _paired(results: list[dict]) -> dict:
    """Each profile's median angle to the truth minus each baseline's, over the
    images where both were scored, with a 95% paired-bootstrap interval
    (uwhl_rs.truth.paired_medians): whether a difference would hold on other
    images of the same kind."""
    profiles = list(dict.fromkeys(m for r in results for m in r.get("profiles", {})))
    out = {}
    for m in profiles:
        for b in PAIRED_BASELINES:
            pairs = [(r["truth_angles"][m].get("median_deg"), r["truth_angles"][b].get("median_deg"))
                     for r in results if m in r.get("truth_angles", {}) and b in r.get("truth_angles", {})]
            if not pairs:
                continue
            p = gt.paired_medians([x for x, _ in pairs], [y for _, y in pairs])
            out.setdefault(m, {})[b] = {"difference_deg": _finite(p["difference"]), "low_deg": _finite(p["low"]),
                                        "high_deg": _finite(p["high"]), "better": p["better"],
                                        "worse": p["worse"], "images": p["images"]}
    return out


def summarize(results: list[dict]) -> dict:
    """Per method and baseline: the mean psi-bar over all charts, the mean
    rho over the images with a distance map, the median over the images
    with a truth of their angle statistics (``truth_median_deg``, ...), and
    (each profile) how often the true type was chosen."""
    methods: dict[str, dict] = {}

    def of(m):
        return methods.setdefault(m, {"psi": [], "rho_B": [], "rho_R": [], "truth": []})

    for r in results:
        for row in r["charts"]:
            of(row["method"])["psi"].append(row["psi_deg"])
        for m, v in r["rho"].items():
            of(m)["rho_B"].append(v["rho_B"])
            of(m)["rho_R"].append(v["rho_R"])
        for m, v in r.get("truth_angles", {}).items():
            of(m)["truth"].append(v)
    out = {}
    for m, v in methods.items():
        out[m] = {"psi_deg": _finite(_mean(v["psi"])), "charts": sum(x is not None for x in v["psi"]),
                  "rho_B": _finite(_mean(v["rho_B"])), "rho_R": _finite(_mean(v["rho_R"])),
                  "images_with_distance": sum(x is not None for x in v["rho_B"]),
                  "images_with_truth": len(v["truth"])}
        # the median over images of each image's statistic, as benches/truth.py tabulates it
        for k in TRUTH_KEYS:
            out[m][f"truth_{k}"] = _finite(_median([a.get(k) for a in v["truth"]]))
        if v["truth"]:
            out[m]["truth_median_deg_ci95"] = [_finite(x) for x in gt.median_interval(
                [a.get("median_deg") for a in v["truth"]])]
    by_method: dict[str, list] = {}
    for r in results:
        for m, p in r.get("profiles", {}).items():
            if p["truth"]:
                by_method.setdefault(m, []).append(p["truth"])
    paired = _paired(results)
    if paired:
        out["paired"] = paired
    if by_method:
        out["water_type"] = {m: {"images": len(t), "exact": sum(x["exact"] for x in t) / len(t),
                                 "within_one": sum(x["within_one"] for x in t) / len(t)}
                             for m, t in by_method.items()}
        for m, t in by_method.items():
            if all("plausible" in x for x in t):
                out["water_type"][m]["plausible"] = sum(x["plausible"] for x in t) / len(t)
    return out


def write_results(out_dir: str, manifest: str, results: list[dict], problems: list[str], parameters: dict) -> dict:
    """Writes ``results.json`` and ``results.csv`` into ``out_dir``; returns the JSON document."""
    import uwhl_rs
    from .images import atomic_write_bytes

    os.makedirs(out_dir, exist_ok=True)
    doc = {
        "uwhl_version": uwhl_rs.__version__, "manifest": os.path.abspath(manifest), "parameters": parameters,
        "problems": problems, "summary": summarize(results),
        "images": [{k: v for k, v in r.items() if not k.startswith("_")} for r in results],
    }
    text = json.dumps(doc, indent=2, allow_nan=False) + "\n"

    def put_json(tmp):
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(text)

    atomic_write_bytes(os.path.join(out_dir, "results.json"), put_json)

    def put_csv(tmp):
        with open(tmp, "w", newline="", encoding="utf-8") as f:
            # undecodable bytes of a name (lone surrogates) as U+FFFD, as results.json and the console show them
            wr = _DisplayedRows(csv.writer(f))
            # image: the entry's path as written in the manifest (to join on); label: images[K] (path)
            wr.writerow(["image", "label", "chart", "method", "psi_deg", "rho_B", "rho_R", "water_type",
                         "true_water_type", *(f"truth_{k}" for k in TRUTH_KEYS)])
            for r in results:
                key = (r["manifest_path"], r["image"])
                truth = r["water_type_truth"] or {}
                chosen = r["water_type"]
                seen = set()
                profiles = r.get("profiles", {})
                angles = r.get("truth_angles", {})

                def tail(m):
                    # a profile's own choice, the type a type:NAME row was given, none for a baseline
                    # (input, stretch, gray world: no water type), then the truth angles
                    a = angles.get(m, {})
                    wt = profiles[m]["water_type"] if m in profiles else m[5:] if m.startswith("type:") else ""
                    return [wt, truth.get("true", ""),
                            *(_fmt(a.get(k)) for k in TRUTH_KEYS)]

                for row in r["charts"]:
                    rho = r["rho"].get(row["method"], {})
                    seen.add(row["method"])
                    wr.writerow([*key, row["chart"], row["method"], _fmt(row["psi_deg"]), _fmt(rho.get("rho_B")),
                                 _fmt(rho.get("rho_R")), *tail(row["method"])])
                for m in dict.fromkeys([*r["rho"], *angles]):
                    if m not in seen:
                        rho = r["rho"].get(m, {})
                        wr.writerow([*key, "", m, "", _fmt(rho.get("rho_B")), _fmt(rho.get("rho_R")), *tail(m)])
                if not r["charts"] and not r["rho"] and not angles:
                    wr.writerow([*key, "", "", "", "", "", chosen, truth.get("true", ""), *[""] * len(TRUTH_KEYS)])

    atomic_write_bytes(os.path.join(out_dir, "results.csv"), put_csv)
    return doc


class _DisplayedRows:
    """A CSV writer whose text cells are written as :func:`printable` shows
    them, those of ``TEXT_COLUMNS`` (names from the manifest) with a
    spreadsheet formula neutralised as summary.csv does (docs/EVALUATE.md);
    the numbers, written as text too, are left as they are."""

    TEXT_COLUMNS = frozenset({0, 1, 2, 3, 7, 8})

    def __init__(self, writer):
        self._w = writer

    def writerow(self, row) -> None:
        # printable: a name's ESC or U+202E would act on the terminal that shows the file
        self._w.writerow([(_core.csv_text(printable(x)) if k in self.TEXT_COLUMNS else printable(x))
                          if isinstance(x, str) else x for k, x in enumerate(row)])


def _fmt(x) -> str:
    return "" if x is None else f"{x:.4f}"
