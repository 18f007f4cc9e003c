import sys, numpy as np
sys.path.insert(0, '..')
import truth as T
import harness as H, viz
from uwhl_rs import truth as tr
rows=[];labels=[]
pick = {"chelsea_floor_gray_white_3C_n0.003","coffee_wall_gray_tinted_5C_n0.015","rocket_floor_gray_white_1C_n0.015","chelsea_floor_water_own_white_7C_n0.003", "rocket_wall_gray_white_III_n0.003"}
for r in T.scenes('tune', 360):
    if r.name not in pick and len(rows)>=5: continue
    if r.name not in pick and not (r.stats=='gray' and r.water_type in ('3C','5C','1C')): continue
    st = H.Image(r.image)
    v, rad, k, lb = st.haze(r.water_type)
    rmax = np.zeros(H.N_POINTS); np.maximum.at(rmax, k[k>=0], rad[k>=0])
    tt = st.t_tilde(rad, k, rmax)
    p = st.blend(tt, lb); q = st.guided(p)
    im, jc, tb, ve = H.finish(st, r.water_type, q)
    ttrue = np.where(r.objects, r.t[...,2], 0)
    lo, hi = 0, 1
    obj=r.objects
    print(r.name, 'rho q', np.corrcoef(-np.log(q[obj]), -np.log(np.clip(ttrue[obj],1e-6,1)))[0,1], 'mean q', q[obj].mean(), 'mean true', ttrue[obj].mean(), 'angle', tr.score(im, r.truth, obj)['median'])
    rows.append([viz.tile(r.image), viz.tile(r.truth), viz.tile(ttrue,lo=0,hi=1), viz.tile(0.9*tt,lo=0,hi=1), viz.tile(p,lo=0,hi=1), viz.tile(q,lo=0,hi=1), viz.tile(im)])
    labels.append([r.name[:30], 'truth', 'true tB', '0.9 t~', 'p', 'q', 'default tt'])
    if len(rows)>=8: break
viz.sheet(rows, 'out/diag1.png', labels)
