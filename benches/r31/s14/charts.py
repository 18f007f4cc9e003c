"""The real charts (benches/eval/charts.json, charts masked as `uwhl
evaluate --mask-charts` does) under the type rules of rules.py: mean
gray-patch angle of the default and of each rule's type.

    PYTHONPATH=python python3 benches/r31/s14/charts.py
"""
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import dither as D  # noqa: E402
import entropy as E  # noqa: E402
import rules as R  # noqa: E402

import uwhl_rs  # noqa: E402
from uwhl_rs import evaluate as ev  # noqa: E402
from uwhl_rs import images  # noqa: E402

HERE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "eval")
man = json.load(open(os.path.join(HERE, "charts.json")))
tot = {n: [] for n in R.RULES}
for e in man["images"]:
    img, _ = images.read_image(os.path.normpath(os.path.join(HERE, e["path"])))
    h, w = img.shape[:2]
    mask = np.ones((h, w), bool)
    for ch in e["charts"]:
        for x0, y0, x1, y1 in ch["region"]:
            mask[y0:y1, x0:x1] = False
    est = uwhl_rs.restore(img, mask=mask)
    im64 = np.asarray(img, np.float64)
    if os.environ.get("DITHER"):
        im64 = D.dithered(im64)
    ent, n = E.scores(im64, np.array(est.veiling_light, np.float64), mask & ~np.asarray(est.veiling_mask, bool),
                      E.immerkaer(np.asarray(img, np.float64))[None, None, :], 0.05, 2.0)
    row = {"chosen": est.water_type, "sog": {t: float(est.scores[t]) for t in R.TY}, "ent": ent}
    picks = {name: f(row) for name, f in R.RULES.items()}
    disp = {}
    for name, t in picks.items():
        if t not in disp:
            disp[t] = est.image if t == est.water_type else uwhl_rs.restore(img, mask=mask, water_types=[t]).image
        for c in e["charts"]:
            tot[name].append(np.mean([ev.angle_deg(ev._patch_mean(disp[t], b)) for b in c["gray_patches"]]))
    print(os.path.basename(e["path"]), picks)
print({k: round(float(np.mean(v)), 2) for k, v in tot.items()})
