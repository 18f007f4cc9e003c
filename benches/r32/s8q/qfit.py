"""The mirror fit (benches/r32/fit.py, eiv=True as the core) with candidate treatments of quantised z."""
import os
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import numpy as np  # noqa: E402
from scipy.ndimage import gaussian_filter, uniform_filter  # noqa: E402

import fit as F  # noqa: E402

TILE = 8


def smooth(z, kind, s):
    """Normalised filtering of z over its known pixels (unknown stay unknown). kind: gauss / box on z,
    igauss / ibox on 1/z (disparity space)."""
    k = np.isfinite(z) & (z > 0)
    x = np.where(k, 1.0 / z if kind[0] == "i" else z, 0.0)
    filt = (lambda a: gaussian_filter(a, s, mode="nearest")) if kind.endswith("gauss") else \
        (lambda a: uniform_filter(a, int(s), mode="nearest"))
    num, den = filt(x), filt(k.astype(np.float64))
    out = np.full(z.shape, np.nan)
    v = num[k] / np.maximum(den[k], 1e-12)
    out[k] = 1.0 / v if kind[0] == "i" else v
    return out


def tile_stats(img, z, kmin=0, few=0, win=0, qvar=None, eiv_min=0.25, inv_plane=False, grow=None, inv_few=False):
    """fit.tile_stats(eiv=True) (the core) plus: kmin: drop tiles whose z takes fewer than kmin
    distinct values; few/win: tiles with fewer than `few` distinct values fit their plane over the
    tile grown by win px on each side; qvar: per-pixel noise variance of z as a function of z
    (replaces the plane's residual variance in the errors-in-variables term); inv_plane: the
    plane fitted to 1/z, then inverted."""
    h, w = z.shape
    ok = F.usable(img, z)
    dy, dx = np.mgrid[0:TILE, 0:TILE].astype(np.float64) - (TILE - 1) / 2
    out = {k: [] for k in ("m", "s", "w", "zm", "vz", "n")}
    for y0, x0, k, n in F.tiles(ok, TILE):
        zz = z[y0:y0 + TILE, x0:x0 + TILE][k].astype(np.float64)
        nd = len(np.unique(zz)) if (kmin or few) else 99
        if nd < kmin:
            continue
        X = np.stack([np.ones(n), dy[k], dx[k]], 1)
        if grow is not None:  # (L, wins): the smallest grown window holding >= L distinct levels
            L, wins = grow
            few, win = 0, None
            if len(np.unique(zz)) < L:
                few = L
                for wv in wins:
                    ya, yb, xa, xb = max(0, y0 - wv), min(h, y0 + TILE + wv), max(0, x0 - wv), min(w, x0 + TILE + wv)
                    zw = z[ya:yb, xa:xb][ok[ya:yb, xa:xb]]
                    if len(np.unique(zw)) >= L:
                        win = wv
                        break
                if win is None:
                    continue
            nd = len(np.unique(zz))
        inv = inv_plane
        if few and nd < few:
            inv = inv_plane or inv_few  # inv_few: 1/z planes only for the grown (few-level) tiles
            Xw, zw = F.grown_window(ok, z, y0, x0, TILE, win)
            tw = 1.0 / zw if inv else zw
            coef, *_ = np.linalg.lstsq(Xw, tw, rcond=None)
            res = tw - Xw @ coef
            s2 = (res ** 2).sum() / max(len(zw) - 3, 1)
            cov = s2 * np.linalg.inv(Xw.T @ Xw)
            Xc = X[:, 1:] - X[:, 1:].mean(0)
            noise_v = np.trace(Xc.T @ Xc @ cov[1:, 1:]) / n
            zp = X @ coef
            zz = 1.0 / zp if inv else zp
        else:
            tz = 1.0 / zz if inv_plane else zz
            coef, *_ = np.linalg.lstsq(X, tz, rcond=None)
            res = tz - X @ coef
            s2 = (res ** 2).sum() / max(n - 3, 1)
            zp = X @ coef
            zz = 1.0 / zp if inv_plane else zp
            noise_v = 2 * s2 / n
        if inv:  # noise of 1/z to z: times z^4 at the tile's depth
            noise_v *= zz.mean() ** 4
        zm = zz.mean()
        vz = ((zz - zm) ** 2).mean()
        if vz <= 1e-12:
            continue
        if qvar is not None:
            noise_v = 2 * qvar(zm) / n
        vc = vz - noise_v
        if vc < eiv_min * vz:
            continue
        vz = vc
        ii = img[y0:y0 + TILE, x0:x0 + TILE][k].astype(np.float64)
        im, s, vr, w = F.tile_slope(ii, zz, zm, vz, n)
        out["m"].append(im)
        out["s"].append(s)
        out["w"].append(w)
        out["zm"].append(zm)
        out["vz"].append(vz)
        out["n"].append(n)
    return {k: np.array(v) for k, v in out.items()}


def fit(img, z, pre=None, **kw):
    """Returns beta, A, suspect, the z the fit saw (after `pre`), number of tiles."""
    if pre is not None:
        z = smooth(z, *pre)
    ts = tile_stats(img, z, **kw)
    if len(ts["w"]) < 3:
        return np.full(3, np.nan), np.full(3, np.nan), True, z, len(ts["w"])
    beta, a, _ = F.fit_tiles(img, z, ts=ts)
    sus = F.suspect(ts, beta, z)[0]
    return beta, a, sus, z, len(ts["w"])
