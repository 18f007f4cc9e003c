"""Adds to a cache of cache.py each render's spread of the default's
optical depth -ln t_B over its object pixels outside VL (90th minus 10th
percentile): the entropy of entropy.py can tell types apart only where
distances vary (a material smears by the wrong direction times its range
of ln t_B).

    PYTHONPATH=python python3 benches/r31/s14/range.py CACHE.json SPLIT
"""
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
import truth as T  # noqa: E402

import uwhl_rs  # noqa: E402


def depth_range(est) -> float:
    m = ~np.asarray(est.veiling_mask, bool)
    x = -np.log(np.clip(np.asarray(est.transmission, np.float64)[m], 1e-6, 1))
    return float(np.percentile(x, 90) - np.percentile(x, 10)) if x.size else 0.0


if __name__ == "__main__":
    path, split = sys.argv[1:3]
    rows = json.load(open(path))
    for r, sc in zip(rows, T.scenes(split)):
        assert r["name"] == sc.name
        r["range"] = depth_range(uwhl_rs.restore(sc.image))
    json.dump(rows, open(path, "w"))
