"""Transmission error itself (true type): median |ln t_est - ln t_true| over objects, and after the best per-image scale."""
import sys, numpy as np
sys.path.insert(0, '..')
import truth as T, harness as H, exp1, exp4, wls
from scipy.ndimage import gaussian_filter

def anchor(tt, k, obj, q=0.99):
    m = np.quantile(tt[obj & (k >= 0)], q)
    return np.clip(tt / max(m, 1e-3), 0.01, 1)

def cands(r, st):
    rr, k, lb = exp4.base(r, st, 500)
    rmax = exp4.rmax_of(rr, k, 500)
    tt = exp4.tt_of(rr, k, rmax)
    out = {}
    out['gf'] = st.guided(st.blend(tt, lb))
    for mu in (0.1, 1.0):
        c = exp4.cluster_offsets(tt, k, 500, mu=mu)
        t2 = np.where(k >= 0, np.clip(tt * np.exp(c[np.maximum(k, 0)]), 0.01, 1), tt)
        out[f'ccal{mu}'] = st.guided(st.blend(t2, lb))
        out[f'ccal{mu}_anchor'] = st.guided(st.blend(anchor(t2, k, ~st.vl), lb))
    out['p95'] = st.guided(st.blend(exp4.tt_of(rr, k, exp4.rmax_of(rr, k, 500, 0.95)), lb))
    cs = exp1.parts(r, st)
    out['wls_u_1'] = np.clip(wls.solve(cs['p'], np.ones_like(cs['p']), cs['L'], 1.0), 0.01, 1)
    out['lb_only'] = st.guided(np.maximum(lb, 0.1))
    out['const0.5'] = np.full_like(tt, 0.5)
    return out

if __name__ == "__main__":
    res = {}
    n = 0
    for r in T.scenes('tune', 360):
        n += 1
        if (n - 1) % 2: continue
        st = H.Image(r.image)
        obj = r.objects
        lt = np.log(np.clip(r.t[..., 2][obj], 1e-4, 1))
        cond = f"{r.stats}/{r.light}"
        br = H.JER[r.water_type][0]
        for name, q in cands(r, st).items():
            lq = np.log(np.clip(q[obj], 0.1 ** br, 1))
            e = np.median(np.abs(lq - lt))
            s = (lq @ lt) / (lq @ lq)
            es = np.median(np.abs(s * lq - lt))
            res.setdefault(name, {}).setdefault(cond, []).append((e, es, np.corrcoef(lq, lt)[0, 1]))
        print(r.name, file=sys.stderr, flush=True)
    print("| t | " + " | ".join(["gray/white", "gray/tinted", "own/white", "own/tinted"]) + " |")
    for name, d in res.items():
        print(f"| {name} | " + " | ".join(f"{np.median([x[0] for x in v]):.3f} / {np.median([x[1] for x in v]):.3f} / {np.median([x[2] for x in v]):.2f}" for v in d.values()) + " |")
