"""The guards of guard.py on the shared photos (480 px): the default's
type and the entropy's, both measures for each, the type each guard keeps
(margin 0 for N0, 0.01 for the magenta share), and a contact sheet of the
photos whose type the chosen guard changes: input, default, guarded.

    PYTHONPATH=python python3 benches/r31/s16/guard_photos.py n0|m [OUT.png]
"""
import glob
import os
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from guard import both, measures, take  # noqa: E402
from viz import sheet, tile  # noqa: E402

from uwhl_rs import images  # noqa: E402

MARGIN = {"n0": 0.0, "m": 0.01}
by = sys.argv[1]
rows, labels = [], []
for p in sorted(glob.glob("/work/shared/data/images/*.jpg") + glob.glob("/work/shared/data/images/*.png")):
    img, _ = images.read_image(p)
    s = int(np.ceil(max(img.shape[:2]) / 480))
    img = np.ascontiguousarray(img[::s, ::s])
    d, e, k = both(img)
    g = measures(d, e, k)
    kept = take(g, d.water_type, by, MARGIN[by])
    n = os.path.basename(p)
    print(f"{n:32s} default {d.water_type:4s} N0 {g['n0_default']:.3f} magenta {g['m_default']:.3f} "
          f"fb {d.fallback_share or 0:.2f} | ent3 {k:4s} N0 {g['n0_k']:.3f} magenta {g['m_k']:.3f} "
          f"fb {e.fallback_share or 0:.2f} | kept {kept}")
    if kept != d.water_type:
        rows.append([tile(x[::2, ::2]) for x in (img, d.image, e.image)])
        labels.append([n[:30], f"default {d.water_type}", f"guarded {kept}"])
print(f"{len(rows)} photos change type")
if rows:
    sheet(rows, sys.argv[2] if len(sys.argv) > 2 else f"/tmp/s16_photos_{by}.png", labels)
