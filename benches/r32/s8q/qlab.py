"""s8q: the distance fit (METHOD §13.2, NumPy mirror benches/r32/fit.py) on disparity-quantised maps.

Renders are cached in /tmp/s8q. Usage (repo root):
  PYTHONPATH=python RAYON_NUM_THREADS=1 python3 benches/r32/s8q/qlab.py cache tune|held
Throwaway research (issue 32, 2026-12-06)."""
import os
import pickle
import sys

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import numpy as np  # noqa: E402

import common as C  # noqa: E402
import fit as F  # noqa: E402

OUT = "/tmp/s8q"
CONDS = ["gray/white", "gray/tinted", "own/white", "own/tinted"]


class R:
    def __init__(self, d):
        self.__dict__.update(d)

    @property
    def objects(self):
        return np.isfinite(self.distance)


def cache(split):
    p = f"{OUT}/renders_{split}.pkl"
    if os.path.exists(p):
        return [R(d) for d in pickle.load(open(p, "rb"))]
    out = []
    for r in C.renders(split):
        out.append(dict(name=r.name, content=r.content, geometry=r.geometry, stats=r.stats, light=r.light,
                        water_type=r.water_type, noise=r.noise, image=r.image, truth=r.truth.astype(np.float32),
                        distance=r.distance.astype(np.float32), bt=C.beta_true(r)))
    pickle.dump(out, open(p, "wb"))
    return [R(d) for d in out]


def truez(r):
    return np.where(np.isfinite(r.distance), r.distance, np.nan).astype(np.float64)


def quantise(z, d0=30.0, q=1.0):
    """A stereo rig's map: disparity d = fB / z with fB such that the nearest known distance has
    disparity d0 px, d rounded to multiples of q px (at least q), back to z."""
    k = np.isfinite(z) & (z > 0)
    fb = d0 * np.nanmin(z[k])
    d = np.full(z.shape, np.nan)
    d[k] = np.maximum(np.round(fb / z[k] / q) * q, q)
    return fb / d


if __name__ == "__main__":
    if sys.argv[1] == "cache":
        rs = cache(sys.argv[2])
        print(len(rs))
