import os, sys
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import lab8 as L, rules as U
recs = L.load("tune")
print(sum(r["suspect"] for r in recs), "suspect of", len(recs))
L.table(recs, {"current": U.current, "oracle": U.oracle})
