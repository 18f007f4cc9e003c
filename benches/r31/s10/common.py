"""What the display prototypes of this folder share: the core's default on
every render of a split (`../s9/cache.py`'s cache) or on the real charts
(charts masked out of estimation, as `uwhl evaluate --mask-charts`), each
output made by ``make(result, objects, variant)`` and scored."""
import sys, os, json
import numpy as np
import uwhl_rs

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "s9"))


def renders(split, variants, make):
    """Median angle per condition of each variant on the renders of ``split``."""
    from ens import load, med, CONDS
    res = {v: {} for v in variants}
    for d in load(split):
        r = uwhl_rs.restore(d["image"].astype(np.float64))
        for v in variants:
            res[v].setdefault(str(d["cond"]), []).append(med(make(r, ~r.veiling_mask, v), d))
    print(split)
    for v in variants:
        print(f"{str(v):16s}", " / ".join(f"{np.median(res[v][c]):5.2f}" for c in CONDS))


def charts(variants, make):
    """Mean gray-patch angle (psi-bar) of each variant on benches/eval/charts.json."""
    from uwhl_rs import images, evaluate as ev
    man = json.load(open(os.path.join(HERE, "..", "..", "eval", "charts.json")))
    tot = {v: [] for v in variants}
    for e in man["images"]:
        img, _ = images.read_image(os.path.normpath(os.path.join(HERE, "..", "..", "eval", e["path"])))
        mask = np.ones(img.shape[:2], bool)
        for ch in e["charts"]:
            for x0, y0, x1, y1 in ch["region"]:
                mask[y0:y1, x0:x1] = False
        r = uwhl_rs.restore(img, mask=mask)
        for v in variants:
            out = make(r, mask & ~r.veiling_mask, v)
            for c in e["charts"]:
                tot[v].append(np.mean([ev.angle_deg(ev._patch_mean(out, b)) for b in c["gray_patches"]]))
    print("charts psi-bar", {str(v): round(float(np.mean(x)), 2) for v, x in tot.items()})
