"""s8: cache per render (fitted water as the core: F.fit_tiles, suspect -> default restore)
the recovered J (float32), the fitted beta, and the (d, residual) of the three §13.4 estimates.
Run from /tmp/s8d:  PYTHONPATH=/work/main/python RAYON_NUM_THREADS=1 python3 /work/main/benches/r32/s8/lab8.py tune
"""
import os
import pickle
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import numpy as np  # noqa: E402

import common as C  # noqa: E402
import displab as D  # noqa: E402
import fit as F  # noqa: E402

OUT = "/tmp/s8d/cache"
KS = ("gw0.0", "ge1_0.0", "wp0.0")
CONDS = ["gray/white", "gray/tinted", "own/white", "own/tinted"]


def one(r):
    z = C.variants(r)["distance"]
    ts = F.tile_stats(r.image, z)
    b, a, _ = F.fit_tiles(r.image, z, ts=ts)
    rec = dict(name=r.name, cname=r.content if hasattr(r, "content") else r.name.split("_")[0],
               cond=f"{r.stats}/{r.light}", true_d=5.0 if r.light == "tinted" else 0.0,
               wtype=r.water_type, bt=C.beta_true(r), b=b)
    rec["suspect"] = bool(F.suspect(ts, b, z)[0])
    if rec["suspect"]:
        import uwhl_rs
        rec["default"] = C.score(uwhl_rs.restore(r.image).image, r)
        return rec, None
    j = C.recover(r.image, z, b, a)
    sel = r.objects
    tmin = np.exp(-b.max() * C.fill_nearest(z))
    est = D.estimates(j, sel, tmin, D.box_edges(j))
    rec["est"] = {k: est[k] for k in KS}
    rec["P"] = {k: D.project(est[k], b) for k in KS}
    return rec, dict(j=j.astype(np.float32), sel=sel, truth=r.truth.astype(np.float32), objects=r.objects)


def build(split):
    t0 = time.time()
    recs = []
    os.makedirs(OUT, exist_ok=True)
    for r in C.renders(split):
        rec, arr = one(r)
        if arr is not None:
            np.savez(os.path.join(OUT, f"{split}_{r.name}.npz"), **arr)
        recs.append(rec)
        print(r.name, f"{time.time() - t0:.0f}s", file=sys.stderr)
    pickle.dump(recs, open(os.path.join(OUT, f"{split}.pkl"), "wb"))


class R:
    """Minimal stand-in for a Render for C.score (truth, objects)."""
    def __init__(self, truth, objects):
        self.truth, self.objects = truth, objects


def load(split):
    recs = pickle.load(open(os.path.join(OUT, f"{split}.pkl"), "rb"))
    for rec in recs:
        if not rec["suspect"]:
            z = np.load(os.path.join(OUT, f"{split}_{rec['name']}.npz"))
            rec["j"] = z["j"].astype(np.float64)
            rec["r"] = R(z["truth"].astype(np.float64), z["objects"])
    return recs


def score_d(rec, d):
    if rec["suspect"]:
        return rec["default"]
    key = round(float(d), 6)
    cache = rec.setdefault("_sc", {})
    if key not in cache:
        cache[key] = C.score(C.expose(rec["j"], np.exp(rec["b"] * d), rec["r"].objects), rec["r"])
    return cache[key]


def table(recs, rules, prefix=""):
    """rules: name -> f(rec) -> d. Prints median angle and median d per condition."""
    rows = {}
    for name, f in rules.items():
        sc = {c: [] for c in CONDS}
        dd = {c: [] for c in CONDS}
        for rec in recs:
            if rec["suspect"]:
                sc[rec["cond"]].append(rec["default"])
                continue
            d = f(rec)
            sc[rec["cond"]].append(score_d(rec, d))
            dd[rec["cond"]].append(d)
        med = [float(np.median(sc[c])) for c in CONDS]
        rows[name] = med
        print(f"{prefix}{name:28s}", " | ".join(f"{m:5.2f} (d {np.median(dd[c]) if dd[c] else float('nan'):4.1f})"
                                              for m, c in zip(med, CONDS)), f" mean {np.mean(med):.2f}")
    return rows


if __name__ == "__main__":
    build(sys.argv[1])
