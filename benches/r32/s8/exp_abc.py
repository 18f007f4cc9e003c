"""s8: the brief's candidates (a) largest d within k x the smallest residual, (b) 1/r^2 mean without
the clamp before averaging (and no margin), (c) offset delta when the chosen residual > thr; tune only."""
import os, sys
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import numpy as np
import lab8 as L, rules as U
recs = L.load("tune")
rules = {"current": U.current, "oracle": U.oracle}
for k in (1.5, 2, 3, 5):
    rules[f"a_largest_within_{k}"] = U.largest_within(k)
rules["b_w2_margin"] = U.wmean(2, True)
rules["b_w2_nomargin"] = U.wmean(2, False)
rules["b_w1_margin"] = U.wmean(1, True)
L.table(recs, rules)
# cue: chosen residual (with margin) and raw gw residual by condition
for c in L.CONDS:
    R = [r for r in recs if not r["suspect"] and r["cond"] == c]
    ch = [min(v[1] for v in U.rres(r).values()) for r in R]
    gw = [r["P"]["gw0.0"][1] for r in R]
    print(c, "chosen r pct10/50/90", np.round(np.percentile(ch, [10, 50, 90]), 3), " raw gw r", np.round(np.percentile(gw, [10, 50, 90]), 3))
rows = {}
for thr in (0.03, 0.05, 0.07, 0.1):
    for delta in (1, 1.5, 2, 2.5, 3, 4):
        rows[(thr, delta)] = L.table(recs, {f"c_thr{thr}_delta{delta}": U.offset(thr, delta)})
