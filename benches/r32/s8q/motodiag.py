"""Diagnosis only (held motorcycle): is the map quantised, and what does the fit see in the content alone?
The fit run on the water-free truth J (no water, no noise): whatever attenuation it finds is the content's."""
import os, sys
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import numpy as np
import qlab as Q, qfit as G, fit as F

rs = Q.cache("held")
for cname in ("motorcycle",):
    r = next(x for x in rs if x.content == cname and x.stats == "own")
    z = Q.truez(r)
    for nm, img in (("truth J (own)", r.truth), ):
        ts = G.tile_stats(img.astype(np.float64), z)
        beta, a, _ = F.fit_tiles(img, z, ts=ts)
        w = ts["w"]
        k = [F.wmedian_rows((-ts["s"][:, c] / np.maximum(ts["m"][:, c], 1e-3))[None], w)[0] for c in range(3)]
        print(cname, nm, "fit beta", np.round(beta, 3), "wmedian of -s/m per channel", np.round(k, 3))
    # content brightness against distance over the objects
    lum = r.truth.mean(2); zz = z[np.isfinite(z)]
    print("corr(log J mean, z) over pixels", np.corrcoef(np.log(lum[np.isfinite(z)] + 1e-3), zz)[0, 1])
    # depth edges: share of tiles whose plane residual is large
    ts1 = F.tile_stats(r.image, z.astype(np.float32), eiv=False)
    print("tiles", len(ts1["w"]))

# depth-edge tiles: the plane's residual against the tile's planed variance
import numpy as np
dy, dx = np.mgrid[0:8, 0:8].astype(float) - 3.5
X = np.stack([np.ones(64), dy.ravel(), dx.ravel()], 1)
h, w = z.shape
rel = []
for y0 in range(0, h - 7, 8):
    for x0 in range(0, w - 7, 8):
        t = z[y0:y0+8, x0:x0+8].ravel()
        if not np.all(np.isfinite(t)): continue
        c, *_ = np.linalg.lstsq(X, t, rcond=None); res = t - X @ c
        rel.append(np.sqrt((res**2).mean()) / t.mean())
rel = np.array(rel)
print("tile rms plane residual / z: p50 %.4f p75 %.4f p90 %.4f; share > 1%%: %.2f, > 3%%: %.2f" % (np.median(rel), *np.percentile(rel, [75, 90]), (rel > .01).mean(), (rel > .03).mean()))
for thr in (0.003, 0.01, 0.03):
    zz = z.copy()
    for y0 in range(0, h - 7, 8):
        for x0 in range(0, w - 7, 8):
            t = z[y0:y0+8, x0:x0+8].ravel()
            if not np.all(np.isfinite(t)): continue
            c, *_ = np.linalg.lstsq(X, t, rcond=None); res = t - X @ c
            if np.sqrt((res**2).mean()) / t.mean() > thr: zz[y0:y0+8, x0:x0+8] = np.nan
    for nm, img in (("truth J", r.truth), ("render I type", r.image)):
        ts = G.tile_stats(img.astype(np.float64), zz)
        beta, a, _ = F.fit_tiles(img, zz, ts=ts)
        print(f"  smooth tiles only (resid<{thr}) {nm}: tiles {len(ts['w'])} beta {np.round(beta,3)}", "true" if nm != "truth J" else "", np.round(r.bt, 3) if nm != "truth J" else "")
