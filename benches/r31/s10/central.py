"""The central type choice built in the core (METHOD §12.2) against
today's shades_of_gray choice and the prototype's medoid of the three best
(`../s9/medoid.py`), on `../s9/cache.py`'s renders of a split."""
import sys, os, numpy as np
sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "s9"))
from ens import load, med, TY, CONDS
import uwhl_rs
split = sys.argv[1]
res, steps, same = {}, {}, 0
data = load(split)
for d in data:
    img = d["image"].astype(np.float64)
    out = {"shades_of_gray": uwhl_rs.restore(img, type_choice="shades_of_gray"),
           "central": uwhl_rs.restore(img, type_choice="central")}
    ti = TY.index(str(d["true"]))
    for k, r in out.items():
        res.setdefault(k, {}).setdefault(str(d["cond"]), []).append(med(r.image, d))
        steps.setdefault(k, {}).setdefault(str(d["cond"]), []).append(abs(TY.index(r.water_type) - ti) <= 1)
print(split, len(data))
for k in res:
    print(f"{k:16s}", " / ".join(f"{np.median(res[k][c]):5.2f}" for c in CONDS), "  within1", " ".join(f"{sum(steps[k][c])}/{len(steps[k][c])}" for c in CONDS))
