"""A peer that needs the distance, beside ``restore(distance=z)`` on the
renders of benches/truth.py (issue 32; METHOD §13.5): the error against the
true radiance and the time per render, in the same process.

    python3 benches/seathru_peer.py --peer DIR [--split held] [--every 1] [--size 360]

``DIR`` holds ``seathru.py`` of a public Sea-thru implementation (the one
measured: hainh/sea-thru at 5b9e740, taken with ``git show
HEAD:seathru.py`` from a clone; its code never enters this project). It is
imported and its ``run_pipeline`` called on the linear render and the true
distance (open water given its largest depth, as its own
``preprocess_sfm_depth_map`` does with a zero), with its defaults but
``min_depth = 0``: its default 0.1 leaves the nearest 10% of the depth range
unrestored. It needs scikit-learn, scikit-image, scipy, matplotlib and
rawpy (its imports). Its output is scaled to [0, 1] by its own ``scale``;
the angle is insensitive to exposure. Both run single-threaded
(RAYON_NUM_THREADS=1 is set here) so that the times compare one core each.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import os
import sys
import time

os.environ.setdefault("RAYON_NUM_THREADS", "1")

import numpy as np  # noqa: E402

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import truth as T  # noqa: E402

import uwhl_rs  # noqa: E402
from uwhl_rs import evaluate as ev  # noqa: E402
from uwhl_rs import truth as TR  # noqa: E402


def peer_args():
    return argparse.Namespace(f=2.0, l=0.5, p=0.01, min_depth=0.0, max_depth=1.0, spread_data_fraction=0.01,
                              size=10**6, output_graphs=False, monodepth=False, equalize_image=False)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--peer", required=True, help="folder holding the peer's seathru.py")
    ap.add_argument("--split", default="held", choices=["tune", "held", "all"])
    ap.add_argument("--every", type=int, default=1, help="every N-th render of the split")
    ap.add_argument("--size", type=int, default=360)
    a = ap.parse_args(argv)
    sys.path.insert(0, a.peer)
    import matplotlib

    matplotlib.use("Agg")
    matplotlib.use = lambda *_, **__: None  # the peer asks for TkAgg, which a headless machine has not
    import seathru  # the peer, from outside the project

    rows = {}
    for k, r in enumerate(T.scenes(a.split, a.size)):
        if k % a.every:
            continue
        z = np.where(np.isfinite(r.distance), r.distance, np.nan)
        cond = f"{r.stats}/{r.light}"
        t0 = time.perf_counter()
        ours = uwhl_rs.restore(r.image, distance=z.astype(np.float32)).image
        t_ours = time.perf_counter() - t0
        depths = np.where(np.isfinite(z), z, np.nanmax(z)).astype(np.float64)
        t0 = time.perf_counter()
        with contextlib.redirect_stdout(io.StringIO()):
            theirs = seathru.run_pipeline(np.asarray(r.image, np.float64), depths, peer_args())
        t_peer = time.perf_counter() - t0
        score = lambda img: TR.score(np.asarray(img, np.float64), r.truth, r.objects, gains=False)["median"]
        row = rows.setdefault(cond, {"ours": [], "peer": [], "gray_world": [], "t_ours": [], "t_peer": []})
        row["ours"].append(score(ours))
        row["peer"].append(score(theirs))
        row["gray_world"].append(score(ev.grayworld(r.image)))
        row["t_ours"].append(t_ours)
        row["t_peer"].append(t_peer)
        print(f"{r.name}: ours {row['ours'][-1]:.1f} deg {t_ours:.2f} s, peer {row['peer'][-1]:.1f} deg {t_peer:.2f} s",
              file=sys.stderr, flush=True)
    conds = [f"{s}/{l}" for s, l in T.CONDITIONS if f"{s}/{l}" in rows]
    print(f"split {a.split}, {a.size} px, every {a.every}; median over renders of the per-render median angle (deg), "
          "and the median seconds a render")
    print("| row | " + " | ".join(conds) + " |")
    print("|---|" + "---|" * len(conds))
    for key, label in (("ours", "restore(distance=z)"), ("peer", "Sea-thru peer, true z"), ("gray_world", "gray world")):
        print(f"| {label} | " + " | ".join(f"{np.median(rows[c][key]):.1f}" for c in conds) + " |")
    for key, label in (("t_ours", "seconds, restore(distance=z)"), ("t_peer", "seconds, Sea-thru peer")):
        print(f"| {label} | " + " | ".join(f"{np.median(rows[c][key]):.2f}" for c in conds) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
