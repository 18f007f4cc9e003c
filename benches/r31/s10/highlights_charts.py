"""`highlights.py`'s rule on the real charts (gray patches, charts masked
out of estimation as `uwhl evaluate --mask-charts` does) and on the by-eye
photos as a contact sheet. Usage: highlights_charts.py [OUT.png]"""
import sys, os, numpy as np
import uwhl_rs
from uwhl_rs import images
here = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, here); sys.path.insert(0, os.path.join(here, ".."))
from highlights import neutral
from viz import sheet, tile
LOS = (None, 0.6, 0.7, 0.8, 0.9)
# per pixel on the display: the charts' own patches are neutralised too
from common import charts
charts(LOS, lambda r, objects, lo: r.image if lo is None else neutral(r.image, lo))
D = "/work/shared/data/images/"
rows, labels = [], []
for n in ["uwhl_Ancuti2_input.jpg", "uwhl_ship_highres_input.jpg", "udc_hazed5.jpg", "uieb_616.png", "lcm_sample_1.jpg"]:
    img, _ = images.read_image(D + n)
    r = uwhl_rs.restore(img)
    s = int(np.ceil(max(img.shape[:2]) / 300))
    rows.append([tile(x[::s, ::s]) for x in (img, r.image, neutral(r.image, 0.7))])
    labels.append([n[:30], "default", "highlights to neutral from 0.7"])
sheet(rows, sys.argv[1] if len(sys.argv) > 1 else "/tmp/s10/highlights.png", labels)
