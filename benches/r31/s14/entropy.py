"""Water type by entropy minimisation (measured, issue 31 item 4).

In ln|I_c - A_c| = (beta_c / beta_B) ln t_B + ln|J_c - A_c| (METHOD §0) a
material's pixels lie on a line of the type's direction
v = (1/beta_BR, 1/beta_BG, 1) whatever their distance. Projected onto the
plane orthogonal to v, each material collapses to a point with the right
type and smears along a segment with a wrong one: the type whose
projection has the least entropy is chosen (the idea of Finlayson et al.'s
intrinsic images, with distance in the place of the illuminant). No
grouping into materials, no distance proxy. Prototype, tune split unless
--split; A true (oracle) or the default's.

    PYTHONPATH=python python3 benches/r31/s14/entropy.py [--split tune] [--every 1]
"""

import argparse
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", ".."))
import truth as T  # noqa: E402

import uwhl_rs  # noqa: E402
from uwhl_rs import synth  # noqa: E402


def directions():
    out = {}
    for k in T.TYPES:
        br, bg = synth.JERLOV[k]
        v = np.array([1 / br, 1 / bg, 1.0])
        out[k] = v / np.linalg.norm(v)
    return out


def basis(v):
    a = np.array([1.0, 0, 0]) if abs(v[0]) < 0.9 else np.array([0, 1.0, 0])
    u1 = np.cross(v, a)
    u1 /= np.linalg.norm(u1)
    u2 = np.cross(v, u1)
    return np.stack([u1, u2], 1)


def entropy2(p, bw):
    lo = p.min(0)
    idx = np.floor((p - lo) / bw).astype(np.int64)
    key = idx[:, 0] * 100003 + idx[:, 1]
    _, c = np.unique(key, return_counts=True)
    q = c / c.sum()
    return float(-(q * np.log(q)).sum())


NORM = False


def scores(img, a, mask, sigma, bw, kmin):
    d = np.abs(img - a[None, None, :])
    ok = mask & np.all(d > kmin * sigma, axis=2)
    lg = np.log(d[ok])
    if lg.shape[0] < 200:
        return None, int(ok.sum())
    # robust: the central 98% of each channel
    out = {}
    for k, v in directions().items():
        p = lg @ basis(v)
        if NORM:
            out[k] = entropy2(p, bw * float(np.std(lg @ v)))
        else:
            out[k] = entropy2(p, bw)
    return out, int(ok.sum())


def immerkaer(img):
    """Per-channel noise sigma (METHOD §12.5 step 1): median |K * I| / (6 x 0.6745)."""
    out = []
    for c in range(3):
        x = img[:, :, c]
        k = (x[:-2, :-2] - 2 * x[:-2, 1:-1] + x[:-2, 2:] - 2 * x[1:-1, :-2] + 4 * x[1:-1, 1:-1]
             - 2 * x[1:-1, 2:] + x[2:, :-2] - 2 * x[2:, 1:-1] + x[2:, 2:])
        out.append(np.median(np.abs(k)) / (6 * 0.6745))
    return np.array(out)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--split", default="tune")
    ap.add_argument("--every", type=int, default=1)
    ap.add_argument("--bw", type=float, nargs="+", default=[0.05, 0.1, 0.2])
    ap.add_argument("--kmin", type=float, nargs="+", default=[3.0])
    ap.add_argument("--oracle", action="store_true", help="true object mask and noise sigma")
    ap.add_argument("--by-geom", action="store_true")
    ap.add_argument("--norm", action="store_true")
    args = ap.parse_args()
    global NORM
    NORM = args.norm
    conds = [(s, l) for s in ("gray", "own") for l in ("white", "tinted")]
    res = {}
    for i, r in enumerate(T.scenes(args.split)):
        if i % args.every:
            continue
        cond = (r.stats, r.light) if not args.by_geom else r.geometry
        est = uwhl_rs.restore(r.image)
        a_est = np.array(est.veiling_light, dtype=np.float64)
        img = r.image.astype(np.float64)
        mask = r.objects if args.oracle else ~np.asarray(est.veiling_mask, bool)
        sig = r.noise if args.oracle else immerkaer(img)[None, None, :]
        for aname, a in (("trueA", r.a), ("estA", a_est)):
            for bw in args.bw:
                for km in args.kmin:
                    s, n = scores(img, a, mask, sig, bw, km)
                    key = (aname, bw, km)
                    pick = min(s, key=s.get) if s else None
                    st = (T.TYPES.index(pick) - T.TYPES.index(r.water_type)) if pick else None
                    res.setdefault(key, {}).setdefault(cond, []).append(st)
        st = (T.TYPES.index(est.water_type) - T.TYPES.index(r.water_type)) if est.water_type in T.TYPES else None
        res.setdefault(("default", 0, 0), {}).setdefault(cond, []).append(st)
        print(i, r.name, r.water_type, est.water_type, file=sys.stderr) if i % 20 == 0 else None
    for key in sorted(res, key=str):
        cells = []
        for c in (conds if not args.by_geom else sorted({g for d in res.values() for g in d})):
            v = res[key].get(c, [])
            ex = sum(1 for x in v if x == 0)
            bias = np.mean([x for x in v if x is not None]) if any(x is not None for x in v) else float('nan')
            w1 = sum(1 for x in v if x is not None and abs(x) <= 1)
            cells.append(f"{ex}/{w1}/{len(v)} ({bias:+.1f})")
        print(key, " | ".join(cells))


if __name__ == "__main__":
    main()
