"""Diagnosis of the distance path on a split: fit errors and display errors per render.

    PYTHONPATH=/work/research_pkg RAYON_NUM_THREADS=1 python3 benches/r32/diag.py tune
"""

import json
import sys
import time

import numpy as np

import uwhl_rs
import common as C
import fit as F

split = sys.argv[1] if len(sys.argv) > 1 else "tune"
recs = []
t0 = time.time()
for r in C.renders(split):
    bt = C.beta_true(r)
    for key, z in C.variants(r).items():
        res = uwhl_rs.restore(r.image, distance=z)
        used = bool(res.distance["used"])
        rec = {"name": r.name, "content": r.content, "geom": r.geometry, "cond": f"{r.stats}/{r.light}",
               "type": r.water_type, "noise": r.noise, "var": key, "used": used, "bt": bt.tolist(),
               "at": r.a.tolist(), "core": C.score(res.image, r)}
        if res.water is not None:
            rec["bf"] = list(res.water["beta"])
            rec["af"] = list(res.water["veiling_light"]) if "veiling_light" in res.water else None
        rec["d_core"] = res.distance.get("light_path")
        if key == "distance":
            bnp, anp, _ = F.fit_tiles(r.image, z)
            rec["bnp"] = bnp.tolist()
            rec["anp"] = anp.tolist()
            sel = r.objects
            dtrue = 5.0 if r.light == "tinted" else 0.0
            jt = C.recover(r.image, z, bt, r.a)
            dct = C.light_path_core(jt, sel, bt)
            rec["oracle_t_dcore"] = C.score(C.expose(jt, np.exp(bt * dct), sel), r)
            rec["oracle_t_dtrue"] = C.score(C.expose(jt, np.exp(bt * dtrue), sel), r)
            rec["d_oracle_search"] = dct
            jf = C.recover(r.image, z, bnp, anp)
            dcf = C.light_path_core(jf, sel, bnp)
            rec["np_dcore"] = C.score(C.expose(jf, np.exp(bnp * dcf), sel), r)
            rec["np_dtrue"] = C.score(C.expose(jf, np.exp(bnp * dtrue), sel), r)
            rec["d_np"] = dcf
        recs.append(rec)
    print(r.name, f"{time.time() - t0:.0f}s", file=sys.stderr)
with open(f"{C.HERE}/diag_{split}.json", "w") as f:
    json.dump(recs, f, indent=0)
