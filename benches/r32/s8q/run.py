"""Run fit candidates on true and disparity-quantised maps; records to /tmp/s8q/<tag>.pkl, summary printed.
  PYTHONPATH=python RAYON_NUM_THREADS=1 python3 benches/r32/s8q/run.py tune TAG cand1,cand2 [maps] [angles]"""
import os
import pickle
import sys
from multiprocessing import Pool

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import numpy as np  # noqa: E402

import qfit as G  # noqa: E402
import qlab as Q  # noqa: E402
import fit as F  # noqa: E402
import common as C  # noqa: E402


def qstep(z):
    """The map's own disparity quantum: median gap between consecutive distinct values of 1/z."""
    u = np.unique(1.0 / z[np.isfinite(z)])
    g = np.diff(u)
    return float(np.median(g)) if len(g) else 0.0


def cands():
    c = {"base": {}}
    for k in (2, 3, 4):
        c[f"kmin{k}"] = dict(kmin=k)
    for s in (1, 2, 4, 8, 12):
        c[f"gauss{s}"] = dict(pre=("gauss", s))
        c[f"igauss{s}"] = dict(pre=("igauss", s))
    for s in (9, 17, 25):
        c[f"box{s}"] = dict(pre=("box", s))
        c[f"ibox{s}"] = dict(pre=("ibox", s))
    for few in (3, 4):
        for win in (8, 16, 24, 32):
            c[f"few{few}w{win}"] = dict(few=few, win=win)
            c[f"ifew{few}w{win}"] = dict(few=few, win=win, inv_plane=True)
    for L in (3, 4, 6):
        c[f"grow{L}"] = dict(grow=(L, (4, 8, 16, 32, 64)))
        c[f"igrow{L}"] = dict(grow=(L, (4, 8, 16, 32, 64)), inv_plane=True)
    for few in (3, 4):
        for win in (16, 24):
            c[f"jfew{few}w{win}"] = dict(few=few, win=win, inv_few=True)
    c["jgrow3"] = dict(grow=(3, (8, 16, 24, 32, 48)), inv_few=True)
    c["qvar"] = "qvar"
    c["qvar_k2"] = "qvar_k2"
    return c


CANDS = cands()
MAPS = {"true": None, "q1": (30.0, 1.0), "q05": (30.0, 0.5)}


def kwargs(name, z):
    c = CANDS[name]
    if c in ("qvar", "qvar_k2"):
        dq = qstep(z)
        kw = dict(qvar=lambda zm: (zm * zm * dq) ** 2 / 12.0)
        if c == "qvar_k2":
            kw["kmin"] = 2
        return kw
    return dict(c)


def one(args):
    r, names, maps, angles = args
    zt = Q.truez(r)
    recs = []
    for mn in maps:
        z = zt if MAPS.get(mn) is None else Q.quantise(zt, *MAPS[mn])
        for nm in names:
            beta, a, sus, zf, nt = G.fit(r.image, z, **kwargs(nm, z))
            ratio = beta / r.bt
            rec = dict(name=r.name, content=r.content, geom=r.geometry, cond=f"{r.stats}/{r.light}",
                       type=r.water_type, map=mn, cand=nm, ratio=ratio, err=float(np.nanmax(np.abs(ratio - 1))),
                       exact=bool(np.all(np.isfinite(beta)) and F.nearest_type(beta) == r.water_type),
                       sus=bool(sus), ntiles=nt)
            if angles:
                if not sus:
                    j = C.recover(r.image, zf, beta, a)
                    sel = r.objects & np.isfinite(zf)
                    d = C.light_path_core(j, sel, beta)
                    rec["ang"] = C.score(C.expose(j, np.exp(beta * d), r.objects), r)
                else:
                    import uwhl_rs
                    rec["ang"] = C.score(uwhl_rs.restore(r.image).image, r)
            recs.append(rec)
    return recs


def summary(recs, by="cand"):
    lines = []
    keys = list(dict.fromkeys((x["map"], x["cand"]) for x in recs))
    for mn, nm in keys:
        s = [x for x in recs if x["map"] == mn and x["cand"] == nm]
        cells = []
        for c in Q.CONDS:
            q = [x for x in s if x["cond"] == c]
            cell = f"b{sum(x['err'] <= .1 for x in q):2d} t{sum(x['exact'] for x in q):2d}"
            if "ang" in q[0]:
                cell += f" {np.median([x['ang'] for x in q]):5.2f}"
            cells.append(cell)
        geo = {g: sum(x["err"] <= .1 for x in s if x["geom"] == g) for g in dict.fromkeys(x["geom"] for x in s)}
        med = np.median([x["err"] for x in s])
        rat = np.nanmedian(np.array([x["ratio"] for x in s]), 0)
        lines.append(f"{mn:5s} {nm:10s} b10 {sum(x['err'] <= .1 for x in s):3d}/{len(s)} medworst {med:5.2f} "
                     f"exact {sum(x['exact'] for x in s):3d} sus {sum(x['sus'] for x in s):2d} "
                     f"ratio R/G/B {rat[0]:.2f}/{rat[1]:.2f}/{rat[2]:.2f} | " + " | ".join(cells) + f" | {geo}")
    return "\n".join(lines)


if __name__ == "__main__":
    split, tag, names = sys.argv[1], sys.argv[2], sys.argv[3].split(",")
    if names == ["all"]:
        names = list(CANDS)
    maps = sys.argv[4].split(",") if len(sys.argv) > 4 else list(MAPS)
    angles = len(sys.argv) > 5 and sys.argv[5] == "angles"
    shard = os.environ.get("SHARD")  # "i/n": every n-th render from i, saved as TAG.i; "merge": join them
    if shard == "merge":
        n = int(os.environ.get("NSHARD", "2"))
        recs = [x for i in range(n) for x in pickle.load(open(f"{Q.OUT}/{tag}.{i}.pkl", "rb"))]
    else:
        rs = Q.cache(split)
        i, n = map(int, (shard or "0/1").split("/"))
        recs = [x for r in rs[i::n] for x in one((r, names, maps, angles))]
        if shard:
            pickle.dump(recs, open(f"{Q.OUT}/{tag}.{i}.pkl", "wb"))
            sys.exit(0)
    pickle.dump(recs, open(f"{Q.OUT}/{tag}.pkl", "wb"))
    txt = summary(recs)
    open(f"{Q.OUT}/{tag}.txt", "w").write(txt + "\n")
    print(txt)
