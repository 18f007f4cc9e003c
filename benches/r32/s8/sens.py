"""s8: how the score moves with d per condition (tune, from diag8's grid): median over renders of s(d) - s(true)."""
import pickle, numpy as np
rows = pickle.load(open("/tmp/s8d/diag_tune.pkl", "rb"))
G = np.arange(0, 15.01, 0.25)
for c in ["gray/white", "gray/tinted", "own/white", "own/tinted"]:
    R = [w for w in rows if w["cond"] == c]
    S = np.array([w["sgrid"] for w in R])
    t = 0 if "white" in c else 20
    print(c, " ".join(f"d{G[i]:.1f}:{np.median(S[:, i]):.2f}" for i in range(0, 41, 4)))
