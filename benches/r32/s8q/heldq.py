"""One held-split run: base vs jfew4w16 (qfit.py as is) on true / q=1 / q=0.5 maps, with angles.
Per condition and total: beta within 10% on every channel, median worst-channel error, type exact,
suspect count, median angle. Records to /tmp/s8q/heldq.pkl.
  PYTHONPATH=/work/main/python RAYON_NUM_THREADS=1 python3 benches/r32/s8q/heldq.py   (repo root)"""
import os
import pickle
import sys
from multiprocessing import Pool

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import numpy as np  # noqa: E402

import qlab as Q  # noqa: E402
import run as RUN  # noqa: E402

NAMES = ["base", "jfew4w16"]
MAPS = ["true", "q1", "q05"]


def job(i):
    rs = Q.cache("held")
    return RUN.one((rs[i], NAMES, MAPS, True))


def row(label, q):
    if not q:
        return f"{label:12s} (none)"
    return (f"{label:12s} n{len(q):3d}  b10 {sum(x['err'] <= .1 for x in q):3d}  medworst {np.median([x['err'] for x in q]):5.3f}  "
            f"exact {sum(x['exact'] for x in q):3d}  sus {sum(x['sus'] for x in q):3d}  "
            f"medang {np.median([x['ang'] for x in q]):6.2f}")


if __name__ == "__main__":
    n = len(Q.cache("held"))
    with Pool(2) as p:
        recs = [x for rr in p.map(job, range(n), chunksize=1) for x in rr]
    pickle.dump(recs, open(f"{Q.OUT}/heldq.pkl", "wb"))
    out = []
    for mn in MAPS:
        for nm in NAMES:
            s = [x for x in recs if x["map"] == mn and x["cand"] == nm]
            out.append(f"== map {mn}  fit {nm}")
            for c in Q.CONDS:
                out.append(row(c, [x for x in s if x["cond"] == c]))
            out.append(row("total", s))
            for g in dict.fromkeys(x["geom"] for x in s):
                out.append(row("  " + g, [x for x in s if x["geom"] == g]))
    txt = "\n".join(out)
    open(f"{Q.OUT}/heldq.txt", "w").write(txt + "\n")
    print(txt)
