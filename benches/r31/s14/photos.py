"""A type rule of rules.py (default ent3->sog) on the shared photos beside the default's,
and a contact sheet: input, default, the default restored with the entropy
type. Usage: photos.py [OUT.png]"""
import glob
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import dither as DI  # noqa: E402
import entropy as E  # noqa: E402
import rules as R  # noqa: E402
from viz import sheet, tile  # noqa: E402

import uwhl_rs  # noqa: E402
from uwhl_rs import images  # noqa: E402

D = "/work/shared/data/images/"
RULE = sys.argv[2] if len(sys.argv) > 2 else "ent3->sog"
rows, labels = [], []
for p in sorted(glob.glob(D + "*.jpg") + glob.glob(D + "*.png")):
    img, _ = images.read_image(p)
    s = int(np.ceil(max(img.shape[:2]) / 480))
    img = np.ascontiguousarray(img[::s, ::s])
    r = uwhl_rs.restore(img)
    if os.environ.get("DITHER"):
        ent = DI.ent_scores(img, r)
    else:
        im64 = np.asarray(img, np.float64)
        ent, _ = E.scores(im64, np.array(r.veiling_light, np.float64), ~np.asarray(r.veiling_mask, bool),
                          E.immerkaer(im64)[None, None, :], 0.05, 2.0)
    k = R.RULES[RULE]({"chosen": r.water_type, "sog": {t: float(r.scores[t]) for t in R.TY}, "ent": ent})
    e = uwhl_rs.restore(img, water_types=[k]) if k and k != r.water_type else r
    n = os.path.basename(p)
    print(f"{n:32s} default {r.water_type:4s} {RULE} {k} fallback {r.fallback_share or 0:.2f}")
    rows.append([tile(x[::2, ::2]) for x in (img, r.image, e.image)])
    labels.append([n[:30], f"default {r.water_type}", f"{RULE} {k}"])
sheet(rows, sys.argv[1] if len(sys.argv) > 1 else "/tmp/s14_photos.png", labels)
