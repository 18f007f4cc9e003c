"""Colour-lines t_B with a given A (true or estimated), densified, then today's recovery/balance/fallback (harness)."""
import numpy as np, glob, sys, json
sys.path.insert(0,'..'); sys.path.insert(0,'../..')
from clines import estimate
import harness as H
import truth as T
from uwhl_rs import truth as TR, evaluate as ev
from scipy.ndimage import gaussian_filter

def dense(r, good, shape, fallback, sigma=12):
    h, w = shape
    num = np.zeros((h, w)); den = np.zeros((h, w))
    x = -np.log(r['t'][good])
    np.add.at(num, (r['cy'][good], r['cx'][good]), x)
    np.add.at(den, (r['cy'][good], r['cx'][good]), 1.0)
    num = gaussian_filter(num, sigma); den = gaussian_filter(den, sigma)
    fb = -np.log(np.clip(fallback, 1e-3, 1))
    k = 1e-4  # prior mass of the fallback
    return np.exp(-(num + k * fb) / (den + k))

split = sys.argv[1]; step = int(sys.argv[2])
res = {}
for f in sorted(glob.glob(f'out/cache/{split}/*.npz'))[::step]:
    d = np.load(f); wt = str(d['meta'][2]); I = d['image']; cond = str(d['meta'][1])
    atrue = np.asarray(d['atrue'], float)
    if atrue.max() > 1: continue
    sc = lambda x: TR.score(x, d['truth'], d['objects'], gains=False)['median']
    sigma = H.noise_sigma(I)
    out = {'D': d['D'], 'Dt': d['Dt'], 'G': ev.grayworld(I)}
    for aname, a in [('atrue', atrue), ('aest', np.asarray(d['at'], float))]:
        st = H.Image(I, a=a)
        q0 = st.default_q(wt)
        out[f'hl_{aname}'] = H.finish(st, wt, q0)[0]
        r = estimate(I, st.a, wt, sigma)
        obj = np.ones(I.shape[:2], bool)
        good = (~r['clipped']) & r['interior'] & (r['spread'] > 6 * sigma.mean()) & (r['line'] < 0.05) & (r['emin'] < 0.2 * r['spread']) & (r['below'] < 0.02) & (r['sharp'] > 0.5 * r['spread'])
        q = dense(r, good, I.shape[:2], q0)
        out[f'cl_{aname}'] = H.finish(st, wt, q)[0]
        ttrue = np.exp(-T.BETA_B[wt] * np.where(np.isfinite(d['dist']), d['dist'], 1e3))
        out[f'tt_{aname}'] = H.finish(st, wt, ttrue)[0]
    for k, v in out.items(): res.setdefault((cond, k), []).append(sc(v))
    print(str(d['meta'][0])[:40], ' '.join(f'{k} {sc(v):.1f}' for k, v in out.items()), flush=True)
conds = sorted({c for c, k in res}); keys = list(dict.fromkeys(k for c, k in res))
for k in keys: print(f'{k:10s}', ' '.join(f'{np.median(res[(c,k)]):6.2f}' for c in conds), len(res[(conds[0],k)]))
