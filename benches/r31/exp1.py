import sys, numpy as np
import harness as H, wls, exp

def cluster_stats(st, wt):
    v, r, k, lb = st.haze(wt)
    ok = k >= 0
    K = H.N_POINTS
    rmax = np.zeros(K); np.maximum.at(rmax, k[ok], r[ok])
    tt = st.t_tilde(r, k, rmax)
    cnt = np.bincount(k[ok], minlength=K).astype(float)
    s1 = np.bincount(k[ok], weights=tt[ok], minlength=K)
    s2 = np.bincount(k[ok], weights=tt[ok] ** 2, minlength=K)
    mean = s1 / np.maximum(cnt, 1)
    std = np.sqrt(np.maximum(s2 / np.maximum(cnt, 1) - mean ** 2, 0))
    return dict(v=v, r=r, k=k, lb=lb, rmax=rmax, tt=tt, cnt=cnt, mean=mean, std=std, ok=ok)

CACHE = {}
def parts(r, st):
    key = r.name
    if key not in CACHE:
        CACHE.clear()
        cs = cluster_stats(st, r.water_type)
        cs['p'] = st.blend(cs['tt'], cs['lb'])
        L, _ = wls.laplacian(st.guide)
        cs['L'] = L
        CACHE[key] = cs
    return CACHE[key]

def fin(r, st, q, fb=True):
    im, jc, tb, ve = H.finish(st, r.water_type, q, fallback=fb)
    return im, {"rho": exp.rho(r, tb)}

def gf(eps=1e-3, fb=True):
    def f(r, st):
        cs = parts(r, st)
        q = np.asarray(H.C._stage_guided(st.guide, np.ascontiguousarray(cs['p'], np.float32), st.radius, eps), np.float64)
        return fin(r, st, q, fb)
    return f

def per_pixel_w(cs, kind):
    k, ok = cs['k'], cs['ok']
    if kind == 'uniform':
        wc = np.ones(H.N_POINTS)
    elif kind == 'nld':   # 1 / std of t~ in the haze-line
        wc = 1.0 / np.maximum(cs['std'], 0.02) ** 2
        wc /= np.median(wc[cs['cnt'] > 0])
    elif kind == 'count':
        wc = np.minimum(1.0, cs['cnt'] / 200.0)
    elif kind == 'spread':  # clusters spanning a range of t~ are more likely to hold a haze-free pixel
        wc = np.clip(cs['std'] / 0.15, 0, 1) * np.minimum(1.0, cs['cnt'] / 200.0)
    w = np.where(ok, wc[np.maximum(k, 0)], 0.0)
    return np.maximum(w, 1e-4)

def wlsc(kind, lam, fb=True, log=False):
    def f(r, st):
        cs = parts(r, st)
        w = per_pixel_w(cs, kind)
        t0 = cs['p']
        if log:
            q = np.exp(-wls.solve(-np.log(np.clip(t0, 1e-3, 1)), w, cs['L'], lam))
        else:
            q = wls.solve(t0, w, cs['L'], lam)
        return fin(r, st, np.clip(q, 0, 1), fb)
    return f

cands = {
    "gf": gf(), "gf_nofb": gf(fb=False), "gf_eps1e-2": gf(1e-2), "gf_eps1e-1": gf(1e-1),
    "wls_u_0.01": wlsc("uniform", 0.01), "wls_u_0.1": wlsc("uniform", 0.1), "wls_u_1": wlsc("uniform", 1.0), "wls_u_10": wlsc("uniform", 10.0),
    "wls_nld_0.1": wlsc('nld', 0.1), "wls_nld_1": wlsc('nld', 1.0),
    "wls_cnt_1": wlsc('count', 1.0), "wls_spr_1": wlsc('spread', 1.0),
}
if __name__ == "__main__":
    every = int(sys.argv[1]) if len(sys.argv) > 1 else 1
    exp.run(cands, every=every, out=f"out/exp1_{every}.json")
