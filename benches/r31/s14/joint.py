"""Type and veiling light searched together by the entropy of entropy.py:
does the least entropy over A near the estimate move A toward the truth
(frames without open water, where the estimated A is off), or run away?

    PYTHONPATH=python python3 benches/r31/s14/joint.py [--every 2] [--geoms floor wall]
"""

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", ".."))
import entropy as E  # noqa: E402
import truth as T  # noqa: E402

import uwhl_rs  # noqa: E402


def pixels(image, est, n):
    """The default's A, the noise sigma and at most ``n`` object pixels
    (outside VL, 2 sigma from A in every channel; a fixed sample)."""
    img = np.asarray(image, np.float64)
    a0 = np.array(est.veiling_light, np.float64)
    sig = E.immerkaer(img)
    ok = ~np.asarray(est.veiling_mask, bool) & np.all(np.abs(img - a0) > 2 * sig, axis=2)
    px = img[ok]
    if len(px) > n:
        px = px[np.random.default_rng(0).choice(len(px), n, replace=False)]
    return a0, sig, px


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--split", default="tune")
    ap.add_argument("--every", type=int, default=2)
    ap.add_argument("--geoms", nargs="+", default=["floor", "wall", "floor_water"])
    ap.add_argument("--steps", type=float, nargs="+", default=[-0.4, -0.2, 0.0, 0.2, 0.4])
    ap.add_argument("--n", type=int, default=20000)
    args = ap.parse_args()
    dirs = E.directions()
    bases = {k: E.basis(v) for k, v in dirs.items()}
    out = []
    for i, r in enumerate(T.scenes(args.split)):
        if i % args.every or r.geometry not in args.geoms:
            continue
        est = uwhl_rs.restore(r.image)
        a0, sig, px = pixels(r.image, est, args.n)
        if len(px) < 200:
            continue
        best = (np.inf, None, None)
        grid = [(x, y, z) for x in args.steps for y in args.steps for z in args.steps]
        for dl in grid:
            a = a0 * np.exp(np.array(dl))
            lg = np.log(np.maximum(np.abs(px - a), sig))
            for k, b in bases.items():
                h = E.entropy2(lg @ b, 0.05)
                if h < best[0]:
                    best = (h, k, a)
        # the entropy choice at the estimated A, and at the true A (same pixels)
        def pick(a):
            lg = np.log(np.maximum(np.abs(px - a), 1e-6))
            s = {k: E.entropy2(lg @ b, 0.05) for k, b in bases.items()}
            return min(s, key=s.get)
        k0, kt = pick(a0), pick(r.a)
        e0 = float(np.max(np.abs(np.log(a0 / r.a))))
        e1 = float(np.max(np.abs(np.log(best[2] / r.a))))
        st = lambda k: T.type_steps(k, r.water_type)
        out.append((r.geometry, st(k0), st(best[1]), st(kt), e0, e1))
        print(i, r.name, r.water_type, "est", k0, "joint", best[1], "trueA", kt, f"|lnA err| {e0:.2f} -> {e1:.2f}", file=sys.stderr)
    for g in args.geoms:
        rr = [o for o in out if o[0] == g]
        w = lambda j: sum(1 for o in rr if o[j] is not None and o[j] <= 1)
        print(g, len(rr), "within one: estA", w(1), "joint", w(2), "trueA", w(3),
              "median |ln A err| est %.2f joint %.2f" % (np.median([o[4] for o in rr]), np.median([o[5] for o in rr])))


if __name__ == "__main__":
    main()
