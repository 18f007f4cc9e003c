"""entropy.py's scores with the input's 8-bit quantisation dithered away:
an 8-bit photo's channel with little signal (a red of a few codes) takes
few distinct values, whose logarithms lie in stripes, and a projection that
keeps that channel scores a lower entropy for it. Each value moves by a
uniform fraction of the 8-bit sRGB step at it (a fixed hash of the pixel's
index, so the same everywhere). Recomputes the caches' entropy scores.

    PYTHONPATH=python python3 benches/r31/s14/dither.py CACHE.json SPLIT OUT.json
"""
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
import entropy as E  # noqa: E402
import truth as T  # noqa: E402

import uwhl_rs  # noqa: E402


def step8(v):
    """The linear size of one 8-bit sRGB code at linear value v."""
    v = np.clip(v, 0, 1)
    slope = np.where(v <= 0.0031308, 1 / 12.92, (2.4 / 1.055) * np.maximum(v, 1e-9) ** (1.4 / 2.4))
    return (1 / 255) * slope


def dithered(img):
    h, w, _ = img.shape
    idx = np.arange(h * w * 3, dtype=np.uint64).reshape(h, w, 3)
    # a fixed hash of the index to [0, 1)
    x = (idx * np.uint64(0x9E3779B97F4A7C15)) >> np.uint64(40)
    u = x.astype(np.float64) / float(1 << 24) - 0.5
    return img + u * step8(img)


def ent_scores(img, est):
    img = dithered(np.asarray(img, np.float64))
    a = np.array(est.veiling_light, np.float64)
    mask = ~np.asarray(est.veiling_mask, bool)
    s, _ = E.scores(img, a, mask, E.immerkaer(np.asarray(img, np.float64))[None, None, :], 0.05, 2.0)
    return s


if __name__ == "__main__":
    cache, split, out = sys.argv[1:4]
    rows = json.load(open(cache))
    for r, sc in zip(rows, T.scenes(split)):
        assert r["name"] == sc.name
        r["ent"] = ent_scores(sc.image, uwhl_rs.restore(sc.image))
    json.dump(rows, open(out, "w"))
