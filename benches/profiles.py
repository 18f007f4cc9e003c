#!/usr/bin/env python3
"""The revised profile against the paper's, side by side in one run
(docs/METHOD.md §12): time per image, and whether fast selection picks
the same type as the exhaustive one under the revised choice.

    python3 benches/profiles.py            # 2.7 and 12 MP, every shared photo, renders of ten types
    python3 benches/profiles.py --quick    # 1 MP, two renders, no photos

* ``time``: ``restore`` on ``uwhl_rs.synth.demo_input`` renders with all ten
  types, each profile timed alternately, best of ``--repeat`` calls; the
  ratio revised / paper, and the same with ``selection="fast"``;
* ``fast``: ``selection="fast"`` against ``"exhaustive"`` under the revised
  profile: the chosen type on every shared photo (``../shared/data/images``,
  full size, sRGB decoded to linear) and on renders of the ten types
  (540x1100, two seeds), with both times.
"""

from __future__ import annotations

import argparse
import os
import sys
import time

import numpy as np

import uwhl_rs
from uwhl_rs import synth

DATA = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "shared", "data", "images")


sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from quality import best_of  # noqa: E402


def timing(sizes, repeat: int) -> None:
    print(f"{'size':>10} {'selection':>10} {'paper s':>8} {'revised s':>9} {'ratio':>6}")
    for h, w in sizes:
        img, _ = synth.demo_input(h, w, water_type="III", seed=3)
        for sel in ("exhaustive", "fast"):
            t = {"paper": float("inf"), "revised": float("inf")}
            for _ in range(repeat):  # alternate, so both see the same machine state
                for m in t:
                    t[m] = min(t[m], best_of(lambda: uwhl_rs.restore(img, method=m, selection=sel), 1))
            print(f"{w}x{h:>5} {sel:>10} {t['paper']:8.2f} {t['revised']:9.2f} {t['revised'] / t['paper']:6.2f}")


def agreement(quick: bool) -> None:
    from uwhl_rs.images import read_image

    cases = []
    if not quick and os.path.isdir(DATA):
        for name in sorted(os.listdir(DATA)):
            if name.lower().endswith((".jpg", ".jpeg", ".png")):
                cases.append(("photo", name, lambda name=name: read_image(os.path.join(DATA, name))[0]))
    for k, wt in enumerate(["III", "5C"] if quick else [n for n, _, _ in uwhl_rs._core.JERLOV_TABLE]):
        for seed in (1,) if quick else (1, 2):
            cases.append(("render", f"{wt} seed {seed}",
                          lambda wt=wt, seed=seed: synth.demo_input(540, 1100, water_type=wt, seed=seed)[0]))
    same = {"photo": [0, 0], "render": [0, 0]}
    print(f"\n{'kind':>6} {'input':>28} {'WxH':>10} {'exhaustive':>10} {'fast':>5} {'t exh':>6} {'t fast':>6}")
    for kind, name, load in cases:
        img = np.ascontiguousarray(load(), dtype=np.float32)
        t0 = time.perf_counter()
        ex = uwhl_rs.restore(img)
        t1 = time.perf_counter()
        fa = uwhl_rs.restore(img, selection="fast")
        t2 = time.perf_counter()
        same[kind][0] += ex.water_type == fa.water_type
        same[kind][1] += 1
        flag = "" if ex.water_type == fa.water_type else "  DIFFERENT"
        print(f"{kind:>6} {name:>28} {img.shape[1]:>4}x{img.shape[0]:<5} {ex.water_type:>10} {fa.water_type:>5} "
              f"{t1 - t0:6.2f} {t2 - t1:6.2f}{flag}", flush=True)
    print("agreement (revised): " + ", ".join(f"{k}s {v[0]}/{v[1]}" for k, v in same.items() if v[1]))


def main(argv) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true")
    ap.add_argument("--repeat", type=int, default=3)
    a = ap.parse_args(argv)
    print(f"uwhl_rs {uwhl_rs.__version__}, {os.cpu_count()} cores")
    timing([(1000, 1000)] if a.quick else [(1340, 2010), (3000, 4000)], a.repeat)
    agreement(a.quick)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
