import numpy as np, glob, sys

from uwhl_rs import truth as TR, evaluate as ev
def mink(J, m, p):
    x = np.maximum(J[m], 0)
    if p == 'max': e = np.percentile(x, 99, axis=0)
    else: e = (x**p).mean(0)**(1/p)
    return e
def disp(J, m, e):
    g = e.mean()/np.maximum(e, 1e-9); D = J*g
    s = 1/max(np.percentile(D[m].max(1), 99), 1e-9); return np.clip(D*s, 0, 1)
def med(img, d): return TR.score(img, d['truth'], d['objects'], gains=False)['median']
res = {}
for split in ['tune','held']:
  for f in sorted(glob.glob(f'out/cache/{split}/*.npz')):
    d = np.load(f); cond = str(d['meta'][1])
    I = d['image'].astype(np.float64); m = ~d['vm'].astype(bool)
    outs = {'input': I, 'gw_in': ev.grayworld(I), 'D': d['D']}
    for jk in ['J', 'Jt']:
        J = d[jk].astype(np.float64)
        for p in [1, 2, 4, 'max']:
            outs[f'{jk}p{p}'] = disp(J, m, mink(J, m, p))
    for k, v in outs.items(): res.setdefault((split, cond, k), []).append(med(v, d))
for split in ['tune','held']:
    conds = sorted({c for s,c,k in res if s==split}); keys = list(dict.fromkeys(k for s,c,k in res if s==split))
    print(split, conds)
    for k in keys: print(f'{k:10s}', ' '.join(f'{np.median(res[(split,c,k)]):6.2f}' for c in conds))
