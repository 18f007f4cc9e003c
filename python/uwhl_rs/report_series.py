"""The sequence panels of ``uwhl report`` (docs/REPORT.md "Over the
sequence"): the x axis of a batch (EXIF time or frame index) and the SVG
of its water type, A, the choice's score and, where photos had a distance,
the blue attenuation fitted from it with its plausible range."""

from __future__ import annotations

import html
from typing import NamedTuple

import numpy as np

from . import _core
from .outdir import Photo
from .sidecars import printable

__all__ = ["Axis", "fitted_blue", "series_axis", "series_svg", "used_water"]


def _taken(p: Photo):
    """When the photo was taken (its EXIF, through the sidecar), or None."""
    from datetime import datetime

    t = ((p.doc.get("metadata") or {}).get("taken_at"))
    try:
        return datetime.fromisoformat(t) if t else None
    except ValueError:
        return None


class Axis(NamedTuple):
    """The x axis of the sequence (:func:`series_axis`)."""

    #: the photos in axis order
    photos: list
    #: their x: seconds from the first photo, or the frame index
    xs: list
    #: the labels at the two ends
    first: str
    last: str
    #: whether the axis is EXIF time (else the frame index)
    by_time: bool


def series_axis(photos: list[Photo]) -> Axis:
    """The x axis of the sequence: EXIF time when every photo has one (in
    time order, seconds from the first), else the frame index (name order)."""
    times = [_taken(p) for p in photos]
    if photos and all(t is not None for t in times) and len({t.tzinfo is None for t in times}) == 1:
        order = sorted(range(len(photos)), key=lambda k: times[k])
        t0 = times[order[0]]
        xs = [(times[k] - t0).total_seconds() for k in order]
        label = [p.doc["metadata"]["taken_at"] for p in photos]  # as the EXIF says it
        return Axis([photos[k] for k in order], xs, f"EXIF time {label[order[0]]}",
                    f"{label[order[-1]]} (+{xs[-1]:.0f} s)", True)
    return Axis(photos, [float(k) for k in range(len(photos))], "frame 1", f"frame {len(photos)}", False)


def used_water(doc) -> dict | None:
    """The water a photo's distance fit gave (the sidecar's
    ``distance.water``) when its distance was used; None otherwise or when
    the record is not what OUTPUTS.md says."""
    d = doc.get("distance") if isinstance(doc, dict) else None
    w = d.get("water") if isinstance(d, dict) and d.get("used") is True else None
    return w if isinstance(w, dict) else None


def fitted_blue(doc) -> tuple[float, float, float] | None:
    """The blue attenuation a photo's distance fit gave and its plausible
    range (the sidecar's ``distance.water.beta[2]`` and ``beta_range[2]``,
    METHOD §13.2 step 6), when the distance was used and the numbers are
    what a fit writes (lo <= beta <= hi on the fit's attenuation grid,
    ``_core.FIT_BETA_GRID``); else None."""
    w = used_water(doc)
    try:
        b = float(w["beta"][2])
        lo, hi = (float(v) for v in w["beta_range"][2])
    except (TypeError, KeyError, IndexError, ValueError):
        return None
    g0, g1 = _core.FIT_BETA_GRID
    ok = all(np.isfinite(v) for v in (b, lo, hi)) and g0 * (1 - 1e-9) <= lo <= b <= hi <= g1 * (1 + 1e-9)
    return (b, lo, hi) if ok else None


def series_svg(axis: Axis, types: list[str]) -> str:
    """Water type (steps), A (R, G, B) and the chosen type's score over the
    sequence's ``axis``: three stacked panels sharing the x axis, and a
    fourth when photos had their water fitted from a distance: the fitted
    blue attenuation, each with a bar over its plausible range (log scale)."""
    photos, tx, first, last, _ = axis
    W, H, left = 900, 140, 48
    blue = [fitted_blue(p.doc) for p in photos]
    panels = 4 if any(blue) else 3
    span = max(tx) - min(tx) if tx and max(tx) > min(tx) else 1.0
    xs = [left + (W - left - 10) * ((t - tx[0]) / span) for t in tx]

    def poly(vals, lo, hi, y0, color, width=1.4):
        pts = " ".join(f"{x:.1f},{y0 + H - 8 - (H - 30) * ((v - lo) / (hi - lo) if hi > lo else 0.5):.1f}"
                       for x, v in zip(xs, vals) if v is not None and np.isfinite(v))
        return f'<polyline fill="none" stroke="{color}" stroke-width="{width}" points="{pts}"/>'

    out = [f'<svg class="series" width="{W}" height="{panels * H + 40}" role="img" aria-label="over the sequence">']
    idx = {t: k for k, t in enumerate(types)}
    wt = [idx.get(p.doc.get("water_type"), None) for p in photos]
    out.append(f'<text x="{left}" y="12" class="lab">water type</text>')
    for k, t in enumerate(types):
        y = H - 8 - (H - 30) * (k / max(1, len(types) - 1))
        out.append(f'<text x="{left - 6}" y="{y + 4:.1f}" text-anchor="end" class="tick">{html.escape(printable(t))}</text>')
    out.append(poly(wt, 0, max(1, len(types) - 1), 0, "#333", 1.2))
    a = np.array([p.doc.get("veiling_light") or [np.nan] * 3 for p in photos], dtype=float).reshape(-1, 3)
    hi = float(np.nanmax(a)) if np.isfinite(a).any() else 1.0
    out.append(f'<text x="{left}" y="{H + 12}" class="lab">A (R, G, B), 0 to {hi:.3f}</text>')
    for c, color in enumerate(("#d62728", "#2ca02c", "#1f77b4")):
        out.append(poly(list(a[:, c]), 0.0, hi, H, color))
    sc = [(p.doc.get("scores") or {}).get(p.doc.get("water_type")) for p in photos]
    sv = [v for v in sc if v is not None and np.isfinite(v)]
    scale = f", {min(sv):.3f} to {max(sv):.3f}" if sv else ""
    out.append(f'<text x="{left}" y="{2 * H + 12}" class="lab">score of the chosen type (lower is better){scale}</text>')
    if sv:
        out.append(poly(sc, min(sv), max(sv), 2 * H, "#9467bd"))
    if panels == 4:
        lo = min(v[1] for v in blue if v)
        hi = max(v[2] for v in blue if v)
        llo, lhi = np.log10(lo), np.log10(hi) if hi > lo else np.log10(lo) + 1
        out.append(f'<text x="{left}" y="{3 * H + 12}" class="lab">blue attenuation fitted from the distance, '
                   f'1/m ({lo:.3g} to {hi:.3g}, log scale; bars: its plausible range)</text>')

        def y(v):
            return 3 * H + H - 8 - (H - 30) * ((np.log10(v) - llo) / (lhi - llo))

        for x, v in zip(xs, blue):
            if v:
                out.append(f'<line x1="{x:.1f}" x2="{x:.1f}" y1="{y(v[1]):.1f}" y2="{y(v[2]):.1f}" '
                           'stroke="#9ecae1" stroke-width="3"/>')
        out.append(poly([np.log10(v[0]) if v else None for v in blue], llo, lhi, 3 * H, "#08519c"))
    out.append(f'<text x="{left}" y="{panels * H + 30}" class="tick">{html.escape(printable(first))}</text>'
               f'<text x="{W - 10}" y="{panels * H + 30}" text-anchor="end" class="tick">{html.escape(printable(last))}</text>')
    out.append("</svg>")
    return "".join(out)
