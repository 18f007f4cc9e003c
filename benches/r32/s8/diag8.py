"""s8 diagnosis on tune: per render the true d, each estimate's (d, residual), the pick, the best d on a grid."""
import os, sys
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import numpy as np
import lab8 as L, rules as U
import pickle
split = sys.argv[1] if len(sys.argv) > 1 else "tune"
recs = L.load(split)
GRID = np.arange(0, 15.01, 0.25)
rows = []
for rec in recs:
    if rec["suspect"]:
        continue
    q = U.rres(rec)
    pick = min(U.KS, key=lambda k: q[k][1])
    sg = np.array([L.score_d(rec, d) for d in GRID])
    rows.append(dict(name=rec["name"], cond=rec["cond"], true=rec["true_d"],
                     **{f"d_{k[:2]}": rec["P"][k][0] for k in U.KS}, **{f"r_{k[:2]}": rec["P"][k][1] for k in U.KS},
                     pick=pick[:2], d_cur=U.current(rec), s_cur=L.score_d(rec, U.current(rec)),
                     s_or=L.score_d(rec, rec["true_d"]), dbest=GRID[sg.argmin()], sbest=sg.min(), sgrid=sg,
                     bratio=rec["b"] / rec["bt"]))
pickle.dump(rows, open(f"/tmp/s8d/diag_{split}.pkl", "wb"))
print(f"{'name':44s} {'true':>4s} | {'d_gw':>5s} {'r_gw':>5s} | {'d_ge':>5s} {'r_ge':>5s} | {'d_wp':>5s} {'r_wp':>5s} | pk  d_cur s_cur s_or | dbest sbest | b/bt")
for c in L.CONDS:
    for w in rows:
        if w["cond"] != c:
            continue
        print(f"{w['name']:44s} {w['true']:4.1f} | {w['d_gw']:5.1f} {w['r_gw']:5.2f} | {w['d_ge']:5.1f} {w['r_ge']:5.2f} | "
              f"{w['d_wp']:5.1f} {w['r_wp']:5.2f} | {w['pick']} {w['d_cur']:5.1f} {w['s_cur']:5.1f} {w['s_or']:5.1f} | "
              f"{w['dbest']:5.2f} {w['sbest']:5.1f} | {np.round(w['bratio'], 2)}")
    print()
print("per condition medians: d_gw d_ge d_wp, r_gw r_ge r_wp, dbest; nearest-truth counts; pick counts")
for c in L.CONDS:
    R = [w for w in rows if w["cond"] == c]
    md = lambda k: np.median([w[k] for w in R])
    near = {k: 0 for k in ("gw", "ge", "wp")}
    for w in R:
        k = min(("gw", "ge", "wp"), key=lambda k: abs(np.clip(w[f"d_{k}"], 0, 15) - w["true"]))
        near[k] += 1
    picks = {k: sum(w["pick"] == k for w in R) for k in ("gw", "ge", "wp")}
    print(f"{c:12s} n={len(R)} d {md('d_gw'):5.2f} {md('d_ge'):5.2f} {md('d_wp'):5.2f} r {md('r_gw'):.3f} {md('r_ge'):.3f} {md('r_wp'):.3f}"
          f" dbest {md('dbest'):5.2f} near {near} pick {picks}")
