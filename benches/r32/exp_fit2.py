import numpy as np, common as C, fit as F, sys, time, json
from collections import defaultdict
split = sys.argv[1] if len(sys.argv)>1 else "tune"
vars_ = sys.argv[2].split(",") if len(sys.argv)>2 else ["distance","distance_noise","distance_holes"]
recs=[]
t0=time.time()
for r in C.renders(split):
    bt=C.beta_true(r)
    for vn in vars_:
        z=C.variants(r)[vn]
        ts=F.tile_stats(r.image,z)
        Z,I,K,_=F.tile_pixels(r.image,z)
        w=ts["w"]
        out={}
        b,a,_=F.fit_tiles(r.image,z,ts=ts); out["core"]=(b,a)
        for amax in (2.0,):
            cs,ks=F.lin_costs_clamped(ts,w,amax); b,a,_,_=F.curve_search(cs,ks); out[f"lin_A{amax}"]=(b,a)
        cs,ks=F.exact_costs(Z,I,K,w); b,a,_,_=F.curve_search(cs,ks); out["exact"]=(b,a)
        cs,ks=F.exact_costs(Z,I,K,w,amax=2.0); b,a,_,_=F.curve_search(cs,ks); out["exact_A2"]=(b,a)
        for k,(b,a) in out.items():
            recs.append(dict(name=r.name,geom=r.geometry,type=r.water_type,cond=f"{r.stats}/{r.light}",var=vn,cand=k,
                             ratio=(b/bt).tolist(),a=a.tolist(),at=r.a.tolist(),nt=F.nearest_type(b)))
    print(r.name, f"{time.time()-t0:.0f}", file=sys.stderr)
json.dump(recs,open(f"fit2_{split}.json","w"))
