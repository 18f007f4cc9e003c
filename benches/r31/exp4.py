"""Per-haze-line calibration candidates (true type): robust r_max, cluster offsets
fitted by spatial consistency, finer clusters, windowed lower bound."""
import sys, numpy as np
import scipy.sparse as sp, scipy.sparse.linalg as spl
from scipy.ndimage import maximum_filter
import harness as H, exp, exp1

def haze_k(st, wt, npts):
    br, bg = H.conditioned(wt)
    d = st.a[None, None, :] - st.img.astype(np.float64)
    v = np.stack([np.sign(d[..., 0]) * np.abs(d[..., 0]) ** br, np.sign(d[..., 1]) * np.abs(d[..., 1]) ** bg, d[..., 2]], -1)
    r = np.linalg.norm(v, axis=-1)
    u = (v / np.maximum(r, 1e-12)[..., None]).reshape(-1, 3).astype(np.float32)
    _, near = H.C._stage_sphere(npts, u)
    k = np.asarray(near, np.int64).reshape(st.h, st.w); k[r <= 0] = -1
    return r, k

CK = {}
def base(r, st, npts=500):
    key = (r.name, npts)
    if key not in CK:
        if len(CK) > 4: CK.clear()
        rr, k = haze_k(st, r.water_type, npts)
        cs = exp1.parts(r, st)
        CK[key] = (rr, k, cs['lb'])
    return CK[key]

def rmax_of(rr, k, npts, q=None):
    ok = k >= 0
    rmax = np.zeros(npts)
    if q is None:
        np.maximum.at(rmax, k[ok], rr[ok])
        return rmax
    order = np.lexsort((rr[ok], k[ok]))
    ks, rs = k[ok][order], rr[ok][order]
    starts = np.searchsorted(ks, np.arange(npts)); ends = np.searchsorted(ks, np.arange(npts), 'right')
    for c in range(npts):
        if ends[c] > starts[c]:
            rmax[c] = np.quantile(rs[starts[c]:ends[c]], q)
    return rmax

def tt_of(rr, k, rmax):
    t = np.ones_like(rr); ok = k >= 0
    t[ok] = np.clip(rr[ok] / np.maximum(rmax[k[ok]], 1e-12), 0.01, 1)
    return t

def cluster_offsets(tt, k, npts, mu=1.0, prior=None):
    """log t = log t~ + c_k: offsets making neighbouring pixels of different clusters agree."""
    lt = np.log(np.clip(tt, 1e-3, 1))
    pairs = []
    for a, b in ((k[:, :-1], k[:, 1:]), (k[:-1, :], k[1:, :])):
        pairs.append((a.ravel(), b.ravel()))
    la = np.concatenate([lt[:, :-1].ravel(), lt[:-1, :].ravel()])
    lb_ = np.concatenate([lt[:, 1:].ravel(), lt[1:, :].ravel()])
    ka = np.concatenate([p[0] for p in pairs]); kb = np.concatenate([p[1] for p in pairs])
    m = (ka != kb) & (ka >= 0) & (kb >= 0)
    ka, kb, d = ka[m], kb[m], (la - lb_)[m]
    n = len(d)
    # rows: c_ka - c_kb = -d
    D = sp.coo_matrix((np.concatenate([np.ones(n), -np.ones(n)]), (np.concatenate([np.arange(n)] * 2), np.concatenate([ka, kb]))), shape=(n, npts)).tocsr()
    cnt = np.bincount(k[k >= 0], minlength=npts).astype(float)
    pw = mu * (cnt if prior is None else prior)
    M = (D.T @ D) + sp.diags(pw + 1e-9)
    c = spl.spsolve(M.tocsc(), D.T @ (-d))
    return c

def make(npts=500, q=None, ccal=None, scale=0.9, window=0, fb=True):
    def f(r, st):
        rr, k, lb = base(r, st, npts)
        rmax = rmax_of(rr, k, npts, q)
        tt = tt_of(rr, k, rmax)
        if ccal is not None:
            c = cluster_offsets(tt, k, npts, mu=ccal)
            c = np.minimum(c, 0) if False else c
            tt = np.where(k >= 0, np.clip(tt * np.exp(c[np.maximum(k, 0)]), 0.01, 1), tt)
        lbw = maximum_filter(lb, size=window) if window else lb
        p = st.blend(tt, lbw, scale)
        qq = st.guided(p)
        return exp1.fin(r, st, qq, fb)
    return f

cands = {"gf": make(), "gf_nofb": make(fb=False), "p99": make(q=0.99), "p95": make(q=0.95),
         "ccal1": make(ccal=1.0), "ccal0.1": make(ccal=0.1), "ccal0.1_nofb": make(ccal=0.1, fb=False),
         "n2000": make(2000), "n2000_ccal0.1": make(2000, ccal=0.1), "lbmax15": make(window=15), "lbmax41": make(window=41)}
if __name__ == "__main__":
    every = int(sys.argv[1]) if len(sys.argv) > 1 else 1
    exp.run(cands, every=every, out=f"out/exp4_{every}.json")
