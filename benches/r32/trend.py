"""How much of the fit's error is the content's own trend along the distance (METHOD §13.5).

For each content and geometry of benches/truth.py: the slope of ln J_c (the true radiance) on z over
the object pixels, per channel (1/m), beside the water's attenuation; then, over the renders under
white light with the content's own colours, the correlation of the fit's error beta_fit - beta with
minus that slope (a content that darkens with distance reads as more attenuation).

    PYTHONPATH=python python3 benches/r32/trend.py
"""

import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import truth as T  # noqa: E402  benches/truth.py

import uwhl_rs  # noqa: E402
from uwhl_rs import synth  # noqa: E402


def slopes(rho, z):
    ok = np.isfinite(z)
    lj = np.log(np.maximum(rho[ok], 1e-3))
    return np.array([np.polyfit(z[ok], lj[:, c], 1)[0] for c in range(3)])


def main():
    for split in ("tune", "held", "fresh"):
        for cname in T.SPLITS[split]:
            rho, zmap = T.content(cname, 360)
            h, w = rho.shape[:2]
            for g in (["stereo"] if zmap is not None else list(T.GEOMETRIES)):
                z = zmap if zmap is not None else T.geometry(g, h, w)
                s = slopes(rho, z)
                print(f"{split:5s} {cname:11s} {g:11s} d ln J / dz  R {s[0]:+.3f}  G {s[1]:+.3f}  B {s[2]:+.3f} 1/m")
    for split in ("tune", "held", "fresh"):
        err, tr = [], []
        for r in T.scenes(split, 360, conditions=[("own", "white")]):
            z = np.where(np.isfinite(r.distance), r.distance, np.nan).astype(np.float32)
            res = uwhl_rs.restore(r.image, distance=z)
            if not res.distance["used"]:
                continue
            bb = T.BETA_B[r.water_type]
            br, bg = synth.JERLOV[r.water_type]
            err.append(np.array(res.water["beta"]) - np.array([bb / br, bb / bg, bb]))
            tr.append(slopes(r.truth, r.distance))
        err, tr = np.array(err), np.array(tr)
        cor = [np.corrcoef(err[:, c], -tr[:, c])[0, 1] for c in range(3)]
        print(f"{split}: {len(err)} fits; corr(beta_fit - beta, -slope) R {cor[0]:.2f} G {cor[1]:.2f} B {cor[2]:.2f}; "
              f"median |beta_fit - beta| {np.median(np.abs(err), 0).round(3)}, median |slope| {np.median(np.abs(tr), 0).round(3)}")


if __name__ == "__main__":
    main()
