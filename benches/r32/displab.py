"""Display (white balance) lab: estimators of the light path d on recovered radiance.

Builds a cache of J with the true water and with the fitted water (core's fit, mirrored in NumPy),
then scores estimators of d.
"""

import os
import sys

import numpy as np

import common as C
import fit as F

DS = np.arange(0, 15.0 + 1e-9, 0.25)


def build(split="tune"):
    out = []
    for r in C.renders(split):
        z = C.variants(r)["distance"]
        bt = C.beta_true(r)
        bf, af, _ = F.fit_tiles(r.image, z)
        out.append(dict(r=r, z=z, bt=bt, bf=bf, af=af))
    return out


def cast_d(e, beta, ds=DS):
    """argmin over d of the spread (std/mean) of e * e^(beta d); e: (k,3) several estimates summed."""
    g = np.exp(beta[None, :] * ds[:, None])
    cost = 0
    for ee in np.atleast_2d(e):
        v = g * ee[None, :]
        cost = cost + v.std(1, ddof=1) / v.mean(1)
    return ds[int(np.argmin(cost))], cost


def project(e, beta):
    """(d, residual): the least-squares d in log chromaticity (log e_c + beta_c d
    equal over c; unclamped) and how far e stays from every light through this
    water (the norm left after that d)."""
    le = np.log(np.maximum(e, 1e-12))
    le = le - le.mean()
    b = beta - beta.mean()
    d = -np.dot(le, b) / np.dot(b, b)
    return d, np.linalg.norm(le + d * b)


def log_d(e, beta, w=None, lo=0.0, hi=15.0):
    """Least-squares d in log chromaticity: log e_c + beta_c d equal over c."""
    return float(np.clip(project(e, beta)[0], lo, hi))


def minkowski(px, p):
    if p == np.inf:
        return px.max(0)
    return (px ** p).mean(0) ** (1 / p)


def edges(j, sigma=1.0):
    from scipy.ndimage import gaussian_filter
    out = np.empty_like(j)
    for c in range(3):
        jc = gaussian_filter(j[:, :, c], sigma) if sigma > 0 else j[:, :, c]
        gy, gx = np.gradient(jc)
        out[:, :, c] = np.hypot(gx, gy)
    return out


def box_edges(j):
    """Gradient magnitude of J smoothed by a 5 x 5 box (central differences, 0 on the border)."""
    from scipy.ndimage import uniform_filter
    jb = np.stack([uniform_filter(j[:, :, c], 5, mode="nearest") for c in range(3)], 2)
    gy = np.zeros_like(jb)
    gx = np.zeros_like(jb)
    gy[1:-1] = (jb[2:] - jb[:-2]) / 2
    gx[:, 1:-1] = (jb[:, 2:] - jb[:, :-2]) / 2
    return np.hypot(gx, gy)


def estimates(j, sel, tmin, edge_map):
    """The light's colour estimated from J over the object pixels whose smallest
    transmission is at least tau (0, 0.1, 0.25; all of them where fewer than 2000
    are left): gray world, shades of gray p = 2 and 4, white patch, gray edge p = 1, 2."""
    out = {}
    for tau in (0.0, 0.1, 0.25):
        s = sel & (tmin >= tau)
        if s.sum() < 2000:
            s = sel
        px = j[s][::3]
        out[f"gw{tau}"] = minkowski(px, 1)
        out[f"sog2_{tau}"] = minkowski(px, 2)
        out[f"sog4_{tau}"] = minkowski(px, 4)
        out[f"wp{tau}"] = np.percentile(px, 99, axis=0)
        ed = edge_map[s][::3]
        out[f"ge1_{tau}"] = minkowski(ed, 1)
        out[f"ge2_{tau}"] = minkowski(ed, 2)
    return out


def run(candidates, edge_fn=lambda j: edges(j, 2.0), split="tune"):
    """Scores light-path estimators on the renders of `split` with the fitted water:
    `candidates(P)` maps each estimate's (d, residual) of [`project`] to named
    light paths, scored beside the core's (`core`) and the true one (`true`);
    a render whose fit is suspect keeps the default's score
    (cache/default_tune.pkl). Prints one row per estimator."""
    import pickle
    from collections import defaultdict

    default = pickle.load(open("cache/default_tune.pkl", "rb"))
    res = defaultdict(lambda: defaultdict(list))
    dd = defaultdict(lambda: defaultdict(list))
    for r in C.renders(split):
        z = C.variants(r)["distance"]
        cond = f"{r.stats}/{r.light}"
        ts = F.tile_stats(r.image, z)
        b, a, _ = F.fit_tiles(r.image, z, ts=ts)
        if not F.suspect(ts, b, z)[0]:
            j = C.recover(r.image, z, b, a)
            sel = r.objects
            tmin = np.exp(-b.max() * C.fill_nearest(z))
            est = estimates(j, sel, tmin, edge_fn(j))
            cands = {"core": C.light_path_core(j, sel, b)}
            cands.update(candidates({k: project(e, b) for k, e in est.items()}))
            cands["true"] = 5.0 if r.light == "tinted" else 0.0
            for k, d in cands.items():
                res[k][cond].append(C.score(C.expose(j, np.exp(b * d), sel), r))
                dd[k][cond].append(d)
        else:
            for k in list(res.keys()) or ["core"]:
                res[k][cond].append(default[r.name])
        print(r.name, file=sys.stderr)
    conds = ["gray/white", "gray/tinted", "own/white", "own/tinted"]
    for k in res:
        print(f"{k:22s}", " | ".join(f"{np.median(res[k][c]):5.1f} (d {np.median(dd[k][c]):4.1f})" for c in conds),
              f" max {max(np.median(res[k][c]) for c in conds):.1f}")
