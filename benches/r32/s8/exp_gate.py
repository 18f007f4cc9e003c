"""s8 (d): gate on the raw gray-world residual; tune only."""
import os, sys, time
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import numpy as np
import lab8 as L, rules as U
recs = L.load("tune")
t0 = time.time()
L.table(recs, {"current": U.current, "oracle": U.oracle})
for tau in (0.1, 0.15, 0.2, 0.25):
    L.table(recs, {f"gate_tau{tau}_nodelta_drop": U.gated(tau, 0.0)})
    for delta in (1, 1.5, 2, 2.5, 3):
        L.table(recs, {f"gate_tau{tau}_d{delta}_drop": U.gated(tau, delta),
                       f"gate_tau{tau}_d{delta}_keep": U.gated(tau, delta, drop_gw=False)})
print(time.time() - t0, "s", file=sys.stderr)
