"""Does a tone curve other than the one decoded bend the entropy's choice
(entropy.py)? The tune renders (every 4th) through x -> x^g (a camera
curve the sRGB decoding does not undo), the true A through the same, the
type of least entropy; within one step and the mean signed step (positive:
murkier than the truth).

    PYTHONPATH=python python3 benches/r31/s14/tone.py
"""
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
import entropy as E  # noqa: E402
import truth as T  # noqa: E402

res = {}
for i, r in enumerate(T.scenes("tune")):
    if i % 4:
        continue
    for g in (0.8, 1.0, 1.25):
        img = np.clip(r.image.astype(np.float64), 0, 1) ** g
        a = np.clip(r.a, 1e-6, 1) ** g
        sig = E.immerkaer(img)[None, None, :]
        s, _ = E.scores(img, a, r.objects, sig, 0.05, 2.0)
        k = min(s, key=s.get)
        res.setdefault(g, []).append(T.TYPES.index(k) - T.TYPES.index(r.water_type))
for g, v in res.items():
    v = np.array(v)
    print(f"g {g}: within one {np.sum(np.abs(v) <= 1)} of {len(v)}, mean step {v.mean():+.2f}")
