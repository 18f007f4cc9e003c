"""Bright pixels as a second estimate of the light (prototype on the
core's display): the mean colour of the brightest TOP share of object
pixels (masked in, not VL, none clipped) is taken as gray, and the
display gets those gains to the power ALPHA (global, no pixel treated
alone), exposure kept. Renders of a split (`../s9/cache.py`'s) and, with
`charts`, the real charts (charts masked out of estimation, so the
estimate never sees them)."""
import sys, os, numpy as np
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))

VARIANTS = [(None, None), (0.02, 0.5), (0.02, 1.0), (0.05, 0.5), (0.05, 1.0), (0.1, 0.5)]

def bright_gains(img, objects, top):
    s = img.sum(-1)
    ok = objects & (img.max(-1) < 0.995)
    if ok.sum() < 20:
        return np.ones(3)
    thr = np.quantile(s[ok], 1 - top)
    e = img[ok & (s >= thr)].mean(0)
    mu = e.mean()
    return np.where(e > 0, mu / np.maximum(e, 1e-9), 1.0)

def apply(img, objects, top, alpha):
    if top is None:
        return img
    g = bright_gains(img, objects, top) ** alpha
    out = img * g
    k = np.quantile(img.max(-1), 0.99) / max(np.quantile(out.max(-1), 0.99), 1e-9)
    return np.clip(out * k, 0, 1)

if __name__ == "__main__":
    from common import renders, charts
    make = lambda r, objects, v: apply(r.image, objects, *v)
    charts(VARIANTS, make) if sys.argv[1] == "charts" else renders(sys.argv[1], VARIANTS, make)
