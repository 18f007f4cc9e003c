"""s8 (d): gate variants, finer delta, kappa * r_gw, combos of ge/wp on coloured scenes; tune only.
Second line per rule: mean over renders per condition (a steadier view than the median)."""
import os, sys
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import numpy as np
import lab8 as L, rules as U
recs = L.load("tune")
rules = {"current": U.current, "oracle": U.oracle}
for tau in (0.1, 0.15, 0.2):
    for delta in (0.5, 0.75, 1.0, 1.25):
        rules[f"gate_t{tau}_d{delta}"] = U.gated(tau, delta, drop_gw=False)
for tau in (0.15,):
    for kap in (2, 3, 4, 5):
        rules[f"gate_t{tau}_kappa{kap}"] = U.gated(tau, 0.0, drop_gw=False, kappa=kap)
    for how in ("wp", "mean", "max", "w2"):
        for delta in (0, 0.5, 1.0):
            rules[f"combo_t{tau}_{how}_d{delta}"] = U.gated_combo(tau, delta, how)
L.table(recs, rules)
print("means over renders")
for name, f in rules.items():
    out = []
    for c in L.CONDS:
        s = [L.score_d(r, 0 if r["suspect"] else f(r)) for r in recs if r["cond"] == c]
        out.append(np.mean(s))
    print(f"{name:28s}", " | ".join(f"{m:5.2f}" for m in out))
