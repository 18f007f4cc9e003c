"""The HTML page of ``uwhl evaluate`` (docs/EVALUATE.md "What it writes"):
one self-contained file, images inline, no network. The numbers come from
``uwhl_rs.evaluate``; this module only draws them."""

from __future__ import annotations

import math
import os

import numpy as np

from . import _core
from .manifest import Chart, Entry
from .sidecars import printable
from .truth import pixel_angles

__all__ = ["write_report"]


#: The statistics of an image's angles to its truth, as ``uwhl_rs.evaluate`` records them.
TRUTH_KEYS = ("median_deg", "p90_deg", "gain_median_deg", "gain_p90_deg")
#: Keys of ``summary`` that are not a method or baseline.
SUMMARY_EXTRAS = ("water_type", "paired")


def _fmt(x) -> str:
    return "" if x is None else f"{x:.4f}"


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


def _map_uri(v: np.ndarray, max_side: int = 480, scale=None) -> str:
    """A data URI of a scalar map through the colour map (NaN: black), scaled
    to ``scale`` (lo, hi) or else to its 1%-99% range."""
    ok = np.isfinite(v)
    lo, hi = scale or (np.percentile(v[ok], [1, 99]) if ok.any() else (0.0, 1.0))
    t = np.clip((np.nan_to_num(v, nan=lo) - lo) / max(hi - lo, 1e-12), 0, 1).astype(np.float32)
    rgb = _core._colormap(np.ascontiguousarray(t))
    rgb[~ok] = 0
    return _png_data_uri(rgb, max_side)


def _truth_figures(r: dict) -> str:
    """The true radiance (magenta where it is not scored: no scene has that hue over a region) and the
    method's per-pixel angle to it (0 to 30 degrees; black where not scored)."""
    scored = r["_truth_scored"]
    shown = np.where(scored[:, :, None], np.clip(r["_truth"], 0, 1), np.array([1.0, 0.0, 1.0])).astype(np.float32)
    ang = np.full(scored.shape, np.nan)
    ang[scored] = pixel_angles(r["_images"][r["method"]], r["_truth"], scored)
    return (f'<figure><img src="{_png_data_uri(shown)}"><figcaption>truth (magenta: not scored)</figcaption></figure>'
            f'<figure><img src="{_map_uri(ang, scale=(0.0, 30.0))}"><figcaption>angle to the truth '
            f'({_esc(r["method"])}), 0 to 30&#176;</figcaption></figure>')


def _truth_table(r: dict, methods: list[str]) -> str:
    """The angles to the truth of the method, the other profiles and the baselines."""
    rows = ["<table class='truth'><tr><th>angle to truth (deg)</th><th>median</th><th>p90</th>"
            "<th>after best gains, median</th><th>p90</th></tr>"]
    for m in methods:
        a = r["truth_angles"].get(m)
        if a is not None:
            rows.append(f"<tr><td>{_esc(m)}</td>" + "".join(f"<td>{_fmt(a.get(k))}</td>" for k in TRUTH_KEYS)
                        + "</tr>")
    rows.append(f"</table><p>{r['truth_pixels']} pixels scored</p>")
    return "<figure>" + "".join(rows) + "</figure>"


def _esc(x) -> str:
    """``x`` as the page's text: as the console shows it (undecodable bytes
    as U+FFFD, control and bidirectional characters as visible escapes, so
    a name cannot reorder the line it is in), then HTML-escaped."""
    import html

    return html.escape(printable(str(x)))


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


def report_methods(method: str, compare=()) -> list[str]:
    """The columns of the report: the baselines, then ``method``, then the
    other profiles of ``compare``."""
    return ["input", "stretch", "grayworld", method, *[m for m in compare if m != method]]


def image_section(r: dict, e: Entry, methods: list[str]) -> str:
    """The report's section of one evaluated image ``r`` (of
    :func:`uwhl_rs.evaluate.evaluate_entry`, entry ``e``): its thumbnails,
    maps, bars and tables. Made as soon as the image is evaluated, so that
    its full-size images need not be kept until the page is written."""
    parts: list[str] = []
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
    if r.get("_truth") is not None:
        parts.append(_truth_figures(r))
    parts.append("</div><div class='row'>")
    if r["charts"]:
        parts.append(f"<figure>{_bars(r['charts'], methods)}<figcaption>psi-bar per chart</figcaption></figure>")
    if r["_distance"] is not None:
        rho = r["rho"].get(r["method"], {}).get("rho_B")
        parts.append(f"<figure>{_scatter(r['_distance'], r['_transmission'], rho)}</figure>")
    if r.get("truth_angles"):
        parts.append(_truth_table(r, methods))
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
    return "".join(parts)


def write_report(out_dir: str, doc: dict, results: list[dict], entries: list[Entry], method: str,
                 compare=(), sections: dict[str, str] | None = None) -> str:
    """Writes ``report.html``: one self-contained page (images inline, no
    network) with the summary table and, per image, the input with its
    chart boxes, the restored image, t_B, the distance map, the psi-bar bars,
    the -ln t_B scatter and the candidate types. ``sections``: each
    image's section made already (:func:`image_section`), by its label;
    the others are made here from the results' images."""
    from .images import atomic_write_bytes

    by_label = {e.label: e for e in entries}
    methods = report_methods(method, compare)
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
    with_truth = any(v.get("images_with_truth") for m, v in summ.items() if m not in SUMMARY_EXTRAS)
    truth_heads = ("<th>angle to truth, median (deg)</th><th>p90</th><th>after best gains, median</th>"
                   "<th>p90</th><th>images with truth</th>") if with_truth else ""
    parts.append('<h2>Summary</h2><table id="summary"><tr><th>method</th><th>mean psi-bar (deg)</th><th>charts</th>'
                 f'<th>mean rho (t_B)</th><th>mean rho (t_R)</th><th>images with distance</th>{truth_heads}</tr>')
    for m, v in summ.items():
        if m in SUMMARY_EXTRAS:
            continue
        cells = ("".join(f"<td>{_fmt(v.get(f'truth_{k}'))}</td>" for k in TRUTH_KEYS)
                 + f"<td>{v.get('images_with_truth', 0)}</td>") if with_truth else ""
        parts.append(f"<tr><td>{_esc(m)}</td><td>{_fmt(v['psi_deg'])}</td><td>{v['charts']}</td>"
                     f"<td>{_fmt(v['rho_B'])}</td><td>{_fmt(v['rho_R'])}</td><td>{v['images_with_distance']}</td>"
                     f"{cells}</tr>")
    parts.append("</table>")
    if with_truth:
        parts.append("<p>Angles to the truth: per image, the median and 90th percentile of the per-pixel angle "
                     "between the output and the true radiance over the scored pixels, raw and after the best "
                     "global per-channel gains; here the median over the images.</p>")
    paired = summ.get("paired", {})
    if paired:
        parts.append('<h2>Each profile against the baselines</h2><table id="paired"><tr><th>profile</th>'
                     '<th>baseline</th><th>difference of median angles (deg)</th><th>95% interval</th>'
                     '<th>images better</th><th>worse</th><th>of</th></tr>')
        for m, against in paired.items():
            for b, p in against.items():
                parts.append(f"<tr><td>{_esc(m)}</td><td>{_esc(b)}</td><td>{_fmt(p['difference_deg'])}</td>"
                             f"<td>{_fmt(p['low_deg'])} to {_fmt(p['high_deg'])}</td><td>{p['better']}</td>"
                             f"<td>{p['worse']}</td><td>{p['images']}</td></tr>")
        parts.append("</table><p>The profile's median angle to the truth minus the baseline's, over the images "
                     "both were scored on; the interval is a paired bootstrap over those images (an interval "
                     "that holds 0: the difference could go either way on other images of the same kind).</p>")
    for m, wt in summ.get("water_type", {}).items():
        parts.append(f'<p class="water-type">Water type ({_esc(m)}): {wt["exact"]:.0%} exact, '
                     f'{wt["within_one"]:.0%} within one step'
                     + (f', the true one plausible in {wt["plausible"]:.0%}' if "plausible" in wt else "")
                     + f' ({wt["images"]} images with a true type).</p>')
    for r in results:
        parts.append(sections[r["image"]] if sections and r["image"] in sections
                     else image_section(r, by_label[r["image"]], methods))
    parts.append("</body></html>\n")
    page = "".join(parts)

    def put(tmp):
        with open(tmp, "w", encoding="utf-8") as f:
            f.write(page)

    path = os.path.join(out_dir, "report.html")
    atomic_write_bytes(path, put)
    return path
