"""Per render of a split: the median angle to the truth of the display
restored with each of the ten types, §12.2's scores, the entropy scores of
entropy.py, the default's choice and angle, gray world's angle. Rules that
combine the two scores are then compared offline (rules.py).

    PYTHONPATH=python python3 benches/r31/s14/cache.py SPLIT OUT.json
"""
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
import entropy as E  # noqa: E402
import truth as T  # noqa: E402

import uwhl_rs  # noqa: E402
from uwhl_rs import truth  # noqa: E402

split, path = sys.argv[1], sys.argv[2]
rows = []
for i, r in enumerate(T.scenes(split)):
    est = uwhl_rs.restore(r.image)
    img = np.asarray(r.image, np.float64)
    a = np.array(est.veiling_light, np.float64)
    mask = ~np.asarray(est.veiling_mask, bool)
    ent, n = E.scores(img, a, mask, E.immerkaer(img)[None, None, :], 0.05, 2.0)
    ang = {}
    for t in T.TYPES:
        out = est.image if t == est.water_type else uwhl_rs.restore(r.image, water_types=[t]).image
        ang[t] = truth.score(out, r.truth, r.objects, gains=True)["median"]
    rows.append({"name": r.name, "content": r.content, "geometry": r.geometry, "cond": f"{r.stats}/{r.light}",
                 "true": r.water_type, "chosen": est.water_type, "sog": {t: float(est.scores[t]) for t in T.TYPES},
                 "ent": ent, "ang": ang, "default": truth.score(est.image, r.truth, r.objects, gains=True)["median"],
                 "gw": truth.score(T.baseline_rows(r)["gray_world"], r.truth, r.objects, gains=True)["median"],
                 "vl": float(np.asarray(est.veiling_mask, bool).mean()), "n": n})
    print(i, r.name, file=sys.stderr)
json.dump(rows, open(path, "w"))
