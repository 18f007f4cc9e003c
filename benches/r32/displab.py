"""Display (white balance) lab: estimators of the light path d on recovered radiance.

Builds a cache of J with the true water and with the fitted water (core's fit, mirrored in NumPy),
then scores estimators of d.
"""

import os
import sys

import numpy as np

import common as C
import fit as F

DS = np.arange(0, 15.0 + 1e-9, 0.25)


def build(split="tune"):
    out = []
    for r in C.renders(split):
        z = C.variants(r)["distance"]
        bt = C.beta_true(r)
        bf, af, _ = F.fit_tiles(r.image, z)
        out.append(dict(r=r, z=z, bt=bt, bf=bf, af=af))
    return out


def cast_d(e, beta, ds=DS):
    """argmin over d of the spread (std/mean) of e * e^(beta d); e: (k,3) several estimates summed."""
    g = np.exp(beta[None, :] * ds[:, None])
    cost = 0
    for ee in np.atleast_2d(e):
        v = g * ee[None, :]
        cost = cost + v.std(1, ddof=1) / v.mean(1)
    return ds[int(np.argmin(cost))], cost


def log_d(e, beta, w=None, lo=0.0, hi=15.0):
    """Least-squares d in log chromaticity: log e_c + beta_c d equal over c."""
    le = np.log(np.maximum(e, 1e-12))
    le = le - le.mean()
    b = beta - beta.mean()
    d = -np.dot(le, b) / np.dot(b, b)
    return float(np.clip(d, lo, hi))


def minkowski(px, p):
    if p == np.inf:
        return px.max(0)
    return (px ** p).mean(0) ** (1 / p)


def edges(j, sigma=1.0):
    from scipy.ndimage import gaussian_filter
    out = np.empty_like(j)
    for c in range(3):
        jc = gaussian_filter(j[:, :, c], sigma) if sigma > 0 else j[:, :, c]
        gy, gx = np.gradient(jc)
        out[:, :, c] = np.hypot(gx, gy)
    return out
