"""A constant blend of the default's display toward a gray-world balance of
the input, brought to the display's brightness per pixel (two estimates with
partly independent errors), scored on a split of benches/truth.py.

    RAYON_NUM_THREADS=1 PYTHONPATH=python python3 benches/r31/s15/blend.py SPLIT [OUT.json]
"""
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
import truth as T  # noqa: E402

import uwhl_rs  # noqa: E402
from uwhl_rs import truth  # noqa: E402
from uwhl_rs import evaluate as ev  # noqa: E402

WS = [0.0, 0.25, 0.4, 0.5, 0.6, 0.75, 1.0]
CONDS = ["gray/white", "gray/tinted", "own/white", "own/tinted"]
split = sys.argv[1]
rows = []
for r in T.scenes(split):
    res = uwhl_rs.restore(r.image)
    d = np.asarray(res.image, np.float64)
    b = np.asarray(ev.grayworld(r.image), np.float64)
    b = b * (d.sum(2, keepdims=True) / np.maximum(b.sum(2, keepdims=True), 1e-9))
    ang = {w: truth.score((1 - w) * d + w * b, r.truth, r.objects, gains=False)["median"] for w in WS}
    ang["input"] = truth.score(r.image, r.truth, r.objects, gains=False)["median"]
    rows.append({"cond": f"{r.stats}/{r.light}", "name": r.name, "fb": res.fallback_share, "ang": ang})
    print(r.name, " ".join(f"{ang[w]:.1f}" for w in WS), file=sys.stderr)
if len(sys.argv) > 2:
    json.dump(rows, open(sys.argv[2], "w"))
for key in WS + ["input"]:
    print(f"{str(key):6s}", " | ".join(f"{np.median([x['ang'][key] for x in rows if x['cond'] == c]):5.2f}" for c in CONDS))
