"""The central type choice on the shared photos at full size through the
core: the types it changes, and a contact sheet (input, shades_of_gray,
central) of those (`../viz.py`). Usage: central_photos.py [OUT.png]"""
import sys, glob, os
import numpy as np
import uwhl_rs
from uwhl_rs import images
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from viz import sheet, tile
rows, labels = [], []
for p in sorted(glob.glob("/work/shared/data/images/*")):
    if p.endswith(".mat"): continue
    img, _ = images.read_image(p)
    a = uwhl_rs.restore(img, type_choice="shades_of_gray"); b = uwhl_rs.restore(img, type_choice="central")
    name = os.path.basename(p)
    print(f"{name:40s} {a.water_type:4s} -> {b.water_type:4s} fs {a.fallback_share or 0:.2f} {b.fallback_share or 0:.2f}", flush=True)
    if a.water_type != b.water_type:
        s = int(np.ceil(max(img.shape[:2]) / 240))
        rows.append([tile(x[::s, ::s]) for x in (img, a.image, b.image)])
        labels.append([name[:30], f"shades_of_gray {a.water_type}", f"central {b.water_type}"])
if rows:
    sheet(rows, sys.argv[1] if len(sys.argv) > 1 else "/tmp/s10/central_photos.png", labels)
