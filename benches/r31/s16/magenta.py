"""Does the display turn the water a hue the veiling light does not have?
For the default type and the entropy's (ent3->sog): the share of the
farthest fifth of the pixels (lowest t_B, VL included: the water) whose
displayed colour is magenta (green below 0.9 x both red and blue, and not
gray: max - min over 0.05). On renders (the s14 caches' order) and on the
shared photos; a guard takes the entropy's type only where it does not
raise that share by more than a margin.

    PYTHONPATH=python python3 benches/r31/s16/magenta.py SPLIT CACHE.json OUT.json
    PYTHONPATH=python python3 benches/r31/s16/magenta.py photos
"""
import glob
import json
import os
import sys

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", ".."))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "s14"))
import entropy as E  # noqa: E402
import rules as R  # noqa: E402

import uwhl_rs  # noqa: E402


def magenta(res) -> float:
    img = np.asarray(res.image, np.float64)
    t = np.asarray(res.transmission, np.float64)
    far = t <= np.quantile(t, 0.2)
    p = img[far]
    r, g, b = p[:, 0], p[:, 1], p[:, 2]
    m = (g < 0.9 * np.minimum(r, b)) & (p.max(1) - p.min(1) > 0.05)
    return float(m.mean()) if m.size else 0.0


if sys.argv[1] == "photos":
    sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
    from viz import sheet, tile  # noqa: E402

    from uwhl_rs import images
    rows, labels = [], []
    for p in sorted(glob.glob("/work/shared/data/images/*.jpg") + glob.glob("/work/shared/data/images/*.png")):
        img, _ = images.read_image(p)
        s = int(np.ceil(max(img.shape[:2]) / 480))
        img = np.ascontiguousarray(img[::s, ::s])
        d = uwhl_rs.restore(img)
        im64 = np.asarray(img, np.float64)
        ent, _ = E.scores(im64, np.array(d.veiling_light, np.float64), ~np.asarray(d.veiling_mask, bool),
                          E.immerkaer(im64)[None, None, :], 0.05, 2.0)
        k = R.r_ent3_sog({"chosen": d.water_type, "sog": {t: float(d.scores[t]) for t in R.TY}, "ent": ent})
        e = d if k == d.water_type else uwhl_rs.restore(img, water_types=[k])
        kept = k if magenta(e) - magenta(d) <= 0.01 else d.water_type
        print(f"{os.path.basename(p):32s} {d.water_type:4s} {magenta(d):.3f} | {k:4s} {magenta(e):.3f} | kept {kept}")
        if kept != d.water_type:
            rows.append([tile(x[::2, ::2]) for x in (img, d.image, e.image)])
            labels.append([os.path.basename(p)[:30], f"default {d.water_type}", f"guarded {kept}"])
    if rows:
        sheet(rows, sys.argv[2] if len(sys.argv) > 2 else "/tmp/s16_magenta.png", labels)
    sys.exit(0)

import truth as T  # noqa: E402

split, cache, out = sys.argv[1], sys.argv[2], sys.argv[3]
rows = json.load(open(cache))
got = []
for i, (r, c) in enumerate(zip(T.scenes(split), rows)):
    k = R.r_ent3_sog(c)
    d = uwhl_rs.restore(r.image)
    e = d if k == d.water_type else uwhl_rs.restore(r.image, water_types=[k])
    got.append({"name": c["name"], "k": k, "m_default": magenta(d), "m_k": magenta(e)})
json.dump(got, open(out, "w"))
