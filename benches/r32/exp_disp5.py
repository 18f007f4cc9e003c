"""The three estimates of METHOD §13.4 (gray world, box gray edge, white
patch): gray world's residual scaled by a margin, and weights 1/residual^2, ^4."""
import numpy as np

import displab as D


def candidates(P):
    cands = {}
    ks = ["gw0.0", "ge1_0.0", "wp0.0"]
    for m in (1.0, 0.7, 0.5, 0.3):
        rr = {k: P[k][1] * (1.0 if k == "gw0.0" else 1 / m) for k in ks}
        best = min(ks, key=lambda k: rr[k])
        cands[f"c3_m{m}"] = np.clip(P[best][0], 0, 15)
    for power in (2, 4):
        w = np.array([1 / max(P[k][1], 1e-3) ** power for k in ks])
        cands[f"c3_w{power}"] = np.clip(np.dot(w, [P[k][0] for k in ks]) / w.sum(), 0, 15)
    return cands


if __name__ == "__main__":
    D.run(candidates, edge_fn=D.box_edges)
