"""The entropy's type (benches/r31/s14, rule ent3->sog) guarded by what
the restoration itself shows, against §12.2's type (METHOD §12.6): the
veil excess N0 of §12.5 step 2 (the share of object pixels the estimated
veil over-explains), and the magenta share of the water (the farthest
fifth of the pixels, lowest t_B, VL included, shown with green under 0.9
x both red and blue and not gray: max - min over 0.05). Per render of a
split, in the order of the s14 cache: the entropy's type and both
measures for it and for the default's.

    PYTHONPATH=python python3 benches/r31/s16/guard.py SPLIT CACHE.json OUT.json
"""
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "s14"))
import entropy as E  # noqa: E402
import rules as R  # noqa: E402

import uwhl_rs  # noqa: E402


def magenta(res) -> float:
    """The share of the farthest fifth of the pixels shown magenta."""
    img = np.asarray(res.image, np.float64)
    t = np.asarray(res.transmission, np.float64)
    p = img[t <= np.quantile(t, 0.2)]
    m = (p[:, 1] < 0.9 * np.minimum(p[:, 0], p[:, 2])) & (p.max(1) - p.min(1) > 0.05)
    return float(m.mean()) if m.size else 0.0


def both(img, cached=None):
    """The default's restoration and the entropy's type's, and that type:
    from the cached scores of a render, else computed on the photo."""
    d = uwhl_rs.restore(img)
    if cached is None:
        im64 = np.asarray(img, np.float64)
        ent, _ = E.scores(im64, np.array(d.veiling_light, np.float64), ~np.asarray(d.veiling_mask, bool),
                          E.immerkaer(im64)[None, None, :], 0.05, 2.0)
        cached = {"chosen": d.water_type, "sog": {t: float(d.scores[t]) for t in R.TY}, "ent": ent}
    k = R.r_ent3_sog(cached)
    e = d if k == d.water_type else uwhl_rs.restore(img, water_types=[k])
    return d, e, k


def measures(d, e, k) -> dict:
    return {"k": k, "n0_default": d.veil_excess or 0.0, "n0_k": e.veil_excess or 0.0,
            "m_default": magenta(d), "m_k": magenta(e)}


def take(g: dict, chosen: str, by: str, margin) -> str:
    """The type a guard keeps: the entropy's where its measure `by` (n0 or
    m) is at most the default's plus `margin`; None: no guard."""
    if margin is None or g["k"] == chosen:
        return g["k"] if margin is not None else chosen
    return g["k"] if g[f"{by}_k"] - g[f"{by}_default"] <= margin else chosen


if __name__ == "__main__":
    import truth as T  # noqa: E402

    split, cache, out = sys.argv[1], sys.argv[2], sys.argv[3]
    rows = json.load(open(cache))
    got = []
    for i, (r, c) in enumerate(zip(T.scenes(split), rows)):
        assert r.name == c["name"], (r.name, c["name"])
        d, e, k = both(r.image, c)
        assert d.water_type == c["chosen"], (d.water_type, c["chosen"])
        got.append({"name": c["name"], **measures(d, e, k)})
        if i % 20 == 0:
            print(i, r.name, file=sys.stderr)
    json.dump(got, open(out, "w"))
