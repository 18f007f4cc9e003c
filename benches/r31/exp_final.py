"""Issue 31 candidates on the full tune split, side by side: with the true type, and
with the type chosen by METHOD §12.2 from each candidate's own transmission."""
import sys, numpy as np
sys.path.insert(0, '..')
import truth as T, uwhl_rs, harness as H, exp, exp1, exp4, wls
from scipy.ndimage import gaussian_filter, maximum_filter

def q_for(kind, r, st, wt):
    v, rr, k, lb = st.haze(wt)
    ok = k >= 0
    if kind == 'p95':
        rmax = exp4.rmax_of(rr, k, 500, 0.95)
    else:
        rmax = exp4.rmax_of(rr, k, 500)
    tt = exp4.tt_of(rr, k, rmax)
    if kind.startswith('ccal'):
        c = exp4.cluster_offsets(tt, k, 500, mu=float(kind[4:]))
        tt = np.where(ok, np.clip(tt * np.exp(c[np.maximum(k, 0)]), 0.01, 1), tt)
    if kind == 'lbmax15':
        lb = maximum_filter(lb, size=15)
    p = st.blend(tt, lb)
    if kind.startswith('wls'):
        _, lam, wk = kind.split('_')
        L, _ = wls.laplacian(st.guide)
        cs = dict(k=k, ok=ok, cnt=np.bincount(k[ok], minlength=500).astype(float))
        s1 = np.bincount(k[ok], tt[ok], 500); s2 = np.bincount(k[ok], tt[ok] ** 2, 500)
        m = s1 / np.maximum(cs['cnt'], 1); cs['std'] = np.sqrt(np.maximum(s2 / np.maximum(cs['cnt'], 1) - m * m, 0))
        return np.clip(wls.solve(p, exp1.per_pixel_w(cs, wk), L, float(lam)), 0.01, 1)
    if kind == 'gf_eps0.1':
        return np.asarray(H.C._stage_guided(st.guide, np.ascontiguousarray(p, np.float32), st.radius, 0.1), np.float64)
    if kind == 'smooth20':
        q = st.guided(p)
        return np.exp(-gaussian_filter(-np.log(np.clip(q, 1e-3, 1)), 20))
    return st.guided(p)

def true_type(kind):
    def f(r, st):
        return exp1.fin(r, st, q_for(kind, r, st, r.water_type))
    return f

def chosen(kind):
    def f(r, st):
        best = None
        for wt in H.TYPES:
            q = q_for(kind, r, st, wt)
            _, jc, _, _ = H.finish(st, wt, q, fallback=False)
            s = H.spread(jc, st.objects)
            if best is None or s < best[0]:
                best = (s, wt, q)
        s, wt, q = best
        im, jc, tb, ve = H.finish(st, wt, q)
        return im, {"rho": exp.rho(r, tb), "steps": abs(H.TYPES.index(wt) - H.TYPES.index(r.water_type)), "type": wt}
    return f

def core_default(r, st):
    res = uwhl_rs.restore(r.image)
    return res.image, {"rho": exp.rho(r, res.transmission), "steps": abs(H.TYPES.index(res.water_type) - H.TYPES.index(r.water_type))}

def true_t(r, st):
    return exp1.fin(r, st, np.where(r.objects, r.t[..., 2], 1.0))

TT = ["gf", "gf_eps0.1", "smooth20", "wls_1_uniform", "wls_1_nld", "wls_0.1_nld", "wls_1_spread", "wls_1_count", "p95", "ccal0.1", "ccal1", "lbmax15"]
cands = {"core_default": core_default, "floor_true_t (est A, SoG, fallback)": true_t}
cands.update({f"tt:{k}": true_type(k) for k in TT})
cands.update({f"chosen:{k}": chosen(k) for k in ("gf", "p95", "ccal1")})
if __name__ == "__main__":
    every = int(sys.argv[1]) if len(sys.argv) > 1 else 1
    exp.run(cands, every=every, out=f"out/final_{every}.json")
