import numpy as np, glob, sys
sys.path.insert(0,'../..')
import truth as T
import uwhl_rs
from uwhl_rs import truth as TR, evaluate as ev
import scipy.sparse as sp, scipy.sparse.linalg as spl
def laplace_fill(z):
    h, w = z.shape; unk = ~np.isfinite(z)
    idx = -np.ones((h, w), int); idx[unk] = np.arange(unk.sum())
    rows, cols, vals = [], [], []; b = np.zeros(unk.sum())
    ys, xs = np.nonzero(unk)
    for dy, dx in [(-1,0),(1,0),(0,-1),(0,1)]:
        yy, xx = ys+dy, xs+dx; ok = (yy>=0)&(yy<h)&(xx>=0)&(xx<w)
        i = idx[ys[ok], xs[ok]]; yy, xx = yy[ok], xx[ok]
        rows.append(i); cols.append(i); vals.append(np.ones(len(i)))
        nb_unk = unk[yy, xx]
        rows.append(i[nb_unk]); cols.append(idx[yy[nb_unk], xx[nb_unk]]); vals.append(-np.ones(nb_unk.sum()))
        np.add.at(b, i[~nb_unk], z[yy[~nb_unk], xx[~nb_unk]])
    A = sp.csr_matrix((np.concatenate(vals), (np.concatenate(rows), np.concatenate(cols))), shape=(len(b), len(b)))
    out = z.copy(); out[unk] = spl.spsolve(A, b); return out
res = {}
for split in ['tune','held']:
  for f in sorted(glob.glob(f'out/cache/{split}/*.npz')):
    d = np.load(f); name = str(d['meta'][0]); cond = str(d['meta'][1])
    I = d['image']; dist = d['dist']
    z = np.where(np.isfinite(dist), dist, np.nan).astype(np.float32)
    zh = T.holes(z, 0.3, seed=len(name))
    water = ~np.isfinite(dist)
    zl = laplace_fill(np.where(water, 1.0, zh).astype(np.float64))  # water as a known dummy, reset below
    zl = np.where(water, np.nan, zl).astype(np.float32)
    outs = {'gw': ev.grayworld(I), 'true': uwhl_rs.restore(I, distance=z).image,
            'near': uwhl_rs.restore(I, distance=zh).image, 'lap': uwhl_rs.restore(I, distance=zl).image}
    for k, v in outs.items():
        res.setdefault((split, cond, k), []).append(TR.score(v, d['truth'], d['objects'], gains=False)['median'])
  conds = sorted({c for s,c,k in res if s==split}); keys = list(dict.fromkeys(k for s,c,k in res if s==split))
  print(split, conds, flush=True)
  for k in keys: print(f'{k:6s}', ' '.join(f'{np.median(res[(split,c,k)]):6.2f}' for c in conds), flush=True)
