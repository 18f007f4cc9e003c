"""Colour lines with a known distance: the veil point of each patch is fixed by (beta, A) and z."""
import numpy as np, glob, sys, json
sys.path.insert(0,'..'); sys.path.insert(0,'../..')
from clines import patches
import harness as H, truth as T
import uwhl_rs
from uwhl_rs import synth
from scipy.optimize import minimize

def lines_z(img, z, sigma, size=7, stride=4, k=6, maxline=0.05):
    P, cy, cx = patches(img.astype(np.float64), size, stride)
    Z, _, _ = patches(np.repeat(z[:, :, None], 3, 2), size, stride); Z = Z[..., 0]
    mu = P.mean(1); X = P - mu[:, None, :]
    C = np.einsum('nki,nkj->nij', X, X) / P.shape[1]
    lam, vec = np.linalg.eigh(C); D = vec[:, :, 2]
    spread = np.sqrt(np.maximum(lam[:, 2], 0)); line = lam[:, 1] / np.maximum(lam[:, 2], 1e-12)
    clipped = ((P > 0.98) | (P < 0.002)).any((1, 2))
    zf = np.isfinite(Z).all(1) & (Z > 0).all(1)
    zm = np.where(zf[:, None], Z, 1).mean(1)
    ok = (~clipped) & (spread > k * sigma.mean()) & (line < maxline) & zf
    return dict(mu=mu[ok], D=D[ok], spread=spread[ok], z=zm[ok])

def loss(L, beta, a, tau=0.1):
    V = (1 - np.exp(-np.outer(L['z'], beta))) * a[None, :]
    W = V - L['mu']
    proj = (W * L['D']).sum(1)
    r = np.linalg.norm(W - proj[:, None] * L['D'], axis=1) / L['spread']
    q = (r / tau) ** 2
    return np.mean(q / (1 + q))

def refine(L, beta0, a0):
    x0 = np.log(np.concatenate([beta0, a0]))
    f = lambda x: loss(L, np.exp(x[:3]), np.exp(x[3:]))
    r = minimize(f, x0, method='Nelder-Mead', options=dict(xatol=0.003, fatol=1e-5, maxiter=2000, maxfev=4000))
    return np.exp(r.x[:3]), np.exp(r.x[3:]), r.fun

if __name__ == '__main__':
    split = sys.argv[1]; step = int(sys.argv[2])
    out = []
    for f in sorted(glob.glob(f'out/cache/{split}/*.npz'))[::step]:
        d = np.load(f); wt = str(d['meta'][2]); I = d['image']
        z = np.where(np.isfinite(d['dist']), d['dist'], np.nan)
        bt = np.array([T.BETA_B[wt] / synth.JERLOV[wt][0], T.BETA_B[wt] / synth.JERLOV[wt][1], T.BETA_B[wt]])
        atrue = np.asarray(d['atrue'], float)
        res = uwhl_rs.restore(I, distance=z.astype(np.float32))
        if res.water is None: continue
        b0 = np.array(res.water['beta'], float); a0 = np.array(res.veiling_light, float)
        L = lines_z(I, z, H.noise_sigma(I))
        b1, a1, fun = refine(L, b0, a0)
        e0 = np.max(np.abs(b0 / bt - 1)); e1 = np.max(np.abs(b1 / bt - 1))
        out.append(dict(name=str(d['meta'][0]), cond=str(d['meta'][1]), wt=wt, e0=e0, e1=e1, n=len(L['z'])))
        print(str(d['meta'][0])[:40], len(L['z']), f'fit err {e0:.2f} -> {e1:.2f}', 'loss true', round(loss(L, bt, atrue), 3), 'fit0', round(loss(L, b0, a0), 3), 'ref', round(fun, 3),
              'A err', np.abs(a0 - atrue).max().round(3), np.abs(a1 - atrue).max().round(3), flush=True)
    e0 = np.array([o['e0'] for o in out]); e1 = np.array([o['e1'] for o in out])
    print('within 10%:', (e0 <= 0.1).sum(), '->', (e1 <= 0.1).sum(), 'of', len(out), 'median err', np.median(e0).round(3), np.median(e1).round(3))
