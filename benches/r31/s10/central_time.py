"""Time of the central type choice against shades_of_gray in one process
(alternating, best of 3), on demo renders at 2.7 and 12 MP."""
import time, numpy as np, uwhl_rs
from uwhl_rs import synth
for h, w in ((1350, 2000), (3000, 4000)):
    img, _ = synth.demo_input(h, w, water_type="III", seed=3)
    best = {"shades_of_gray": 1e9, "central": 1e9}
    for _ in range(3):
        for k in best:
            t = time.perf_counter(); r = uwhl_rs.restore(img, type_choice=k); best[k] = min(best[k], time.perf_counter() - t)
    print(f"{h}x{w}", {k: round(v, 2) for k, v in best.items()}, "ratio", round(best["central"] / best["shades_of_gray"], 3))
