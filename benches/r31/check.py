import sys, time, numpy as np
sys.path.insert(0, '..')
import truth as T, uwhl_rs
import harness as H
from uwhl_rs import truth as tr
n=0
for r in T.scenes('tune', 360):
    n+=1
    if n%7: continue
    t0=time.time()
    res = uwhl_rs.restore(r.image, water_types=[r.water_type])
    t1=time.time()
    st = H.Image(r.image)
    q = st.default_q(r.water_type)
    im, jc, tb, ve = H.finish(st, r.water_type, q)
    t2=time.time()
    a = tr.score(res.image, r.truth, r.objects, gains=False)['median']
    b = tr.score(im, r.truth, r.objects, gains=False)['median']
    print(r.name, f"core {a:.2f} harness {b:.2f} |dtb| {np.abs(tb-res.transmission).max():.4f} |dimg| {np.abs(im-res.image).max():.4f} A {np.abs(st.a-res.veiling_light).max():.1e} ve {ve:.3f} {res.veil_excess:.3f} t {t1-t0:.2f} {t2-t1:.2f}")
