"""Water type from material groups: per group, the slope of ln(A_c - I_c) on ln(A_B - I_B)
is beta_c / beta_B = 1 / beta_Bc (METHOD §0) whatever the distance; pooled -> ratios -> nearest type."""
import sys, numpy as np
sys.path.insert(0, '..')
import truth as T, harness as H
from scipy.cluster.vq import kmeans2
from scipy.ndimage import gaussian_filter

def slopes(img, a, groups, sigma, minn=30, k=3.0):
    d = a[None, None, :] - img.astype(np.float64)
    out = []
    for c in (0, 1):
        ok = (d[..., c] > k * sigma[c]) & (d[..., 2] > k * sigma[2]) & (groups >= 0)
        x = np.log(d[..., 2][ok]); y = np.log(d[..., c][ok]); g = groups[ok]
        G = g.max() + 1 if g.size else 1
        n = np.bincount(g, minlength=G).astype(float)
        good = n >= minn
        mx = np.bincount(g, x, G) / np.maximum(n, 1); my = np.bincount(g, y, G) / np.maximum(n, 1)
        xc = x - mx[g]; yc = y - my[g]
        keep = good[g]
        sxx = (xc[keep] ** 2).sum(); sxy = (xc[keep] * yc[keep]).sum(); syy = (yc[keep] ** 2).sum()
        # reduced major axis: errors in both
        out.append(np.sign(sxy) * np.sqrt(syy / max(sxx, 1e-12)) if sxx > 0 else np.nan)
        out.append(sxy / max(sxx, 1e-12))
    return out  # [rma_R, ols_R, rma_G, ols_G] as 1/beta_BR, 1/beta_BG

def nearest_type(inv_br, inv_bg):
    if not (np.isfinite(inv_br) and np.isfinite(inv_bg)):
        return "3C"
    best, bd = None, np.inf
    for t in H.TYPES:
        br, bg = H.JER[t]
        dd = (np.log(1 / br) - np.log(max(inv_br, 1e-3))) ** 2 + (np.log(1 / bg) - np.log(max(inv_bg, 1e-3))) ** 2
        if dd < bd: best, bd = t, dd
    return best

def groups_truth(r, k=48):
    obj = r.objects
    x = r.truth[obj].astype(np.float64)
    x = np.log(x + 0.01)
    np.random.seed(0)
    _, lab = kmeans2(x, k, minit='++', seed=0)
    g = -np.ones(obj.shape, int); g[obj] = lab
    return g

def groups_invariant(r, st, k=48, s=2.0):
    """A t-free feature: |grad I_c| / (A_c - I_c) = |grad J_c| / (A_c - J_c) where t is smooth."""
    img = gaussian_filter(st.img.astype(np.float64), (s, s, 0))
    d = st.a[None, None, :] - img
    gy, gx = np.gradient(img, axis=(0, 1))
    gm = np.sqrt(gx ** 2 + gy ** 2)
    f = np.log(gm + 1e-4) - np.log(np.abs(d) + 1e-3)
    obj = ~st.vl
    _, lab = kmeans2(f[obj], k, minit='++', seed=0)
    g = -np.ones(obj.shape, int); g[obj] = lab
    return g

if __name__ == "__main__":
    res = {}
    n = 0
    for r in T.scenes('tune', 360):
        n += 1
        if (n - 1) % 2: continue
        st = H.Image(r.image)
        sig = st.sigma
        cond = f"{r.stats}/{r.light}"
        tr_br, tr_bg = H.JER[r.water_type]
        for name, a, g in (("truthgroups_trueA", np.clip(r.a, 1e-4, 1), groups_truth(r)), ("truthgroups_estA", st.a, None), ("invgroups_estA", st.a, groups_invariant(r, st))):
            if g is None: g = groups_truth(r)
            s = slopes(r.image, a, g, sig)
            print(' ', name, f"{s[0]:.2f} {s[2]:.2f} ols {s[1]:.2f} {s[3]:.2f}", file=sys.stderr)
            for m, (ir, ig) in (("rma", (s[0], s[2])), ("ols", (s[1], s[3]))):
                t = nearest_type(ir, ig)
                steps = abs(H.TYPES.index(t) - H.TYPES.index(r.water_type))
                res.setdefault((name, m), {}).setdefault(cond, []).append(steps)
        print(r.name, f"true 1/br {1/tr_br:.2f} 1/bg {1/tr_bg:.2f}", file=sys.stderr, flush=True)
    for key, d in res.items():
        print(key, {c: f"{sum(x <= 1 for x in v)}/{len(v)}" for c, v in d.items()})
