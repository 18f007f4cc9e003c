import numpy as np, glob, sys

from uwhl_rs import truth as TR
def sog(img, m, p=4):
    e = (img[m]**p).mean(0)**(1/p); return img*(e.mean()/np.maximum(e,1e-9))
def gw(img, m):
    e = img[m].mean(0); return img*(e.mean()/np.maximum(e,1e-9))
def med(img, d):
    return TR.score(img, d['truth'], d['objects'], gains=False)['median']
res = {}
for split in ['tune','held']:
  for f in sorted(glob.glob(f'out/cache/{split}/*.npz')):
    d = np.load(f); meta = d['meta']; cond = str(meta[1])
    I = d['image'].astype(np.float64); D = d['D'].astype(np.float64); m = ~d['vm'].astype(bool)
    outs = {'input': I, 'gw': gw(I, d['objects']), 'D': D}
    for tname, Bf in [('sog', sog), ('gwm', gw)]:
        B = Bf(I, m); Bp = B * (D.sum(2, keepdims=True) / np.maximum(B.sum(2, keepdims=True), 1e-9))
        for w0 in [0.2, 0.35, 0.5]:
            outs[f'{tname}{w0}'] = np.clip((1-w0)*D + w0*Bp, 0, 1)
    for k, v in outs.items():
        res.setdefault((split, cond, k), []).append(med(v, d))
import collections
for split in ['tune','held']:
    conds = sorted({c for s,c,k in res if s==split})
    keys = list(dict.fromkeys(k for s,c,k in res if s==split))
    print(split, conds)
    for k in keys:
        print(f'{k:10s}', ' '.join(f'{np.median(res[(split,c,k)]):6.2f}' for c in conds))
