"""The entropy's type (ent3->sog) where its display's magenta share of the
far pixels (magenta.py) is at most the default's plus a margin; the caches
of benches/r31/s14 and the shares of magenta.py.

    python3 benches/r31/s16/magenta_rules.py CACHE.json MAG.json [...pairs]
"""
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "s14"))
import rules as R  # noqa: E402

MARGINS = [None, 0.0, 0.005, 0.01, 0.02, 1.0]


def pick(c, g, m):
    if m is None:
        return c["chosen"]
    return g["k"] if g["k"] == c["chosen"] or g["m_k"] - g["m_default"] <= m else c["chosen"]


args = sys.argv[1:]
for cache, mag in zip(args[::2], args[1::2]):
    rows, gs = json.load(open(cache)), json.load(open(mag))
    print(f"== {cache}")
    for m in MARGINS:
        cells = []
        for c in R.CONDS:
            sel = [(r, g) for r, g in zip(rows, gs) if r["cond"] == c]
            picks = [pick(r, g, m) for r, g in sel]
            ang = np.median([r["ang"][p] for (r, _), p in zip(sel, picks)])
            w1 = sum(abs(R.TY.index(p) - R.TY.index(r["true"])) <= 1 for (r, _), p in zip(sel, picks))
            cells.append(f"{ang:6.2f} {w1:2d}/{len(sel)}")
        blocked = sum(1 for r, g in zip(rows, gs) if m is not None and g["k"] != r["chosen"]
                      and g["m_k"] - g["m_default"] > m)
        name = "default" if m is None else f"ent3 mag+{m}"
        print(f"{name:14s}", " | ".join(cells), f" blocked {blocked}")
