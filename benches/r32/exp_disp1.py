import sys, numpy as np, common as C, displab as D
from collections import defaultdict
data = D.build("tune")
res = defaultdict(lambda: defaultdict(list)); dch = defaultdict(lambda: defaultdict(list))
for it in data:
    r, z = it['r'], it['z']
    cond = f"{r.stats}/{r.light}"; dtrue = 5.0 if r.light=="tinted" else 0.0
    for wname, beta, a in (("true", it['bt'], r.a), ("fit", it['bf'], it['af'])):
        j = C.recover(r.image, z, beta, a)
        zf = C.fill_nearest(z)
        tmin = np.exp(-beta.max()*zf)
        obj = r.objects
        ed = D.edges(j, 1.0)
        cands = {}
        for tau in (0.0, 0.1, 0.3):
            sel = obj & (tmin >= tau) if tau>0 else obj
            if sel.sum() < 500: sel = obj
            px = j[sel][::3]; ex = ed[sel][::3]
            cands[f"core_t{tau}"] = D.cast_d(np.array([D.minkowski(px,1), D.minkowski(px,4)]), beta)[0]
            cands[f"gw_t{tau}"] = D.cast_d(D.minkowski(px,1), beta)[0]
            cands[f"ge1_t{tau}"] = D.cast_d(D.minkowski(ex,1), beta)[0]
            cands[f"ge6_t{tau}"] = D.cast_d(D.minkowski(ex,6), beta)[0]
            cands[f"wp995_t{tau}"] = D.cast_d(np.percentile(px,99.5,axis=0), beta)[0]
            cands[f"sog4_t{tau}"] = D.cast_d(D.minkowski(px,4), beta)[0]
        cands["true_d"] = dtrue; cands["zero"] = 0.0
        for k, d in cands.items():
            res[(wname,k)][cond].append(C.score(C.expose(j, np.exp(beta*d), obj), r))
            dch[(wname,k)][cond].append(d)
    print(r.name, file=sys.stderr)
conds = ["gray/white","gray/tinted","own/white","own/tinted"]
for key in res:
    print(key, " | ".join(f"{np.median(res[key][c]):5.1f} (d {np.median(dch[key][c]):4.1f})" for c in conds), f" mean4 {np.mean([np.median(res[key][c]) for c in conds]):.2f}")
