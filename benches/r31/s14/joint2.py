"""joint.py with a criterion that does not reward an A far from the
pixels: H(projection orthogonal to v) - 2 H(projection on v), each a
histogram entropy with bins 0.05 (scaling every logarithm by s moves the
first by 2 ln s and the second by ln s). Type alone at the default's A and
the true A, then type and A searched together.

    PYTHONPATH=python python3 benches/r31/s14/joint2.py [--every 2]
"""
import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
import entropy as E  # noqa: E402
import joint as J  # noqa: E402
import truth as T  # noqa: E402

import uwhl_rs  # noqa: E402


def entropy1(x, bw):
    idx = np.floor((x - x.min()) / bw).astype(np.int64)
    c = np.bincount(idx)
    q = c[c > 0] / len(x)
    return float(-(q * np.log(q)).sum())


def crit(lg, v, b, w):
    return E.entropy2(lg @ b, 0.05) - w * entropy1(lg @ v, 0.05)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--every", type=int, default=2)
    ap.add_argument("--w", type=float, nargs="+", default=[0.0, 1.0, 2.0])
    ap.add_argument("--joint", action="store_true")
    args = ap.parse_args()
    dirs = E.directions()
    bases = {k: E.basis(v) for k, v in dirs.items()}
    steps = [-0.4, -0.2, 0.0, 0.2, 0.4]
    out = {}
    for i, r in enumerate(T.scenes("tune")):
        if i % args.every:
            continue
        est = uwhl_rs.restore(r.image)
        a0, sig, px = J.pixels(r.image, est, 20000)
        for w in args.w:
            for aname, a in (("est", a0), ("true", r.a)):
                lg = np.log(np.maximum(np.abs(px - a), sig))
                s = {k: crit(lg, dirs[k], bases[k], w) for k in dirs}
                k = min(s, key=s.get)
                out.setdefault((w, aname, r.geometry), []).append(T.type_steps(k, r.water_type))
            if args.joint:
                best = (np.inf, None, None)
                for dl in [(x, y, z) for x in steps for y in steps for z in steps]:
                    a = a0 * np.exp(np.array(dl))
                    lg = np.log(np.maximum(np.abs(px - a), sig))
                    for k in dirs:
                        c = crit(lg, dirs[k], bases[k], w)
                        if c < best[0]:
                            best = (c, k, a)
                out.setdefault((w, "joint", r.geometry), []).append(T.type_steps(best[1], r.water_type))
                out.setdefault((w, "joint_aerr", r.geometry), []).append(float(np.max(np.abs(np.log(best[2] / r.a)))))
                out.setdefault((w, "est_aerr", r.geometry), []).append(float(np.max(np.abs(np.log(a0 / r.a)))))
    for key in sorted(out, key=str):
        v = out[key]
        if "aerr" in key[1]:
            print(key, "median |ln A err| %.2f" % np.median(v))
        else:
            print(key, "within one", sum(1 for x in v if x is not None and x <= 1), "of", len(v))


if __name__ == "__main__":
    main()
