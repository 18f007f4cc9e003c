import sys, numpy as np
sys.path.insert(0, '..')
import truth as T, harness as H, viz, exp1
from uwhl_rs import truth as tr
rows=[];labels=[]
want = ["chelsea_floor_gray_white_3C_n0.003", "coffee_wall_gray_white_5C_n0.003", "rocket_floor_gray_white_III_n0.015", "coffee_floor_gray_tinted_1C_n0.003", "chelsea_floor_own_white_II_n0.015"]
for r in T.scenes('tune', 360):
    if r.name not in want: continue
    st = H.Image(r.image); obj = r.objects
    cs = exp1.parts(r, st); q = st.guided(cs['p'])
    tt = np.where(obj, r.t[...,2], 1)
    imq, jq, tbq, _ = H.finish(st, r.water_type, q, fallback=False)
    imt, jt, tbt, _ = H.finish(st, r.water_type, tt, fallback=False)
    gq = tr.best_gains(imq, r.truth, obj); gt = tr.best_gains(imt, r.truth, obj)
    aq = tr.pixel_angles(imq*gq, r.truth).reshape(obj.shape); at = tr.pixel_angles(imt*gt, r.truth).reshape(obj.shape)
    err = -np.log(np.clip(tbq,1e-4,1)) + np.log(np.clip(tbt,1e-4,1))
    # error split by truth brightness and by t~ cluster count
    lum = r.truth.mean(-1)
    print(r.name, 'median ang q/t', np.median(aq[obj]).round(1), np.median(at[obj]).round(1), 'err ln t mean/sd', err[obj].mean().round(3), err[obj].std().round(3),
          'corr(err, lum)', np.corrcoef(err[obj], lum[obj])[0,1].round(2), 'corr(err, z)', np.corrcoef(err[obj], r.distance[obj])[0,1].round(2))
    rows.append([viz.tile(r.image), viz.tile(imq*gq), viz.tile(imt*gt), viz.tile(r.truth), viz.tile(err, lo=-0.7, hi=0.7), viz.tile(aq, lo=0, hi=30), viz.tile(at, lo=0, hi=30)])
    labels.append([r.name[:32], 'est t (best gains)', 'true t (best gains)', 'truth', 'ln t err -0.7..0.7', 'angle est 0-30', 'angle true t'])
viz.sheet(rows, 'out/diag2.png', labels)
