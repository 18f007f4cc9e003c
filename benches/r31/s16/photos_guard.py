"""The guarded entropy rule of guard.py on the shared photos (480 px): the
default's type, the entropy's (ent3->sog), both veil excesses N0, and the
type the guard (margin 0) keeps; a contact sheet of the photos whose type
it changes: input, default, guarded.

    PYTHONPATH=python python3 benches/r31/s16/photos_guard.py [OUT.png]
"""
import glob
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "s14"))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import entropy as E  # noqa: E402
import rules as R  # noqa: E402
from viz import sheet, tile  # noqa: E402

import uwhl_rs  # noqa: E402
from uwhl_rs import images  # noqa: E402

D = "/work/shared/data/images/"
rows, labels, changed = [], [], 0
for p in sorted(glob.glob(D + "*.jpg") + glob.glob(D + "*.png")):
    img, _ = images.read_image(p)
    s = int(np.ceil(max(img.shape[:2]) / 480))
    img = np.ascontiguousarray(img[::s, ::s])
    r = uwhl_rs.restore(img)
    im64 = np.asarray(img, np.float64)
    ent, _ = E.scores(im64, np.array(r.veiling_light, np.float64), ~np.asarray(r.veiling_mask, bool),
                      E.immerkaer(im64)[None, None, :], 0.05, 2.0)
    k = R.r_ent3_sog({"chosen": r.water_type, "sog": {t: float(r.scores[t]) for t in R.TY}, "ent": ent})
    e = uwhl_rs.restore(img, water_types=[k]) if k and k != r.water_type else r
    n0d, n0k = r.veil_excess or 0.0, e.veil_excess or 0.0
    kept = k if n0k - n0d <= 0.0 else r.water_type
    n = os.path.basename(p)
    print(f"{n:32s} default {r.water_type:4s} N0 {n0d:.3f} fb {r.fallback_share or 0:.2f} | ent3 {k:4s} "
          f"N0 {n0k:.3f} fb {e.fallback_share or 0:.2f} | guarded {kept}")
    if kept != r.water_type:
        changed += 1
        rows.append([tile(x[::2, ::2]) for x in (img, r.image, e.image)])
        labels.append([n[:30], f"default {r.water_type}", f"guarded {kept}"])
print(f"{changed} photos change type")
if rows:
    sheet(rows, sys.argv[1] if len(sys.argv) > 1 else "/tmp/s16_photos_guard.png", labels)
