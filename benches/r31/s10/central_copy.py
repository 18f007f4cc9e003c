"""Does the central choice on fast selection's sampled copy (the core,
photos at full size) pick what the rule gives on the full-size displays
of the same three best-scored types (with the same margin)? Every shared
photo."""
import glob, os, numpy as np
import uwhl_rs
from uwhl_rs import images
def chroma(x): y = np.maximum(x.astype(np.float64), 1e-6); return y / y.sum(1, keepdims=True)
agree = 0; n = 0
for p in sorted(glob.glob("/work/shared/data/images/*")):
    if p.endswith(".mat"): continue
    img, _ = images.read_image(p)
    r = uwhl_rs.restore(img)
    best3 = sorted(r.scores, key=r.scores.get)[:3]
    obj = ~r.veiling_mask
    rng = np.random.default_rng(0); idx = np.flatnonzero(obj.ravel()); keep = rng.choice(idx, min(20000, idx.size), replace=False)
    ch = {k: chroma(uwhl_rs.restore(img, water_types=[k]).image.reshape(-1, 3)[keep]) for k in best3}
    sp = {a: sum(np.median(np.abs(ch[a] - ch[b]).sum(1)) for b in best3) for a in best3}
    pick = min(best3, key=sp.get)
    if sp[pick] >= sp[best3[0]] - 1e-3:  # CENTRAL_MARGIN
        pick = best3[0]
    n += 1; agree += pick == r.water_type
    print(f"{os.path.basename(p):34s} core {r.water_type:4s} full {pick:4s}", {k: round(v, 4) for k, v in sp.items()}, flush=True)
print(f"agree {agree}/{n}")
