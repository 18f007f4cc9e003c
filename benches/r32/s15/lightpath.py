"""What the light path of METHOD §13.4 comes out at on a split of
benches/truth.py with the true distance (true path: 0 under white light,
LIGHT_PATH under tinted), and the angle with it and with the true path
(a NumPy re-display of the core's radiance: gains e^(beta_fit d), exposure
and clipping as §13.4, without the settling of far noise).

    RAYON_NUM_THREADS=1 PYTHONPATH=python python3 benches/r32/s15/lightpath.py SPLIT
"""
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
import truth as T  # noqa: E402

import uwhl_rs  # noqa: E402
from uwhl_rs import truth  # noqa: E402

CONDS = ["gray/white", "gray/tinted", "own/white", "own/tinted"]


def shown(res, d):
    beta = np.array(res.water["beta"])
    j = np.asarray(res.radiance, np.float64)
    g = np.exp((beta - beta.max()) * d)
    x = j * g
    s = 1 / max(np.percentile(x.max(axis=2), 99), 1e-9)
    return np.clip(x * s, 0, 1)


rows = []
for r in T.scenes(sys.argv[1]):
    z = np.where(np.isfinite(r.distance), r.distance, np.nan).astype(np.float32)
    res = uwhl_rs.restore(r.image, distance=z)
    if not res.distance["used"]:
        continue
    d = res.distance["light_path"]
    true = T.LIGHT_PATH if r.light == "tinted" else 0.0
    a = {k: truth.score(v, r.truth, r.objects, gains=False)["median"]
         for k, v in (("core", res.image), ("est", shown(res, d)), ("true", shown(res, true)))}
    rows.append((f"{r.stats}/{r.light}", d, true, a))
    print(r.name, f"d {d:.2f} true {true}", " ".join(f"{k} {v:.1f}" for k, v in a.items()), file=sys.stderr)
for c in CONDS:
    rr = [x for x in rows if x[0] == c]
    ds = np.array([x[1] for x in rr])
    print(f"{c:12s} n {len(rr)} d median {np.median(ds):.2f} [{np.percentile(ds, 10):.2f}, {np.percentile(ds, 90):.2f}]",
          " ".join(f"{k} {np.median([x[3][k] for x in rr]):.2f}" for k in ("core", "est", "true")))
