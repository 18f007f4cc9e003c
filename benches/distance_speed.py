"""restore() with a distance map against without, in one process (METHOD §13).

    python3 benches/distance_speed.py [--size 1080x2560] [--repeat 3]

A rendered reef under open water (uwhl_rs.synth, a seabed from 1.5 to about
10 m: a span the fit takes, METHOD §13.1) of the given size with its true
distance (open water unknown);
the two calls alternate and the medians are reported as a ratio (no timed
assertion: speed is a ratio against the baseline run beside it)."""

import argparse
import time

import numpy as np

import uwhl_rs
from uwhl_rs import synth


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--size", default="1080x2560", help="HxW")
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args()
    h, w = (int(v) for v in a.size.split("x"))
    sc = synth.scene(h, w, kind="open_water", seed=2)
    img = synth.render(sc.clean, sc.distance, "3C", beta_b=0.3, noise=0.005, seed=1)
    z = np.where(np.isfinite(sc.distance), sc.distance, np.nan).astype(np.float32)
    uwhl_rs.restore(img[:64, :64])
    with_d, without = [], []
    for _ in range(a.repeat):
        t = time.perf_counter()
        uwhl_rs.restore(img)
        without.append(time.perf_counter() - t)
        t = time.perf_counter()
        r = uwhl_rs.restore(img, distance=z)
        with_d.append(time.perf_counter() - t)
    if not r.distance["used"]:
        raise SystemExit(f"the map was not used ({r.distance['rejected']}): this would time the fallback, not the fit")
    m0, m1 = float(np.median(without)), float(np.median(with_d))
    print(f"{h}x{w}: without distance {m0:.3f} s, with {m1:.3f} s, ratio {m1 / m0:.2f} "
          f"(distance used: {r.distance['used']})")


if __name__ == "__main__":
    main()
