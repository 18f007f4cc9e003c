"""Rules over the caches of benches/r31/s14/cache.py and the N0 of
guard.py: the entropy's type (ent3->sog) where its veil excess is at most
the default's plus a margin. Median angle per condition, type within one.

    python3 benches/r31/s16/guard_rules.py CACHE.json GUARD.json [...pairs]
"""
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "s14"))
import rules as R  # noqa: E402

MARGINS = [None, 0.0, 0.02, 0.05, 0.1, 1.0]


def pick(c, g, m):
    if m is None:
        return c["chosen"]
    k = g["k"]
    if k == c["chosen"]:
        return k
    return k if (g["n0_k"] or 0) - (g["n0_default"] or 0) <= m else c["chosen"]


args = sys.argv[1:]
for cache, guard in zip(args[::2], args[1::2]):
    rows, gs = json.load(open(cache)), json.load(open(guard))
    print(f"== {cache}")
    print(f"{'gray world':14s}", " | ".join(f"{np.median([r['gw'] for r in rows if r['cond'] == c]):6.2f}      "
                                         for c in R.CONDS))
    for m in MARGINS:
        cells = []
        for c in R.CONDS:
            sel = [(r, g) for r, g in zip(rows, gs) if r["cond"] == c]
            picks = [pick(r, g, m) for r, g in sel]
            ang = np.median([r["ang"][p] for (r, _), p in zip(sel, picks)])
            w1 = sum(abs(R.TY.index(p) - R.TY.index(r["true"])) <= 1 for (r, _), p in zip(sel, picks))
            cells.append(f"{ang:6.2f} {w1:2d}/{len(sel)}")
        name = "default" if m is None else f"ent3 N0+{m}"
        print(f"{name:14s}", " | ".join(cells))
