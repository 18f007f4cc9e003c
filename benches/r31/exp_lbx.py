"""The lower bound of METHOD §5 applied again after the guided filter, with
the type's own exponents (those of the recovery, §7) and a noise margin:
t_B >= max_c (1 - (I_c + sigma_c) / A_c)^(beta_B / beta_c), so that no
pixel's veil exceeds its light (the veil excess of §12.5 is then 0 and the
fallback blends by the local confidence only). 2026-12-05.

    PYTHONPATH=../../python RAYON_NUM_THREADS=1 python3 exp_lbx.py tune [every]
"""
import sys

import numpy as np

import exp
import harness as H
import uwhl_rs


def lbx(st, wt, margin=1.0):
    br, bg = H.JER[wt]
    a = st.a
    img = st.img.astype(np.float64)
    x = np.clip(1 - (img + margin * st.sigma) / np.maximum(a, 1e-4), 0, 1)
    return np.maximum.reduce([x[..., 0] ** br, x[..., 1] ** bg, x[..., 2]])


def cand(kind, which):
    def f(r, st):
        if which == "true":
            wt = r.water_type
        else:
            wt = uwhl_rs.restore(r.image).water_type
        q = st.default_q(wt)
        if kind == "lbx":
            q = np.maximum(q, lbx(st, wt))
        im, jc, tb, ve = H.finish(st, wt, q)
        return im, {"rho": exp.rho(r, tb), "steps": abs(H.TYPES.index(wt) - H.TYPES.index(r.water_type))}
    return f


def core(r, st):
    res = uwhl_rs.restore(r.image)
    return res.image, {"steps": abs(H.TYPES.index(res.water_type) - H.TYPES.index(r.water_type))}


if __name__ == "__main__":
    split = sys.argv[1] if len(sys.argv) > 1 else "tune"
    every = int(sys.argv[2]) if len(sys.argv) > 2 else 1
    exp.run({"core": core, "chosen": cand("q", "chosen"), "chosen_lbx": cand("lbx", "chosen"),
             "true": cand("q", "true"), "true_lbx": cand("lbx", "true")}, split=split, every=every)
