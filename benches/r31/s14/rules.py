"""Rules combining §12.2's scores and the entropy of entropy.py, on the
caches of cache.py: median angle per condition and the type within one
step. Rules are chosen on tune; held and fresh are read once.

    python3 benches/r31/s14/rules.py CACHE.json [CACHE2.json ...]
"""
import json
import sys

import numpy as np

TY = ["I", "IA", "IB", "II", "III", "1C", "3C", "5C", "7C", "9C"]
CONDS = ["gray/white", "gray/tinted", "own/white", "own/tinted"]


def ranks(d):
    order = sorted(TY, key=lambda t: d[t])
    return {t: order.index(t) for t in TY}


def r_default(r):
    return r["chosen"]


def r_entropy(r):
    return min(TY, key=lambda t: r["ent"][t]) if r["ent"] else r["chosen"]


def r_sog3_ent(r):
    best3 = sorted(TY, key=lambda t: r["sog"][t])[:3]
    return min(best3, key=lambda t: r["ent"][t]) if r["ent"] else r["chosen"]


def r_ent3_sog(r):
    if not r["ent"]:
        return r["chosen"]
    best3 = sorted(TY, key=lambda t: r["ent"][t])[:3]
    return min(best3, key=lambda t: r["sog"][t])


def r_ranksum(r):
    if not r["ent"]:
        return r["chosen"]
    a, b = ranks(r["sog"]), ranks(r["ent"])
    return min(TY, key=lambda t: (a[t] + b[t], b[t]))


def r_mid(r):
    """halfway (in the Jerlov order) between the default's and the entropy's, toward the entropy's"""
    if not r["ent"]:
        return r["chosen"]
    i, j = TY.index(r["chosen"]), TY.index(r_entropy(r))
    return TY[(i + j + (1 if j > i else 0)) // 2]


def spread(r):
    v = list(r["ent"].values())
    return (max(v) - min(v)) / np.mean(v)


def r_ent3_sog_gated(r, thr=0.03):
    """ent3->sog where the entropy tells the types apart (its spread over
    the ten at least 3% of its mean; chosen on tune), else the default's"""
    return r_ent3_sog(r) if r["ent"] and spread(r) >= thr else r["chosen"]


RULES = {"default": r_default, "entropy": r_entropy, "sog3->ent": r_sog3_ent, "ent3->sog": r_ent3_sog,
         "ranksum": r_ranksum, "mid": r_mid, "gated": r_ent3_sog_gated}


def report(rows, title):
    print(f"== {title} ({len(rows)} renders)")
    print(f"{'gray world':12s}", " | ".join(f"{np.median([r['gw'] for r in rows if r['cond'] == c]):5.1f}      " for c in CONDS))
    print(f"{'oracle':12s}", " | ".join(f"{np.median([min(r['ang'].values()) for r in rows if r['cond'] == c]):5.1f}      " for c in CONDS))
    for name, f in RULES.items():
        cells = []
        for c in CONDS:
            rr = [r for r in rows if r["cond"] == c]
            picks = [f(r) for r in rr]
            ang = np.median([r["ang"][p] for r, p in zip(rr, picks)])
            w1 = sum(1 for r, p in zip(rr, picks) if abs(TY.index(p) - TY.index(r["true"])) <= 1)
            cells.append(f"{ang:6.2f} {w1:2d}/{len(rr)}")
        print(f"{name:12s}", " | ".join(cells))


if __name__ == "__main__":
    for p in sys.argv[1:]:
        rows = json.load(open(p))
        report(rows, p)
