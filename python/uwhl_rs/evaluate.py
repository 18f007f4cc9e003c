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
from .errors import ManifestError
# the manifest's format and reader, re-exported: uwhl_rs.evaluate is where the command and tests find them
from .manifest import METHODS, TYPE_ORDER, Chart, Entry, load_manifest

__all__ = ["METHODS", "Chart", "Entry", "ManifestError", "load_manifest", "evaluate_entry", "summarize",
           "write_results", "write_report"]


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


def read_distance(path: str, height: int, width: int) -> np.ndarray:
    """A distance map in metres, resized to height x width with nearest
    neighbour; NaN where it has no value (0, NaN, negative). Float TIFF,
    16-bit PNG in millimetres, ``.npy``, or a ``.mat`` holding one 2-D array."""
    ext = os.path.splitext(path)[1].lower()
    try:
        if ext in (".tif", ".tiff"):
            import tifffile

            d = tifffile.imread(path).astype(np.float64)
        elif ext == ".png":
            from PIL import Image

            with Image.open(path) as im:
                a = np.asarray(im)
            if a.dtype != np.uint16 and im.mode not in ("I;16", "I;16B", "I"):
                raise ManifestError(f"{path}: a PNG distance map is 16-bit, in millimetres (this one is {im.mode})")
            d = a.astype(np.float64) / 1000.0
        elif ext == ".npy":
            d = np.load(path, allow_pickle=False).astype(np.float64)
        elif ext == ".mat":
            try:
                from scipy.io import loadmat
            except ImportError:
                raise ManifestError(f"{path}: reading .mat distance maps needs scipy (pip install scipy)") from None
            m = loadmat(path)
            arrays = [v for k, v in m.items() if not k.startswith("__") and isinstance(v, np.ndarray)
                      and v.ndim == 2 and v.dtype.kind in "iuf" and min(v.shape) > 1]
            if len(arrays) != 1:
                raise ManifestError(f"{path}: a .mat distance file holds exactly one 2-D numeric array "
                                    f"(found {len(arrays)})")
            d = arrays[0].astype(np.float64)
        else:
            raise ManifestError(f"{path}: distance maps are .tif, .png (16-bit mm), .npy or .mat, not {ext or 'none'}")
    except ManifestError:
        raise
    except Exception as e:
        raise ManifestError(f"{path}: cannot read the distance map ({type(e).__name__}: {e})") from None
    if d.ndim == 3 and d.shape[2] == 1:
        d = d[:, :, 0]
    if d.ndim != 2 or d.size == 0:
        raise ManifestError(f"{path}: a distance map is one 2-D array, not shape {d.shape}")
    d = np.where(np.isfinite(d) & (d > 0), d, np.nan)
    rows = (np.arange(height) * d.shape[0]) // height
    cols = (np.arange(width) * d.shape[1]) // width
    return d[rows][:, cols]


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
    for ch in entry.charts:
        for b in ch.gray_patches + ch.region:
            if b[2] > w or b[3] > h:
                raise ManifestError(f"{entry.label}: chart {ch.name!r} box {list(b)} is outside the {w}x{h} image "
                                    "(x1 <= width, y1 <= height; pixels as displayed, after EXIF orientation)")
    distance = read_distance(entry.distance, h, w) if entry.distance else None
    mask = None
    if mask_charts:
        mask = np.ones((h, w), bool)
        for ch in entry.charts:
            for x0, y0, x1, y1 in ch.region:
                mask[y0:y1, x0:x1] = False
    kwargs = {**restore_kwargs, **entry.restore, "method": method}
    if entry.water_mask:
        from .files import read_mask

        try:
            kwargs["water_mask"] = read_mask(entry.water_mask, (h, w), "water_mask")
        except ValueError as e:
            raise ManifestError(f"{entry.label}: {e}") from None
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
    rho = {}
    if distance is not None:
        for m, r in restorations.items():
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
    truth = profiles[method]["truth"]
    for name in types:
        types[name]["psi_deg"] = _finite(_mean([r["psi_deg"] for r in rows if r["method"] == f"type:{name}"]))
    return {
        "image": entry.label, "path": entry.path, "manifest_path": entry.manifest_path, "width": w, "height": h,
        "orientation": meta.orientation,
        "water_type": res.water_type, "veiling_light": [float(v) for v in res.veiling_light],
        "flags": list(res.flags), "charts": rows, "rho": rho, "water_type_truth": truth, "types": types,
        "method": method, "profiles": profiles,
        "_images": images, "_transmission": res.transmission, "_distance": distance,
    }


def _mean(xs) -> float:
    xs = [x for x in xs if x is not None and not (isinstance(x, float) and math.isnan(x))]
    return float(np.mean(xs)) if xs else float("nan")


def summarize(results: list[dict]) -> dict:
    """Per method and baseline: the mean psi-bar over all charts, the mean
    rho over the images with a distance map, and (the method) how often
    the true type was chosen."""
    methods: dict[str, dict] = {}
    for r in results:
        for row in r["charts"]:
            methods.setdefault(row["method"], {"psi": [], "rho_B": [], "rho_R": []})["psi"].append(row["psi_deg"])
        for m, v in r["rho"].items():
            s = methods.setdefault(m, {"psi": [], "rho_B": [], "rho_R": []})
            s["rho_B"].append(v["rho_B"])
            s["rho_R"].append(v["rho_R"])
    out = {m: {"psi_deg": _finite(_mean(v["psi"])), "charts": sum(x is not None for x in v["psi"]),
               "rho_B": _finite(_mean(v["rho_B"])), "rho_R": _finite(_mean(v["rho_R"])),
               "images_with_distance": sum(x is not None for x in v["rho_B"])} for m, v in methods.items()}
    by_method: dict[str, list] = {}
    for r in results:
        for m, p in r.get("profiles", {}).items():
            if p["truth"]:
                by_method.setdefault(m, []).append(p["truth"])
    if by_method:
        out["water_type"] = {m: {"images": len(t), "exact": sum(x["exact"] for x in t) / len(t),
                                 "within_one": sum(x["within_one"] for x in t) / len(t)}
                             for m, t in by_method.items()}
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
            wr = csv.writer(f)
            # image: the entry's path as written in the manifest (to join on); label: images[K] (path)
            wr.writerow(["image", "label", "chart", "method", "psi_deg", "rho_B", "rho_R", "water_type",
                         "true_water_type"])
            for r in results:
                key = (r["manifest_path"], r["image"])
                truth = r["water_type_truth"] or {}
                chosen = r["water_type"]
                seen = set()
                profiles = r.get("profiles", {})

                def chosen_by(m):
                    # a profile's own choice; baselines and type:NAME rows show the method's
                    return profiles[m]["water_type"] if m in profiles else chosen

                for row in r["charts"]:
                    rho = r["rho"].get(row["method"], {})
                    seen.add(row["method"])
                    wr.writerow([*key, row["chart"], row["method"], _fmt(row["psi_deg"]), _fmt(rho.get("rho_B")),
                                 _fmt(rho.get("rho_R")), chosen_by(row["method"]), truth.get("true", "")])
                for m, rho in r["rho"].items():
                    if m not in seen:
                        wr.writerow([*key, "", m, "", _fmt(rho["rho_B"]), _fmt(rho["rho_R"]), chosen_by(m),
                                     truth.get("true", "")])
                if not r["charts"] and not r["rho"]:
                    wr.writerow([*key, "", "", "", "", "", chosen, truth.get("true", "")])

    atomic_write_bytes(os.path.join(out_dir, "results.csv"), put_csv)
    return doc


def _fmt(x) -> str:
    return "" if x is None else f"{x:.4f}"


# ------------------------------------------------------------------- report


def _png_data_uri(img: np.ndarray, max_side: int = 480) -> str:
    """An sRGB PNG data URI of a linear HxWx3 image or an 8-bit one, shrunk to max_side."""
    import base64

    from .images import quantize

    h, w = img.shape[:2]
    s = max(1, math.ceil(max(h, w) / max_side))
    small = img[::s, ::s]
    if small.dtype != np.uint8:
        small = quantize(small, 8, encoding="linear")
    return "data:image/png;base64," + base64.b64encode(_core._encode_png(np.ascontiguousarray(small))).decode()


def _map_uri(v: np.ndarray, max_side: int = 480) -> str:
    """A data URI of a scalar map through the colour map (NaN: black), scaled to its 1%-99% range."""
    ok = np.isfinite(v)
    lo, hi = (np.percentile(v[ok], [1, 99]) if ok.any() else (0.0, 1.0))
    t = np.clip((np.nan_to_num(v, nan=lo) - lo) / max(hi - lo, 1e-12), 0, 1).astype(np.float32)
    rgb = _core._colormap(np.ascontiguousarray(t))
    rgb[~ok] = 0
    return _png_data_uri(rgb, max_side)


def _esc(x) -> str:
    import html

    return html.escape(str(x))


def _bars(rows: list[dict], methods: list[str]) -> str:
    """An SVG bar chart of psi-bar per chart (groups) and method (bars), as the paper's Fig. 9."""
    charts = list(dict.fromkeys(r["chart"] for r in rows))
    colors = ["#888", "#d95f02", "#7570b3", "#1b9e77", "#e7298a"]
    top = max([r["psi_deg"] or 0 for r in rows if r["method"] in methods] + [10])
    bw, gap, H = 18, 24, 160
    width = 40 + len(charts) * (len(methods) * bw + gap)
    out = [f'<svg class="bars" width="{width}" height="{H + 40}" role="img">']
    for i, ch in enumerate(charts):
        x0 = 40 + i * (len(methods) * bw + gap)
        for j, m in enumerate(methods):
            v = next((r["psi_deg"] for r in rows if r["chart"] == ch and r["method"] == m), None)
            if v is None:
                continue
            bh = H * v / top
            out.append(f'<rect x="{x0 + j * bw}" y="{H - bh + 10:.1f}" width="{bw - 2}" height="{bh:.1f}" '
                       f'fill="{colors[j % len(colors)]}"><title>{_esc(ch)} {_esc(m)}: {v:.1f} deg</title></rect>')
        out.append(f'<text x="{x0}" y="{H + 28}" font-size="11">{_esc(ch)}</text>')
    out.append(f'<text x="0" y="20" font-size="11">{top:.0f}&#176;</text><text x="0" y="{H + 10}" '
               'font-size="11">0</text></svg>')
    legend = " ".join(f'<span style="color:{colors[j % len(colors)]}">&#9632; {_esc(m)}</span>'
                      for j, m in enumerate(methods))
    return "".join(out) + f'<div class="legend">{legend}</div>'


def _scatter(distance: np.ndarray, t: np.ndarray, rho) -> str:
    """An SVG scatter of -ln t_B against the distance (at most 1500 points)."""
    ok = np.isfinite(distance)
    d = distance[ok]
    y = -np.log(np.clip(t[ok].astype(np.float64), 1e-12, 1))
    if d.size == 0:
        return ""
    step = max(1, d.size // 1500)
    d, y = d[::step], y[::step]
    W, H = 320, 220
    dx, dy = max(float(d.max() - d.min()), 1e-9), max(float(y.max() - y.min()), 1e-9)
    pts = "".join(f'<circle cx="{30 + (a - d.min()) / dx * (W - 40):.1f}" cy="{H - 20 - (b - y.min()) / dy * (H - 40):.1f}" '
                  'r="1.5"/>' for a, b in zip(d, y))
    label = f"rho = {rho:.3f}" if rho is not None else "rho: -"
    return (f'<svg class="scatter" width="{W}" height="{H}" role="img"><g fill="#1b9e77">{pts}</g>'
            f'<text x="30" y="14" font-size="11">-ln t_B against distance (m), {label}</text></svg>')


def _boxes_svg(entry_charts: list[Chart], w: int, h: int, uri: str) -> str:
    """The input with the chart regions (blue) and gray patches (orange) drawn on it."""
    s = min(1.0, 480 / max(w, h))
    rects = []
    for ch in entry_charts:
        for x0, y0, x1, y1 in ch.region:
            rects.append(f'<rect x="{x0 * s:.1f}" y="{y0 * s:.1f}" width="{(x1 - x0) * s:.1f}" '
                         f'height="{(y1 - y0) * s:.1f}" fill="none" stroke="#39f" stroke-width="2"/>')
        for x0, y0, x1, y1 in ch.gray_patches:
            rects.append(f'<rect x="{x0 * s:.1f}" y="{y0 * s:.1f}" width="{(x1 - x0) * s:.1f}" '
                         f'height="{(y1 - y0) * s:.1f}" fill="none" stroke="#f90" stroke-width="2"/>')
    return (f'<svg class="input" width="{w * s:.0f}" height="{h * s:.0f}" role="img">'
            f'<image href="{uri}" width="{w * s:.0f}" height="{h * s:.0f}"/>{"".join(rects)}</svg>')


def write_report(out_dir: str, doc: dict, results: list[dict], entries: list[Entry], method: str,
                 compare=()) -> str:
    """Writes ``report.html``: one self-contained page (images inline, no
    network) with the summary table and, per image, the input with its
    chart boxes, the restored image, t_B, the distance map, the psi-bar bars,
    the -ln t_B scatter and the candidate types."""
    from .images import atomic_write_bytes

    by_label = {e.label: e for e in entries}
    methods = ["input", "stretch", "grayworld", method, *[m for m in compare if m != method]]
    parts = ['<!doctype html><html><head><meta charset="utf-8"><title>uwhl evaluate</title><style>'
             'body{font:13px sans-serif;margin:16px}table{border-collapse:collapse}td,th{border:1px solid #ccc;'
             'padding:2px 6px;text-align:right}th{background:#eee}.row{display:flex;gap:8px;flex-wrap:wrap;'
             'align-items:flex-start}figure{margin:0}figcaption{font-size:11px;color:#555}'
             'section{border-top:2px solid #444;margin-top:18px;padding-top:6px}'
             '.sheet figure.chosen img{outline:3px solid #2a2}</style></head><body>',
             f'<h1>uwhl evaluate</h1><p>{_esc(doc["manifest"])} &middot; uwhl_rs {_esc(doc["uwhl_version"])} '
             f'&middot; method {_esc(method)}</p>']
    if doc["problems"]:
        parts.append("<h2>Problems</h2><ul>" + "".join(f"<li>{_esc(p)}</li>" for p in doc["problems"]) + "</ul>")
    summ = doc["summary"]
    parts.append('<h2>Summary</h2><table id="summary"><tr><th>method</th><th>mean psi-bar (deg)</th><th>charts</th>'
                 '<th>mean rho (t_B)</th><th>mean rho (t_R)</th><th>images with distance</th></tr>')
    for m, v in summ.items():
        if m == "water_type":
            continue
        parts.append(f"<tr><td>{_esc(m)}</td><td>{_fmt(v['psi_deg'])}</td><td>{v['charts']}</td>"
                     f"<td>{_fmt(v['rho_B'])}</td><td>{_fmt(v['rho_R'])}</td><td>{v['images_with_distance']}</td></tr>")
    parts.append("</table>")
    for m, wt in summ.get("water_type", {}).items():
        parts.append(f'<p class="water-type">Water type ({_esc(m)}): {wt["exact"]:.0%} exact, '
                     f'{wt["within_one"]:.0%} within one step ({wt["images"]} images with a true type).</p>')
    for r in results:
        e = by_label[r["image"]]
        imgs = r["_images"]
        parts.append(f'<section class="image"><h2>{_esc(r["image"])}</h2><p>chosen {_esc(r["water_type"])}'
                     + (f', true {_esc(r["water_type_truth"]["true"])}' if r["water_type_truth"] else "")
                     + f', A = {", ".join(f"{v:.3f}" for v in r["veiling_light"])}</p><div class="row">')
        parts.append(f"<figure>{_boxes_svg(e.charts, r['width'], r['height'], _png_data_uri(imgs['input']))}"
                     "<figcaption>input, charts (blue) and gray patches (orange)</figcaption></figure>")
        for m in methods[3:]:
            if m in imgs:
                p = r.get("profiles", {}).get(m, {})
                parts.append(f'<figure><img src="{_png_data_uri(imgs[m])}"><figcaption>restored ({_esc(m)}, '
                             f'{_esc(p.get("water_type", ""))})</figcaption></figure>')
        parts.append(f'<figure><img src="{_map_uri(r["_transmission"])}"><figcaption>t_B</figcaption></figure>')
        if r["_distance"] is not None:
            parts.append(f'<figure><img src="{_map_uri(r["_distance"])}"><figcaption>distance</figcaption></figure>')
        parts.append("</div><div class='row'>")
        if r["charts"]:
            parts.append(f"<figure>{_bars(r['charts'], methods)}<figcaption>psi-bar per chart</figcaption></figure>")
        if r["_distance"] is not None:
            rho = r["rho"].get(r["method"], {}).get("rho_B")
            parts.append(f"<figure>{_scatter(r['_distance'], r['_transmission'], rho)}</figure>")
        parts.append("</div><table class='types'><tr><th>type</th><th>score</th><th>excluded</th>"
                     "<th>psi-bar (deg)</th><th>rho (t_B)</th></tr>")
        for name, t in r["types"].items():
            rho = r["rho"].get(f"type:{name}", {}).get("rho_B")
            mark = " &#10003;" if name == r["water_type"] else ""
            parts.append(f"<tr><td>{_esc(name)}{mark}</td><td>{t['score']:.4f}</td><td>{'yes' if t['excluded'] else ''}"
                         f"</td><td>{_fmt(t['psi_deg'])}</td><td>{_fmt(rho)}</td></tr>")
        parts.append("</table>")
        # the contact sheet: every candidate type restored with the method's A
        sheet = [f'<figure class="type{" chosen" if name == r["water_type"] else ""}">'
                 f'<img src="{_png_data_uri(imgs[f"type:{name}"], 200)}"><figcaption>{_esc(name)}'
                 f'{" &#10003;" if name == r["water_type"] else ""} {t["score"]:.3f}</figcaption></figure>'
                 for name, t in r["types"].items() if f"type:{name}" in imgs]
        if sheet:
            parts.append('<div class="row sheet">' + "".join(sheet) + "</div>")
        parts.append("</section>")
    parts.append("</body></html>\n")
    page = "".join(parts)

    def put(tmp):
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(page)

    path = os.path.join(out_dir, "report.html")
    atomic_write_bytes(path, put)
    return path
