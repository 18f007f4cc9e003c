"""Light-path estimators on the fitted water: the most consistent of several
sets of estimates, and gray world first when it is on the family."""
import numpy as np

import displab as D


def candidates(P):
    cands = {}
    for k, (d, o) in P.items():
        cands["d_" + k] = np.clip(d, 0, 15)
    for tau in (0.0, 0.1):
        for nm, ks in (("c4", ["gw", "sog4_", "ge1_", "wp"]), ("c3", ["gw", "ge1_", "wp"]),
                       ("c6", ["gw", "sog2_", "sog4_", "ge1_", "ge2_", "wp"]), ("cgw_wp", ["gw", "wp"]),
                       ("c_ge2wp", ["gw", "ge2_", "wp"])):
            ks = [k + str(tau) for k in ks]
            best = min(ks, key=lambda k: P[k][1])
            cands[f"{nm}_{tau}"] = np.clip(P[best][0], 0, 15)
        for th in (0.02, 0.05):
            ks = [k + str(tau) for k in ["gw", "sog4_", "ge1_", "wp"]]
            if P[ks[0]][1] < th:
                cands[f"gwfirst{th}_{tau}"] = np.clip(P[ks[0]][0], 0, 15)
            else:
                cands[f"gwfirst{th}_{tau}"] = np.clip(P[min(ks[1:], key=lambda k: P[k][1])][0], 0, 15)
    return cands


if __name__ == "__main__":
    D.run(candidates)
