"""The veil excess of METHOD §12.5 per channel on real photos (2026-12-05):
which channel sits under the modelled veil, and how low.

    python3 n0diag.py chart_calib_3_under.jpg udc_hazed5.jpg ...
"""
import sys, numpy as np
sys.path.insert(0, __import__('os').path.join(__import__('os').path.dirname(__file__), '..', '..', 'python'))
import uwhl_rs
from uwhl_rs import synth
J=synth.JERLOV
for n in sys.argv[1:]:
    img=uwhl_rs.read_image(__import__('os').path.join(__import__('os').path.dirname(__file__), '..', '..', '..', 'shared', 'data', 'images', n))
    img=np.asarray(img[0], np.float32)
    r=uwhl_rs.restore(img)
    wt=r.water_type; br,bg=J[wt] if wt in J else (1,1)
    tb=r.transmission.astype(np.float64)
    t=np.stack([tb**(1/br), tb**(1/bg), tb],-1)
    A=np.array(r.veiling_light)
    veil=(1-t)*A
    obj=~np.asarray(r.veiling_mask)
    ex=(img < veil - 0.004)
    share=[ex[...,c][obj].mean() for c in range(3)]
    # for red-excess pixels, how low is I_R
    red=ex[...,0]&obj
    print(f'{n:28s} {wt:4s} N0 {r.veil_excess:.2f} excess share R/G/B {share[0]:.2f}/{share[1]:.2f}/{share[2]:.2f}  A {A.round(3)}  I_R at red-excess p50 {np.median(img[...,0][red]) if red.any() else 0:.4f} veil_R p50 {np.median(veil[...,0][red]) if red.any() else 0:.4f}  frac I_R<1/255^2.2 {(img[...,0][obj]<0.0005).mean():.2f}')
