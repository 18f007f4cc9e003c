"""The guards of guard.py over the s14 caches: median angle per
condition, the type within one step, and how many type changes a guard
stops, for each margin.

    python3 benches/r31/s16/guard_rules.py n0|m CACHE.json GUARD.json [CACHE GUARD ...]
"""
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "s14"))
import rules as R  # noqa: E402
from guard import take  # noqa: E402

MARGINS = {"n0": [None, 0.0, 0.02, 0.05, 0.1, 1.0], "m": [None, 0.0, 0.005, 0.01, 0.02, 1.0]}

by, args = sys.argv[1], sys.argv[2:]
for cache, guard in zip(args[::2], args[1::2]):
    rows, gs = json.load(open(cache)), json.load(open(guard))
    print(f"== {cache} (guard {by})")
    print(f"{'gray world':14s}", " | ".join(f"{np.median([r['gw'] for r in rows if r['cond'] == c]):6.2f}      "
                                         for c in R.CONDS))
    for m in MARGINS[by]:
        cells = []
        for c in R.CONDS:
            sel = [(r, g) for r, g in zip(rows, gs) if r["cond"] == c]
            picks = [take(g, r["chosen"], by, m) for r, g in sel]
            ang = np.median([r["ang"][p] for (r, _), p in zip(sel, picks)])
            w1 = sum(abs(R.TY.index(p) - R.TY.index(r["true"])) <= 1 for (r, _), p in zip(sel, picks))
            cells.append(f"{ang:6.2f} {w1:2d}/{len(sel)}")
        stopped = sum(1 for r, g in zip(rows, gs) if take(g, r["chosen"], by, m) != take(g, r["chosen"], by, 1e9))
        name = "default" if m is None else f"ent3 {by}+{m}"
        print(f"{name:14s}", " | ".join(cells), f" stopped {stopped if m is not None else '-'}")
