"""Joint fit of A (and type) from colour-lines: prototype."""
import numpy as np, glob, sys
sys.path.insert(0,'..'); sys.path.insert(0,'../..')
from clcore import feats
import harness as H
from uwhl_rs import synth
from scipy.optimize import minimize
TYPES = H.TYPES
TG = np.exp(np.linspace(np.log(0.03), 0, 80))

def candidates(img, sigma, maxn=1500, seed=0):
    F = feats(img, sigma)
    ok = (~F['clipped']) & (F['spread'] > 6 * F['sig']) & (F['line'] < 0.05) & (F['mid'] > 0.3)
    idx = np.nonzero(ok)[0]
    if len(idx) > maxn:
        idx = np.random.default_rng(seed).choice(idx, maxn, replace=False)
    return dict(mu=F['mu'][idx], D=F['D'][idx], spread=F['spread'][idx], cy=F['cy'][idx], cx=F['cx'][idx], n=len(idx))

def dist(c, a, wt):
    br, bg = wt if isinstance(wt, tuple) else synth.JERLOV[wt]
    ex = np.array([1 / br, 1 / bg, 1.0])
    V = (1 - TG[:, None] ** ex[None, :]) * a[None, :]
    W = V[None] - c['mu'][:, None, :]
    proj = np.einsum('ngc,nc->ng', W, c['D'])
    e = np.linalg.norm(W - proj[..., None] * c['D'][:, None, :], axis=-1)
    gi = e.argmin(1)
    return e[np.arange(len(gi)), gi] / c['spread'], TG[gi], gi

def loss(c, a, wt, tau=0.1):
    r, t, gi = dist(c, a, wt)
    q = (r / tau) ** 2
    return np.mean(q / (1 + q))  # Cauchy-like, bounded

def fit_a(c, a0, wt, tau=0.1):
    f = lambda la: loss(c, np.exp(la), wt, tau)
    best = None
    for s in [1.0, 0.7, 1.4]:
        x0 = np.log(np.maximum(a0 * s, 1e-3))
        r = minimize(f, x0, method='Nelder-Mead', options=dict(xatol=0.01, fatol=1e-4, maxiter=300))
        if best is None or r.fun < best.fun: best = r
    return np.exp(best.x), best.fun

if __name__ == '__main__':
    split = sys.argv[1]; step = int(sys.argv[2]); mode = sys.argv[3]
    out = []
    for f in sorted(glob.glob(f'out/cache/{split}/*.npz'))[::step]:
        d = np.load(f); wt = str(d['meta'][2]); I = d['image']
        sigma = H.noise_sigma(I); c = candidates(I, sigma)
        atrue = np.asarray(d['atrue'], float); a0 = np.asarray(d['a'], float)
        if mode == 'a':
            a, fun = fit_a(c, a0, wt)
            print(str(d['meta'][0])[:38], c['n'], 'A0 err', np.abs(a0 - atrue).max().round(3), 'fit err', np.abs(a - atrue).max().round(3),
                  'loss true', round(loss(c, atrue, wt), 3), 'fit', round(fun, 3), flush=True)
        else:
            fits = {t: fit_a(c, a0, t) for t in TYPES}
            pick = min(TYPES, key=lambda t: fits[t][1])
            steps = abs(TYPES.index(pick) - TYPES.index(wt))
            print(str(d['meta'][0])[:38], str(d['meta'][1]), wt, '->', pick, steps, 'Aerr', np.abs(fits[pick][0] - atrue).max().round(3), 'A0err', np.abs(a0 - atrue).max().round(3),
                  ' '.join(f'{fits[t][1]:.3f}' for t in TYPES), flush=True)
