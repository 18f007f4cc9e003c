"""Map statistics: unique levels, relative step, distinct values per 8x8 tile, tiles kept by the fit."""
import sys, os
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import numpy as np
import qlab as Q
import fit as F

def stats(name, z, img):
    k = np.isfinite(z)
    u = np.unique(z[k])
    rel = np.diff(u) / u[1:]
    nd = []
    h, w = z.shape
    for y in range(0, h - 7, 8):
        for x in range(0, w - 7, 8):
            t = z[y:y+8, x:x+8]; t = t[np.isfinite(t)]
            if len(t) >= 32: nd.append(len(np.unique(t)))
    nd = np.array(nd)
    ts0 = F.tile_stats(img, z.astype(np.float32), eiv=False)
    ts1 = F.tile_stats(img, z.astype(np.float32), eiv=True)
    print(f"{name:34s} levels {len(u):6d} relstep p50 {np.median(rel):.4f} p90 {np.percentile(rel,90):.4f} | distinct/tile p10/50/90 {np.percentile(nd,10):.0f}/{np.median(nd):.0f}/{np.percentile(nd,90):.0f}  <=2: {np.mean(nd<=2):.2f} | tiles {len(nd)} planed {len(ts0['w'])} eiv-kept {len(ts1['w'])}")

for split, pick in (("tune", ("chelsea_floor_gray_white", "chelsea_wall", "coffee_floor_water")), ("held", ("motorcycle_stereo_gray_white_I_", "astronaut_wall"))):
    rs = Q.cache(split)
    for p in pick:
        r = next(r for r in rs if r.name.startswith(p))
        z = Q.truez(r)
        stats(r.name, z, r.image)
        if split == "tune":
            for q in (1.0, 0.5):
                stats(f"  q{q} d0=30", Q.quantise(z, 30, q), r.image)
        else:
            k = np.isfinite(z); print("  zmin", np.nanmin(z), "disp range at 360px (fB=1.5*p99d*360/741):")
