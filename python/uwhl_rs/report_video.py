"""The videos of ``uwhl report`` (docs/REPORT.md "Videos"): each video of
the folder as its strip of frames (input above, restored below, written
by the restoration), its water type and veiling light over time, and the
estimates' events; a video that stopped part way, or whose frames were
flagged, is listed under "needs a look".

Every value comes from a checked sidecar (``uwhl_rs.sidecars``) and is
escaped as text; the strip is a bare file name beside its sidecar.
"""

from __future__ import annotations

import html
import math

import numpy as np

from .outdir import Photo
from .sidecars import printable

__all__ = ["is_video", "needs_a_look", "videos_html"]


def is_video(p: Photo) -> bool:
    """Whether ``p``'s sidecar is a video's."""
    return p.doc.get("kind") == "video" and isinstance(p.doc.get("video"), dict)


def needs_a_look(p: Photo) -> list[str]:
    """Why a video needs a look: its flags (``video_truncated``, a flag of
    most of its frames)."""
    return list(p.flags)


def _series_svg(p: Photo, types: list[str]) -> str:
    """Water type and A (R, G, B) over the video's time (or frames): steps
    from one estimate to the next."""
    v = p.doc["video"]
    # a sidecar is untrusted: its estimates drawn in frame order, its times only when they make an axis
    ev = sorted(v.get("estimates") or [], key=lambda e: e["frame"])
    if not ev:
        return ""
    frames = v.get("frames") or {}
    rate = _rate(p)
    end_frame = max(int(frames.get("decoded") or 0), ev[-1]["frame"] + 1)
    times = [e.get("time") for e in ev]
    by_time = rate is not None and all(t is not None and 0 <= t <= _MAX_SECONDS for t in times) \
        and all(b >= a for a, b in zip(times, times[1:])) and end_frame / rate >= times[-1]
    xs = [float(e["time"]) if by_time else float(e["frame"]) for e in ev]
    x_end = end_frame / rate if by_time else float(end_frame)
    if not all(math.isfinite(x) for x in (*xs, x_end)):
        return ""  # numbers no browser draws: no series rather than a broken one
    W, H, left = 900, 110, 48
    span = max(x_end - min(xs), 1e-9)

    def sx(x):
        return left + (W - left - 10) * (x - xs[0]) / span

    def steps(vals, lo, hi, y0, color):
        pts = []
        for k, (x, val) in enumerate(zip(xs, vals)):
            nxt = xs[k + 1] if k + 1 < len(xs) else x_end
            y = y0 + H - 8 - (H - 30) * ((val - lo) / (hi - lo) if hi > lo else 0.5)
            pts += [f"{sx(x):.1f},{y:.1f}", f"{sx(nxt):.1f},{y:.1f}"]
        return f'<polyline fill="none" stroke="{color}" stroke-width="1.4" points="{" ".join(pts)}"/>'

    idx = {t: k for k, t in enumerate(types)}
    out = [f'<svg class="series" width="{W}" height="{2 * H + 40}" role="img" aria-label="over the video">',
           f'<text x="{left}" y="12" class="lab">water type</text>']
    for k, t in enumerate(types):
        y = H - 8 - (H - 30) * (k / max(1, len(types) - 1))
        out.append(f'<text x="{left - 6}" y="{y + 4:.1f}" text-anchor="end" class="tick">{html.escape(printable(t))}</text>')
    out.append(steps([idx.get(e["water_type"], 0) for e in ev], 0, max(1, len(types) - 1), 0, "#333"))
    a = np.clip(np.array([e["veiling_light"] for e in ev], dtype=float), 0.0, None)
    hi = float(a.max()) if a.size else 1.0
    if not math.isfinite(hi):
        return ""
    out.append(f'<text x="{left}" y="{H + 12}" class="lab">A (R, G, B), 0 to {hi:.3f}</text>')
    for c, color in enumerate(("#d62728", "#2ca02c", "#1f77b4")):
        out.append(steps(list(a[:, c]), 0.0, hi, H, color))
    for e, x in zip(ev, xs):
        if e["event"] in ("cut", "drift"):
            out.append(f'<line x1="{sx(x):.1f}" x2="{sx(x):.1f}" y1="16" y2="{2 * H}" stroke="#d95f02" '
                       f'stroke-dasharray="3,3"><title>{html.escape(printable(e["event"]))} at frame {e["frame"]}</title></line>')
    unit = "s" if by_time else "frame"
    out.append(f'<text x="{left}" y="{2 * H + 30}" class="tick">0 {unit}</text>'
               f'<text x="{W - 10}" y="{2 * H + 30}" text-anchor="end" class="tick">{x_end:.1f} {unit}</text></svg>')
    return "".join(out)


#: the longest video time drawn (seconds: a year); beyond, the series is by frame
_MAX_SECONDS = 3.2e7


def _rate(p: Photo) -> float | None:
    """The stream's rate when it is one a video has (0.001 to 1000 frames a second), else None."""
    rate = (p.doc["video"].get("stream") or {}).get("rate")
    return float(rate) if isinstance(rate, (int, float)) and 1e-3 <= rate <= 1000 else None


def videos_html(videos: list[Photo], types: list[str], rel_url) -> str:
    """The page's section of the videos (empty without any)."""
    if not videos:
        return ""
    parts = [f'<section id="videos"><h2>Videos: {len(videos)}</h2>']
    for p in videos:
        v = p.doc["video"]
        fr = v.get("frames") or {}
        st = v.get("stream") or {}
        ev = v.get("estimates") or []
        cuts = sum(e["event"] == "cut" for e in ev)
        unrestored = int(fr.get("unrestored") or 0)
        strip = rel_url(p.output("strip"))
        flags = needs_a_look(p)
        stop = v.get("stopped")
        size = "" if not st.get("width") else f" of {int(st['width'])}x{int(st.get('height') or 0)}"
        rate = "" if _rate(p) is None else f" at {_rate(p):.3g} frames/s"
        flagged = " flagged" if flags else ""
        parts.append(f'<div class="cell{flagged}"><p><b>{html.escape(printable(p.sidecar[:-5]))}</b>: '
                     f'{int(fr.get("restored") or 0)} frames restored{size}{rate}'
                     + (f" ({unrestored} held nothing to restore: written as they came)" if unrestored else "")
                     + '; water type '
                     f'<b>{html.escape(printable(p.doc["water_type"]))}</b> most of the time; {len(ev)} estimates, {cuts} at cuts'
                     + (f'; <span class="flags">{", ".join(html.escape(printable(f)) for f in flags)}</span>' if flags else "")
                     + "</p>")
        if stop:
            where = f"frame {int(stop['frame'])}" + ("" if stop.get("time") is None else f" ({float(stop['time']):.3f} s)")
            parts.append(f'<p class="flags">stopped at {html.escape(printable(where))}: {html.escape(printable(stop["error"]))}</p>')
        if strip:
            parts.append(f'<img class="strip" alt="frames: input above, restored below" src="{html.escape(strip)}" '
                         'style="max-width:100%">')
        parts.append(_series_svg(p, types))
        parts.append(f'<p class="meta"><a href="{html.escape(rel_url(p.sidecar) or "")}">sidecar</a>'
                     + ("" if not p.output("video") else
                        f' &middot; <a href="{html.escape(rel_url(p.output("video")) or "")}">restored video</a>')
                     + "</p></div>")
    parts.append("</section>")
    return "".join(parts)
