"""s8: light-path rules (METHOD §13.4 current and candidates), functions of a cached record."""
import numpy as np

KS = ("gw0.0", "ge1_0.0", "wp0.0")
GWM = 0.5


def rres(rec):
    """(d, residual with gray world's margin) per estimate, unclamped."""
    P = rec["P"]
    return {k: (P[k][0], P[k][1] * (GWM if k == "gw0.0" else 1.0)) for k in KS}


def current(rec):
    q = rres(rec)
    k = min(KS, key=lambda k: q[k][1])
    return float(np.clip(q[k][0], 0, 15))


def oracle(rec):
    return rec["true_d"]


def largest_within(kf):
    def f(rec):
        q = rres(rec)
        rmin = min(v[1] for v in q.values())
        return float(np.clip(max(v[0] for v in q.values() if v[1] <= kf * rmin), 0, 15))
    return f


def wmean(power=2, margin=True):
    def f(rec):
        q = rres(rec) if margin else {k: rec["P"][k] for k in KS}
        w = np.array([1 / max(q[k][1], 1e-3) ** power for k in KS])
        return float(np.clip(np.dot(w, [q[k][0] for k in KS]) / w.sum(), 0, 15))
    return f


def offset(thr, delta):
    def f(rec):
        q = rres(rec)
        k = min(KS, key=lambda k: q[k][1])
        d = q[k][0] + (delta if q[k][1] > thr else 0.0)
        return float(np.clip(d, 0, 15))
    return f


def gated(tau, delta, drop_gw=True, margin_base=True, kappa=0.0):
    """(d) the raw gray-world residual as the cue that the scene has a colour of its own:
    if r_gw > tau, gray world leaves the competition (drop_gw) and delta (+ kappa * r_gw) is added
    to the chosen d; otherwise the current rule."""
    def f(rec):
        q = rres(rec)
        rgw = rec["P"]["gw0.0"][1]
        if rgw > tau:
            ks = [k for k in KS if not (drop_gw and k == "gw0.0")]
            k = min(ks, key=lambda k: q[k][1])
            return float(np.clip(q[k][0] + delta + kappa * rgw, 0, 15))
        k = min(KS, key=lambda k: q[k][1])
        return float(np.clip(q[k][0], 0, 15))
    return f


def gated_combo(tau, delta, how):
    """Coloured scenes (r_gw > tau) take d from ge/wp by `how` (+ delta); others the current rule."""
    def f(rec):
        rgw = rec["P"]["gw0.0"][1]
        if rgw <= tau:
            return current(rec)
        dge, rge = rec["P"]["ge1_0.0"]
        dwp, rwp = rec["P"]["wp0.0"]
        if how == "wp":
            d = dwp
        elif how == "mean":
            d = (dge + dwp) / 2
        elif how == "max":
            d = max(dge, dwp)
        elif how == "w2":
            w = np.array([1 / max(rge, 1e-3) ** 2, 1 / max(rwp, 1e-3) ** 2])
            d = (w[0] * dge + w[1] * dwp) / w.sum()
        return float(np.clip(d + delta, 0, 15))
    return f
