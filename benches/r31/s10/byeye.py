"""Issue 31's by-eye photos (ship_highres, uieb_616, udc_hazed5, Ancuti2)
and the chart photos: input, the default, gray world of the input, as a
contact sheet (`../viz.py`). Usage: byeye.py [OUT.png]"""
import sys, os
import numpy as np
import uwhl_rs
from uwhl_rs import images, evaluate as ev
sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
from viz import sheet, tile
D = "/work/shared/data/images/"
NAMES = ["uwhl_ship_highres_input.jpg", "uieb_616.png", "udc_hazed5.jpg", "uwhl_Ancuti2_input.jpg",
         "udc_1.jpg", "chart_calib_1_under.png", "chart_calib_2_under.jpg", "chart_calib_3_under.jpg"]
rows, labels = [], []
for n in NAMES:
    img, _ = images.read_image(D + n)
    r = uwhl_rs.restore(img)
    s = int(np.ceil(max(img.shape[:2]) / 320))
    rows.append([tile(x[::s, ::s]) for x in (img, r.image, ev.grayworld(img))])
    labels.append([n[:34], f"default {r.water_type} fallback {r.fallback_share or 0:.2f}", "gray world"])
    print(n, r.water_type, round(r.fallback_share or 0, 2), r.flags)
sheet(rows, sys.argv[1] if len(sys.argv) > 1 else "/tmp/s10/byeye.png", labels)
