import numpy as np, glob, sys, json
sys.path.insert(0,'..')
from clcore import feats, rel
import harness as H
from uwhl_rs import synth
TYPES = H.TYPES
VARIANTS = {
  'base': dict(k=6, line=0.05, mid=0.0, tau=0.1),
  'mid': dict(k=6, line=0.05, mid=0.3, tau=0.1),
  'tau05': dict(k=6, line=0.05, mid=0.0, tau=0.05),
  'tau2': dict(k=6, line=0.05, mid=0.0, tau=0.2),
  'k10': dict(k=10, line=0.05, mid=0.0, tau=0.1),
  'line02': dict(k=6, line=0.02, mid=0.0, tau=0.1),
}
split = sys.argv[1]; step = int(sys.argv[2])
res = {}
for f in sorted(glob.glob(f'out/cache/{split}/*.npz'))[::step]:
    d = np.load(f); wt = str(d['meta'][2]); I = d['image']; cond = str(d['meta'][1])
    sigma = H.noise_sigma(I); F = feats(I, sigma); a = np.asarray(d['a'], float)
    for vn, v in VARIANTS.items():
        sel = (~F['clipped']) & (F['spread'] > v['k'] * F['sig']) & (F['line'] < v['line']) & (F['mid'] >= v['mid'])
        if sel.sum() < 10: pick = str(d['meta'][3])
        else:
            sc = {t: np.mean(rel(F, a, t, sel) < v['tau']) for t in TYPES}
            pick = max(TYPES, key=lambda t: sc[t])
        res.setdefault((vn, cond), []).append(abs(TYPES.index(pick) - TYPES.index(wt)))
    res.setdefault(('today', cond), []).append(abs(TYPES.index(str(d['meta'][3])) - TYPES.index(wt)))
for vn in list(VARIANTS) + ['today']:
    print(f'{vn:8s}', ' '.join(f"{c}: {sum(s==0 for s in res[(vn,c)])}/{sum(s<=1 for s in res[(vn,c)])}/{len(res[(vn,c)])}" for c in sorted({c for _, c in res})),
          'total w1', sum(sum(s<=1 for s in res[(vn,c)]) for c in sorted({c for _, c in res})))
