"""The central choice with a margin: the best-scored type stays unless
another of the three is more central by more than M (summed median L1
chromaticity distance). On ../s9/cache.py's renders."""
import sys, os, numpy as np
sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "s9"))
from ens import load, med, TY, CONDS
def chroma(x, m):
    y = np.maximum(x[m].astype(np.float64), 1e-6); return y / y.sum(1, keepdims=True)
split = sys.argv[1]; MS = (0, 0.0005, 0.001, 0.002, 0.005, 0.01, 0.02, 0.04)
res = {m: {} for m in MS}; steps = {m: {} for m in MS}; ties = 0
for d in load(split):
    disp = d["disp"].astype(np.float32); obj = d["obj"]
    idx = np.flatnonzero(obj); rng = np.random.default_rng(0); keep = rng.choice(idx, min(4000, idx.size), replace=False)
    msk = np.zeros(obj.size, bool); msk[keep] = True; msk = msk.reshape(obj.shape)
    best3 = list(np.argsort(d["scores"])[:3]); ch = {k: chroma(disp[k], msk) for k in best3}
    sp = {a: sum(np.median(np.abs(ch[a] - ch[b]).sum(1)) for b in best3) for a in best3}
    ties += max(sp.values()) < 1e-9
    ti = TY.index(str(d["true"]))
    for m in MS:
        pick = min(best3, key=sp.get)
        if sp[pick] > sp[best3[0]] - m: pick = best3[0]
        res[m].setdefault(str(d["cond"]), []).append(med(disp[pick], d))
        steps[m].setdefault(str(d["cond"]), []).append(abs(pick - ti) <= 1)
print(split, "all three displays equal:", ties)
for m in MS:
    print(f"M={m:<6}", " / ".join(f"{np.median(res[m][c]):5.2f}" for c in CONDS), "  within1", " ".join(f"{sum(steps[m][c])}/{len(steps[m][c])}" for c in CONDS))
