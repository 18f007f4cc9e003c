"""s8: the estimates' log chromaticities in a fixed basis (x = (R-B)/sqrt2, y = (R+B-2G)/sqrt6), and beta~ there."""
import os, sys
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import numpy as np
import lab8 as L, rules as U
E1 = np.array([1, 0, -1]) / np.sqrt(2)
E2 = np.array([1, -2, 1]) / np.sqrt(6)
def xy(v):
    v = np.asarray(v, float); v = v - v.mean(); return np.array([v @ E1, v @ E2])
def lch(e):
    return xy(np.log(np.maximum(e, 1e-12)))
recs = L.load(sys.argv[1] if len(sys.argv) > 1 else "tune")
for c in L.CONDS:
    print(c)
    for r in recs:
        if r["suspect"] or r["cond"] != c: continue
        b = xy(r["b"]); bt = xy(r["bt"])
        ang = np.degrees(np.arctan2(b[1], b[0]))
        s = "  ".join(f"{k[:2]} {np.array2string(lch(r['est'][k]), precision=2)}" for k in U.KS)
        # content chroma with the true light removed (fitted family): l + d_true * beta~
        cgw = lch(r["est"]["gw0.0"]) + r["true_d"] * b
        print(f"  {r['name']:42s} beta~ {np.array2string(b, precision=3)} ang {ang:6.1f} | {s} | content_gw {np.array2string(cgw, precision=2)} ang {np.degrees(np.arctan2(cgw[1], cgw[0])):6.1f}")
