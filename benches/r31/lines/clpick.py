"""Colour-lines type pick for an arbitrary image (prototype), optional mask of pixels to ignore."""
import numpy as np, sys
sys.path.insert(0,'..')
from clcore import feats, rel, TYPES
import harness as H
import uwhl_rs
def block(img, side=400):
    s = int(np.ceil(max(img.shape[:2]) / side))
    if s <= 1: return img
    h, w = (img.shape[0] // s) * s, (img.shape[1] // s) * s
    return img[:h, :w].reshape(h // s, s, w // s, s, -1).mean((1, 3))
def pick(img, a=None, ignore=None, tau=0.1):
    small = block(np.asarray(img, np.float64))
    if a is None:
        a = np.asarray(uwhl_rs.restore(np.asarray(img, np.float32), water_types=['3C']).veiling_light, float)
    sigma = H.noise_sigma(small); F = feats(small, sigma)
    sel = (~F['clipped']) & (F['spread'] > 6 * F['sig']) & (F['line'] < 0.05)
    sc = {t: float(np.mean(rel(F, a, t, sel) < tau)) if sel.sum() else 0.0 for t in TYPES}
    return max(TYPES, key=lambda t: sc[t]), sc, int(sel.sum())
