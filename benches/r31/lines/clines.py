"""Colour-lines (Fattal 2014's idea, underwater form) as local t_B estimates: prototype."""
import numpy as np, glob, sys
sys.path.insert(0,'../..'); sys.path.insert(0,'..')
from uwhl_rs import synth
import truth as T

TGRID = np.exp(np.linspace(np.log(0.03), 0, 240))

def patches(img, size=7, stride=4):
    h, w, _ = img.shape
    ys = np.arange(0, h - size + 1, stride); xs = np.arange(0, w - size + 1, stride)
    iy = ys[:, None, None, None] + np.arange(size)[None, None, :, None]
    ix = xs[None, :, None, None] + np.arange(size)[None, None, None, :]
    P = img[iy, ix]  # ny, nx, s, s, 3
    P = P.reshape(len(ys) * len(xs), size * size, 3)
    cy = (ys + size // 2)[:, None].repeat(len(xs), 1).ravel(); cx = (xs + size // 2)[None, :].repeat(len(ys), 0).ravel()
    return P, cy, cx

def estimate(img, a, wt, sigma, size=7, stride=4):
    br, bg = synth.JERLOV[wt]
    P, cy, cx = patches(img.astype(np.float64), size, stride)
    mu = P.mean(1); X = P - mu[:, None, :]
    C = np.einsum('nki,nkj->nij', X, X) / P.shape[1]
    lam, vec = np.linalg.eigh(C)  # ascending
    D = vec[:, :, 2]; l1, l2 = lam[:, 2], lam[:, 1]
    # the veil curve V(t)_c = (1 - t_c) A_c, t_c = t^(1/beta_Bc)
    ex = np.array([1 / br, 1 / bg, 1.0])
    Tc = TGRID[:, None] ** ex[None, :]           # G x 3
    V = (1 - Tc) * a[None, :]                    # G x 3
    W = V[None, :, :] - mu[:, None, :]           # N x G x 3
    proj = np.einsum('ngc,nc->ng', W, D)
    perp = W - proj[..., None] * D[:, None, :]
    e = np.linalg.norm(perp, axis=-1)            # N x G
    gi = e.argmin(1); emin = e[np.arange(len(gi)), gi]
    t = TGRID[gi]
    # the lower bound: every pixel >= its veil (J >= 0), within noise
    veil = V[gi]                                  # N x 3
    below = (P < veil[:, None, :] - 2 * sigma[None, None, :]).mean((1, 2))
    spread = np.sqrt(l1)
    line = l2 / np.maximum(l1, 1e-12)
    # how sharply the line picks t: slope of e around the minimum
    gl = np.clip(gi - 12, 0, len(TGRID) - 1); gh = np.clip(gi + 12, 0, len(TGRID) - 1)
    sharp = (e[np.arange(len(gi)), gl] + e[np.arange(len(gi)), gh]) / 2 - emin
    clipped = ((P > 0.98) | (P < 0.002)).any((1, 2))
    return dict(t=t, cy=cy, cx=cx, emin=emin, spread=spread, line=line, sharp=sharp, below=below, clipped=clipped,
                interior=(gi > 0) & (gi < len(TGRID) - 1))

if __name__ == '__main__':
    import harness as H
    split = sys.argv[1] if len(sys.argv) > 1 else 'tune'
    stats = []
    for f in sorted(glob.glob(f'out/cache/{split}/*.npz'))[::3]:
        d = np.load(f); wt = str(d['meta'][2]); I = d['image']
        dist = d['dist']; obj = np.isfinite(dist)
        ttrue = np.exp(-T.BETA_B[wt] * np.where(obj, dist, 1e3))
        sigma = H.noise_sigma(I)
        for aname, a in [('atrue', np.asarray(d['atrue'], float)), ('aest', np.asarray(d['at'], float))]:
            r = estimate(I, a, wt, sigma)
            ok = (~r['clipped']) & r['interior'] & obj[r['cy'], r['cx']]
            good = ok & (r['spread'] > 6 * sigma.mean()) & (r['line'] < 0.05) & (r['emin'] < 0.2 * r['spread']) & (r['below'] < 0.02) & (r['sharp'] > 0.5 * r['spread'])
            err = np.abs(np.log(r['t']) - np.log(ttrue[r['cy'], r['cx']]))
            tbh = d['tbt']; errh = np.abs(np.log(np.clip(tbh, 1e-3, 1)) - np.log(ttrue))[obj]
            stats.append((str(d['meta'][1]), wt, aname, good.sum(), np.median(err[good]) if good.sum() else np.nan, np.median(err[ok]), np.median(errh)))
            print(str(d['meta'][0])[:40], aname, f'good {good.sum():5d}/{ok.sum()} err_good {stats[-1][4]:.3f} err_all {stats[-1][5]:.3f} hazeline {stats[-1][6]:.3f}', flush=True)
