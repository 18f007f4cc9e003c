"""Temporal consistency of videos (METHOD §10, sequence mode), on rendered
clips with known truth (``uwhl_rs.clip``):

    python3 benches/video.py [--quick] [--json OUT.json]

- **Flicker**: a camera panning 3 columns a frame through one water (five
  Jerlov types x two seeds, 48 frames of 144 x 192, noise 0.005 and
  0.015); a patch of the seabed fixed in the world is followed from frame
  to frame, and the angle between its mean colour in consecutive frames is
  averaged (and its 95th percentile taken), with the change of its
  brightness. Rows: the input; each frame restored on its own
  (``restore``); the sequence without smoothing and with it (estimates
  every 12 or 6 frames, so that scheduled estimates happen inside the clip).
- **Cuts**: clips that cut from one water to another at frame 24 (every
  pair of five types, two seeds): on which frame the cut is estimated
  (0 = the cut's own frame) and the number of cuts seen where there is
  none.
- **Lag**: a slow descent (the veiling light's red and green fade over the
  clip, no cut): the mean |A used - A true| and its lag behind the truth
  (the shift, in frames, that best aligns the A used with the true A),
  for smoothing 1 (none), 0.5 and 0.25, estimates every 12 frames.

Every number is a median or a mean over the clips, stated in the table.
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys

import numpy as np

import uwhl_rs
from uwhl_rs import _core, clip

TYPES = ["IB", "III", "3C", "5C", "9C"]


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    c = float(np.dot(a, b) / max(np.linalg.norm(a) * np.linalg.norm(b), 1e-12))
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def flicker(c: clip.Clip, images: list[np.ndarray]) -> tuple[float, float, float]:
    """Mean and 95th percentile of the frame-to-frame angle of the fixed
    patch's colour, and the mean |log| change of its brightness (%)."""
    cols = []
    for k, img in enumerate(images):
        where = clip.patch_track(c, k)
        cols.append(None if where is None else img[where].reshape(-1, 3).mean(axis=0).astype(np.float64))
    ang, lum = [], []
    for a, b in zip(cols, cols[1:]):
        if a is None or b is None:
            continue
        ang.append(_angle(a, b))
        lum.append(abs(np.log(max(b.sum(), 1e-9) / max(a.sum(), 1e-9))) * 100)
    return float(np.mean(ang)), float(np.percentile(ang, 95)), float(np.mean(lum))


def sequence(frames, refresh: int, smoothing: float, cut: float = _core.VIDEO_SCENE_CUT):
    seq = uwhl_rs.Sequence(refresh_every=refresh, scene_cut=cut, smoothing=smoothing)
    out = []
    for f in frames:
        r = seq.restore(f)
        out.append((r, seq.last_decision))
    return out


def run_flicker(quick: bool) -> list[dict]:
    rows = []
    seeds = (1,) if quick else (1, 2)
    for wt, seed, noise in itertools.product(TYPES, seeds, (0.005, 0.015)):
        c = clip.clip(frames=48, height=144, width=192, water_type=wt, pan=3, noise=noise, seed=seed)
        res = {"input": c.frames,
               "per frame": [uwhl_rs.restore(f).image for f in c.frames],
               "sequence, no smoothing": [r.image for r, _ in sequence(c.frames, 12, 1.0)],
               "sequence, smoothing 0.5": [r.image for r, _ in sequence(c.frames, 12, 0.5)],
               "sequence, smoothing 0.25": [r.image for r, _ in sequence(c.frames, 12, 0.25)],
               "sequence, no smoothing, estimates every 6": [r.image for r, _ in sequence(c.frames, 6, 1.0)],
               "sequence, smoothing 0.5, estimates every 6": [r.image for r, _ in sequence(c.frames, 6, 0.5)]}
        for name, imgs in res.items():
            m, p95, lum = flicker(c, imgs)
            rows.append({"test": "flicker", "type": wt, "seed": seed, "noise": noise, "row": name, "mean": m,
                         "p95": p95, "brightness": lum})
        print(f"flicker {wt} seed {seed} noise {noise}", file=sys.stderr)
    return rows


def run_cuts(quick: bool) -> list[dict]:
    rows = []
    seeds = (1,) if quick else (1, 2)
    for (a, b), seed in itertools.product(itertools.permutations(TYPES, 2), seeds):
        c = clip.clip(frames=36, height=96, width=128, water_type=a, second_type=b, cut_at=24, pan=3, noise=0.01,
                      seed=seed)
        got = sequence(c.frames, 1000, 1.0)
        cuts = [k for k, (_, d) in enumerate(got) if d[0] == "cut"]
        seen = [k - 24 for k in cuts if k >= 24]
        rows.append({"test": "cut", "from": a, "to": b, "seed": seed, "detected_at": seen[0] if seen else None,
                     "false_cuts": sum(1 for k in cuts if k != 24), "change_at_cut": float(got[24][1][1]),
                     "largest_change_elsewhere": float(max(d[1] for k, (_, d) in enumerate(got) if k != 24))})
    print("cuts done", file=sys.stderr)
    return rows


def run_lag(quick: bool) -> list[dict]:
    rows = []
    seeds = (1,) if quick else (1, 2, 3)
    for wt, seed in itertools.product(("III", "3C", "7C"), seeds):
        c = clip.clip(frames=96, height=96, width=128, water_type=wt, pan=2, noise=0.005, descent=1.2, seed=seed)
        true_a = np.array(c.veiling_lights)
        for w in (1.0, 0.5, 0.25):
            got = sequence(c.frames, 12, w)
            used = np.array([r.veiling_light for r, _ in got])
            err = float(np.abs(used - true_a).max(axis=1).mean())
            # the lag: the shift s >= 0 of the truth that best matches the A used (green channel)
            g_used, g_true = used[:, 1], true_a[:, 1]
            lag = min(range(0, 30), key=lambda s: float(np.abs(g_used[s:] - g_true[: len(g_true) - s]).mean()))
            jumps = float(np.abs(np.diff(used, axis=0)).max())
            rows.append({"test": "lag", "type": wt, "seed": seed, "smoothing": w, "mean_abs_A_error": err,
                         "lag_frames": lag, "largest_A_step": jumps})
    print("lag done", file=sys.stderr)
    return rows


def tables(rows: list[dict]) -> str:
    out = ["Flicker of a fixed patch on a pan through one water (mean over clips; degrees frame to frame):", "",
           "| row | mean angle | p95 angle | brightness change % |", "|---|---|---|---|"]
    fl = [r for r in rows if r["test"] == "flicker"]
    for name in dict.fromkeys(r["row"] for r in fl):
        sel = [r for r in fl if r["row"] == name]
        out.append(f"| {name} | {np.mean([r['mean'] for r in sel]):.3f} | {np.mean([r['p95'] for r in sel]):.3f} | "
                   f"{np.mean([r['brightness'] for r in sel]):.2f} |")
    cu = [r for r in rows if r["test"] == "cut"]
    if cu:
        at = [r["detected_at"] for r in cu]
        out += ["", f"Cuts: {len(cu)} clips; estimated on the cut's own frame in "
                f"{sum(a == 0 for a in at)}, one frame later in {sum(a == 1 for a in at)}, missed in "
                f"{sum(a is None for a in at)}; cuts seen where there is none: {sum(r['false_cuts'] for r in cu)}; "
                f"colour change at the cut median {np.median([r['change_at_cut'] for r in cu]):.2f} "
                f"(min {min(r['change_at_cut'] for r in cu):.2f}), elsewhere at most "
                f"{max(r['largest_change_elsewhere'] for r in cu):.3f}"]
    lg = [r for r in rows if r["test"] == "lag"]
    if lg:
        out += ["", "A on a slow descent (estimates every 12 frames):", "",
                "| smoothing | mean max-channel error of A | lag (frames, median) | largest step of A |", "|---|---|---|---|"]
        for w in (1.0, 0.5, 0.25):
            sel = [r for r in lg if r["smoothing"] == w]
            out.append(f"| {w} | {np.mean([r['mean_abs_A_error'] for r in sel]):.4f} | "
                       f"{np.median([r['lag_frames'] for r in sel]):.0f} | {np.mean([r['largest_A_step'] for r in sel]):.4f} |")
    return "\n".join(out)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help="one seed and noise level fewer")
    p.add_argument("--json", default=None)
    a = p.parse_args(argv)
    rows = run_flicker(a.quick) + run_cuts(a.quick) + run_lag(a.quick)
    if a.json:
        with open(a.json, "w") as f:
            json.dump(rows, f, indent=1)
    print(tables(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
