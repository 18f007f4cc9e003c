"""The entropy type of entropy.py put through the default's restoration:
median angle to the truth and the type within one step, side by side with
the default and gray world, per condition (issue 31).

    PYTHONPATH=python python3 benches/r31/s14/colour.py --split tune [--json F]
"""

import argparse
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", ".."))
import entropy as E  # noqa: E402
import truth as T  # noqa: E402

import uwhl_rs  # noqa: E402
from uwhl_rs import truth  # noqa: E402


def entropy_type(img, est, bw=0.05, kmin=2.0):
    img = np.asarray(img, np.float64)
    a = np.array(est.veiling_light, np.float64)
    mask = ~np.asarray(est.veiling_mask, bool)
    s, n = E.scores(img, a, mask, E.immerkaer(img)[None, None, :], bw, kmin)
    return (min(s, key=s.get) if s else None), float(np.asarray(est.veiling_mask, bool).mean())


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--split", default="tune")
    ap.add_argument("--every", type=int, default=1)
    ap.add_argument("--json")
    args = ap.parse_args()
    rows = []
    for i, r in enumerate(T.scenes(args.split)):
        if i % args.every:
            continue
        est = uwhl_rs.restore(r.image)
        k, vl = entropy_type(r.image, est)
        cand = uwhl_rs.restore(r.image, water_types=[k]) if k and k != est.water_type else est
        gw = T.baseline_rows(r)["gray_world"]
        row = {"scene": r.name, "content": r.content, "geometry": r.geometry, "condition": f"{r.stats}/{r.light}",
               "true": r.water_type, "default_type": est.water_type, "entropy_type": k, "vl_share": vl}
        for name, img in (("default", est.image), ("entropy", cand.image), ("gray_world", gw)):
            row[name] = truth.score(img, r.truth, r.objects, gains=True)["median"]
        rows.append(row)
        print(i, r.name, r.water_type, est.water_type, k, f"{row['default']:.1f} {row['entropy']:.1f}", file=sys.stderr)
    if args.json:
        json.dump(rows, open(args.json, "w"))
    report(rows)


def report(rows, gate=None):
    conds = ["gray/white", "gray/tinted", "own/white", "own/tinted"]
    for name in ("gray_world", "default", "entropy"):
        print(f"{name:12s}", " | ".join(f"{np.median([r[name] for r in rows if r['condition'] == c]):5.1f}" for c in conds))
    for col in ("default_type", "entropy_type"):
        cells = []
        for c in conds:
            v = [T.type_steps(r[col], r["true"]) for r in rows if r["condition"] == c]
            cells.append(f"{sum(1 for x in v if x == 0)}/{sum(1 for x in v if x is not None and x <= 1)}/{len(v)}")
        print(f"{col:12s}", " | ".join(cells))


if __name__ == "__main__":
    main()
