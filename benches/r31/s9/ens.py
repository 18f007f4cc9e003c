import sys, glob, numpy as np
sys.path.insert(0, "/work/main/benches")
from uwhl_rs import truth as TR
TY = ["I", "IA", "IB", "II", "III", "1C", "3C", "5C", "7C", "9C"]
CONDS = ["gray/white", "gray/tinted", "own/white", "own/tinted"]

def load(split):
    return [dict(np.load(f, allow_pickle=True)) for f in sorted(glob.glob(f"/tmp/s9/cache_{split}/*.npz"))]

def med(img, d):
    return TR.angle_stats(TR.pixel_angles(img, d["truth"], d["obj"] & (d["truth"].sum(2) > TR.MIN_TRUTH_SUM)))["median"]

def cands(d):
    disp = d["disp"].astype(np.float32)
    s = d["scores"]
    out = {"input": d["image"], "gw": d["gw"], "default": d["default"]}
    ti = TY.index(str(d["true"]))
    out["true_type"] = disp[ti]
    for tau in (0.1, 0.25, 0.5):
        rel = s / s.min() - 1
        w = np.exp(-rel / tau); w /= w.sum()
        out[f"soft{tau}"] = np.tensordot(w, disp, 1)
        # geometric in chroma: log mean then keep brightness of arithmetic
        lg = np.tensordot(w, np.log(np.maximum(disp, 1e-4)), 1)
        g = np.exp(lg); a = out[f"soft{tau}"]
        out[f"geo{tau}"] = g * (a.sum(2, keepdims=True) / np.maximum(g.sum(2, keepdims=True), 1e-6))
    out["mean_all"] = disp.mean(0)
    out["median_all"] = np.median(disp, 0)
    ci = TY.index(str(d["chosen"]))
    nb = [j for j in (ci - 1, ci, ci + 1) if 0 <= j < 10]
    out["nbr3"] = disp[nb].mean(0)
    return out

if __name__ == "__main__":
    split = sys.argv[1]
    data = load(split)
    res = {}
    for d in data:
        for k, v in cands(d).items():
            res.setdefault(k, {}).setdefault(str(d["cond"]), []).append(med(v, d))
    print(f"{split}: " + " | ".join(CONDS))
    for k, v in res.items():
        print(f"{k:12s} " + " / ".join(f"{np.median(v[c]):5.2f}" for c in CONDS))
