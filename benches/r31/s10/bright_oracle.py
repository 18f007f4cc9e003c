"""The better of the default display and bright.py's (top 5%, power 0.5) per render
(an oracle), and a choice between them by the size of the bright gains
(sum of |ln g|) over a threshold. Usage: bright_oracle.py SPLIT"""
import sys, os, numpy as np
HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE); sys.path.insert(0, os.path.join(HERE, "..", "s9"))
import uwhl_rs
from bright import apply
from ens import load, med, CONDS
split = sys.argv[1]
res = {}
for d in load(split):
    r = uwhl_rs.restore(d["image"].astype(np.float64))
    obj = ~r.veiling_mask
    a = med(r.image, d); b_img = apply(r.image, obj, 0.05, 0.5); b = med(b_img, d)
    # candidate signal: angle between the SOG display's bright-pixel colour and gray
    from bright import bright_gains
    g = bright_gains(r.image, obj, 0.05)
    sig = float(np.abs(np.log(g)).sum())
    c = str(d["cond"])
    res.setdefault(c, []).append((a, b, sig))
print(split)
for c in CONDS:
    x = np.array(res[c])
    print(c, "sog", round(np.median(x[:, 0]), 2), "bright", round(np.median(x[:, 1]), 2), "oracle", round(np.median(x[:, :2].min(1)), 2), "signal median", round(np.median(x[:, 2]), 3))
    for thr in (0.1, 0.2, 0.3, 0.5):
        pick = np.where(x[:, 2] > thr, x[:, 1], x[:, 0])
        print("   thr", thr, round(np.median(pick), 2), end="")
    print()
