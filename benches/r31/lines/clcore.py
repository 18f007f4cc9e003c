"""Colour-line features of 7 x 7 patches and their distance to a type's veil curve (shared by the scripts here)."""
import numpy as np, glob, sys, json
sys.path.insert(0,'..')
from clines import patches, TGRID
import harness as H
from uwhl_rs import synth
TYPES = H.TYPES
def feats(img, sigma, size=7, stride=4):
    P, cy, cx = patches(img.astype(np.float64), size, stride)
    mu = P.mean(1); X = P - mu[:, None, :]
    C = np.einsum('nki,nkj->nij', X, X) / P.shape[1]
    lam, vec = np.linalg.eigh(C); D = vec[:, :, 2]
    spread = np.sqrt(np.maximum(lam[:, 2], 0)); line = lam[:, 1] / np.maximum(lam[:, 2], 1e-12)
    s = np.einsum('nkc,nc->nk', X, D); lo, hi = s.min(1), s.max(1)
    u = (s - lo[:, None]) / np.maximum(hi - lo, 1e-12)[:, None]
    mid = ((u > 0.25) & (u < 0.75)).mean(1)
    clipped = ((P > 0.98) | (P < 0.002)).any((1, 2))
    return dict(mu=mu, D=D, spread=spread, line=line, mid=mid, clipped=clipped, sig=sigma.mean(), cy=cy, cx=cx)
def rel(f, a, wt, sel):
    br, bg = synth.JERLOV[wt]; ex = np.array([1 / br, 1 / bg, 1.0])
    V = (1 - TGRID[:, None] ** ex[None, :]) * a[None, :]
    mu, D = f['mu'][sel], f['D'][sel]
    W = V[None] - mu[:, None, :]
    proj = np.einsum('ngc,nc->ng', W, D)
    e = np.linalg.norm(W - proj[..., None] * D[:, None, :], axis=-1)
    return e.min(1) / f['spread'][sel]


def by_condition(rows):
    """(split, condition, the rows of that cell, the median of a column) for the printing loops."""
    for split in ['tune', 'held']:
        for c in sorted({r['cond'] for r in rows}):
            rr = [r for r in rows if r['split'] == split and r['cond'] == c]
            yield split, c, rr, (lambda k, rr=rr: np.median([r[k] for r in rr]))
