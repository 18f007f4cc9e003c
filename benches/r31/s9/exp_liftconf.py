"""The confidence of METHOD §12.5 told where the displayed colour is the
artifact clamp's lift rather than the scene's: theta_lift = the angle
between g (J - shift) / div (what is shown, before the exposure) and
g max(J, 0) (the scene's colour), added to the noise angle in quadrature
(or its maximum). The blend of step 4 then follows as it is.

    python3 benches/r31/s9/exp_liftconf.py tune 2
"""
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
import exp
import harness as H
from exp_noshift import recovered
import uwhl_rs


def finish(st, wt, q, mode):
    """H.finish with the lift's angle in the local confidence (mode "quad" or "max"), or today's (None)."""
    if mode is None:
        return H.finish(st, wt, q)
    tb, t, img, j = recovered(st, wt, q)
    lo, hi = j.min(), j.max()
    shift = max(lo, -0.08)
    div = min(max(hi - shift, 0), 1.6)
    jc = np.minimum(np.maximum(j - shift, 0) / div, 1)
    obj = st.objects
    g = H.gains_from(H.sog(jc, obj))
    pct = np.array([np.quantile(jc[..., c], 0.99) for c in range(3)])
    k = g / (g * pct).max()
    image = np.clip(jc * k, 0, 1)
    sig = st.sigma
    ve = ((t * j) < -sig).any(axis=-1)[obj].mean()
    wp = np.clip((ve - 0.02) / 0.18, 0, 1)
    kin = H.gains_from(H.sog(img, obj))
    scene = g * np.maximum(j, 0)
    shown = np.sqrt((scene ** 2).sum(-1)).clip(1e-6)
    theta = np.sqrt(2 / 3 * ((g * sig / t) ** 2).sum(-1)) / shown
    disp = g * jc
    cosang = (disp * scene).sum(-1) / (np.sqrt((disp ** 2).sum(-1)) * shown).clip(1e-12)
    lift = np.arccos(np.clip(cosang, -1, 1))
    lift = np.where((scene ** 2).sum(-1) > 0, lift, np.pi / 2)
    if mode == "quad":
        theta = np.sqrt(theta ** 2 + lift ** 2)
    elif mode == "max":
        theta = np.maximum(theta, lift)
    local = 1 / (1 + (theta / 0.15) ** 2)
    wgt = 1 - (1 - wp) * (1 - 0.3 * (1 - local))
    base = np.maximum(img * kin, 0)
    scale = image.sum(-1) / np.maximum(base.sum(-1), 1e-9)
    image = np.clip((1 - wgt[..., None]) * image + wgt[..., None] * base * scale[..., None], 0, 1)
    return image, jc, tb, ve, local * (1 - wp)


def make(mode):
    def f(r, st):
        wt = uwhl_rs.restore(r.image).water_type
        q = st.default_q(wt)
        out = finish(st, wt, q, mode)
        return out[0], {"steps": abs(H.TYPES.index(wt) - H.TYPES.index(r.water_type))}
    return f


if __name__ == "__main__":
    split = sys.argv[1] if len(sys.argv) > 1 else "tune"
    every = int(sys.argv[2]) if len(sys.argv) > 2 else 1
    exp.run({"today": make(None), "lift_quad": make("quad"), "lift_max": make("max")}, split=split, every=every)
