"""Shared helpers for the issue-32 research: renders cache, NumPy recovery and display, scoring."""

from __future__ import annotations

import os
import pickle
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import truth as T  # noqa: E402  benches/truth.py

from uwhl_rs import truth as sc  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))


def renders(split="tune"):
    return list(T.scenes(split, 360))


def beta_true(r):
    bb = T.BETA_B[r.water_type]
    br, bg = T.synth.JERLOV[r.water_type]
    return np.array([bb / br, bb / bg, bb])


def variants(r):
    """The same z variants as benches/truth.py method_rows."""
    z = np.where(np.isfinite(r.distance), r.distance, np.nan).astype(np.float32)
    return {"distance": z, "distance_holes": T.holes(z, 0.3, seed=len(r.name)),
            "distance_noise": z * np.random.default_rng(len(r.name)).lognormal(0.0, 0.1, z.shape).astype(np.float32)}


def fill_nearest(z):
    from scipy.ndimage import distance_transform_cdt
    bad = ~(np.isfinite(z) & (z > 0))
    if not bad.any():
        return z.astype(np.float64)
    idx = distance_transform_cdt(bad, metric="taxicab", return_distances=False, return_indices=True)
    return z[tuple(idx)].astype(np.float64)


def recover(img, z, beta, a):
    zf = fill_nearest(z)
    t = np.maximum(np.exp(-beta[None, None, :] * zf[:, :, None]), 0.05)
    return np.maximum(a + (img - a) / t, 0)


def expose(j, gains, inside=None):
    g = j * gains
    mx = g.max(2)
    top = np.percentile(mx[inside] if inside is not None else mx, 99)
    return np.clip(g / max(top, 1e-12), 0, 1)


def light_path_core(j, sel, beta, dmax=15.0, step=0.25):
    """The core's §13.4 search (gray world + shades of gray p=4 casts)."""
    px = j.reshape(-1, 3)[sel.reshape(-1)][::7].astype(np.float64)
    e1 = px.mean(0)
    e4 = (px ** 4).mean(0) ** 0.25
    ds = np.arange(0, dmax + 1e-9, step)
    g = np.exp(beta[None, :] * ds[:, None])

    def spread(e):
        m = e.mean(1)
        return e.std(1, ddof=1) / m
    cost = spread(g * e1) + spread(g * e4)
    return ds[int(np.argmin(cost))]


def score(img, r):
    s = sc.score(img, r.truth, r.objects, gains=False)
    return s["median"]


def cache(name, fn):
    p = os.path.join(HERE, "cache", name + ".pkl")
    if os.path.exists(p):
        with open(p, "rb") as f:
            return pickle.load(f)
    v = fn()
    os.makedirs(os.path.dirname(p), exist_ok=True)
    with open(p, "wb") as f:
        pickle.dump(v, f)
    return v
