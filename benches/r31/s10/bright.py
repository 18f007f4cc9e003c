"""Bright pixels as a second estimate of the light (prototype on the
core's display): the mean colour of the brightest TOP share of object
pixels (masked in, not VL, none clipped) is taken as gray, and the
display gets those gains to the power ALPHA (global, no pixel treated
alone), exposure kept. Renders of a split (`../s9/cache.py`'s) and, with
`charts`, the real charts (charts masked out of estimation, so the
estimate never sees them)."""
import sys, os, json, numpy as np
here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(here, "..", "s9"))
import uwhl_rs

VARIANTS = [(None, None), (0.02, 0.5), (0.02, 1.0), (0.05, 0.5), (0.05, 1.0), (0.1, 0.5)]

def bright_gains(img, objects, top):
    s = img.sum(-1)
    ok = objects & (img.max(-1) < 0.995)
    if ok.sum() < 20:
        return np.ones(3)
    thr = np.quantile(s[ok], 1 - top)
    e = img[ok & (s >= thr)].mean(0)
    mu = e.mean()
    return np.where(e > 0, mu / np.maximum(e, 1e-9), 1.0)

def apply(img, objects, top, alpha):
    if top is None:
        return img
    g = bright_gains(img, objects, top) ** alpha
    out = img * g
    k = np.quantile(img.max(-1), 0.99) / max(np.quantile(out.max(-1), 0.99), 1e-9)
    return np.clip(out * k, 0, 1)

if __name__ == "__main__" and sys.argv[1] != "charts":
    from ens import load, med, CONDS
    split = sys.argv[1]
    res = {v: {} for v in VARIANTS}
    for d in load(split):
        r = uwhl_rs.restore(d["image"].astype(np.float64))
        objects = ~r.veiling_mask
        for v in VARIANTS:
            res[v].setdefault(str(d["cond"]), []).append(med(apply(r.image, objects, *v), d))
    print(split)
    for v in VARIANTS:
        print(f"{str(v):12s}", " / ".join(f"{np.median(res[v][c]):5.2f}" for c in CONDS))
elif __name__ == "__main__":
    from uwhl_rs import images, evaluate as ev
    man = json.load(open(os.path.join(here, "..", "..", "eval", "charts.json")))
    tot = {v: [] for v in VARIANTS}
    for e in man["images"]:
        p = os.path.normpath(os.path.join(here, "..", "..", "eval", e["path"]))
        img, _ = images.read_image(p)
        mask = np.ones(img.shape[:2], bool)
        for ch in e["charts"]:
            for x0, y0, x1, y1 in ch["region"]:
                mask[y0:y1, x0:x1] = False
        r = uwhl_rs.restore(img, mask=mask)
        objects = mask & ~r.veiling_mask
        for v in VARIANTS:
            out = apply(r.image, objects, *v)
            for c in e["charts"]:
                tot[v].append(np.mean([ev.angle_deg(ev._patch_mean(out, b)) for b in c["gray_patches"]]))
    print("charts psi-bar", {str(v): round(float(np.mean(x)), 2) for v, x in tot.items()})
