"""Signed type error (chosen minus true, in steps of the Jerlov order) of
the default on a split's renders (`../s9/cache.py`'s cache): is the choice
biased toward clear or murky types, per true type and condition?"""
import sys, os
import numpy as np
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "s9"))
import uwhl_rs
from ens import load, TY, CONDS

split = sys.argv[1]
rows = []
for d in load(split):
    r = uwhl_rs.restore(d["image"].astype(np.float64))
    rows.append((str(d["cond"]), str(d["true"]), TY.index(r.water_type) - TY.index(str(d["true"]))))
for c in CONDS:
    e = np.array([x[2] for x in rows if x[0] == c])
    print(f"{c:12s} within1 {np.mean(np.abs(e) <= 1):.2f} mean {e.mean():+.2f} median {np.median(e):+.1f}  "
          + " ".join(f"{k:+d}:{np.sum(e == k)}" for k in range(-9, 10) if np.sum(e == k)))
print("per true type (all conditions): mean signed step")
for t in TY:
    e = np.array([x[2] for x in rows if x[1] == t])
    if len(e):
        print(f"  {t:4s} n={len(e):3d} mean {e.mean():+.2f} within1 {np.mean(np.abs(e) <= 1):.2f}")
