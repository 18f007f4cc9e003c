import numpy as np, glob, sys, json

from uwhl_rs import truth as TR, evaluate as ev, synth
from scipy.ndimage import uniform_filter
def estimates(J, m):
    x = np.maximum(J, 0)
    gw = x[m].mean(0)
    gy, gx = np.gradient(x, axis=(0, 1))
    gm = np.sqrt(gx**2 + gy**2)
    gm = np.stack([uniform_filter(gm[..., c], 5) for c in range(3)], -1)
    ge = gm[m].mean(0)
    wp = np.percentile(x[m], 99, axis=0)
    return {'gw': gw, 'ge': ge, 'wp': wp}
def path_gains(J, m, wt, margin=0.5, xmax=4.0, only=None):
    br, bg = synth.JERLOV[wt]; b = np.array([1/br, 1/bg, 1.0]); bt = b - b.mean()
    best = None
    for k, e in estimates(J, m).items():
        if only and k not in only: continue
        l = np.log(np.maximum(e, 1e-9)); l = l - l.mean()
        x = -(l @ bt) / (bt @ bt); r = np.linalg.norm(l + x * bt)
        if k == 'gw': r *= margin
        if best is None or r < best[0]: best = (r, x, k)
    x = float(np.clip(best[1], 0, xmax)); return np.exp(x * b), x, best[2]
def disp(J, m, g):
    D = J * g; s = 1/max(np.percentile(D[m].max(1), 99), 1e-9); return np.clip(D*s, 0, 1)
def sogd(J, m, p=4):
    e = (np.maximum(J[m],0)**p).mean(0)**(1/p); return disp(J, m, e.mean()/np.maximum(e,1e-9))
res = {}
for split in ['tune','held']:
  for f in sorted(glob.glob(f'out/cache/{split}/*.npz')):
    d = np.load(f); cond = str(d['meta'][1]); wt = str(d['meta'][2]); ch = str(d['meta'][3])
    m = ~d['vm'].astype(bool)
    sc = lambda x: TR.score(x, d['truth'], d['objects'], gains=False)['median']
    outs = {'D': d['D'], 'G': ev.grayworld(d['image'])}
    for jk, t in [('J', ch), ('Jt', wt)]:
        J = d[jk].astype(np.float64)
        outs[jk+'sog'] = sogd(J, m)
        outs[jk+'path3'] = disp(J, m, path_gains(J, m, t)[0])
        outs[jk+'none'] = disp(J, m, np.ones(3))
    for k, v in outs.items(): res.setdefault((split, cond, k), []).append(sc(v))
for split in ['tune','held']:
    conds = sorted({c for s,c,k in res if s==split}); keys = list(dict.fromkeys(k for s,c,k in res if s==split))
    print(split, conds)
    for k in keys: print(f'{k:10s}', ' '.join(f'{np.median(res[(split,c,k)]):6.2f}' for c in conds))
