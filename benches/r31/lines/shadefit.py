"""Tile slopes with a per-tile shading term (prototype for METHOD §13.2)."""
import numpy as np, sys
sys.path.insert(0,'../..')
from scipy.optimize import minimize
from uwhl_rs import synth
JER = [synth.JERLOV[t] for t in ["I", "IA", "IB", "II", "III", "1C", "3C", "5C", "7C", "9C"]]
P = np.array([[np.log(br), np.log(bg)] for br, bg in JER])

def curve(u):
    k = int(np.clip(np.floor(u), 0, len(P) - 2)); f = u - k
    p = P[k] + f * (P[k + 1] - P[k])
    return np.exp(p[0]), np.exp(p[1])

def tiles(img, z, T=8):
    h, w, _ = img.shape
    out = []
    yy, xx = np.mgrid[0:T, 0:T].astype(float); yy -= (T - 1) / 2; xx -= (T - 1) / 2
    X = np.stack([np.ones(T * T), yy.ravel(), xx.ravel()], 1)
    for y0 in range(0, h - T + 1, T):
        for x0 in range(0, w - T + 1, T):
            zt = z[y0:y0 + T, x0:x0 + T].ravel(); it = img[y0:y0 + T, x0:x0 + T].reshape(-1, 3)
            ok = np.isfinite(zt)
            if ok.sum() < 32: continue
            coef, *_ = np.linalg.lstsq(X[ok], zt[ok], rcond=None)
            zp = X[ok] @ coef; n = ok.sum()
            zm = zp.mean(); vz = ((zp - zm) ** 2).mean()
            if vz <= 1e-12: continue
            I = it[ok]; m = I.mean(0)
            s = ((zp - zm)[:, None] * (I - m)).mean(0) / vz
            v = (((I - m) - s[None] * (zp - zm)[:, None]) ** 2).mean(0)
            wgt = np.sqrt(np.median(n * vz / np.maximum(v, 1e-8)))
            out.append((m, s, zm, wgt))
    m = np.array([o[0] for o in out]); s = np.array([o[1] for o in out]); zb = np.array([o[2] for o in out]); wt = np.array([o[3] for o in out])
    return dict(m=m, s=s, z=zb, w=wt)

def cost(Tl, beta, a, shade=True, delta=None):
    m, s, zb, w = Tl['m'], Tl['s'], Tl['z'], Tl['w']
    r = s + beta[None] * (m - a[None])                  # water model residual
    if shade:
        t = np.exp(-np.outer(zb, beta))
        D = m - (1 - t) * a[None]
        g = (r * D).sum(1) / np.maximum((D * D).sum(1), 1e-12)
        r = r - g[:, None] * D
    # scale: per channel robust spread of s, to make channels comparable
    e = np.sqrt((r ** 2).sum(1))
    if delta is None: delta = np.median(e) + 1e-12
    return np.sum(w * np.where(e < delta, 0.5 * e ** 2 / delta, e - 0.5 * delta))

def refine(Tl, beta0, a0, shade=True):
    # parameters: u along the curve, ln beta_B, ln A
    best = None
    br0, bg0 = beta0[2] / beta0[0], beta0[2] / beta0[1]
    us = np.linspace(0, 9, 91)
    u0 = us[np.argmin([(np.log(curve(u)[0]) - np.log(br0)) ** 2 + (np.log(curve(u)[1]) - np.log(bg0)) ** 2 for u in us])]
    delta = None
    def f(x):
        u, lb = x[0], x[1]; br, bg = curve(np.clip(u, -0.5, 9.5)); bb = np.exp(lb)
        beta = np.array([bb / br, bb / bg, bb]); a = np.exp(x[2:])
        return cost(Tl, beta, a, shade, delta)
    x0 = np.concatenate([[u0, np.log(beta0[2])], np.log(np.maximum(a0, 1e-3))])
    delta_e = None
    r = minimize(f, x0, method='Nelder-Mead', options=dict(xatol=1e-3, fatol=1e-7, maxiter=3000, maxfev=6000))
    for start_u in [u0 - 2, u0 + 2]:
        x1 = x0.copy(); x1[0] = start_u
        r2 = minimize(f, x1, method='Nelder-Mead', options=dict(xatol=1e-3, fatol=1e-7, maxiter=3000, maxfev=6000))
        if r2.fun < r.fun: r = r2
    u, lb = r.x[0], r.x[1]; br, bg = curve(np.clip(u, -0.5, 9.5)); bb = np.exp(lb)
    return np.array([bb / br, bb / bg, bb]), np.exp(r.x[2:]), r.fun
