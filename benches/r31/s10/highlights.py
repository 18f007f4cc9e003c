"""Highlights toward neutral (prototype on the core's display): where the
displayed pixel's largest channel m is above LO, its colour moves toward
the gray of its own mean by w = min(1, (m - LO) / (1 - LO)). Renders of a
split (`../s9/cache.py`'s), against the display as it is."""
import sys, os, numpy as np
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "s9"))
from ens import load, med, CONDS
import uwhl_rs

def neutral(x, lo):
    m = x.max(-1, keepdims=True)
    w = np.clip((m - lo) / (1 - lo), 0, 1)
    g = x.mean(-1, keepdims=True)
    return (1 - w) * x + w * g

if __name__ == "__main__":
    split = sys.argv[1]
    LOS = (None, 0.6, 0.7, 0.8, 0.9)
    res = {lo: {} for lo in LOS}
    for d in load(split):
        img = uwhl_rs.restore(d["image"].astype(np.float64)).image
        for lo in LOS:
            res[lo].setdefault(str(d["cond"]), []).append(med(img if lo is None else neutral(img, lo), d))
    print(split)
    for lo in LOS:
        print(f"lo={lo}", " / ".join(f"{np.median(res[lo][c]):5.2f}" for c in CONDS))
