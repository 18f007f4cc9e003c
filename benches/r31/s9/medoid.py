import sys, numpy as np
sys.path.insert(0, __import__("os").path.dirname(__file__))
from ens import load, med, TY, CONDS
def chroma(x, m):
    y = np.maximum(x[m].astype(np.float64), 1e-6); return y / y.sum(1, keepdims=True)
split = sys.argv[1]
res = {}; steps = {}
for d in load(split):
    disp = d["disp"].astype(np.float32); obj = d["obj"]
    sub = obj.copy(); idx = np.flatnonzero(sub); 
    rng = np.random.default_rng(0); keep = rng.choice(idx, min(4000, idx.size), replace=False)
    m = np.zeros(sub.size, bool); m[keep] = True; m = m.reshape(sub.shape)
    ch = [chroma(disp[k], m) for k in range(10)]
    D = np.array([[np.median(np.abs(ch[a] - ch[b]).sum(1)) for b in range(10)] for a in range(10)])
    s = d["scores"]
    cands = {"today": int(np.argmin(s)), "medoid": int(np.argmin(D.sum(1)))}
    # medoid among the 5 best-scored
    best5 = np.argsort(s)[:5]; cands["medoid_of_best5"] = int(best5[np.argmin(D[np.ix_(best5, best5)].sum(1))])
    best3 = np.argsort(s)[:3]; cands["medoid_of_best3"] = int(best3[np.argmin(D[np.ix_(best3, best3)].sum(1))])
    ti = TY.index(str(d["true"]))
    for k, v in cands.items():
        res.setdefault(k, {}).setdefault(str(d["cond"]), []).append(med(disp[v], d))
        steps.setdefault(k, {}).setdefault(str(d["cond"]), []).append(abs(v - ti) <= 1)
print(split)
for k in res:
    print(f"{k:16s}", " / ".join(f"{np.median(res[k][c]):5.2f}" for c in CONDS), "  within1", " ".join(f"{sum(steps[k][c])}/{len(steps[k][c])}" for c in CONDS))
