import sys, json, os, numpy as np
import uwhl_rs
from uwhl_rs import images, evaluate as ev
TY = ["I", "IA", "IB", "II", "III", "1C", "3C", "5C", "7C", "9C"]
def chroma(x, m):
    y = np.maximum(x[m].astype(np.float64), 1e-6); return y / y.sum(1, keepdims=True)
man = json.load(open("/work/main/benches/eval/charts.json"))
tot = {"today": [], "medoid3": []}
for e in man["images"]:
    p = os.path.normpath(os.path.join("/work/main/benches/eval", e["path"]))
    img, _ = images.read_image(p)
    h, w = img.shape[:2]
    mask = np.ones((h, w), bool)
    for ch in e["charts"]:
        for x0, y0, x1, y1 in ch["region"]:
            mask[y0:y1, x0:x1] = False
    r = uwhl_rs.restore(img, mask=mask)
    s = np.array([r.scores[t] for t in TY]); best3 = np.argsort(s)[:3]
    disps = {k: uwhl_rs.restore(img, mask=mask, water_types=[TY[k]]).image for k in best3}
    rng = np.random.default_rng(0); idx = np.flatnonzero(mask.ravel()); keep = rng.choice(idx, min(20000, idx.size), replace=False)
    m = np.zeros(h * w, bool); m[keep] = True; m = m.reshape(h, w)
    ch_ = {k: chroma(disps[k], m) for k in best3}
    D = {a: sum(np.median(np.abs(ch_[a] - ch_[b]).sum(1)) for b in best3) for a in best3}
    pick = min(best3, key=lambda a: D[a])
    print(os.path.basename(p), "today", r.water_type, "best3", [TY[k] for k in best3], "medoid", TY[pick])
    for c in e["charts"]:
        for name, im in (("today", r.image), ("medoid3", disps[pick])):
            tot[name].append(np.mean([ev.angle_deg(ev._patch_mean(im, b)) for b in c["gray_patches"]]))
print({k: round(float(np.mean(v)), 2) for k, v in tot.items()})
