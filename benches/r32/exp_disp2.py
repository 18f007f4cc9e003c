"""Light-path estimators on the fitted water: each estimate projected on the
water's family, the most consistent one, the median of four, weights 1/residual^2."""
import numpy as np

import displab as D


def candidates(P):
    cands = {}
    for k, (d, o) in P.items():
        cands["d_" + k] = np.clip(d, 0, 15)
    for tau in (0.0, 0.1, 0.25):
        ks = [f"gw{tau}", f"sog4_{tau}", f"ge1_{tau}", f"wp{tau}"]
        best = min(ks, key=lambda k: P[k][1])
        cands[f"consist{tau}"] = np.clip(P[best][0], 0, 15)
        cands[f"median4_{tau}"] = np.clip(np.median([P[k][0] for k in ks]), 0, 15)
        ks2 = [f"gw{tau}", f"ge1_{tau}"]
        best = min(ks2, key=lambda k: P[k][1])
        cands[f"consist_gwge{tau}"] = np.clip(P[best][0], 0, 15)
        # weighted by 1/o^2
        wts = np.array([1 / max(P[k][1], 1e-3) ** 2 for k in ks])
        cands[f"wcons{tau}"] = np.clip(np.dot(wts, [P[k][0] for k in ks]) / wts.sum(), 0, 15)
    return cands


if __name__ == "__main__":
    D.run(candidates)
