"""s8: the winner chosen on tune (gate tau = 0.15 on gray world's raw residual, delta = 1.0 m, gray world kept
in the competition) beside the current rule and the true d, on tune, held and fresh (held/fresh run once).
Also per condition: how many renders the gate fires on, and per-render changes."""
import os, sys
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import numpy as np
import lab8 as L, rules as U
WIN = U.gated(0.15, 1.0, drop_gw=False)
for split in sys.argv[1:]:
    recs = L.load(split)
    print(f"== {split}: {len(recs)} renders, {sum(r['suspect'] for r in recs)} suspect (default's score)")
    L.table(recs, {"current": U.current, "winner_t0.15_d1.0": WIN, "oracle": U.oracle})
    for c in L.CONDS:
        R = [r for r in recs if r["cond"] == c and not r["suspect"]]
        fired = sum(r["P"]["gw0.0"][1] > 0.15 for r in R)
        ch = [L.score_d(r, WIN(r)) - L.score_d(r, U.current(r)) for r in R]
        print(f"  {c:12s} gate fired {fired}/{len(R)}; per-render change better/worse/same "
              f"{sum(x < -0.05 for x in ch)}/{sum(x > 0.05 for x in ch)}/{sum(abs(x) <= 0.05 for x in ch)}, mean {np.mean(ch):+.2f}")
